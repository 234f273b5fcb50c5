/* The motion term: what an object moving at a declared speed adds to a set's error, and the
 * lower-bound mark when motion is seen and no speed was declared (docs/accuracy.md, "Moving
 * objects").
 *
 * Model. During a set of frames at times t_k an object moving at v along x stands, relative to
 * its place at the set's middle t_m, displaced by v (t_k - t_m). A pixel's transmission over the
 * set is then T_k = T(x - v (t_k - t_m)), and the estimators see samples that change under them.
 * The squared error a pixel gets is proportional to how much its transmission departs, over
 * the set, from its value at the middle (the truth the error is measured against):
 *     err^2 = kappa * sum_px mean_k (T(x - v (t_k - t_m)) - T(x))^2 / sum_px T(x)^2
 * with kappa from the estimator's response to a sharp edge crossing a pixel at a uniformly
 * random point u of a long set (phases in order, the pixel's stripe phase uniform), against the
 * 1/4 that the departure itself averages to over u:
 *   - sine: the first harmonic of a step is u plus an oscillating part whose power averages
 *     sin^2 (2 pi u) / pi^2; the mean square error over u is 1/12 + 1/(2 pi^2), kappa = 0.536;
 *   - max/min: the pixel reads the lit level when one of its lit phases (half the set, a block
 *     in phase order) fell before the edge; the mean square error over u is 3/8, kappa = 1.5.
 * Both responses are idealised (a long set, a lit block of exactly half of it, square stripes
 * for max/min and sine ones for sine); the simulator's noise-free sets land within a factor 1.5
 * of the term (tests/daemon/test_motion_term.c), sine below it and max/min above it. robust
 * has no such closed form: its motion term is unknown (NAN), and a prediction with it is a
 * lower bound. The departure is computed on the scene's transmissive image as the pilot saw
 * it (shifted along x by linear interpolation), so any shape and contrast count as they are.
 *
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/operating_point.h"
#include "daemon/operating/rig_timing.h"
#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

/* The frame times of a set of N phases x M averages in the rig's timing model
 * (ds_rig_timing_set_ms): each phase settles, then its M frames follow, each a trigger, an
 * exposure and a readout. times_s[k M + j] is frame j of phase k's exposure midpoint from the
 * set's start (s). */
void ds_motion_frame_times (const DsRigTiming *timing, guint width, guint height, guint n_phases, guint averages,
                            double exposure_us, double *times_s);

/* kappa of the model above; NAN for an estimator without one. */
double ds_motion_kappa (DsEstimator estimator);

/* The motion term (relative RMSE of the transmissive image, the error model's unit) of a set
 * whose frames expose at times_s[0 .. n_times - 1], an object moving at speed_px_s along x over
 * `transmissive` (f32, the scene as still). NAN for an estimator without a kappa. Fails
 * (G_IO_ERROR_INVALID_ARGUMENT) on an image that is not f32, has no light, or a speed or time
 * that is not finite. */
gboolean ds_motion_term (const DsImage *transmissive, double speed_px_s, const double *times_s, guint n_times,
                         DsEstimator estimator, double *term, GError **error);

/* Adds a declared speed's motion term to a point in quadrature (both ends of its prediction),
 * and marks the point a lower bound when the term is unknown (NAN). With no speed declared
 * (speed_px_s NAN) and motion seen (motion_pixels > 0, the result's motion bit), the point is
 * marked a lower bound: the prediction assumed a still scene. An unknown term leaves the point no
 * upper end (predicted_error_upper INFINITY, upper_bounded FALSE). Returns TRUE when it marked the
 * point; *why (may be NULL) then gets the reason, a static string. */
gboolean ds_motion_apply (DsOperatingPoint *point, double speed_px_s, double term, guint64 motion_pixels,
                          const char **why);

/* The departure of ds_motion_term for many frame times over one image: sum_px (T(x - s) - T(x))^2
 * at whole-pixel shifts s, each computed once (on first use) and kept; between two of them the
 * linear interpolation's departure is exact,
 *     D(i + f) = (1 - f) D(i) + f D(i + 1) - f (1 - f) E(i),
 * E(i) the squared differences of neighbouring pixels over the columns the shift keeps (the
 * image's border clamps as ds_motion_term's does). So a term costs one pass over the image per
 * whole pixel the set moves, once for every candidate of the operating point.
 * A noisy image departs by its noise at any shift: with noise_var (DN^2, each pixel's variance,
 * independent between pixels; 0: none) its expectation is taken out of D, E and the light.
 * Rows are independent (motion along x): images taller than DS_MOTION_TABLE_ROWS keep that many,
 * evenly spaced. */
#define DS_MOTION_TABLE_ROWS 256
typedef struct DsMotionTable DsMotionTable;
/* Fails as ds_motion_term on an image that is not f32 or holds no light beyond its noise. */
DsMotionTable *ds_motion_table_new (const DsImage *transmissive, const DsImage *noise_var, GError **error);
void ds_motion_table_free (DsMotionTable *table);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsMotionTable, ds_motion_table_free)
/* ds_motion_term's value from the table (NAN for an estimator without a kappa). Not thread-safe:
 * the table grows. */
double ds_motion_table_term (DsMotionTable *table, double speed_px_s, const double *times_s, guint n_times,
                             DsEstimator estimator);

G_END_DECLS
