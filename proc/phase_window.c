/* The sliding phase window (proc/phase_window.h).
 *
 * This version keeps a copy of the newest frame of each phase and refolds the N frames into
 * one DsPhaseSet for every result, in arrival order. That is the definition of the window's
 * result (a fresh set over the same frames), so equality holds by construction; it costs N
 * folds per result. */
#include "proc/phase_window.h"

#include <string.h>

#include "proc/proc_error.h"

struct DsPhaseWindow {
  guint n;
  guint width, height;
  DsPhaseSet *set;
  DsImage **slot;      /* newest frame of each phase since the last break; NULL: none */
  guint64 *arrival;    /* push number of each slot's frame */
  guint64 pushes;      /* pushes since the window was made */
  guint64 since_break; /* pushes since the last break */
  guint fill;
  guint *order;        /* scratch: phases by arrival */
};

DsPhaseWindow *
ds_phase_window_new (const DsSeparationParams *params, guint width, guint height, GError **error)
{
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (params, width, height, error);
  if (!set)
    return NULL;
  DsPhaseWindow *w = g_new0 (DsPhaseWindow, 1);
  w->n = params->n_phases;
  w->width = width;
  w->height = height;
  w->set = g_steal_pointer (&set);
  w->slot = g_new0 (DsImage *, w->n);
  w->arrival = g_new0 (guint64, w->n);
  w->order = g_new0 (guint, w->n);
  return w;
}

void
ds_phase_window_free (DsPhaseWindow *window)
{
  if (!window)
    return;
  for (guint k = 0; k < window->n; k++)
    ds_image_free (window->slot[k]);
  g_free (window->slot);
  g_free (window->arrival);
  g_free (window->order);
  ds_phase_set_free (window->set);
  g_free (window);
}

gboolean
ds_phase_window_set_dark (DsPhaseWindow *window, const DsImage *dark, GError **error)
{
  return ds_phase_set_set_dark (window->set, dark, error);
}

static gboolean
slot_is_live (const DsPhaseWindow *window, guint k)
{
  /* A slot filled before the last break is stale: its memory is kept for reuse only. */
  return window->slot[k] && window->arrival[k] + window->since_break > window->pushes;
}

/* The frames kept since the last break share one sample type and depth: a set refuses a mix,
 * and the window refuses it at the push so that the error names the frame that broke it. */
static const DsImage *
any_live_slot (const DsPhaseWindow *window)
{
  for (guint k = 0; k < window->n; k++)
    if (slot_is_live (window, k))
      return window->slot[k];
  return NULL;
}

gboolean
ds_phase_window_push (DsPhaseWindow *window, guint phase, const DsImage *frame,
                      gboolean *complete, GError **error)
{
  if (phase >= window->n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u is outside 0..%u of an N = %u window", phase, window->n - 1, window->n);
    return FALSE;
  }
  if (!frame || frame->width != window->width || frame->height != window->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %ux%u, the window expects %ux%u", phase,
                 frame ? frame->width : 0, frame ? frame->height : 0, window->width,
                 window->height);
    return FALSE;
  }
  const DsImage *other = any_live_slot (window);
  if (other && (other->type != frame->type || other->bit_depth != frame->bit_depth)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %s with %u bits, the window's frames are %s with %u bits",
                 phase, ds_sample_type_name (frame->type), frame->bit_depth,
                 ds_sample_type_name (other->type), other->bit_depth);
    return FALSE;
  }
  DsImage *dst = window->slot[phase];
  if (!dst || dst->type != frame->type) {
    g_autoptr (DsImage) fresh = ds_image_new (frame->type, frame->width, frame->height, error);
    if (!fresh)
      return FALSE;
    ds_image_free (window->slot[phase]);
    window->slot[phase] = dst = g_steal_pointer (&fresh);
  }
  gboolean was_live = slot_is_live (window, phase);
  dst->bit_depth = frame->bit_depth;
  gsize row = (gsize) frame->width * ds_sample_size (frame->type);
  for (guint y = 0; y < frame->height; y++)
    memcpy (ds_image_row (dst, y), ds_image_row (frame, y), row);
  window->pushes++;
  window->since_break++;
  window->arrival[phase] = window->pushes;
  if (!was_live)
    window->fill++;
  if (complete)
    *complete = window->fill == window->n;
  return TRUE;
}

void
ds_phase_window_break (DsPhaseWindow *window)
{
  window->since_break = 0;
  window->fill = 0;
}

guint
ds_phase_window_fill (const DsPhaseWindow *window)
{
  return window->fill;
}

guint64
ds_phase_window_frames_since_break (const DsPhaseWindow *window)
{
  return window->since_break;
}

guint64
ds_phase_window_span (const DsPhaseWindow *window)
{
  if (window->fill < window->n)
    return 0;
  guint64 oldest = G_MAXUINT64;
  for (guint k = 0; k < window->n; k++)
    oldest = MIN (oldest, window->arrival[k]);
  return window->pushes - oldest + 1;
}

gboolean
ds_phase_window_finalize_into (DsPhaseWindow *window, DsSeparation *sep, GError **error)
{
  if (window->fill < window->n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                 "the window has frames of %u of its %u phases since it was last broken",
                 window->fill, window->n);
    return FALSE;
  }
  for (guint k = 0; k < window->n; k++)
    window->order[k] = k;
  /* Insertion sort by arrival: N is small and the order is nearly cyclic. */
  for (guint i = 1; i < window->n; i++) {
    guint k = window->order[i], j = i;
    for (; j > 0 && window->arrival[window->order[j - 1]] > window->arrival[k]; j--)
      window->order[j] = window->order[j - 1];
    window->order[j] = k;
  }
  ds_phase_set_reset (window->set);
  for (guint i = 0; i < window->n; i++) {
    guint k = window->order[i];
    if (!ds_phase_set_accumulate (window->set, k, window->slot[k], error))
      return FALSE;
  }
  return ds_phase_set_finalize_into (window->set, sep, error);
}
