/* The dark frame: the illuminator off, M frames averaged, each checked for being exposed after
 * the light went off and for showing no stripes. */
#include <math.h>
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"
#include "proc/stripe_phase.h"

gboolean
ds_seq_illuminator_off (DsAcquisition *acq, DsFrameCounters *c, GError **error)
{
  ds_seq_blocking (acq->shared, acq->dev->settle_timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
  if (!acq->dev->illuminator->ops->off (acq->dev->illuminator->backend, acq->dev->settle_timeout_ms,
                                        error)) {
    c->device_errors++;
    g_prefix_error (error, "dark frame: illuminator off: ");
    ds_seq_fatal_device_error (acq, *error); /* a lost illuminator is reconnected */
    return FALSE;
  }
  return TRUE;
}

/* Averages `n` frames into an image of the frames' type. Each frame is checked against the
 * time the illuminator went off before it was exposed: a frame triggered ahead by the previous
 * set (continuous mode, carry.c) against the time it went off for that frame, even
 * when the illuminator lit a phase again since (the previous set re-acquired its dropped last
 * phase after grabbing it); the illuminator is then turned off again for the frames after it. */
DsImage *
ds_seq_acquire_dark (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c, double *mean_dn,
                     GError **error)
{
  gboolean off = FALSE, grab_only = FALSE;
  gint64 off_at = 0, carried_off_at = 0;
  g_autoptr (DsFrame) carried = NULL;
  DsSeqCarry *cy = &acq->carry;
  if (cy->stage != DS_CARRY_NONE) {
    /* The set runner checked that it fits this set (ds_seq_carry_fits). */
    g_assert (cy->dark);
    ds_frame_counters_add (c, &cy->counters);
    if (cy->stage == DS_CARRY_TRIGGERED) {
      off = grab_only = TRUE;
      off_at = cy->applied_at_us;
    } else if (cy->stage == DS_CARRY_HELD) {
      carried = g_steal_pointer (&cy->frame);
      carried_off_at = cy->applied_at_us;
    }
    memset (cy, 0, sizeof *cy);
  }
  g_array_set_size (acq->dark_ids, 0);
  g_autofree double *sum = NULL;
  guint w = 0, h = 0, got = 0, retries_left = s->phase_retries, bit_depth = 16;
  DsSampleType type = DS_SAMPLE_U16;
  while (got < s->averages) {
    GError *why = NULL;
    if (!ds_seq_check_quit (acq, error))
      return NULL;
    gint64 exposed_after = carried ? carried_off_at : off_at;
    if (!carried && !off) {
      if (!ds_seq_illuminator_off (acq, c, error))
        return NULL;
      ds_seq_flush_stale (acq, c);
      off = TRUE;
      exposed_after = off_at = g_get_monotonic_time ();
    }
    g_autoptr (DsFrame) f = carried      ? g_steal_pointer (&carried)
                            : grab_only ? ds_seq_grab (acq, c, &why)
                                        : ds_seq_trigger_and_grab (acq, c, &why);
    grab_only = FALSE;
    if (f && f->host_time_us != 0 && (gint64) f->host_time_us < exposed_after) {
      ds_frame_counters_drop (c, DS_DROP_STALE, 1);
      why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "stale frame");
      g_clear_pointer (&f, ds_frame_free);
    }
    if (f && s->verify_phase && s->period_px > 2) {
      /* A dark frame must show no stripes: one exposed while the pattern was still on would
       * be subtracted from every phase. */
      DsStripePhase sp;
      if (ds_stripe_phase_measure (f->image, s->period_px, NULL, &sp, NULL) && sp.reliable) {
        ds_frame_counters_drop (c, DS_DROP_WRONG_PHASE, 1);
        why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED,
                           "dark frame shows stripes (snr %.1f): the illuminator was not off", sp.snr);
        g_clear_pointer (&f, ds_frame_free);
      }
    }
    if (!f) {
      if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "dark frame"))
        return NULL;
      continue;
    }
    const DsImage *img = f->image;
    if (!sum) {
      w = img->width;
      h = img->height;
      type = img->type;
      bit_depth = img->bit_depth;
      sum = g_new0 (double, (gsize) w * h);
    } else if (img->width != w || img->height != h) {
      ds_frame_counters_drop (c, DS_DROP_ABORTED, 1);
      g_set_error (error, DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED,
                   "dark frame: frame size changed from %ux%u to %ux%u", w, h, img->width,
                   img->height);
      return NULL;
    }
    for (guint y = 0; y < h; y++) {
      const guint8 *row = ds_image_row (img, y);
      double *out = sum + (gsize) y * w;
      for (guint x = 0; x < w; x++)
        out[x] += img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
                  : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                               : ((const float *) row)[x];
    }
    g_array_append_val (acq->dark_ids, f->frame_id);
    got++;
  }
  /* The dark frame has the frames' own sample type, as the accumulator subtracts like from
   * like; averaging M integer frames rounds to the nearest DN (an unbiased error below the
   * read noise). */
  DsImage *dark = ds_image_new (type, w, h, error);
  if (!dark)
    return NULL;
  dark->bit_depth = bit_depth;
  double total = 0; /* of the values stored: the mean of what is subtracted */
  for (guint y = 0; y < h; y++) {
    void *row = ds_image_row (dark, y);
    for (guint x = 0; x < w; x++) {
      double v = sum[(gsize) y * w + x] / got;
      if (type == DS_SAMPLE_F32) {
        ((float *) row)[x] = (float) v;
        total += isfinite (v) ? (float) v : 0;
      } else if (type == DS_SAMPLE_U16) {
        ((guint16 *) row)[x] = (guint16) CLAMP (v + 0.5, 0, 65535);
        total += ((guint16 *) row)[x];
      } else {
        ((guint8 *) row)[x] = (guint8) CLAMP (v + 0.5, 0, 255);
        total += ((guint8 *) row)[x];
      }
    }
  }
  if (mean_dn)
    *mean_dn = w && h ? total / ((double) w * h) : NAN;
  return dark;
}

void
ds_seq_note_dark (DsAcquisition *acq, const DsCaptureSettings *s, double mean_dn, gboolean by_set)
{
  DsDarkFrameInfo info = { .taken = TRUE, .by_set = by_set, .taken_unix_us = g_get_real_time (),
                           .mean_dn = mean_dn, .frames = s->averages, .exposure_us = s->exposure_us,
                           .gain_db = s->gain_db };
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.last_dark = info;
  if (!by_set) {
    acq->shared->status.stored_dark = info;
    acq->shared->status.has_dark = TRUE;
  }
  g_mutex_unlock (&acq->shared->lock);
}

void
ds_seq_run_dark (DsAcquisition *acq, const DsCaptureSettings *s, guint64 tag)
{
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  DsImage *dark = NULL;
  double mean = NAN;
  if (!ds_seq_ensure_camera (acq, s, &error)) {
    g_prefix_error (&error, "camera: ");
    ds_seq_fatal_device_error (acq, error);
  } else
    dark = ds_seq_acquire_dark (acq, s, &c, &mean, &error);
  if (!dark) {
    ds_seq_account_unfinished (acq->shared, &c, error);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DARK, tag, NULL, g_steal_pointer (&error), NULL);
    return;
  }
  ds_frame_counters_fold_rest (&c);
  ds_seq_account_frames (acq->shared, &c);
  ds_seq_note_dark (acq, s, mean, FALSE);
  g_clear_pointer (&acq->dark, ds_image_free);
  acq->dark = dark;
  g_array_set_size (acq->stored_dark_ids, 0);
  g_array_append_vals (acq->stored_dark_ids, acq->dark_ids->data, acq->dark_ids->len);
  acq->dark_exposure_us = s->exposure_us;
  acq->dark_gain_db = s->gain_db;
  ds_seq_emit_dark (acq->shared, tag, mean);
}

gboolean
ds_seq_dark_for (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c, DsImage **own,
                 const DsImage **use, GError **error)
{
  *own = NULL;
  *use = NULL;
  if (s->dark_frame) {
    double mean_dn = NAN;
    *own = ds_seq_acquire_dark (acq, s, c, &mean_dn, error);
    if (!*own)
      return FALSE;
    ds_seq_note_dark (acq, s, mean_dn, TRUE);
    *use = *own;
  } else if (acq->dark && acq->dark_exposure_us == s->exposure_us && acq->dark_gain_db == s->gain_db) {
    /* the stored dark fits only the exposure and gain it was taken at */
    *use = acq->dark;
  }
  return TRUE;
}
