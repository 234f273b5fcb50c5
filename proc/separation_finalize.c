/* Finalize: the estimators (maxmin, sine, robust), the quality mask, the noise model and the
 * result. Formulas and choices: docs/estimators.md. Per pixel in double precision; integer
 * state is widened here, and the dark frame is subtracted here in signed arithmetic. */
#include <math.h>
#include <string.h>
#include <sys/mman.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"

/* P(Rayleigh noise amplitude > t) = exp(-t^2 / (2 s^2)) = 1e-3 at t = 3.717 s. */
#define DS_RAYLEIGH_999 3.7169221888498383

typedef struct {
  double a, b, m, h;
  guint n, m_frames;
  gboolean model, integer;
  double read_var;        /* read noise^2 (+ quantisation) in DN^2 */
  double gain;            /* K */
  double data_sigma;      /* one frame, NAN if unknown */
  double floor;           /* noise at zero signal (DARK test) */
  double sat;             /* NAN: no saturation test */
  double range_q;
} Consts;

typedef struct {
  double ld, lg, hi, lo, mean, sig_ld, sig_lg;
  guint8 mask;
} PixelOut;

static double
frame_var (const Consts *c, double signal)
{
  return c->read_var + c->gain * (signal > 0 ? signal : 0);
}

/* Robust (square stripes): the phase k_c at which this pixel is lit best comes from the
 * first harmonic of its N phase means (a fit to all N, so noise barely moves it when the
 * modulation is clear); "lit" is the mean of the ceil(aN) - 2 phases centred on k_c, "unlit"
 * the mean of the ceil((1-a)N) - 2 phases centred half a period away (each at least 1). A
 * sharp pattern lights floor(aN) or ceil(aN) consecutive phases (one fewer on a tie), so the
 * windows stay inside the lit and the unlit runs with a margin for blurred edges, and they
 * average several phases instead of picking the noisiest one. N = 2 and 3 reduce to maxmin
 * (one phase each). */
static void
robust_levels (const double *v, const double *cos_tab, const double *sin_tab, guint n,
               double duty, double *hi, double *lo, guint *n_hi, guint *n_lo)
{
  double cs = 0, sn = 0;
  for (guint k = 0; k < n; k++) {
    cs += v[k] * cos_tab[k];
    sn += v[k] * sin_tab[k];
  }
  double kc = atan2 (sn, cs) / (2 * G_PI) * n; /* v_k ~ cos (2 pi (k - kc) / N) */
  guint len_hi = (guint) MAX (1.0, ceil (duty * n - 1e-9) - 2);
  guint len_lo = (guint) MAX (1.0, ceil ((1 - duty) * n - 1e-9) - 2);
  long start_hi = lround (kc - (len_hi - 1) / 2.0);
  long start_lo = lround (kc + n / 2.0 - (len_lo - 1) / 2.0);
  double sh = 0, sl = 0;
  for (guint j = 0; j < len_hi; j++)
    sh += v[(guint) (((start_hi + (long) j) % (long) n + n) % n)];
  for (guint j = 0; j < len_lo; j++)
    sl += v[(guint) (((start_lo + (long) j) % (long) n + n) % n)];
  *hi = sh / len_hi;
  *lo = sl / len_lo;
  *n_hi = len_hi;
  *n_lo = len_lo;
}

/* maxmin on integer frames without noise model or extrema (the daemon's default): the same
 * formulas as the general loop below, in float, on whole rows. */
static void
maxmin_fast (const DsPhaseSet *set, DsSeparation *sep, const Consts *c)
{
  DsMaxminFast k;
  k.inv1b = (float) (1.0 / (1.0 - c->b));
  k.b = (float) c->b;
  k.invm = (float) (1.0 / c->m);
  k.m = (float) c->m;
  k.sat = isnan (c->sat) ? INFINITY : (float) c->sat;
  k.floor = isnan (c->floor) ? -INFINITY : (float) c->floor;
  double lowmod = c->range_q * c->data_sigma / sqrt ((double) c->m_frames);
  k.lowmod = isnan (lowmod) ? -INFINITY : (float) lowmod;
  guint w = set->width;
  g_autofree float *zeros = set->dark ? NULL : g_new0 (float, w);
  guint64 counts[DS_MASK_N_BITS + 1] = { 0 };
  for (guint y = 0; y < set->height; y++) {
    gsize off = (gsize) y * w;
    guint8 *mk = ds_image_row (sep->mask, y);
    ds_maxmin_fast_row (set->max16 + off, set->min16 + off, set->dark ? set->dark + off : zeros,
                        ds_image_row (sep->transmissive, y), ds_image_row (sep->scattered, y), mk,
                        w, &k);
    ds_count_mask_row (mk, w, counts);
  }
  sep->meta.valid_pixels = counts[0];
  for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
    sep->meta.flagged[bit] = counts[1 + bit];
}

/* Result planes are fresh memory: first-touch page faults cost more than the arithmetic.
 * Asking for transparent huge pages (where the system allows them on request) cuts the
 * faults 512-fold. Advisory only: failure changes nothing. */
static DsImage *
new_plane (DsSampleType type, guint w, guint h, GError **error)
{
  DsImage *img = ds_image_new (type, w, h, error);
#ifdef MADV_HUGEPAGE
  const gsize huge = 2u << 20;
  gsize bytes = img ? img->stride * h : 0;
  if (bytes >= 2 * huge) {
    guintptr start = ((guintptr) img->data + huge - 1) & ~(guintptr) (huge - 1);
    guintptr end = ((guintptr) img->data + bytes) & ~(guintptr) (huge - 1);
    if (end > start)
      (void) madvise ((void *) start, end - start, MADV_HUGEPAGE);
  }
#endif
  return img;
}

/* A plane from the recycled result when it has the right shape, else a new one. */
static gboolean
take_plane (DsImage **dst, DsImage **recycled, DsSampleType type, guint w, guint h, GError **error)
{
  if (recycled && *recycled && (*recycled)->type == type && (*recycled)->width == w &&
      (*recycled)->height == h) {
    *dst = g_steal_pointer (recycled);
    return TRUE;
  }
  *dst = new_plane (type, w, h, error);
  return *dst != NULL;
}

DsSeparation *
ds_phase_set_finalize (DsPhaseSet *set, GError **error)
{
  return ds_phase_set_finalize_reusing (set, NULL, error);
}

DsSeparation *
ds_phase_set_finalize_reusing (DsPhaseSet *set, DsSeparation *reuse, GError **error)
{
  g_autoptr (DsSeparation) old = reuse;
  const DsSeparationParams *p = &set->params;
  guint n = p->n_phases;
  if (set->frames == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "phase set is empty: no frame folded");
    return NULL;
  }
  guint m_frames = G_MAXUINT;
  for (guint k = 0; k < n; k++) {
    if (set->count[k] == 0) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                   "phase %u of N = %u has no frame (%u frames folded)", k, n, set->frames);
      return NULL;
    }
    m_frames = MIN (m_frames, set->count[k]);
  }
  ds_phase_set_fold_pending (set);

  Consts c = { 0 };
  c.a = p->duty;
  c.b = p->black_level;
  c.m = ds_pattern_mean (p->pattern, p->duty, p->black_level);
  c.h = p->harmonic_gain > 0 ? p->harmonic_gain
                             : ds_harmonic_gain_theory (p->pattern, p->duty, p->black_level);
  c.n = n;
  c.m_frames = m_frames;
  c.integer = set->type != DS_SAMPLE_F32;
  c.model = p->system_gain > 0;
  c.gain = p->system_gain;
  c.read_var = p->read_noise_dn * p->read_noise_dn + (c.integer ? 1.0 / 12.0 : 0.0);
  c.data_sigma = set->data_noise_dn;
  c.floor = c.model ? sqrt (c.read_var) : c.data_sigma;
  c.sat = p->saturation_level > 0 ? p->saturation_level
          : c.integer             ? (double) ((1u << set->bit_depth) - 1)
                                  : NAN;
  c.range_q = set->range_quantile;

  guint w = set->width, hgt = set->height;
  g_autoptr (DsSeparation) sep = g_new0 (DsSeparation, 1);
  gboolean extrema = p->keep_extrema;
  gboolean ok = take_plane (&sep->transmissive, old ? &old->transmissive : NULL, DS_SAMPLE_F32, w, hgt, error) &&
                take_plane (&sep->scattered, old ? &old->scattered : NULL, DS_SAMPLE_F32, w, hgt, error) &&
                take_plane (&sep->mask, old ? &old->mask : NULL, DS_SAMPLE_U8, w, hgt, error);
  if (ok && extrema)
    ok = take_plane (&sep->max, old ? &old->max : NULL, DS_SAMPLE_F32, w, hgt, error) &&
         take_plane (&sep->min, old ? &old->min : NULL, DS_SAMPLE_F32, w, hgt, error) &&
         take_plane (&sep->mean, old ? &old->mean : NULL, DS_SAMPLE_F32, w, hgt, error);
  if (ok && c.model)
    ok = take_plane (&sep->sigma_transmissive, old ? &old->sigma_transmissive : NULL, DS_SAMPLE_F32, w,
                     hgt, error) &&
         take_plane (&sep->sigma_scattered, old ? &old->sigma_scattered : NULL, DS_SAMPLE_F32, w, hgt,
                     error);
  if (!ok)
    return NULL;

  DsSeparationMeta *meta = &sep->meta;
  g_autofree double *v = g_new (double, n);
  g_autofree double *cos_tab = g_new (double, n);
  g_autofree double *sin_tab = g_new (double, n);
  for (guint k = 0; k < n; k++) {
    cos_tab[k] = cos (2 * G_PI * k / n);
    sin_tab[k] = sin (2 * G_PI * k / n);
  }
  double mean_total = 0;
  guint64 mean_count = 0;
  gboolean fast = set->max16 && p->estimator == DS_ESTIMATOR_MAXMIN && !c.model && !extrema;
  if (fast)
    maxmin_fast (set, sep, &c);
  for (guint y = 0; y < hgt && !fast; y++) {
    gsize off = (gsize) y * w;
    float *t_row = ds_image_row (sep->transmissive, y);
    float *g_row = ds_image_row (sep->scattered, y);
    guint8 *m_row = ds_image_row (sep->mask, y);
    float *mx_row = extrema ? ds_image_row (sep->max, y) : NULL;
    float *mn_row = extrema ? ds_image_row (sep->min, y) : NULL;
    float *me_row = extrema ? ds_image_row (sep->mean, y) : NULL;
    float *st_row = c.model ? ds_image_row (sep->sigma_transmissive, y) : NULL;
    float *sg_row = c.model ? ds_image_row (sep->sigma_scattered, y) : NULL;
    for (guint x = 0; x < w; x++) {
      gsize i = off + x;
      double hi_raw, lo_raw, mean_raw, rmax;
      if (set->max16) {
        hi_raw = set->max16[i];
        lo_raw = set->min16[i];
        mean_raw = set->sum32 ? (double) set->sum32[i] / n : NAN;
        rmax = hi_raw;
      } else {
        hi_raw = set->maxf[i];
        lo_raw = set->minf[i];
        mean_raw = set->sumd[i] / n;
        rmax = set->rawmax ? set->rawmax[i] : hi_raw;
      }
      double d = set->dark ? set->dark[i] : 0.0;
      gboolean bad = (set->nonfinite && set->nonfinite[i]) || !isfinite (d);
      PixelOut o = { 0 };
      if (bad) {
        o.mask = DS_MASK_NONFINITE;
      } else {
        o.hi = hi_raw - d;
        o.lo = lo_raw - d;
        if (o.lo < 0)
          o.mask |= DS_MASK_DARK_EXCEEDS;
        if (!isnan (c.sat) && rmax >= c.sat)
          o.mask |= DS_MASK_SATURATED;
        double var_hi = 0, var_lo = 0;
        guint n_hi = 1, n_lo = 1;
        double amp = 0;
        switch (p->estimator) {
        case DS_ESTIMATOR_SINE: {
          double cs = set->cos_sum[i], sn = set->sin_sum[i];
          amp = 2.0 / n * sqrt (cs * cs + sn * sn);
          o.mean = mean_raw - d;
          o.ld = amp / c.h;
          o.lg = o.mean / c.m - o.ld;
          break;
        }
        case DS_ESTIMATOR_ROBUST: {
          for (guint k = 0; k < n; k++)
            v[k] = set->phase_means[(gsize) k * set->npix + i] - d;
          double lit, unlit;
          robust_levels (v, cos_tab, sin_tab, n, p->pattern == DS_PATTERN_SINE ? 0.5 : c.a, &lit,
                         &unlit, &n_hi, &n_lo);
          o.mean = mean_raw - d;
          o.ld = (lit - unlit) / (1.0 - c.b);
          o.lg = (unlit - c.b * o.ld) / c.m;
          var_hi = lit;
          var_lo = unlit;
          break;
        }
        default:
          o.ld = (o.hi - o.lo) / (1.0 - c.b);
          o.lg = (o.lo - c.b * o.ld) / c.m;
          o.mean = isnan (mean_raw) ? c.m * (o.ld + o.lg) : mean_raw - d;
          var_hi = o.hi;
          var_lo = o.lo;
          break;
        }
        /* Noise of one phase (mean of M frames) at this pixel's signal. */
        double sig_frame = c.model ? sqrt (frame_var (&c, o.mean)) : c.data_sigma;
        double sig_phase = sig_frame / sqrt ((double) c.m_frames);
        if (!isnan (c.floor) && o.mean <= c.floor)
          o.mask |= DS_MASK_DARK;
        if (!isnan (sig_phase)) {
          gboolean low = p->estimator == DS_ESTIMATOR_SINE
                             ? amp < DS_RAYLEIGH_999 * sig_phase * sqrt (2.0 / n)
                             : (hi_raw - lo_raw) < c.range_q * sig_phase;
          if (low)
            o.mask |= DS_MASK_LOW_MODULATION;
        }
        if (o.ld < 0 || o.lg < 0)
          o.mask |= DS_MASK_NEGATIVE;
        if (c.model) {
          double vd = set->dark ? c.read_var : 0.0;
          double mf = c.m_frames;
          if (p->estimator == DS_ESTIMATOR_SINE) {
            double vbar = frame_var (&c, o.mean) / mf;
            double va = 2.0 * vbar / n, vm = vbar / n;
            o.sig_ld = sqrt (va) / c.h;
            o.sig_lg = sqrt (vm / (c.m * c.m) + va / (c.h * c.h) + vd / (c.m * c.m));
          } else {
            double vh = frame_var (&c, var_hi) / (mf * n_hi);
            double vl = frame_var (&c, var_lo) / (mf * n_lo);
            double ib = 1.0 - c.b;
            o.sig_ld = sqrt (vh + vl) / ib;
            o.sig_lg = sqrt ((vl + c.b * c.b * vh) / (ib * ib * c.m * c.m) + vd / (c.m * c.m));
          }
        }
        mean_total += o.mean;
        mean_count++;
      }
      t_row[x] = (float) o.ld;
      g_row[x] = (float) o.lg;
      m_row[x] = o.mask;
      if (extrema) {
        mx_row[x] = (float) o.hi;
        mn_row[x] = (float) o.lo;
        me_row[x] = (float) o.mean;
      }
      if (c.model) {
        st_row[x] = (float) o.sig_ld;
        sg_row[x] = (float) o.sig_lg;
      }
      if (o.mask == 0)
        meta->valid_pixels++;
      else
        for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
          meta->flagged[bit] += (o.mask >> bit) & 1u;
    }
  }

  meta->n_phases = n;
  meta->frames_per_phase = m_frames;
  meta->estimator = p->estimator;
  meta->duty = p->duty;
  meta->black_level = p->black_level;
  meta->pattern_mean = c.m;
  meta->harmonic_gain = c.h;
  meta->dark_subtracted = set->dark != NULL;
  meta->saturation_level = c.sat;
  if (c.model)
    meta->noise_dn = sqrt (frame_var (&c, mean_count ? mean_total / mean_count : 0));
  else
    meta->noise_dn = c.data_sigma;
  return g_steal_pointer (&sep);
}
