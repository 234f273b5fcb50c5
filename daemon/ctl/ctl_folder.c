/* The offline commands' view of a phase folder's stripes: period and phase order (ctl_folder.h). */
#include <math.h>
#include <stdio.h>
#include <sys/resource.h>
#include <unistd.h>

#include "daemon/ctl/ctl_folder.h"
#include "daemon/ctl/image_header.h"
#include "daemon/protocol/json_file.h"
#include "proc/proc_error.h"
#include "proc/stripe_period.h"
#include "proc/stripe_phase.h"

JsonNode *
ds_folder_read_sidecar (const char *path, GError **error)
{
  return ds_json_read_file_strict (path, DS_SIDECAR_MAX_BYTES, DS_SIDECAR_MAX_DEPTH, error);
}

void
ds_folder_limits_init (DsFolderLimits *limits)
{
  *limits = (DsFolderLimits) { .max_side = DS_FOLDER_MAX_SIDE, .max_pixels = DS_FOLDER_MAX_PIXELS };
}

gboolean
ds_folder_limits_from_options (DsFolderLimits *limits, gint64 max_side, gint64 max_pixels, gint64 max_memory_mib,
                               GError **error)
{
  ds_folder_limits_init (limits);
  const char *bad = max_side < 0     ? "--max-side"
                    : max_pixels < 0 ? "--max-pixels"
                    : max_memory_mib < 0 ? "--max-memory"
                                         : NULL;
  if (bad || max_memory_mib > (gint64) (G_MAXUINT64 >> 20)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: must be a positive number",
                 bad ? bad : "--max-memory");
    return FALSE;
  }
  if (max_side)
    limits->max_side = (guint64) max_side;
  if (max_pixels)
    limits->max_pixels = (guint64) max_pixels;
  limits->max_memory = (guint64) max_memory_mib << 20;
  return TRUE;
}

/* The bytes this process can still take: MemAvailable (what the kernel can hand out without
 * swapping) and, under an address-space limit, what is left of it. G_MAXUINT64: unknown. */
static guint64
memory_available (void)
{
  guint64 avail = G_MAXUINT64;
  FILE *f = fopen ("/proc/meminfo", "re");
  if (f) {
    char line[256];
    unsigned long long kib;
    while (fgets (line, sizeof line, f))
      if (sscanf (line, "MemAvailable: %llu kB", &kib) == 1)
        avail = (guint64) kib * 1024;
    fclose (f);
  }
  struct rlimit rl;
  if (getrlimit (RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
    guint64 used = 0;
    FILE *s = fopen ("/proc/self/statm", "re");
    unsigned long long pages;
    if (s && fscanf (s, "%llu", &pages) == 1)
      used = (guint64) pages * (guint64) sysconf (_SC_PAGESIZE);
    if (s)
      fclose (s);
    guint64 left = (guint64) rl.rlim_cur > used ? (guint64) rl.rlim_cur - used : 0;
    avail = MIN (avail, left);
  }
  return avail;
}

static gboolean
check_one (DsPhaseFolder *folder, const char *name, const DsFolderLimits *lim, guint64 *largest, GError **error)
{
  g_autofree char *path = g_build_filename (folder->dir, name, NULL);
  guint64 w = 0, h = 0;
  if (!ds_image_header_size (path, &w, &h, error))
    return FALSE;
  if (w == 0 || h == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: header says %" G_GUINT64_FORMAT "x%"
                 G_GUINT64_FORMAT " pixels", path, w, h);
    return FALSE;
  }
  if (w > lim->max_side || h > lim->max_side) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "%s: %" G_GUINT64_FORMAT "x%" G_GUINT64_FORMAT " pixels, a side above the limit of %"
                 G_GUINT64_FORMAT " (--max-side)", path, w, h, lim->max_side);
    return FALSE;
  }
  if (w * h > lim->max_pixels) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "%s: %" G_GUINT64_FORMAT "x%" G_GUINT64_FORMAT " = %" G_GUINT64_FORMAT
                 " pixels, above the limit of %" G_GUINT64_FORMAT " (--max-pixels)", path, w, h, w * h,
                 lim->max_pixels);
    return FALSE;
  }
  *largest = MAX (*largest, w * h);
  return TRUE;
}

gboolean
ds_folder_check_images (DsPhaseFolder *folder, const DsFolderLimits *lim, double bytes_per_pixel, const char *what,
                        GError **error)
{
  guint64 largest = 0;
  for (guint i = 0; i < ds_phase_folder_n_frames (folder); i++)
    if (!check_one (folder, ds_phase_folder_frame (folder, i)->file, lim, &largest, error))
      return FALSE;
  for (guint i = 0; i < folder->black_files->len; i++)
    if (!check_one (folder, folder->black_files->pdata[i], lim, &largest, error))
      return FALSE;
  double need = bytes_per_pixel * (double) largest;
  guint64 have = lim->max_memory ? lim->max_memory : memory_available ();
  if (need > (double) have) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "%s: %s of %" G_GUINT64_FORMAT " pixels needs about %.0f MiB (%.0f bytes a pixel), more than "
                 "the %.0f MiB %s", folder->dir, what, largest, need / 1048576.0, bytes_per_pixel,
                 (double) have / 1048576.0, lim->max_memory ? "allowed (--max-memory)" : "available");
    return FALSE;
  }
  return TRUE;
}

void
ds_folder_phases_clear (DsFolderPhases *fp)
{
  g_clear_pointer (&fp->fold_phase, g_free);
  g_clear_pointer (&fp->frames, g_free);
  g_clear_pointer (&fp->notice, g_free);
}

/* Frame 0 and the frame given the phase nearest half a period from it: their difference
 * cancels the scene. */
static gboolean
detect_period (DsPhaseFolder *folder, double *period, double *snr, GError **error)
{
  guint n = ds_phase_folder_n_phases (folder), other = 0;
  double best = -1;
  for (guint i = 1; i < ds_phase_folder_n_frames (folder); i++) {
    const DsPhaseFolderFrame *f = ds_phase_folder_frame (folder, i);
    double d = fabs (ds_stripe_phase_diff ((double) f->phase / n, (double) ds_phase_folder_frame (folder, 0)->phase / n));
    if (d > best) {
      best = d;
      other = i;
    }
  }
  g_autoptr (DsImage) a = ds_phase_folder_read (folder, 0, error);
  g_autoptr (DsImage) b = a && other ? ds_phase_folder_read (folder, other, error) : NULL;
  if (!a || (other && !b))
    return FALSE;
  GError *local = NULL;
  gboolean found = ds_stripe_period_detect (a, b, period, snr, &local);
  if (local) {
    g_propagate_error (error, local);
    return FALSE;
  }
  if (!found)
    *period = NAN;
  return TRUE;
}

static void
describe_frame (GString *s, const DsPhaseFolderFrame *f, const DsPhaseOrderFrame *o, guint n, double offset)
{
  if (o->found >= 0) {
    g_string_append_printf (s, "\n  %s: given phase %u, shows phase %d", f->file, f->phase, o->found);
    return;
  }
  long nearest = (lround (ds_stripe_phase_diff (o->phase, offset) * n) % (long) n + (long) n) % (long) n;
  g_string_append_printf (s, "\n  %s: given phase %u, shows none: %.0f %% of a phase step from phase %ld",
                          f->file, f->phase, 100 * fabs (o->residual) * n, nearest);
}

gboolean
ds_folder_phases_find (DsPhaseFolder *folder, double period_px, gboolean check, gboolean strict,
                       DsFolderPhases *out, GError **error)
{
  guint n = ds_phase_folder_n_phases (folder), nf = ds_phase_folder_n_frames (folder);
  const DsPhaseFolderSidecar *sc = &folder->sidecar;
  *out = (DsFolderPhases) { .period_px = NAN, .offset_cycles = NAN, .verdict = DS_PHASE_ORDER_UNKNOWN };
  out->fold_phase = g_new (guint, nf);
  out->frames = g_new0 (DsPhaseOrderFrame, nf);
  for (guint i = 0; i < nf; i++)
    out->fold_phase[i] = out->frames[i].given = ds_phase_folder_frame (folder, i)->phase;
  double snr = NAN;
  if (!isnan (period_px)) {
    out->period_px = period_px;
    out->period_source = "--period";
  } else if (sc->present && !isnan (sc->period_px)) {
    out->period_px = sc->period_px;
    out->period_source = "frames.json";
  } else {
    if (!detect_period (folder, &out->period_px, &snr, error))
      return FALSE;
    if (!isnan (out->period_px))
      out->period_source = "detected";
  }
  if (sc->has_phase_offset)
    out->offset_cycles = sc->phase_offset_cycles;
  if (isnan (out->period_px)) {
    out->notice = g_strdup_printf ("phase order not verified: no stripe period (none in frames.json, "
                                   "none found in the frames: strongest line %.1f sigma); give --period",
                                   snr);
    return TRUE;
  }
  if (!check)
    return TRUE;

  double tol = 0.25 / n; /* the daemon's default tolerance: a quarter of the phase step */
  guint unmeasured = 0;
  for (guint i = 0; i < nf; i++) {
    g_autoptr (DsImage) img = ds_phase_folder_read (folder, i, error);
    if (!img)
      return FALSE;
    DsStripePhase sp;
    GError *local = NULL;
    if (!ds_stripe_phase_measure (img, out->period_px, NULL, &sp, &local)) {
      g_propagate_prefixed_error (error, local, "%s: ", ds_phase_folder_frame (folder, i)->file);
      return FALSE;
    }
    /* measured when it can tell neighbouring phases apart: 2 sigma inside the tolerance */
    out->frames[i].measured = sp.reliable && 2 * sp.phase_sigma <= tol;
    out->frames[i].phase = sp.phase;
    unmeasured += !out->frames[i].measured;
  }
  out->checked = TRUE;
  out->verdict = ds_phase_order_check (out->frames, nf, n, tol, sc->has_phase_offset, &out->offset_cycles);
  out->offset_measured = !sc->has_phase_offset && !isnan (out->offset_cycles);
  for (guint i = 0; i < nf; i++)
    if (out->frames[i].found >= 0)
      out->fold_phase[i] = (guint) out->frames[i].found;

  g_autoptr (GString) s = g_string_new (NULL);
  for (guint i = 0; i < nf; i++)
    if (out->frames[i].measured && out->frames[i].found != (int) out->frames[i].given)
      describe_frame (s, ds_phase_folder_frame (folder, i), &out->frames[i], n, out->offset_cycles);
  switch (out->verdict) {
  case DS_PHASE_ORDER_OK:
    if (unmeasured)
      out->notice = g_strdup_printf ("phase order: %u of %u frames show no measurable stripes and are "
                                     "taken as given", unmeasured, nf);
    return TRUE;
  case DS_PHASE_ORDER_UNKNOWN:
    out->notice = g_strdup_printf ("phase order not verified: no frame shows measurable stripes at the "
                                   "period %g px (%s)", out->period_px, out->period_source);
    return TRUE;
  case DS_PHASE_ORDER_REORDERED:
    if (strict) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PHASE_ORDER,
                   "phase order: frames show other phases than given (stripe period %g px, %s):%s",
                   out->period_px, out->period_source, s->str);
      return FALSE;
    }
    out->notice = g_strdup_printf ("phase order: frames show other phases than given and are folded as "
                                   "they show (stripe period %g px, %s):%s",
                                   out->period_px, out->period_source, s->str);
    return TRUE;
  case DS_PHASE_ORDER_BROKEN:
  default: {
    g_autofree guint *count = g_new0 (guint, n);
    for (guint i = 0; i < nf; i++)
      count[out->fold_phase[i]] += out->frames[i].found >= 0 || !out->frames[i].measured;
    for (guint k = 0; k < n; k++)
      if (count[k] == 0)
        g_string_append_printf (s, "\n  phase %u: no frame shows it", k);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PHASE_ORDER,
                 "phase order: the frames do not make a phase set (stripe period %g px, %s; phase 0 "
                 "at %.3f cycles):%s",
                 out->period_px, out->period_source, out->offset_cycles, s->str);
    return FALSE;
  }
  }
}
