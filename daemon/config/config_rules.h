/* The configuration's cross-key rules: what no single key's type or range can express (a
 * backend's required keys, devices that must be simulated together, absolute paths, limits
 * between keys). Private to daemon/config: ds_config_load_* applies them after every key
 * parsed. */
#pragma once
#include "daemon/config/config.h"

G_BEGIN_DECLS

/* FALSE with DS_CONFIG_ERROR_INCONSISTENT (or the ROI's BAD_VALUE), prefixed with `name`, at the
 * first rule c breaks. */
gboolean ds_config_check_consistency (const DsConfig *c, const char *name, GError **error);

G_END_DECLS
