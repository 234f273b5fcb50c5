/* `descatterctl separate` and `calibrate` on hostile phase folders: each case is a folder an
 * attacker or an accident could hand the offline tools. Each must end with exit status 1 and
 * an error naming what is wrong and where, never a signal, never a hang, and within a bounded
 * address space (RLIMIT_AS set in the child: a read without bound fails the allocation and the
 * test instead of swapping the machine). The expectations come from the files' construction:
 * the test writes the PNG and TIFF headers byte by byte (its own CRC-32), not through the
 * project's writers. */
#include <gio/gio.h>
#include <glib/gstdio.h>
#include <signal.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

/* Under AddressSanitizer the shadow memory alone needs terabytes of address space. */
#if defined(__SANITIZE_ADDRESS__)
#define LIMIT_AS 0
#else
#define LIMIT_AS 1
#endif
#define AS_BYTES (1536ull << 20)
#define TIMEOUT_S 30

static char *root;

static void
limit_child (gpointer unused)
{
  (void) unused;
  if (LIMIT_AS) {
    struct rlimit rl = { AS_BYTES, AS_BYTES };
    setrlimit (RLIMIT_AS, &rl);
  }
}

typedef struct {
  int exit_status;  /* -1: killed by a signal or by the timeout */
  int signal;
  gboolean timed_out;
  char *err;
} Run;

static Run
run_ctl (const char *const *args)
{
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) DESCATTERCTL_PATH);
  for (guint i = 0; args[i]; i++)
    g_ptr_array_add (argv, (gpointer) args[i]);
  g_ptr_array_add (argv, NULL);
  g_autoptr (GSubprocessLauncher) l = g_subprocess_launcher_new (G_SUBPROCESS_FLAGS_STDOUT_SILENCE |
                                                                 G_SUBPROCESS_FLAGS_STDERR_PIPE);
  g_subprocess_launcher_set_child_setup (l, limit_child, NULL, NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (GSubprocess) p = g_subprocess_launcher_spawnv (l, (const char *const *) argv->pdata, &error);
  g_assert_no_error (error);
  Run r = { .exit_status = -1 };
  gint64 deadline = g_get_monotonic_time () + TIMEOUT_S * G_USEC_PER_SEC;
  while (g_get_monotonic_time () < deadline && g_subprocess_get_identifier (p))
    g_usleep (10000);
  if (g_subprocess_get_identifier (p)) {
    r.timed_out = TRUE;
    g_subprocess_force_exit (p);
    g_subprocess_wait (p, NULL, NULL);
  } else if (g_subprocess_get_if_exited (p))
    r.exit_status = g_subprocess_get_exit_status (p);
  else
    r.signal = g_subprocess_get_term_sig (p);
  g_autoptr (GBytes) b = NULL;
  GInputStream *in = g_subprocess_get_stderr_pipe (p);
  b = g_input_stream_read_bytes (in, 1 << 16, NULL, NULL);
  r.err = b ? g_strndup (g_bytes_get_data (b, NULL), g_bytes_get_size (b)) : g_strdup ("");
  return r;
}

/* ---- files written byte by byte ---- */

static guint32
crc32_of (const guint8 *p, gsize n)
{
  guint32 c = 0xFFFFFFFFu;
  for (gsize i = 0; i < n; i++) {
    c ^= p[i];
    for (int k = 0; k < 8; k++)
      c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return c ^ 0xFFFFFFFFu;
}

static void
put_be32 (GByteArray *a, guint32 v)
{
  guint8 b[4] = { v >> 24, v >> 16, v >> 8, v };
  g_byte_array_append (a, b, 4);
}

static void
png_chunk (GByteArray *a, const char *type, const guint8 *data, gsize n)
{
  put_be32 (a, (guint32) n);
  g_autoptr (GByteArray) td = g_byte_array_new ();
  g_byte_array_append (td, (const guint8 *) type, 4);
  if (n)
    g_byte_array_append (td, data, (guint) n);
  g_byte_array_append (a, td->data, td->len);
  put_be32 (a, crc32_of (td->data, td->len));
}

/* A greyscale 8-bit PNG declaring w x h pixels. Its one IDAT holds a stored (uncompressed)
 * zlib block of only the first row: the header is what decoders allocate from. */
static void
write_png (const char *dir, const char *name, guint32 w, guint32 h)
{
  g_autoptr (GByteArray) a = g_byte_array_new ();
  g_byte_array_append (a, (const guint8 *) "\x89PNG\r\n\x1a\n", 8);
  guint8 ihdr[13] = { w >> 24, w >> 16, w >> 8, w, h >> 24, h >> 16, h >> 8, h, 8, 0, 0, 0, 0 };
  png_chunk (a, "IHDR", ihdr, sizeof ihdr);
  guint8 idat[] = { 0x78, 0x01, 0x01, 0x02, 0x00, 0xFD, 0xFF, 0x00, 0x00 };
  png_chunk (a, "IDAT", idat, sizeof idat);
  png_chunk (a, "IEND", NULL, 0);
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_assert_true (g_file_set_contents (path, (const char *) a->data, a->len, NULL));
}

/* A little-endian TIFF, 8-bit greyscale, one uncompressed strip, declaring w x h. */
static void
write_tiff (const char *dir, const char *name, guint32 w, guint32 h)
{
  const guint16 tags[][2] = { { 256, 4 }, { 257, 4 }, { 258, 3 }, { 259, 3 }, { 262, 3 },
                              { 273, 4 }, { 277, 3 }, { 278, 4 }, { 279, 4 } };
  const guint32 values[] = { w, h, 8, 1, 1, 8, 1, h, w * h };
  g_autoptr (GByteArray) a = g_byte_array_new ();
  guint8 head[8] = { 'I', 'I', 42, 0, 16, 0, 0, 0 };
  g_byte_array_append (a, head, 8);
  guint8 pad[8] = { 0 };
  g_byte_array_append (a, pad, 8); /* the "strip" at offset 8 */
  guint8 n[2] = { G_N_ELEMENTS (tags), 0 };
  g_byte_array_append (a, n, 2);
  for (guint i = 0; i < G_N_ELEMENTS (tags); i++) {
    guint16 type = tags[i][1];
    guint32 v = values[i];
    guint8 e[12] = { tags[i][0] & 0xFF, tags[i][0] >> 8, type, 0, 1, 0, 0, 0, v, v >> 8, v >> 16, v >> 24 };
    g_byte_array_append (a, e, 12);
  }
  guint8 next[4] = { 0 };
  g_byte_array_append (a, next, 4);
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_assert_true (g_file_set_contents (path, (const char *) a->data, a->len, NULL));
}

static char *
new_folder (const char *name)
{
  char *d = g_build_filename (root, name, NULL);
  g_assert_cmpint (g_mkdir (d, 0700), ==, 0);
  return d;
}

static void
write_text (const char *dir, const char *name, const char *text, gssize len)
{
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_assert_true (g_file_set_contents (path, text, len, NULL));
}

#define SIDECAR_HEAD "{\"format\": \"descatter-phase-folder\", \"version\": 1, \"width\": 4, \"height\": 4, " \
                     "\"bit_depth\": 8, \"n_phases\": 2, "
#define SIDECAR_FRAMES "\"frames\": [{\"file\": \"a.png\", \"phase\": 0}, {\"file\": \"b.png\", \"phase\": 1}]}"

static char *
folder_with_sidecar (const char *name)
{
  char *d = new_folder (name);
  write_png (d, "a.png", 4, 4);
  write_png (d, "b.png", 4, 4);
  return d;
}

/* Both commands refuse the folder: exit 1, no signal, no hang, and the first error names
 * every fragment given (what and where). */
static void
expect_refused (const char *dir, const char *const *extra, const char *const *fragments)
{
  const char *commands[] = { "separate", "calibrate" };
  for (guint c = 0; c < G_N_ELEMENTS (commands); c++) {
    const char *args[12] = { commands[c], dir, "--quiet" };
    guint n = 3;
    for (guint i = 0; extra && extra[i]; i++)
      args[n++] = extra[i];
    args[n] = NULL;
    Run r = run_ctl (args);
    g_test_message ("%s %s: exit %d signal %d%s: %s", commands[c], dir, r.exit_status, r.signal,
                    r.timed_out ? " (timed out)" : "", r.err);
    if (r.timed_out || r.signal || r.exit_status != 1)
      g_error ("%s %s: exit %d, signal %d, %s; stderr: %s", commands[c], dir, r.exit_status, r.signal,
               r.timed_out ? "timed out" : "ended", r.err);
    for (guint i = 0; fragments[i]; i++)
      if (!strstr (r.err, fragments[i]))
        g_error ("%s %s: the error does not mention \"%s\": %s", commands[c], dir, fragments[i], r.err);
    g_free (r.err);
  }
}

static void
test_sidecar_deep (void)
{
  g_autofree char *d = folder_with_sidecar ("deep");
  gsize depth = 100000;
  g_autofree char *text = g_malloc (2 * depth);
  memset (text, '[', depth);
  memset (text + depth, ']', depth);
  write_text (d, "frames.json", text, (gssize) (2 * depth));
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "deep", NULL });
}

static void
test_sidecar_dev_zero (void)
{
  g_autofree char *d = folder_with_sidecar ("dev-zero");
  g_autofree char *link = g_build_filename (d, "frames.json", NULL);
  g_assert_cmpint (symlink ("/dev/zero", link), ==, 0);
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "not a regular file", NULL });
}

static void
test_sidecar_fifo (void)
{
  g_autofree char *d = folder_with_sidecar ("fifo");
  g_autofree char *fifo = g_build_filename (d, "frames.json", NULL);
  g_assert_cmpint (mkfifo (fifo, 0600), ==, 0);
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "not a regular file", NULL });
}

static void
test_sidecar_directory (void)
{
  g_autofree char *d = folder_with_sidecar ("directory");
  g_autofree char *sub = g_build_filename (d, "frames.json", NULL);
  g_assert_cmpint (g_mkdir (sub, 0700), ==, 0);
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "not a regular file", NULL });
}

static void
test_sidecar_too_large (void)
{
  g_autofree char *d = folder_with_sidecar ("too-large");
  /* valid JSON, padded with whitespace past 4 MiB */
  gsize n = (4u << 20) + 100;
  g_autofree char *text = g_malloc (n);
  memset (text, ' ', n);
  const char *body = SIDECAR_HEAD SIDECAR_FRAMES;
  memcpy (text, body, strlen (body));
  write_text (d, "frames.json", text, (gssize) n);
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "4194304", NULL });
}

static void
test_sidecar_duplicate_key (void)
{
  g_autofree char *d = folder_with_sidecar ("duplicate-key");
  write_text (d, "frames.json", SIDECAR_HEAD "\"n_phases\": 3, " SIDECAR_FRAMES, -1);
  expect_refused (d, NULL, (const char *const[]) { "frames.json", "duplicate member \"n_phases\"", NULL });
}

static void
test_png_too_wide (void)
{
  g_autofree char *d = new_folder ("png-30000");
  const char *names[] = { "p0.png", "p1.png", "p2.png", "p3.png" };
  for (guint i = 0; i < 4; i++)
    write_png (d, names[i], 30000, 30000);
  expect_refused (d, NULL, (const char *const[]) { "p0.png", "30000x30000", "--max-side", NULL });
}

static void
test_png_too_many_pixels (void)
{
  g_autofree char *d = new_folder ("png-9000");
  write_png (d, "p0.png", 9000, 9000);
  write_png (d, "p1.png", 9000, 9000);
  /* 81 000 000 > 64 Mi = 67 108 864 */
  expect_refused (d, NULL, (const char *const[]) { "p0.png", "81000000", "--max-pixels", NULL });
  /* the limit is an option */
  expect_refused (d, (const char *const[]) { "--max-pixels", "1000000", NULL },
                  (const char *const[]) { "p0.png", "1000000 (--max-pixels)", NULL });
}

static void
test_tiff_too_wide (void)
{
  g_autofree char *d = new_folder ("tiff-30000");
  write_tiff (d, "p0.tif", 30000, 30000);
  write_tiff (d, "p1.tif", 30000, 30000);
  expect_refused (d, NULL, (const char *const[]) { "p0.tif", "30000x30000", "--max-side", NULL });
}

/* 8000 x 8000 passes the side and pixel caps; four phases need more than --max-memory (and
 * more than the child's address space, so without the check the decode would fail there). */
static void
test_memory_estimate (void)
{
  g_autofree char *d = new_folder ("memory");
  const char *names[] = { "p0.png", "p1.png", "p2.png", "p3.png" };
  for (guint i = 0; i < 4; i++)
    write_png (d, names[i], 8000, 8000);
  expect_refused (d, (const char *const[]) { "--max-memory", "512", NULL },
                  (const char *const[]) { "64000000 pixels", "MiB", "--max-memory", NULL });
  if (LIMIT_AS)
    expect_refused (d, NULL, (const char *const[]) { "64000000 pixels", "MiB", "available", NULL });
}

static void
remove_tree (const char *path)
{
  GStatBuf st;
  if (g_lstat (path, &st) == 0 && S_ISDIR (st.st_mode)) {
    g_autoptr (GDir) d = g_dir_open (path, 0, NULL);
    const char *name;
    while (d && (name = g_dir_read_name (d))) {
      g_autofree char *p = g_build_filename (path, name, NULL);
      remove_tree (p);
    }
    g_rmdir (path);
  } else
    g_unlink (path);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  root = g_dir_make_tmp ("ds-hostile-XXXXXX", NULL);
  g_test_add_func ("/hostile/sidecar-nested-100000-deep", test_sidecar_deep);
  g_test_add_func ("/hostile/sidecar-dev-zero", test_sidecar_dev_zero);
  g_test_add_func ("/hostile/sidecar-fifo", test_sidecar_fifo);
  g_test_add_func ("/hostile/sidecar-directory", test_sidecar_directory);
  g_test_add_func ("/hostile/sidecar-too-large", test_sidecar_too_large);
  g_test_add_func ("/hostile/sidecar-duplicate-key", test_sidecar_duplicate_key);
  g_test_add_func ("/hostile/png-30000-square", test_png_too_wide);
  g_test_add_func ("/hostile/png-81-megapixels", test_png_too_many_pixels);
  g_test_add_func ("/hostile/tiff-30000-square", test_tiff_too_wide);
  g_test_add_func ("/hostile/memory-estimate", test_memory_estimate);
  int status = g_test_run ();
  remove_tree (root);
  g_free (root);
  return status;
}
