/* Writing result messages (a capture's reply, a streamed result event) to files through the one
 * writer of daemon/output: the message's payloads become planes (and raw frames, when the daemon
 * sent them), its metadata goes with them unchanged, and the files follow the naming scheme of
 * the spool (result_files.h). */
#pragma once
#include "daemon/output/hdf5_run.h"
#include "daemon/output/result_files.h"
#include "daemon/protocol/client.h"

typedef struct DsCtlResult DsCtlResult;

/* Planes from the payloads: transmissive, scattered (f32, or u16 widened exactly to f32), mask,
 * optional max/min/mean, and raw frames listed in the metadata's raw_frames. Fails when a
 * required payload is missing or a raw frame's payload is absent. */
DsCtlResult *ds_ctl_result_new (const DsMessage *message, GError **error);
void ds_ctl_result_free (DsCtlResult *result);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsCtlResult, ds_ctl_result_free)
const DsOutputResult *ds_ctl_result_planes (const DsCtlResult *result);

/* The files of `kinds` in dir with the set's stem; `written` receives the basenames. */
gboolean ds_ctl_write_result (const DsMessage *message, const char *dir, guint kinds, GPtrArray *written,
                              GError **error);
