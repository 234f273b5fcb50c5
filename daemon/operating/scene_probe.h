/* What the pilot frames of an automatic capture say about the scene in front of the camera:
 * how much direct light there is and how it varies, how much scattered light, how noisy a frame
 * is, how blurred the stripes arrive, and how much of the scattered light keeps the stripes
 * (docs/accuracy.md, "Automatic operating point").
 *
 * Pilot frames: a dark frame, and at the configured period P the phases 0 and 1/2 (a two-phase
 * separation); where the illuminator can change its period, the same at 2P. The difference of
 * two opposite phases holds the odd harmonics of the pattern times the light that keeps it;
 * its column profile gives their amplitudes, its mean square how Ld varies across the scene.
 *
 * The model of a harmonic n at period Q (frame mean, first order in the leak):
 *     A_n(Q) = Ld G_n(Q, sigma) exp(alpha Q / n)
 * G_n is the sampled gain of the blurred, pixel-integrated pattern (stripe_model.h), exp(alpha Q/n)
 * the transfer of the pattern by the medium relative to the ballistic light alone: forward
 * scattering at small angles spreads light by a distance that grows with depth, and in the
 * small-angle limit of a Henyey-Greenstein medium the transfer of frequency f is
 * exp(sigma_s integral_0^d exp(-c f (d - z)) dz) ~ exp(sigma_s / (c f)) for c f d >> 1, so the
 * logarithm of the apparent Ld grows linearly in the period: two periods give Ld (the
 * extrapolation to period 0) and alpha.
 *
 * G_n is only as good as the blur it is computed with, and a harmonic the blur has nearly
 * erased moves by tens of % when the blur is off by a few hundredths of a pixel: all of them
 * the same way, which a line through log (A / G) would read as a transfer rising with Q / n,
 * i.e. as scattered stripes. So the blur's error is a third parameter of the fit (how far log
 * G_n moves for DS_PROBE_BLUR_UNCERTAINTY_PX, with a unit normal prior), and the first harmonic
 * at 2P, the least blur-sensitive point after the one at P, stays in the fit unless the
 * harmonics below P over-determine it (tests/daemon/test_error_model.c
 * /error-model/probe-blurred-harmonics; against the simulator's kernels:
 * tests/daemon/test_probe_sim.c).
 *
 * What no pair of periods can see: scattered light whose kernel is narrow against both periods
 * keeps the stripes at both, so it is counted as direct light (Ld too high, the scattered stripes
 * too low by as much). Hence, where the illuminator can change its period, pilot pairs at finer
 * periods too, P/2 and P/4 while the sensor resolves them (ds_scene_probe_finer_periods): light
 * that loses its stripes at P/4 but keeps them at P is scattered light, not direct. The small-angle
 * transfer exp(alpha x), fitted over x <= P, rises from 1 at x = 0 without limit; a kernel only a
 * few pixels wide instead keeps almost all its light modulated at P and 2P and loses it within a
 * factor 2-4 below P, a step in x that a line through log (A / G) follows only between P/4 and P
 * and then extrapolates to x = 0 too high (Ld too high, the leak at P too low by as much). So the
 * transfer carries a second, narrow term, a kernel holding beta Ld of light whose
 * MTF has a closed form, k = 2 pi w n / Q:
 *     A_n(Q) = Ld G_n(Q, sigma) exp(alpha Q / n) (1 + beta (1 + k^2 / nu)^-nu),   nu = 1 or 2
 * nu = 1 is the MTF of a line spread exp (-|u| / w) / 2w. Not a Gaussian (nu -> infinity): the
 * simulator's narrow Monte Carlo kernels have a sharp core (light scattered near the exit moves
 * little) and their MTF falls as a power of the frequency, not as exp(-f^2): nu = 1 follows such
 * a kernel within a few % from 2P down to 4 px, a Gaussian through the same point at P falls far
 * below it at the finest periods.
 * Below the finest period the harmonics say nothing, so the form is a prior on how the transfer
 * goes on to 0: with nu free up to a Gaussian the fit follows the noise there (and reads the leak
 * at P low; nu 1 or 2 comes closest, nu = 1 alone reads it high), and a Gaussian kernel
 * in closed form is read 28 % high with nu 1 or 2 (tests/daemon/test_probe_narrow.c; 63 % with
 * nu = 1 alone). The term is fitted (nu, beta, w on a grid; Ld, alpha and the blur's error linear
 * at each) only with the finer periods, over all the harmonics including 2P (where a line would
 * go on rising and the narrow kernel's transfer has stopped), for kernels narrow against P (MTF
 * >= 1/2 there), and kept when it fits those harmonics better than the line alone
 * (DS_PROBE_NARROW_MIN_CHI2): the amplitudes' scatter (1-2 %, the objects' column profile) can be
 * as large as the step itself, so no significance test can pass, while the line is known
 * to extrapolate such a step wrongly. Without finer periods (an illuminator that cannot change
 * its period, or P/2 below what the sensor resolves) a kernel narrower than P cannot be told
 * from direct light: where the pilot shows scattered light at all, the prediction is then a
 * lower bound (narrow.unresolved, and narrow.note says why); docs/accuracy.md, "Automatic
 * operating point".
 *
 * The line's rise without end is the small-angle law of a kernel wide against the periods. The
 * light a lens accepts has moved at most d tan theta_c (thickness, cone half-angle inside the
 * medium): against periods long to that the transfer saturates at the whole scattered light, and
 * the line, extrapolating the small slope left between the periods, removes that slope's worth of
 * the leak and counts the rest as direct light (the leak at P read at a fraction of the truth).
 * cone_kernel.h derives that kernel's transfer; where no narrow term won and the harmonics over all
 * the periods see its radius (the fit DS_CONE_SEEN_CHI2 below both its limits), the kernel keeps at
 * least half its stripes at P and reads more scattered light than the line, it is the fit
 * (narrow.form DS_PROBE_KERNEL_CONE), with the light that keeps the stripes bounded by the mean's.
 * Its leak at P known within DS_CONE_TOLD_FACTOR is a measurement; otherwise the prediction is a
 * lower bound and narrow.note gives the range.
 *
 * Pure function of the frames; any thread; CPU only (a few passes over the frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/stripe_model.h"
#include "proc/image.h"

G_BEGIN_DECLS

/* How well a calibrated or fitted stripe blur is known (Gaussian sigma, px): the harmonics whose
 * gain this moves by more than a few % weigh little in the scattered stripes' fit. */
#define DS_PROBE_BLUR_UNCERTAINTY_PX 0.05

/* The finest pilot period: the first harmonic of a period Q is sampled by Q pixels (below 4 the
 * pixel's own integration takes a third of it and the higher harmonics alias), and a Gaussian blur
 * sigma keeps exp (-2 pi^2 sigma^2 / Q^2) of it, at least half for Q >= DS_PROBE_FINEST_BLUR_RATIO
 * sigma (2 pi / sqrt (2 ln 2) = 5.34): below, the blur's uncertainty moves the harmonic by more
 * than the scattered stripes it is to show. */
#define DS_PROBE_FINEST_PERIOD_PX 4.0
#define DS_PROBE_FINEST_BLUR_RATIO 5.34
#define DS_PROBE_FINER_MAX 2
/* How much better (weighted squared residuals, chi^2 with the fit's 2 % floor) the narrow kernel
 * term must explain the harmonics to be kept: any improvement (above: why no significance test). */
#define DS_PROBE_NARROW_MIN_CHI2 0.0
/* The narrow term's checks (scene_probe.c): the scene's mean must hold scattered light beyond the
 * line's Ld (at least this share of it), and the kernel's transfer at the finest period must be
 * below this (above, the kernel is narrower than the pilot resolves: a lower bound). */
#define DS_PROBE_NARROW_MIN_LG 0.03
#define DS_PROBE_NARROW_MAX_AT_FINEST 0.25
/* And the kernel must lose at least a quarter of its own stripes at the finest first harmonic:
 * one that keeps more is seen only in the higher harmonics, whose gain rests on the blur. */
#define DS_PROBE_NARROW_MAX_OWN_AT_FINEST 0.75
/* What objects in the column profile put between the first harmonics of two periods, as a share
 * of the modulation (a scene's objects put 1-2 % between two periods' pairs, docs/accuracy.md):
 * a drop of the
 * modulation from the coarsest period to the finest under 3 times this (with the fit's noise) is
 * no sign of a kernel at the edge of what the pilot resolves. */
#define DS_PROBE_PAIR_SCATTER 0.01
/* The probe reads the noise on two pairs' sums at the columns where the pattern model's sums agree
 * within this share of the stripes' swing 1 - b (scene_probe.c: sets_columns): the scene's
 * structure then enters the combination at most at this share, its variance at the square. */
#define DS_PROBE_SETS_MATCH 0.01
/* ... and on at least this many columns (and an eighth of the frame's), else on one pair. */
#define DS_PROBE_SETS_MIN_COLUMNS 16u
/* The normal quantile of the fit's consistency test (transfer.inconsistent): 99.9 %. */
#define DS_PROBE_FIT_Z 3.09
/* The form of the narrow kernel's transfer (DsSceneProbe's narrow.form). */
typedef enum {
  DS_PROBE_KERNEL_NONE = 0,   /* no narrow kernel: narrow.fraction is 0 */
  DS_PROBE_KERNEL_POWER,      /* the MTF (1 + k^2 / nu)^-nu above, nu = narrow.shape, w = narrow.kernel_px */
  DS_PROBE_KERNEL_CONE,       /* the kernel of the lens's acceptance cone (cone_kernel.h), which the probe
                                 fits in place of the line where the line cannot follow a transfer that
                                 saturates between the periods; narrow_kernel_px is its radius */
} DsProbeKernelForm;

/* The finer pilot periods for period P and blur sigma (0 when unknown): P/2 and P/4 as long as they
 * are resolvable (above), rounded to 1/100 px (a projector's PERIOD register unit). Returns how
 * many (0..DS_PROBE_FINER_MAX), finest last. */
guint ds_scene_probe_finer_periods (double period_px, double blur_px, double out[DS_PROBE_FINER_MAX]);

/* The finest period the pilot resolves at this blur. */
double ds_scene_probe_finest_period (double blur_px);

typedef struct {
  const DsImage *frame[2];        /* phase 0 and 1/2 */
  double period_px;
} DsProbePair;

typedef enum {
  DS_BLUR_CALIBRATED = 0,   /* from the calibrated harmonic gain */
  DS_BLUR_MEASURED,         /* fitted to the pilot's harmonics at two periods */
  DS_BLUR_ASSUMED_SHARP,    /* neither possible: sigma 0, the sampling part is a lower bound */
} DsBlurSource;

const char *ds_blur_source_name (DsBlurSource source);

typedef struct {
  const DsImage *dark;            /* illuminator off, the pilot's exposure */
  const DsImage *lit[2];          /* period P: phase 0 and phase 1/2 */
  const DsImage *coarse[2];       /* period 2P: phase 0 and 1/2; NULL when not available */
  const char *coarse_missing;     /* why not (shown with the lower bound) */
  DsProbePair finer[DS_PROBE_FINER_MAX]; /* at ds_scene_probe_finer_periods (); n_finer of them */
  guint n_finer;
  const char *finer_missing;      /* why fewer than the resolvable finer periods (NULL: none missing) */
  double exposure_us;
  double saturation_dn;           /* the ADC's top or a known clip level; 0 = none */
  gboolean saturation_known;      /* saturation_dn is the sensor's real clip level (configured);
                                     FALSE: only the pixel format's top, a full well may be lower */
  DsStripeModel geometry;      /* as configured; blur_px is what the probe finds */
  double calibrated_gain;         /* h measured on a reference (descatterctl calibrate); 0 = none */
  gboolean blur_known;            /* calibrated_blur_px holds a calibrated edge blur */
  double calibrated_blur_px;      /* Gaussian sigma (descatterctl calibrate); wins over the gain's */
  double open_field_dn;           /* the open field's lit level (a fully lit pixel on a clear path, above
                                     dark) at the pilot's exposure and gain, DN; 0 = not known */
  const char *open_field_unused;  /* why a configured open field is not used (0 above); NULL: none */
  double acceptance_half_angle_deg; /* the lens's acceptance cone, object side ([camera]
                                       acceptance-half-angle-deg); 0 = not known */
} DsProbeFrames;

/* The frames' shape, as both the probe and the pattern check need it: a dark frame and the pair
 * at P, the pair at 2P whole or absent, the finer pairs whole and below P, all of one size and
 * sample type. Fails with
 * DS_OPERATING_ERROR_PILOT_FRAMES naming the frame that is missing or differs. Any thread. */
gboolean ds_probe_frames_check (const DsProbeFrames *frames, GError **error);

/* Clip (stage_clip, stage_pairs): where the sensor stops counting. Relies on noise spreading
 * unclipped values over many levels, so that a pile-up of samples at one top value is a clip. */
typedef struct {
  double saturation_dn;           /* the clip level applied: given, or a pile-up found lower */
  gboolean known;                 /* saturation_dn is known to be where the sensor clips (given as
                                     known, or a pile-up found): exposures may rise up to it.
                                     FALSE: a full well below the format's top would go unseen,
                                     so no exposure above the pilot's is safe */
  gboolean flagged;               /* the separation flags samples at saturation_dn (it is the level
                                     given, not a full well the pilot found below it) */
  double bright_dn;               /* 99.9th percentile of the brighter pilot frame minus dark */
  double saturated_fraction;      /* pixels at the clip level in a pilot frame */
} DsProbeClip;

/* Noise (stage_dark, stage_noise): one frame's variance is var0 + gain * signal. Relies on the
 * dark frame having no stripes (its temporal noise is the floor), on the photons being Poisson
 * (the variance grows linearly with the signal) and on objects multiplying the stripes (their
 * transmittance scales both phases of a pair alike, so a combination of the two cancels them:
 * proc/column_stats.h). */
typedef struct {
  double dark_dn;                 /* the dark frame's mean: every offset the lit frames carry */
  double var0;                    /* DN^2 of one frame without signal (read, dark, quantisation) */
  double gain;                    /* DN^2 per DN of signal (shot noise) */
  double dark_shot;               /* the part of var0 that is the shot noise of the dark frame's
                                     own signal (ambient light, dark current): it scales with the
                                     exposure, the rest (read noise, quantisation) does not */
  double at_mean_dn;              /* one frame's noise at the scene's mean light Ld + Lg, DN (what a
                                     result reports, ds_operating_report_to_json ()) */
} DsProbeNoise;

/* Blur (stage_blur): how the stripes' blur in geometry.blur_px was found. Relies on the blur
 * lowering the higher harmonics against the first at one period, which the scattered stripes
 * (rising with the period) do not. */
typedef struct {
  DsBlurSource source;
} DsProbeBlur;

/* Transfer fit (stage_transfer, stage_finer): the harmonics' fit of A_n(Q) = Ld G_n T_n(Q).
 * Relies on the harmonics' noise and the fit's 2 % floor describing their scatter: beyond it
 * the fit is no measurement (inconsistent). */
typedef struct {
  guint equations;                /* harmonics the fit used */
  double finest_period_px;        /* the finest period whose first harmonic the fit used */
  double rms;                     /* rms of the fit's residuals in log amplitude */
  /* The fit's weighted squared residuals beyond the 99.9 % quantile of chi^2 for its degrees of
   * freedom: no transfer the probe models explains the harmonics at the pilot's periods within
   * their noise and the fit's 2 % floor (objects or the places that clip shape the profile), so
   * Ld and the scattered stripes read from them are no measurement and the prediction is a lower
   * bound (note says why). */
  gboolean inconsistent;
  char note[280];
} DsProbeTransfer;

/* Light (stage_transfer, stage_light, the verdict): the direct light is the transfer's
 * extrapolation to period 0, the scattered light what the mean holds beyond it. Relies on two
 * opposite phases summing to the pattern's mean twice over whole periods. */
typedef struct {
  double ld_mean;                 /* direct light Ld (DN at exposure_us), mean over unclipped pixels */
  double ld_spread;               /* mean (Ld^2) / mean (Ld)^2, >= 1 */
  double ld_uncertainty;          /* how far Ld can be off as a share of it (one standard uncertainty):
                                     the first harmonic's noise at P and how far its gain moves for the
                                     blur's uncertainty; 0 when not known */
  double lg_mean;                 /* scattered light Lg (full illumination), DN */
} DsProbeLight;

/* Leak (stage_transfer, stage_leak_bound): the scattered light that keeps the stripes. Relies on
 * the leaked light being scattered light: A_n(Q) = G_n (Ld + S T_n(Q)) with the kernel's MTF
 * T_n <= 1, so every harmonic's leak is at most S / Ld. Where bounded, ds_scene_probe_leak ()
 * returns no more than max (the probe's Lg / Ld). */
typedef struct {
  double per_px;                  /* alpha (1/px); 0 when not measured */
  gboolean measured;
  gboolean bounded;
  double max;
  double at_period;               /* ds_scene_probe_leak () of the first harmonic at the period, as
                                     the probe ended (what a result reports) */
  char note[360];                 /* how it was measured, or why not */
} DsProbeLeak;

/* Narrow kernel and its verdict (stage_transfer, narrow_verdict): scattered light whose kernel
 * is narrow against the periods. Relies on finer periods: without them such a kernel keeps the
 * stripes at every period measured and cannot be told from direct light (unresolved). */
typedef struct {
  double fraction;                /* beta: the narrow kernel's light over Ld; 0 when none was seen */
  double kernel_px;               /* w: its width, px (scene_probe.h: the MTF's form) */
  DsProbeKernelForm form;         /* which kernel fraction and kernel_px describe */
  double shape;                   /* nu of the power form (1 or 2; 1/2 for the interval's kernel) */
  gboolean unresolved;            /* scattered light was seen but no finer period was: a kernel
                                     narrower than P would pass for direct light (a lower bound) */
  gboolean beyond;                /* a kernel still keeping > DS_PROBE_NARROW_MAX_AT_FINEST of Ld at the
                                     finest period: not fitted, a lower bound */
  /* Where the finer periods saw no kernel but the mean shows scattered light that the coarsest period
   * keeps and the fit's leak at P does not (scene_probe_hidden.h): the leak at P can be up to this
   * share of Ld, and ds_scene_probe_worst_case () takes it at every harmonic and period; 0 = none. */
  double hidden_leak;
  char note[448];                 /* why (unresolved), or what the finer periods showed */
} DsProbeNarrow;

/* Interval of the direct light (stage_interval), where narrow.unresolved: how low the direct
 * light can be (light.ld_mean is the interval's upper end, ds_scene_probe_worst_case () the scene
 * at its lower end). Relies on all the scattered light sharing one kernel whose displacement
 * density is finite at 0 (ds_scene_probe_worst_case () below). */
typedef struct {
  gboolean set;                   /* ld_lower, unbounded and note are set */
  gboolean unbounded;             /* the frames show scattered light that keeps the stripes more than any
                                     kernel of the bound's family: no lower end (targets are refused) */
  double ld_lower;                /* DN; light.ld_mean when the frames show no narrow kernel at the edge */
  double worst_kernel_px;         /* the single kernel at the lower end (w, nu = 1/2); 0 = none */
  char note[360];                 /* how the lower end was found, or why there is none */
} DsProbeInterval;

/* Loss (scene_probe_loss.h): the scene's lit level against the open field's. Relies on objects only
 * darkening pixels and on the open field being the same illuminator and camera on a clear path. */
typedef struct {
  gboolean known;                 /* the open field's level was given and the frames had blocks to measure */
  double level_dn;                /* the scene's lit level (bright quantile over blocks), DN */
  double open_dn;                 /* the open field's, DN at the pilot's exposure and gain */
  double transmittance;           /* level_dn / open_dn */
  double floor;                   /* the least transmittance Fresnel, noise and calibration explain */
  gboolean unexplained;           /* below floor while the stripes keep the light: a lower bound */
  double sigma;                   /* the transmittance's relative standard uncertainty */
  /* Where unexplained: the upper end of the bias the film's light in the cone adds (film_bound.h),
   * from the transmittance DS_PROBE_LOSS_Z sigma low, where the lens's acceptance angle is known. */
  gboolean bounded;               /* bias_upper is set and finite */
  double acceptance_deg;          /* the cone's half-angle used; 0 = not known */
  double bias_upper;              /* relative error of the transmissive image, upper end */
  char note[448];                 /* what was measured, or why not */
  char bound_note[320];           /* how the upper end was found, or why there is none */
} DsProbeLoss;

/* The probe: each stage of ds_scene_probe_measure () fills its own part. */
typedef struct {
  DsStripeModel geometry;      /* with the blur found, and the pixel's aperture where a calibrated
                                  gain shows it integrates less than its pitch (ds_stripe_match_gain) */
  double phase_offset;            /* cycles: phase 0's stripes are centred at x = P (j + offset) */
  double exposure_us;
  guint width, height;
  DsProbeClip clip;
  DsProbeNoise noise;
  DsProbeBlur blur;
  DsProbeTransfer transfer;
  DsProbeLight light;
  DsProbeLeak leak;
  DsProbeNarrow narrow;
  DsProbeInterval interval;
  DsProbeLoss loss;
} DsSceneProbe;

gboolean ds_scene_probe_measure (const DsProbeFrames *frames, DsSceneProbe *out, GError **error);

/* The interval of the direct light where scattered light narrower than the periods measured
 * could pass for direct light (narrow.unresolved). The modulation of the first harmonic at a
 * period Q, after the calibrated blur, is A(Q) = Ld + S T(Q), S the scattered light and T its
 * kernel's MTF at 1/Q, 0 <= T <= 1 and rising with Q; the mean holds M = Ld + S. So the finest
 * period bounds Ld from above (T >= 0), and the drop of the modulation from the coarsest period
 * to the finest, A(Q_c) - A(Q_f) = S (T(Q_c) - T(Q_f)), bounds the leak from below. Nothing in
 * the frames bounds Ld from below: light scattered within a fraction of a pixel keeps the stripes
 * at every period the rig can project (T = 1 at all of them) and adds to A exactly as Ld does. The
 * lower end therefore rests on stated physics: all the scattered light shares one kernel whose
 * displacement density is finite at 0 (no share of the light leaves the medium where it
 * entered), so its MTF falls no slower than 1/k; the slowest such form, (1 + 2 k^2)^-1/2
 * (kernel_mtf with nu = 1/2, k = 2 pi w / Q), hides the most light below the finest period. The
 * light the stripes lost by each period, M - A(Q) = S (1 - T(Q)), gives T's ratio between the two
 * periods without Ld, hence w, hence S and Ld = M - S. A drop steeper than any such kernel
 * (r = (M - A(Q_c)) / (M - A(Q_f)) <= (Q_f / Q_c)^2, or A(Q_c) at M) leaves no lower end
 * (interval.unbounded); that is decided on the measured r, the one the lower end is read at, not on
 * whether M - A(Q_c) alone stands out of the noise. A drop within the noise says nothing about a
 * kernel narrower than every period (the method's limit, docs/accuracy.md): the interval is then
 * [light.ld_mean, light.ld_mean] and the flag alone says so. Light kept by a second, narrower
 * kernel than the one the drop shows is not bounded either: that too is the limit, stated in
 * interval.note.
 * Returns FALSE when the probe has no finite lower end below light.ld_mean; otherwise *worst is the
 * probe with Ld at interval.ld_lower, all the rest of the mean scattered by that kernel. */
gboolean ds_scene_probe_worst_case (const DsSceneProbe *probe, DsSceneProbe *worst);

/* The transfer exp(alpha Q / n) (1 + beta M_w (Q / n)) - 1 of harmonic n at period Q: the part of
 * the apparent Ld that is scattered light keeping the stripes; at most leak.max (leak.bounded). */
double ds_scene_probe_leak (const DsSceneProbe *probe, double period_px, guint n);

G_END_DECLS
