/* Stamps a result with where and with what it was taken (DsResultProvenance): the program, the
 * configuration's fingerprint, the backends, the camera's identity, pixel format and ROI, the
 * illuminator's temperature and the learned stripe offset. Main thread. */
#pragma once
#include "daemon/config/config.h"
#include "daemon/acquire/result.h"
#include "daemon/acquire/sequencer.h"

G_BEGIN_DECLS

void ds_provenance_fill (DsResultProvenance *provenance, const DsConfig *config, const char *config_sha256,
                         const DsSequencerStatus *status);

G_END_DECLS
