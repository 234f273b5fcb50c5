#include "daemon/operating/operating_point.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/operating/motion_term.h"
#include "daemon/operating/operating_error.h"

static const DsEstimator all_estimators[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };

double
ds_scene_probe_max_exposure (const DsSceneProbe *p)
{
  /* Float frames (no clip level at all) scale freely; an unknown full well caps at the pilot's
   * exposure, the longest one the frames show unclipped. */
  double unknown_cap = p->clip.saturation_dn > 0 && !p->clip.known ? p->exposure_us : 16 * p->exposure_us;
  if (!(p->clip.saturation_dn > 0) || !(p->clip.bright_dn > 0))
    return unknown_cap;
  double room = 0.9 * p->clip.saturation_dn - p->noise.dark_dn;
  return room > 0 ? MIN (unknown_cap, p->exposure_us * room / p->clip.bright_dn) : 0;
}

/* The scene at both ends of the probe's interval of the direct light (scene_probe.h): `lower` the
 * probe's own (the prediction's lower end), `upper` its worst case when the interval has a finite
 * lower end of Ld, `unbounded` when it has none. */
typedef struct {
  DsErrorModel *lower, *upper;
  gboolean unbounded;
  const DsOperatingMotion *motion;   /* NULL: a still scene */
} Models;

/* A declared speed's motion term, in quadrature to both ends: the set's frames at their times in
 * the rig's timing model. Not scaled by the model's scale, which is fitted on still scenes. */
static void
add_motion (const Models *em, const DsRigTiming *t, guint w, guint h, DsOperatingPoint *p)
{
  p->motion_term = NAN;
  p->predicted_error_still = p->predicted_error;
  guint nt = p->phases * p->averages;
  g_autofree double *times = g_new (double, nt);
  ds_motion_frame_times (t, w, h, p->phases, p->averages, p->exposure_us, times);
  p->motion_span_ms = (times[nt - 1] - times[0]) * 1e3;
  if (!em->motion)
    return;
  p->motion_term = ds_motion_table_term (em->motion->table, em->motion->speed_px_s, times, nt, p->estimator);
  ds_motion_apply (p, em->motion->speed_px_s, p->motion_term, 0, &p->motion_why);
}

static gboolean
predict (const DsOperatingModel *m, const Models *em, const DsSceneProbe *probe, const DsRigTiming *t,
         guint w, guint h, DsEstimator e, guint n, guint mm, double factor, double period,
         DsOperatingPoint *p)
{
  memset (p, 0, sizeof *p);
  /* With a speed declared, an estimator whose motion error has no model is no candidate: its
   * prediction would be a lower bound below every modelled one's (ds_motion_kappa). */
  if (em->motion && isnan (ds_motion_kappa (e)))
    return FALSE;
  /* Only points a request can name: the choice runs them, and a refusal names them for the
   * user to run. */
  if (!ds_error_model_request_accepts (em->lower, e, n, NULL))
    return FALSE;
  if (!ds_error_model_predict (em->lower, e, n, mm, factor, period, &p->parts, NULL))
    return FALSE;
  DsErrorParts worst;
  if (em->unbounded)
    p->predicted_error_upper = INFINITY;
  else if (em->upper)
    p->predicted_error_upper = ds_error_model_predict (em->upper, e, n, mm, factor, period, &worst, NULL)
                                 ? MAX (m->scale * worst.total_upper, m->scale * p->parts.total_upper)
                                 : INFINITY;
  else
    p->predicted_error_upper = m->scale * p->parts.total_upper;
  p->estimator = e;
  p->phases = n;
  p->averages = mm;
  p->exposure_us = probe->exposure_us * factor;
  p->period_px = period > 0 ? period : probe->geometry.period_px;
  p->predicted_error = m->scale * p->parts.total;
  p->predicted_time_ms = ds_rig_timing_set_ms (t, w, h, n, mm, p->exposure_us, TRUE);
  gboolean stripes_lower = !probe->leak.measured || probe->narrow.unresolved || probe->transfer.inconsistent;
  p->lower_bound = stripes_lower || probe->loss.unexplained;
  /* The interval bounds the light a narrow kernel hides, not a leak left unmeasured or harmonics
   * that measure nothing; light lost to a medium the stripes do not show (scene_probe_loss.h) has
   * an upper end only where the lens's acceptance angle bounds it (film_bound.h). */
  p->upper_bounded = (!stripes_lower || (em->upper && !em->unbounded && probe->leak.measured &&
                                         !probe->transfer.inconsistent && isfinite (p->predicted_error_upper))) &&
                     (!probe->loss.unexplained || probe->loss.bounded);
  /* The film's light in the cone is a bias b of the transmissive image, est = truth (1 + b) + e,
   * e the rest of the error. The relative RMSE is a norm, so ||b truth + e|| <= b ||truth|| +
   * ||e||: the bias adds linearly. (Quadrature would need e uncorrelated with the truth, and
   * max/min's noise bias and the sampling error are not.) */
  if (p->upper_bounded && probe->loss.unexplained)
    p->predicted_error_upper += probe->loss.bias_upper;
  /* A lower bound with nothing above it measured has no upper end: it never meets a target (it
   * is undetermined at best, ds_operating_point_choose ()). */
  if (!p->upper_bounded)
    p->predicted_error_upper = INFINITY;
  p->uncertainty = ds_operating_point_uncertainty (m, probe, &p->parts, p->period_px);
  add_motion (em, t, w, h, p);
  return TRUE;
}

/* The robust scale's asymptotic efficiency against the standard deviation at normal noise (the
 * median absolute deviation's, 0.37; the probe's truncated estimators are no better): its
 * relative standard error on n samples is 1 / sqrt (2 n efficiency). */
#define ROBUST_SCALE_EFFICIENCY 0.37

double
ds_operating_point_uncertainty (const DsOperatingModel *m, const DsSceneProbe *probe, const DsErrorParts *parts,
                                double period_px)
{
  double spread = m->scale_spread, e2 = parts->total * parts->total;
  if (!(e2 > 0))
    return spread;
  double d = MAX (0.0, probe->light.ld_uncertainty);
  /* total^2 = noise^2 + systematic^2, so d ln total = sum (part^2 / total^2) d ln part. The noise
   * (shot and read noise over Ld) moves by at most Ld's own relative error d. The sampling part
   * is the pattern's and does not move. */
  double u_ld = MIN (parts->noise * parts->noise, e2) / e2 * d;
  /* The scattered stripes' part grows with the leak L at the point's period (the error model reads
   * it there, ds_error_model_predict ()), and what the pilot measures is the sum of the light
   * keeping the stripes and Ld, the modulated light Ld (1 + L): Ld read d too high leaves
   * (1 + L)/(1 - d) - 1 = L + (1 + L) d, so d ln L = (1 + L)/L d (a leak of 1 % with Ld known to
   * 1 % is known to 2 %), and the part, near proportional to L, moves as much. A leak smaller
   * than its own uncertainty may be none: the part's share s of total^2 can then at most vanish,
   * which moves ln total by -ln (1 - s)/2, however small L is. */
  double leak = ds_scene_probe_leak (probe, period_px > 0 ? period_px : probe->geometry.period_px, 1);
  double share = MIN (parts->scattered_stripes * parts->scattered_stripes / e2, 1.0);
  if (share > 0) {
    double linear = leak > 0 ? share * (1 + leak) / leak * d : INFINITY;
    u_ld += MIN (linear, -0.5 * log1p (-MIN (share, 1 - 1e-9)));
  }
  /* The frame noise is a robust scale read on about every unclipped pixel. */
  double n = (double) probe->width * probe->height * (1 - CLAMP (probe->clip.saturated_fraction, 0.0, 1.0));
  double u_noise = n >= 2 ? MIN (1.0, parts->noise * parts->noise / e2) / sqrt (2 * ROBUST_SCALE_EFFICIENCY * n) : 0;
  return sqrt (spread * spread + u_ld * u_ld + u_noise * u_noise);
}

/* Where a refusal is decided: the lower end of the prediction over its uncertainty, one standard
 * uncertainty towards the better. Above the target, no value the interval allows meets it. */
static double
optimistic_end (const DsOperatingPoint *p)
{
  return p->predicted_error * exp (-p->uncertainty);
}

typedef struct {
  gboolean found;
  DsOperatingPoint p;
} Best;

/* The more accurate of two points is the one whose error can be the smaller: the upper end of its
 * interval first, the lower end between equal upper ends (both unbounded, or no interval). */
static gboolean
more_accurate (const DsOperatingPoint *a, const DsOperatingPoint *b)
{
  if (a->predicted_error_upper != b->predicted_error_upper)
    return a->predicted_error_upper < b->predicted_error_upper;
  return a->predicted_error < b->predicted_error;
}

/* A point meets a target only with the upper end of its interval. */
static gboolean
meets_target (const DsOperatingPoint *p, double target)
{
  return target <= 0 || p->predicted_error_upper <= target;
}

/* The rule: with a target, the fastest point meeting it (ties: the more accurate); otherwise the
 * most accurate (ties: the faster). */
static void
consider (Best *b, const DsOperatingPoint *p, double target)
{
  gboolean better;
  if (!b->found)
    better = TRUE;
  else if (target > 0)
    better = p->predicted_time_ms < b->p.predicted_time_ms ||
             (p->predicted_time_ms == b->p.predicted_time_ms && more_accurate (p, &b->p));
  else
    better = more_accurate (p, &b->p) ||
             (!more_accurate (&b->p, p) && p->predicted_time_ms < b->p.predicted_time_ms);
  if (better) {
    b->p = *p;
    b->found = TRUE;
  }
}

/* The exposure factors that keep the brightest pixels below the clip level; when none does,
 * the largest exposure that does. */
static guint
usable_factors (const DsOperatingModel *m, const DsSceneProbe *probe, double *out)
{
  double max_f = ds_scene_probe_max_exposure (probe) / probe->exposure_us;
  guint n = 0;
  for (guint i = 0; i < m->n_exposure_factors; i++)
    if (m->exposure_factors[i] <= max_f * (1 + 1e-9))
      out[n++] = m->exposure_factors[i];
  if (n == 0 && max_f > 0)
    out[n++] = max_f;
  return n;
}

typedef struct {
  gboolean on_lower_end;    /* a point meets the target with its lower end (the undetermined choice) */
  Best in_budget_meeting;   /* the choice */
  Best least_in_budget;     /* the most accurate within the budget */
  Best meeting_any_time;    /* the fastest meeting the target, whatever the budget */
} Search;

typedef struct {
  DsEstimator estimator;
  guint phases, averages;
  double factor, time_ms;
} Candidate;

static int
compare_candidates (const void *a, const void *b)
{
  const Candidate *x = a, *y = b;
  return (x->time_ms > y->time_ms) - (x->time_ms < y->time_ms);
}

/* Predictions cost a synthetic separation each, times cost nothing: candidates are visited in
 * order of time, so that a target is met by the first candidate that meets it (with those of
 * the same time), and the ones beyond the budget are only visited when the target is not met
 * within it. */
static void
search (const DsOperatingModel *m, const Models *errors, const DsSceneProbe *probe, const DsRigTiming *t,
        guint w, guint h, const guint *phases, guint n_phases, const guint *averages, guint n_averages,
        const double *factors, guint n_factors, double period, double target, double budget, Search *s)
{
  GArray *cands = g_array_new (FALSE, FALSE, sizeof (Candidate));
  for (guint ie = 0; ie < G_N_ELEMENTS (all_estimators); ie++)
    for (guint in = 0; in < n_phases; in++)
      for (guint im = 0; im < n_averages; im++)
        for (guint iff = 0; iff < n_factors; iff++) {
          Candidate c = { all_estimators[ie], phases[in], averages[im], factors[iff], 0 };
          c.time_ms = ds_rig_timing_set_ms (t, w, h, c.phases, c.averages, probe->exposure_us * c.factor, TRUE);
          g_array_append_val (cands, c);
        }
  g_array_sort (cands, compare_candidates);
  double stop_at = INFINITY;   /* the time of the first point meeting the target */
  for (guint i = 0; i < cands->len; i++) {
    const Candidate *c = &g_array_index (cands, Candidate, i);
    gboolean in_budget = budget <= 0 || c->time_ms <= budget;
    if (c->time_ms > stop_at)
      break;
    /* Beyond the budget only the fastest point meeting the target is of interest. */
    if (!in_budget && (target <= 0 || s->meeting_any_time.found))
      break;
    DsOperatingPoint p;
    if (!predict (m, errors, probe, t, w, h, c->estimator, c->phases, c->averages, c->factor, period, &p))
      continue;
    gboolean meets = s->on_lower_end ? target <= 0 || p.predicted_error <= target : meets_target (&p, target);
    if (in_budget)
      consider (&s->least_in_budget, &p, 0);
    if (meets && target > 0) {
      consider (&s->meeting_any_time, &p, 1);
      stop_at = MIN (stop_at, c->time_ms);
    }
    if (in_budget && meets)
      consider (&s->in_budget_meeting, &p, target);
  }
  g_array_unref (cands);
}

static void
append_point (GString *s, const DsOperatingPoint *p)
{
  g_string_append_printf (s, "%.4f", p->predicted_error);
  if (isinf (p->predicted_error_upper))
    g_string_append (s, " to unbounded");
  else if (p->predicted_error_upper > p->predicted_error)
    g_string_append_printf (s, " to %.4f", p->predicted_error_upper);
  g_string_append_printf (s, " (%s, N=%u, M=%u, %.0f µs", ds_estimator_name (p->estimator), p->phases, p->averages,
                          p->exposure_us);
  g_string_append_printf (s, ", period %g px: %.0f ms; noise %.4f, sampling %.4f, scattered stripes %+.4f",
                          p->period_px, p->predicted_time_ms, p->parts.noise, p->parts.sampling,
                          p->parts.scattered_stripes);
  if (isfinite (p->motion_term))
    g_string_append_printf (s, ", motion %.4f", p->motion_term);
  else if (p->motion_why)
    g_string_append (s, ", motion not modelled");
  g_string_append (s, ")");
}

/* The most accurate point of each estimator and N: the most frames and the longest exposure
 * (noise only falls with either; the systematic part does not change). Whether a target can be
 * met at all thus costs one prediction per estimator and N. */
static void
best_reachable (const DsOperatingModel *m, const Models *errors, const DsSceneProbe *probe, const DsRigTiming *t,
                guint w, guint h, guint averages, double factor, double period, double target, Best *least,
                Best *meeting)
{
  for (guint ie = 0; ie < G_N_ELEMENTS (all_estimators); ie++)
    for (guint in = 0; in < m->n_phases; in++) {
      DsOperatingPoint p;
      if (!predict (m, errors, probe, t, w, h, all_estimators[ie], m->phases[in], averages, factor, period, &p))
        continue;
      consider (least, &p, 0);
      if (target > 0 && meets_target (&p, target))
        consider (meeting, &p, 1);
    }
}

static guint
largest (const guint *v, guint n)
{
  guint x = 0;
  for (guint i = 0; i < n; i++)
    x = MAX (x, v[i]);
  return x;
}

/* What would reach a target no candidate reaches: more frames than the candidates hold, more
 * light (which the clip level may forbid), another stripe period. */
static void
append_remedies (GString *msg, const DsOperatingModel *m, const Models *errors, const DsSceneProbe *probe,
                 const DsRigTiming *t, guint w, guint h, double longest, double target, double budget)
{
  static const guint more_m[] = { 32, 64 };
  static const double more_f[] = { 8, 16 };
  Best least = { 0 }, meets = { 0 };
  Search more = { 0 };
  best_reachable (m, errors, probe, t, w, h, 64, longest, 0, target, &least, &meets);
  if (meets.found)
    search (m, errors, probe, t, w, h, m->phases, m->n_phases, more_m, G_N_ELEMENTS (more_m), &longest, 1, 0,
            target, 0, &more);
  else {
    best_reachable (m, errors, probe, t, w, h, largest (m->averages, m->n_averages), more_f[1], 0, target, &least,
                    &meets);
    if (meets.found)
      search (m, errors, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, more_f,
              G_N_ELEMENTS (more_f), 0, target, 0, &more);
  }
  if (more.meeting_any_time.found) {
    g_string_append (msg, ". More frames or light would reach it: ");
    append_point (msg, &more.meeting_any_time.p);
    double max_us = ds_scene_probe_max_exposure (probe);
    double clip_us = probe->clip.known ? max_us : max_us * 16; /* what the clip level alone allows */
    if (!probe->clip.known && probe->clip.saturation_dn > 0 && probe->clip.bright_dn > 0)
      clip_us = probe->exposure_us * (0.9 * probe->clip.saturation_dn - probe->noise.dark_dn) / probe->clip.bright_dn;
    if (more.meeting_any_time.p.exposure_us > max_us && more.meeting_any_time.p.exposure_us <= clip_us)
      g_string_append_printf (msg, ", but exposures above the pilot's %.0f µs may clip unseen (the sensor's clip "
                                   "level is not known: set [camera] saturation-dn)",
                              max_us);
    else if (more.meeting_any_time.p.exposure_us > max_us)
      g_string_append_printf (msg, ", but exposures above %.0f µs clip the brightest pixels: more illumination "
                                   "or a lower gain",
                              MIN (max_us, clip_us));
  }
  /* Other periods: the scattered stripes shrink at finer ones, blur and the pixels' aperture
   * weigh more. */
  static const double period_factors[] = { 0.5, 0.67, 0.75, 1.5, 2 };
  static const guint few_m[] = { 1, 4, 16 };
  Best other = { 0 };
  for (guint i = 0; i < G_N_ELEMENTS (period_factors); i++) {
    double q = probe->geometry.period_px * period_factors[i];
    if (q < 3)
      continue;
    Best pl = { 0 }, pm = { 0 };
    best_reachable (m, errors, probe, t, w, h, 16, longest, q, target, &pl, &pm);
    if (!pm.found)
      continue;
    Search ps = { 0 };
    search (m, errors, probe, t, w, h, m->phases, m->n_phases, few_m, G_N_ELEMENTS (few_m), &longest, 1, q, target,
            budget, &ps);
    if (ps.in_budget_meeting.found)
      consider (&other, &ps.in_budget_meeting.p, 1);
  }
  if (other.found) {
    g_string_append_printf (msg, ". A stripe period of %g px would reach it: ", other.p.period_px);
    append_point (msg, &other.p);
  } else if (!more.meeting_any_time.found)
    g_string_append (msg, ". Neither more time, more light nor another stripe period reaches it");
}

gboolean
ds_operating_point_choose (const DsOperatingModel *m, DsErrorModel *errors, const DsSceneProbe *probe,
                           const DsRigTiming *t, guint w, guint h, double target, double budget,
                           DsOperatingPoint *out, GError **error)
{
  return ds_operating_point_choose_moving (m, errors, probe, t, w, h, target, budget, NULL, out, error);
}

gboolean
ds_operating_point_choose_moving (const DsOperatingModel *m, DsErrorModel *errors, const DsSceneProbe *probe,
                                  const DsRigTiming *t, guint w, guint h, double target, double budget,
                                  const DsOperatingMotion *motion, DsOperatingPoint *out, GError **error)
{
  double factors[DS_OPERATING_MAX_CANDIDATES];
  guint n_factors = usable_factors (m, probe, factors);
  if (n_factors == 0) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CLIPPED,
                 "the pilot frames' brightest pixels are at the clip level (%.0f DN) whatever the exposure: "
                 "lower the gain or the illumination", probe->clip.saturation_dn);
    return FALSE;
  }
  DsSceneProbe worst;
  g_autoptr (DsErrorModel) upper = ds_scene_probe_worst_case (probe, &worst) ? ds_error_model_new_like (errors, &worst) : NULL;
  const Models em = { errors, upper, probe->narrow.unresolved && probe->interval.set && probe->interval.unbounded,
                      motion && motion->table && !isnan (motion->speed_px_s) ? motion : NULL };
  double longest = 0;
  for (guint i = 0; i < n_factors; i++)
    longest = MAX (longest, factors[i]);
  Search s = { 0 };
  gboolean reachable = TRUE;
  if (target > 0) {
    Best least = { 0 }, meets = { 0 };
    best_reachable (m, &em, probe, t, w, h, largest (m->averages, m->n_averages), longest, 0, target, &least,
                    &meets);
    reachable = meets.found;
    if (!reachable && budget <= 0)
      s.least_in_budget = least;
  }
  if (reachable || budget > 0)
    search (m, &em, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, factors, n_factors, 0,
            reachable ? target : 0, budget, &s);
  if (reachable && s.in_budget_meeting.found) {
    *out = s.in_budget_meeting.p;
    return TRUE;
  }
  *out = s.least_in_budget.p;
  if (!s.least_in_budget.found)
    out->predicted_error = INFINITY;
  /* Undetermined: no point's upper end meets the target, but the most accurate one's interval (its
   * lower end, over its uncertainty) reaches it. A target is accepted only on the upper end and
   * refused only on the lower end: between them the frames cannot tell, and refusing would leave
   * the user without a set whose error may well be within the target. It is run, and says so. */
  const DsOperatingPoint *best = &s.least_in_budget.p;
  gboolean margin = target > 0 && s.least_in_budget.found && optimistic_end (best) <= target;
  GString *msg = g_string_new (NULL);
  if (target > 0)
    g_string_append_printf (msg, "no operating point %s a relative error of %.4f",
                            margin ? "is predicted to reach" : "reaches", target);
  else
    g_string_append (msg, "no operating point");
  if (budget > 0)
    g_string_append_printf (msg, " within %.0f ms", budget);
  if (s.least_in_budget.found) {
    g_string_append (msg, "; the best reachable is ");
    append_point (msg, best);
    if (best->lower_bound && isinf (best->predicted_error_upper))
      g_string_append (msg, ", a lower bound whose upper end the pilot cannot bound");
    else if (best->lower_bound)
      g_string_append (msg, ", a lower bound");
    if (target > 0)
      g_string_append_printf (msg, margin ? ", uncertain by %.0f %%: its lower end's optimistic end %.4f reaches the "
                                            "target, so whether it is met is undetermined; it is run and the target "
                                            "may be missed"
                                          : ", uncertain by %.0f %%: even its lower end's optimistic end %.4f is above "
                                            "the target",
                              100 * expm1 (best->uncertainty), optimistic_end (best));
    if (best->parts.blur_assumed)
      g_string_append (msg, " (the stripes' blur is not known: its upper end assumes a blurred pattern; calibrate "
                            "to measure it)");
  } else if (budget > 0)
    g_string_append_printf (msg, "; the fastest candidate does not fit a budget of %.0f ms", budget);
  else
    g_string_append (msg, "; no candidate leaves pixels to separate (each clips or is refused by its estimator)");
  if (target > 0 && reachable && s.meeting_any_time.found) {
    g_string_append_printf (msg, ". A time budget of %.0f ms would reach it: ", ceil (s.meeting_any_time.p.predicted_time_ms));
    append_point (msg, &s.meeting_any_time.p);
  } else if (target > 0)
    append_remedies (msg, m, &em, probe, t, w, h, longest, target, budget);
  if (target > 0 && !probe->leak.measured)
    g_string_append_printf (msg, " (scattered light that keeps the stripes: %s)", probe->leak.note);
  else if (target > 0 && probe->narrow.unresolved && probe->interval.set)
    g_string_append_printf (msg, " (%s; %s)", probe->narrow.note, probe->interval.note);
  else if (target > 0 && probe->narrow.unresolved)
    g_string_append_printf (msg, " (%s)", probe->narrow.note);
  if (target > 0 && probe->transfer.inconsistent)
    g_string_append_printf (msg, " (%s)", probe->transfer.note);
  if (target > 0 && probe->loss.unexplained)
    g_string_append_printf (msg, " (%s; its upper end: %s)", probe->loss.note, probe->loss.bound_note);
  if (margin) {
    /* Run the fastest point whose lower end meets the target, where one fits the budget: the
     * interval says no more of the most accurate point, and a lower bound with no upper end would
     * otherwise always run the longest set. */
    Search lower = { .on_lower_end = TRUE };
    search (m, &em, probe, t, w, h, m->phases, m->n_phases, m->averages, m->n_averages, factors, n_factors, 0,
            target, budget, &lower);
    if (lower.in_budget_meeting.found) {
      *out = lower.in_budget_meeting.p;
      g_string_append (msg, ". Run: the fastest point whose lower end meets the target, ");
      append_point (msg, out);
    }
    out->target_may_be_missed = TRUE;
    out->undetermined = TRUE;
    g_strlcpy (out->target_note, msg->str, sizeof out->target_note);
    g_string_free (msg, TRUE);
    return TRUE;
  }
  g_set_error_literal (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_UNREACHABLE, msg->str);
  g_string_free (msg, TRUE);
  return FALSE;
}
