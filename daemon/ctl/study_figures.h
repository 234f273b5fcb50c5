/* The study's figures (docs/operations.md, "Study figures"): drawn by plot_study.py, installed
 * under the data dir (etc/ of a source tree), with Debian's python3 and matplotlib. The figures
 * are matplotlib's rather than hand-drawn here because they need log axes, legends and PNG as
 * well as SVG; the Debian package descatter-tools depends on python3-matplotlib for them. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Runs `$DESCATTER_PYTHON (default /usr/bin/python3) DATA_DIR/plot_study.py CSV DIR` and waits
 * for it (seconds: one figure set per scene). FALSE with an error carrying the helper's last
 * lines of stderr when it cannot start or fails (no matplotlib, an unreadable CSV). */
gboolean ds_study_draw_figures (const char *csv_path, const char *dir, GError **error);

G_END_DECLS
