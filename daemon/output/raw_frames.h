/* The raw frames of one phase set, kept when a capture asks for them (`save_phases`): every
 * folded phase frame with its phase index and camera frame id, in acquisition order, and the
 * dark frame that was subtracted with the ids of the frames averaged into it. Built by the
 * acquisition thread (or by descatterctl from payloads), then read-only: any thread may read a
 * published one. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint phase;           /* k, 0-based */
  guint64 frame_id;      /* the camera's id (extended across 16-bit wrap); 0 when unknown */
  guint64 timestamp_ns;  /* the camera's timestamp, or host arrival time */
  DsImage *image;        /* owned; u8/u16 as the camera delivered it */
} DsRawFrame;

typedef struct {
  guint n_phases;
  GPtrArray *frames;     /* DsRawFrame *, acquisition order */
  DsImage *black;        /* the dark frame subtracted (the average), or NULL */
  GArray *black_ids;     /* guint64: ids of the frames averaged into black (may be empty) */
  GPtrArray *spare;      /* DsImage *: room reserved for frames not added yet */
} DsRawFrames;

DsRawFrames *ds_raw_frames_new (guint n_phases);
void ds_raw_frames_free (DsRawFrames *raw);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsRawFrames, ds_raw_frames_free)

/* Room for `count` frames of this type and size, allocated and written now: the first-touch
 * page faults of their memory fall here instead of when the frames are added (descatterd
 * reserves a set's frames before its first frame, so that keeping the last one costs a copy,
 * not fresh memory, between the last frame and the result). */
gboolean ds_raw_frames_reserve (DsRawFrames *raw, guint count, DsSampleType type, guint width, guint height,
                                GError **error);
/* Frees the room reserved and not used (before the frames are published). */
void ds_raw_frames_trim (DsRawFrames *raw);
/* Keeps a copy of image (the caller keeps its frame; the copy costs one memcpy), into reserved
 * room of its type and size if there is any left. */
gboolean ds_raw_frames_add (DsRawFrames *raw, guint phase, guint64 frame_id, guint64 timestamp_ns,
                            const DsImage *image, GError **error);
/* Takes ownership of image. */
void ds_raw_frames_add_owned (DsRawFrames *raw, guint phase, guint64 frame_id, guint64 timestamp_ns,
                              DsImage *image);
/* A copy of black; ids may be NULL when n_ids is 0. */
gboolean ds_raw_frames_set_black (DsRawFrames *raw, const DsImage *black, const guint64 *ids, guint n_ids,
                                  GError **error);
/* Frames per phase: the smallest count over the phases (0 if a phase has none). */
guint ds_raw_frames_per_phase (const DsRawFrames *raw);
/* Bytes of pixels held. */
gsize ds_raw_frames_bytes (const DsRawFrames *raw);

G_END_DECLS
