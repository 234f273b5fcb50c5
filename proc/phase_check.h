/* Proof that a frame was lit with the phase the sequencer applied (docs/design.md, "Phase
 * verification"). Acquisition or fold thread, one at a time (the sequencer hands it over).
 *
 * The stripe phase measured in one frame (proc/stripe_phase) is the phase of the first
 * harmonic of everything in the frame at the stripe period, and not all of that moves with the
 * illuminator: the object's own texture at that period (a grid whose pitch is a multiple of
 * it, edges, vessels) times the stripes' mean stays where it is, and square stripes' higher
 * harmonics alias onto the first at short periods. A correct frame's phase is therefore off by
 * a scene-dependent bias, up to asin(|fixed part| / |moving part|) (17.6 deg on the wire grid,
 * sine stripes of period 16 px, measured against an offset taken from one frame).
 *
 * So no frame is judged by its phase against the offset alone. The check is a classifier
 * between "phase k" and "phase k +- 1, or a repeat of a frame of the set", each decision taken
 * halfway between the hypotheses and only where the noise of the first harmonic leaves 5 sigmas
 * on the way; where it does not, the frame is UNVERIFIABLE: it passes (the caller folds it and
 * counts it), joins the set and the set is checked as a whole. What is known of the scene
 * decides which way a frame that cannot show its phase goes. The illuminator projects stripes
 * that move with the phase, so a correct frame shows them, and shows them move, unless the
 * scene is known not to (its own texture or its scattering hides them there):
 * - a frame without stripes at the configured period is NO_STRIPES (refused) when it shows
 *   another pattern's stripes, when its light lies below the set's by what the illuminator
 *   adds (a quarter of the moving first harmonic: unlit), or when the scene is expected to
 *   show stripes at phase k: the template of phase k is strong, or, without templates, the
 *   set's frames predict them (a first harmonic b + a e^{i 2 pi k / N} fitted to them), or
 *   nothing is known yet (the projected pattern). It passes unverified only where the scene
 *   is known to show none at k (the template of k, or the set's fit, is too weak to show 10
 *   noise sigmas), or when, nothing known, it is refused once and taken again shows none
 *   either (the scene's texture may cancel the stripes at k): ds_phase_check_confirm then
 *   judges it against the set's other phases (their fit, their light). Another period the frame shows is another pattern's only if it moved: the
 *   frame's column profile less the set's mean profile keeps what changed between the frames
 *   (the object's texture, lit by the same mean light at every phase, cancels); with the
 *   stripes' own change fitted out, another period that changed more than the stripes did is
 *   another pattern's. A set's first frame, with nothing to compare, is judged so by
 *   ds_phase_check_confirm. A frame too weak to verify whose fit leaves much more than its
 *   noise is judged against the set the same way;
 * - a frame equal within its noise to the set's frame of another phase is a repeat when correct
 *   frames of the two phases are known to lie far enough apart (templates, or the set's other
 *   adjacent phases), when nothing is known yet (the projected stripes move), or when it is the
 *   same exposure (equal far inside the noise); it passes unverified only where the scene is
 *   known to move its first harmonic too little between the two phases;
 * - with templates (the last fully verified set's first harmonic per phase) and a scene that
 *   holds still, a frame of phase k is compared with the template of phase k, which carries the
 *   same bias: beyond halfway to the nearest other template (or the tolerance) it is wrong. The
 *   set's first frame decides whether the scene held still: near its own template it did; on
 *   another phase's template it is that phase (wrong); near neither, the scene changed and the
 *   set is checked as a whole;
 * - checked as a whole (the first set, a set whose scene changed, a set with unverified frames):
 *   when the set is complete, the moving part (DFT bin 1 over the phases) must stand out of the
 *   noise (else the set passes unverified), adjacent phases must not repeat, each phase's
 *   frames less the fixed part (bin 0) must move one step on, and bin 1 must show the
 *   illuminator's offset (once learned). A set that fails fails as a whole
 *   (ds_phase_check_confirm). docs/design.md, "Phase verification", has the numbers. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef enum {
  DS_PHASE_VERDICT_OK = 0,
  DS_PHASE_VERDICT_WRONG,        /* measured phase is another phase than k */
  DS_PHASE_VERDICT_UNVERIFIABLE, /* too little modulation to tell the phases apart where the scene is
                                  * known to show so little: the frame passes unverified (it joined
                                  * the set) */
  DS_PHASE_VERDICT_NO_STRIPES,   /* refused: no stripes at the configured period where the scene is
                                  * expected to show them, or stripes of another period */
} DsPhaseVerdict;

/* Templates and repeat detection are kept for up to this many phases (the configuration's
 * limit); beyond it frames are checked against the offset alone. */
#define DS_PHASE_CHECK_MAX_PHASES 64
/* Columns of a frame's profile kept to compare the set's frames with each other (a wider
 * frame is compared on its first this many columns: hundreds of periods of any stripes). */
#define DS_PHASE_CHECK_PROFILE_MAX 4096

typedef struct {
  double period_px;
  double tolerance_cycles;   /* |measured - expected| allowed, in periods */
  double min_confidence;     /* below this snr the frame shows no stripes: "cannot tell" */
  gboolean offset_known;     /* the illuminator's offset, learned from the first complete set */
  double offset_cycles;
  gboolean provisional;      /* a set is in progress: ds_phase_check_confirm or _abandon ends it */
  /* The set in progress: its accepted frames' first harmonics (sums per phase, and the DFT
   * bin that gives the offset), the first one as the reference while the offset is unknown. */
  guint set_n;
  double set_sum[DS_PHASE_CHECK_MAX_PHASES][2];
  guint set_count[DS_PHASE_CHECK_MAX_PHASES];
  double set_sumsq[DS_PHASE_CHECK_MAX_PHASES];
  double set_noise2;          /* the largest noise variance of c among the accepted frames */
  guint set_frames;
  gboolean set_by_template;   /* decided by the set's first frame */
  /* The last complete set's first harmonic per phase (prior_n 0: none). */
  guint prior_n;
  double prior[DS_PHASE_CHECK_MAX_PHASES][2];
  guint set_unverified;       /* frames of the set in progress that passed unverified */
  /* Per phase of the set in progress: 1 + the phase whose frame a frame of it was refused as
   * repeating while nothing was known of how far the stripes move (0: none). */
  guint8 set_refused_as[DS_PHASE_CHECK_MAX_PHASES];
  gboolean still;             /* the scene is known to move its first harmonic less than the noise
                               * tells between phases (until abandoned) */
  guint64 unverified;         /* frames that passed unverified (DS_PHASE_VERDICT_UNVERIFIABLE) since init */
  guint64 sets_unverified;    /* complete sets whose phases could not be told apart, since init */
  /* The projected pattern, when known (ds_phase_check_set_pattern): its own harmonics bend the
   * measured step between phases, which the whole-set step test allows for. */
  gboolean pattern_known;
  gboolean pattern_square;
  double pattern_duty;
  guint frame_width;          /* the last checked frame's width (the measurement's length) */
  /* What the set's accepted frames share: the sum of their column profiles (rows averaged, the
   * first profile_width columns), so that structure at a period other than the stripes' is
   * judged by whether it moves between the set's frames (another illuminator's stripes do,
   * the object's texture does not). */
  guint profile_width;        /* columns summed (0: none yet) */
  guint profile_frames;       /* frames in profile_sum */
  double level_sum, level_min, level_max; /* their fitted means (the light's level) */
  double profile_sum[DS_PHASE_CHECK_PROFILE_MAX];
  /* The set's frame that showed another period before the set had a frame to compare it with
   * (pending: its phase pending_k); judged by ds_phase_check_confirm against the set's other frames. */
  gboolean pending;
  guint pending_k;
  float pending_profile[DS_PHASE_CHECK_PROFILE_MAX];
  /* Phases (bit k) of the set in progress whose frame showed no stripes while nothing was
   * known of the scene (no templates, the set's other phases too few to fit): refused once
   * (set_refused_bare); the frame taken again that shows none either joins the set
   * (set_deferred) and ds_phase_check_confirm judges it against the set's other phases. */
  guint64 set_refused_bare, set_deferred;
  double set_level[DS_PHASE_CHECK_MAX_PHASES]; /* per phase, the sum of its frames' fitted means */
  double bend_cycles;         /* ds_phase_check_pattern_bend for bend_n phases and frame_width */
  guint bend_n, bend_width;
} DsPhaseCheck;

/* The tolerance when none is configured: half a phase step, in degrees (k is then the nearest
 * phase to what the frame shows; inline, for the settings code that does not link the check). */
static inline double
ds_phase_check_default_tolerance_deg (guint n)
{
  return 180.0 / n;
}

/* The temporal noise of one pixel (DN), from the median absolute difference of adjacent rows
 * (up to 32 pairs of rows, 256 columns of each); INFINITY when it cannot be read (fewer than 2
 * rows, no finite difference). */
double ds_phase_check_pixel_noise (const DsImage *frame);

void ds_phase_check_init (DsPhaseCheck *check, double period_px, double tolerance_deg);
/* The projected pattern (square with a duty, the lit fraction, or sine), for the whole-set step
 * test; without it the test assumes steps unbent by the pattern (sine stripes). Kept until the
 * next ds_phase_check_init. */
void ds_phase_check_set_pattern (DsPhaseCheck *check, gboolean square, double duty);

/* The largest deviation from 1/n (cycles) of the first-harmonic phase measured as the pattern
 * moves from one phase to the next, on a noise-free row `width` pixels wide with sharp edges,
 * each pixel the mean over its width: what the pattern's harmonics above the first, folded back
 * at short periods, bend a step by; blur lowers it. 0 for sine stripes.
 * Pure function, any thread; CPU only (8 x (n + 1) measurements of one row). */
double ds_phase_check_pattern_bend (gboolean square, double duty, double period_px, guint width, guint n);

/* A new set begins. */
void ds_phase_check_begin_set (DsPhaseCheck *check);
/* Checks frame (lit with phase k of n), measuring on at least 256 of its rows evenly spread
 * (all rows of a frame with fewer than 512). An OK or UNVERIFIABLE frame joins the set; a
 * WRONG or NO_STRIPES one does not (the caller refuses it).
 * *measured_cycles receives the measured phase. `why` receives a message when the verdict is not OK. */
DsPhaseVerdict ds_phase_check_frame (DsPhaseCheck *check, const DsImage *frame, guint k, guint n,
                                     double *measured_cycles, char **why);
/* The set's frames are all in: a set checked as a whole is checked now (FALSE with a message
 * naming the phase that does not fit; the set must fail). A verified set's frames become the
 * templates, and the offset is learned if unknown; a set that cannot tell its phases apart
 * passes, counted in sets_unverified. TRUE when no frame was checked (verification off). */
gboolean ds_phase_check_confirm (DsPhaseCheck *check, char **why);
/* The set failed: forget the templates too (the scene may have changed under them). */
void ds_phase_check_abandon (DsPhaseCheck *check);

G_END_DECLS
