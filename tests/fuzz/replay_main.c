/* Replays fuzz inputs through a target without libFuzzer: every file named on the command line
 * (or every file in a named folder) is passed to LLVMFuzzerTestOneInput once. This keeps the
 * seed corpus and every crash ever found (kept as regression inputs) running in the ordinary
 * test suite, plain and under the sanitizers. */
#include <glib.h>
#include <stdint.h>
#include <stdio.h>

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

static int
replay_file (const char *path)
{
  g_autofree char *data = NULL;
  gsize len = 0;
  g_autoptr (GError) error = NULL;
  if (!g_file_get_contents (path, &data, &len, &error)) {
    fprintf (stderr, "replay: %s\n", error->message);
    return 1;
  }
  LLVMFuzzerTestOneInput ((const uint8_t *) data, len);
  return 0;
}

int
main (int argc, char **argv)
{
  unsigned n = 0;
  for (int i = 1; i < argc; i++) {
    if (g_file_test (argv[i], G_FILE_TEST_IS_DIR)) {
      g_autoptr (GDir) dir = g_dir_open (argv[i], 0, NULL);
      const char *name;
      while (dir && (name = g_dir_read_name (dir))) {
        g_autofree char *path = g_build_filename (argv[i], name, NULL);
        if (replay_file (path))
          return 1;
        n++;
      }
    } else {
      if (replay_file (argv[i]))
        return 1;
      n++;
    }
  }
  printf ("replayed %u inputs\n", n);
  return n > 0 ? 0 : 1;
}
