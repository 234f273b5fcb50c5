/* The illuminator interface: the stripe projector's controller (modbus, gpio, sim).
 *
 * Threads: created, used and closed by the acquisition thread only; no concurrent calls.
 * Errors: DS_ILLUMINATOR_ERROR with DsDeviceError codes; messages name the register or line. */
#pragma once
#include <glib.h>

#include "drivers/core/device_error.h"

G_BEGIN_DECLS

typedef enum {
  DS_STRIPES_SQUARE = 0,
  DS_STRIPES_SINE = 1,
} DsStripeKind;

typedef struct {
  DsStripeKind kind;
  double period_px;        /* stripe period as seen by the camera, pixels */
  double duty;             /* lit fraction (0, 1) */
  double black_level;      /* off-stripe leakage [0, 1) */
  double intensity;        /* 0..1 of the maximum */
  guint n_phases;          /* phases per period, >= 2 */
} DsStripePattern;

typedef struct {
  gboolean ready;
  gboolean enabled;
  gboolean fault;
  gboolean over_temperature;
  int applied_phase;       /* -1 when off or unknown */
  guint64 apply_count;     /* patterns applied since power-up (wraps at the device's width) */
  double temperature_c;    /* NAN if the device has no sensor */
  guint firmware_version;
  /* Whether set_pattern may ask for another stripe period (issue 12: scattered light that keeps
   * the stripes is measured at two periods). TRUE: any period_px in [period_min_px,
   * period_max_px] is projected as asked. FALSE: the period is the projector's own (its optics)
   * and set_pattern refuses any other with UNSUPPORTED: the one the device states (period_min_px
   * = period_max_px), or, from a device that states none (0, 0), the period of the first
   * set_pattern after open (the configuration's). Constant while the device is open. */
  gboolean period_adjustable;
  double period_min_px, period_max_px;
  /* The link since open, for a backend that retries requests (Modbus; 0 elsewhere): attempts
   * that got no good answer (a timeout, an exception, a short answer, a lost link), the
   * accesses that failed after all their attempts, and what the last failed attempt was
   * ("" for none). Retried attempts cost time without failing a set: these say why sets slow. */
  guint64 failed_attempts, failed_accesses;
  char last_link_problem[160];
} DsIlluminatorStatus;

typedef struct DsIlluminatorOps DsIlluminatorOps;

typedef struct {
  const DsIlluminatorOps *ops;
  gpointer backend;
} DsIlluminator;

struct DsIlluminatorOps {
  const char *name;        /* "modbus", "gpio", "sim" */
  /* Loads the pattern geometry (not yet lit). Blocks for a few register writes (< timeout).
   * Fails INVALID (out of the device's range), UNSUPPORTED (a period the device cannot project:
   * see DsIlluminatorStatus.period_adjustable; the message names the period and what the device
   * can do), TIMEOUT, DISCONNECTED, FAULT. */
  gboolean (*set_pattern) (gpointer backend, const DsStripePattern *pattern, GError **error);
  /* Lights phase k (0 <= k < n_phases) and returns only when the device reports that phase
   * applied (read back), or fails within timeout_ms: TIMEOUT (never applied), BUSY (stuck not
   * ready), FAULT (fault/over-temperature bit, exception response), INVALID (the device
   * applied a different phase: the message says which). */
  gboolean (*set_phase) (gpointer backend, guint phase, guint timeout_ms, GError **error);
  /* Illuminator off (dark frames, shutdown). Same blocking and errors as set_phase. */
  gboolean (*off) (gpointer backend, guint timeout_ms, GError **error);
  /* One round trip (the period capability is read when the device is opened). Fails TIMEOUT,
   * DISCONNECTED, INCOMPLETE (short read). */
  gboolean (*get_status) (gpointer backend, DsIlluminatorStatus *status, GError **error);
  /* Reopens the link after DISCONNECTED/TIMEOUT; the caller decides when. */
  gboolean (*reconnect) (gpointer backend, GError **error);
  /* Turns off (best effort) and frees everything. */
  void (*close) (gpointer backend);
  /* Lights every stripe at once: the whole field at the pattern's lit level, no stripes (the
   * `preview` light "all", for focusing and exposure: a phase's brightest pixels reach this
   * level, so an exposure that does not clip here does not clip in a set). Acquisition thread;
   * same blocking and errors as set_phase. NULL: the device cannot (its map has no such state);
   * call it through ds_illuminator_all_on, which fails UNSUPPORTED then. */
  gboolean (*all_on) (gpointer backend, guint timeout_ms, GError **error);
};

void ds_illuminator_close (DsIlluminator *illuminator); /* NULL-safe; frees the struct too */
/* ops->all_on, or UNSUPPORTED naming the backend when it has none. Acquisition thread. */
gboolean ds_illuminator_all_on (DsIlluminator *illuminator, guint timeout_ms, GError **error);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsIlluminator, ds_illuminator_close)

G_END_DECLS
