#include "drivers/modbus/modbus_illuminator.h"

#include <errno.h>
#include <math.h>
#include <modbus.h>
#include <stdio.h>
#include <string.h>

#include "drivers/modbus/registers.h"

#define POLL_INTERVAL_US 500

typedef struct {
  modbus_t *ctx;
  char *uri_text;
  DsModbusUri uri;
  guint unit_id;
  guint timeout_ms;
  gboolean connected;
  gboolean lit;            /* we last lit a phase (ENABLE = 1 written and applied) */
  guint n_phases;
  /* What the projector says it can do (read at open and reconnect). rev1: a controller of map
   * revision 1, without CAPABILITIES: a fixed period it does not state. */
  gboolean rev1;
  guint16 capabilities, period_min, period_max;
  guint16 first_period;    /* rev1: PERIOD_CENTIPX of the first set_pattern; 0 = none yet */
  guint64 failed_attempts, failed_accesses; /* since open (DsIlluminatorStatus) */
  char last_link_problem[160];
  /* APPLY_COUNT as the poll that confirmed our last apply read it (apply_and_wait). Known only
   * from that confirmation until anything else could move the count unseen: any failure of an
   * apply, a write of ours not waited for (set_pattern), a lost or new connection. */
  gboolean count_known;
  guint16 count_confirmed;
} ModbusIlluminator;

/* ---- URI ---------------------------------------------------------------------------------- */

static gboolean
uri_error (GError **error, const char *uri, const char *fmt, ...) G_GNUC_PRINTF (3, 4);

static gboolean
uri_error (GError **error, const char *uri, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *msg = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID, "Modbus URI \"%s\": %s", uri, msg);
  return FALSE;
}

static gboolean
parse_uint (const char *s, guint min, guint max, guint *out)
{
  if (!s || !*s)
    return FALSE;
  for (const char *p = s; *p; p++)
    if (!g_ascii_isdigit (*p))
      return FALSE;
  guint64 v = g_ascii_strtoull (s, NULL, 10);
  if (v < min || v > max)
    return FALSE;
  *out = (guint) v;
  return TRUE;
}

gboolean
ds_modbus_uri_parse (const char *uri, DsModbusUri *out, GError **error)
{
  memset (out, 0, sizeof *out);
  if (!uri)
    return uri_error (error, "", "empty");
  if (g_str_has_prefix (uri, "tcp://")) {
    out->transport = DS_MODBUS_TCP;
    const char *hp = uri + 6;
    const char *colon = strrchr (hp, ':');
    gsize hl = colon ? (gsize) (colon - hp) : strlen (hp);
    if (hl == 0)
      return uri_error (error, uri, "host: missing (expected tcp://HOST:PORT)");
    if (hl >= sizeof out->host)
      return uri_error (error, uri, "host: longer than %zu characters", sizeof out->host - 1);
    memcpy (out->host, hp, hl);
    out->host[hl] = 0;
    for (const char *p = out->host; *p; p++)
      if (!(g_ascii_isalnum (*p) || *p == '.' || *p == '-' || *p == '_'))
        return uri_error (error, uri, "host \"%s\": unexpected character '%c'", out->host, *p);
    out->port = 502;
    if (colon && !parse_uint (colon + 1, 1, 65535, &out->port))
      return uri_error (error, uri, "port \"%s\": expected 1..65535", colon + 1);
    return TRUE;
  }
  if (g_str_has_prefix (uri, "rtu:")) {
    out->transport = DS_MODBUS_RTU;
    out->baud = 19200;
    out->parity = 'E';
    out->data_bits = 8;
    out->stop_bits = 1;
    const char *dev = uri + 4;
    const char *q = strchr (dev, '?');
    gsize dl = q ? (gsize) (q - dev) : strlen (dev);
    if (dl == 0 || dev[0] != '/')
      return uri_error (error, uri, "device: expected an absolute path such as /dev/ttyUSB0");
    if (dl >= sizeof out->device)
      return uri_error (error, uri, "device: longer than %zu characters", sizeof out->device - 1);
    memcpy (out->device, dev, dl);
    out->device[dl] = 0;
    if (!q)
      return TRUE;
    g_auto (GStrv) params = g_strsplit (q + 1, "&", -1);
    for (guint i = 0; params[i]; i++) {
      const char *eq = strchr (params[i], '=');
      if (!eq)
        return uri_error (error, uri, "parameter \"%s\": expected key=value", params[i]);
      g_autofree char *key = g_strndup (params[i], (gsize) (eq - params[i]));
      const char *val = eq + 1;
      if (strcmp (key, "baud") == 0) {
        if (!parse_uint (val, 50, 4000000, &out->baud))
          return uri_error (error, uri, "baud \"%s\": expected 50..4000000", val);
      } else if (strcmp (key, "parity") == 0) {
        if (strlen (val) != 1 || !strchr ("NEO", g_ascii_toupper (val[0])))
          return uri_error (error, uri, "parity \"%s\": expected N, E or O", val);
        out->parity = g_ascii_toupper (val[0]);
      } else if (strcmp (key, "data") == 0) {
        if (!parse_uint (val, 5, 8, &out->data_bits))
          return uri_error (error, uri, "data \"%s\": expected 5..8 bits", val);
      } else if (strcmp (key, "stop") == 0) {
        if (!parse_uint (val, 1, 2, &out->stop_bits))
          return uri_error (error, uri, "stop \"%s\": expected 1 or 2 bits", val);
      } else
        return uri_error (error, uri, "parameter \"%s\": unknown (baud, parity, data, stop)", key);
    }
    return TRUE;
  }
  return uri_error (error, uri, "scheme: expected tcp://HOST:PORT or rtu:/dev/DEVICE?baud=...");
}

/* ---- pattern ------------------------------------------------------------------------------ */

static gboolean
to_register (double v, double scale, guint min, guint max, const char *field, int reg,
             guint16 *out, GError **error)
{
  double r = round (v * scale);
  if (!isfinite (v) || r < min || r > max) {
    /* In the unit the configuration uses first: a lab sets period-px, not centipixels. */
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "pattern %s %g: the controller takes %g..%g (register %s holds %u..%u, %g per unit)",
                 field, v, min / scale, max / scale, ds_mb_holding_name (reg), min, max, scale);
    return FALSE;
  }
  *out = (guint16) r;
  return TRUE;
}

gboolean
ds_modbus_pattern_to_registers (const DsStripePattern *p, guint16 regs[8], GError **error)
{
  regs[DS_MB_HOLD_PHASE] = 0;
  regs[DS_MB_HOLD_ENABLE] = 0;
  if (p->kind != DS_STRIPES_SQUARE && p->kind != DS_STRIPES_SINE) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "pattern kind %d: register PATTERN_KIND holds 0 (square) or 1 (sine)", (int) p->kind);
    return FALSE;
  }
  regs[DS_MB_HOLD_PATTERN_KIND] = (guint16) p->kind;
  return to_register (p->n_phases, 1, 2, DS_MB_MAX_PHASES, "phases", DS_MB_HOLD_NUM_PHASES,
                      &regs[DS_MB_HOLD_NUM_PHASES], error) &&
         to_register (p->period_px, 100, DS_MB_CENTIPX_MIN, DS_MB_CENTIPX_MAX, "period (px)", DS_MB_HOLD_PERIOD_CENTIPX,
                      &regs[DS_MB_HOLD_PERIOD_CENTIPX], error) &&
         to_register (p->duty, 1000, 1, 999, "duty", DS_MB_HOLD_DUTY_PERMILLE,
                      &regs[DS_MB_HOLD_DUTY_PERMILLE], error) &&
         to_register (p->black_level, 1000, 0, 999, "black level", DS_MB_HOLD_BLACK_PERMILLE,
                      &regs[DS_MB_HOLD_BLACK_PERMILLE], error) &&
         to_register (p->intensity, 1000, 0, 1000, "intensity", DS_MB_HOLD_INTENSITY_PERMILLE,
                      &regs[DS_MB_HOLD_INTENSITY_PERMILLE], error);
}

/* ---- register access with bounded retries ------------------------------------------------- */

typedef enum { READ_INPUT, WRITE_HOLDING } Access;

static void
disconnect (ModbusIlluminator *m)
{
  if (m->connected)
    modbus_close (m->ctx);
  m->connected = FALSE;
  /* The controller may restart while we are away (its count starts again from 0). */
  m->count_known = FALSE;
}

static gboolean
connect_link (ModbusIlluminator *m, GError **error)
{
  if (m->connected)
    return TRUE;
  if (modbus_connect (m->ctx) < 0) {
    int e = errno;
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_DISCONNECTED,
                 "Modbus %s: cannot connect: %s", m->uri_text, modbus_strerror (e));
    modbus_close (m->ctx);
    return FALSE;
  }
  m->connected = TRUE;
  /* A serial line keeps whatever a late answer left in its input queue across close and open:
   * start from a quiet line. */
  if (m->uri.transport == DS_MODBUS_RTU)
    modbus_flush (m->ctx);
  return TRUE;
}

/* How a failed request is reported and whether another attempt may help. */
static DsDeviceError
classify (int e, gboolean *retry, gboolean *relink)
{
  *retry = FALSE;
  *relink = FALSE;
  switch (e) {
  case EMBXSBUSY:
  case EMBXACK:
    *retry = TRUE;
    return DS_DEVICE_ERROR_BUSY;
  case EMBXILFUN:
    return DS_DEVICE_ERROR_UNSUPPORTED;
  case EMBXILADD:
  case EMBXILVAL:
    return DS_DEVICE_ERROR_INVALID;
  case EMBXSFAIL:
  case EMBXNACK:
  case EMBXMEMPAR:
    return DS_DEVICE_ERROR_FAULT;
  case EMBXGPATH:
  case EMBXGTAR:
    *retry = TRUE;
    return DS_DEVICE_ERROR_DISCONNECTED;
  case EMBBADCRC:
  case EMBBADDATA:
  case EMBBADEXC:
  case EMBUNKEXC:
  case EMBMDATA:
  case EMBBADSLAVE:
    /* A garbled or foreign answer: the stream is out of step, start a fresh one. */
    *retry = TRUE;
    *relink = TRUE;
    return DS_DEVICE_ERROR_INCOMPLETE;
  case ETIMEDOUT:
    /* The late answer would be taken for the next one: reconnect. */
    *retry = TRUE;
    *relink = TRUE;
    return DS_DEVICE_ERROR_TIMEOUT;
  default:
    /* ECONNRESET, EPIPE, ECONNREFUSED, EBADF, ENOTCONN...: the link is gone. */
    *retry = TRUE;
    *relink = TRUE;
    return DS_DEVICE_ERROR_DISCONNECTED;
  }
}

static const char *
exception_text (int e)
{
  switch (e) {
  case EMBXILFUN:
    return "exception 01 (illegal function)";
  case EMBXILADD:
    return "exception 02 (illegal data address: another register map?)";
  case EMBXILVAL:
    return "exception 03 (illegal data value)";
  case EMBXSFAIL:
    return "exception 04 (server device failure)";
  case EMBXACK:
    return "exception 05 (acknowledge, still working)";
  case EMBXSBUSY:
    return "exception 06 (server device busy)";
  case EMBBADDATA:
  case EMBMDATA:
    return "short or malformed answer";
  default:
    return modbus_strerror (e);
  }
}

static void
note_failed_attempt (ModbusIlluminator *m, const char *verb, const char *name, const char *why)
{
  m->failed_attempts++;
  g_snprintf (m->last_link_problem, sizeof m->last_link_problem, "%s register %s: %s", verb, name, why);
}

/* One access of nb registers from addr; bounded attempts and total time. *last_errno (may be
 * NULL): libmodbus's errno of the last failed attempt (0 for a short answer). */
static gboolean
mb_access_errno (ModbusIlluminator *m, Access access, int addr, int nb, guint16 *regs, int *last_errno,
                 GError **error)
{
  const char *name = access == READ_INPUT ? ds_mb_input_name (addr) : ds_mb_holding_name (addr);
  const char *verb = access == READ_INPUT ? "reading input" : "writing holding";
  gint64 start = g_get_monotonic_time ();
  gint64 budget_us = (gint64) DS_MODBUS_MAX_ATTEMPTS * m->timeout_ms * 1000 + 100000;
  DsDeviceError code = DS_DEVICE_ERROR_TIMEOUT;
  g_autofree char *why = NULL;
  guint attempt, made = 0;
  for (attempt = 1; attempt <= DS_MODBUS_MAX_ATTEMPTS; attempt++) {
    if (attempt > 1) {
      gint64 backoff = 2000 << (attempt - 2);
      if (g_get_monotonic_time () + backoff - start > budget_us)
        break;
      g_usleep ((gulong) backoff);
    }
    /* RTU has no transaction id: a late answer to an earlier request still waiting on the line
     * would be taken for this one's. (One arriving during this attempt can only be the answer to
     * an identical earlier attempt of this access: its data is from within the access.) */
    if (m->connected && m->uri.transport == DS_MODBUS_RTU)
      modbus_flush (m->ctx);
    made++;
    if (last_errno)
      *last_errno = ECONNREFUSED;
    g_autoptr (GError) link_error = NULL;
    if (!connect_link (m, &link_error)) {
      code = DS_DEVICE_ERROR_DISCONNECTED;
      g_free (why);
      why = g_strdup (link_error->message);
      note_failed_attempt (m, verb, name, why);
      continue;
    }
    int rc = access == READ_INPUT ? modbus_read_input_registers (m->ctx, addr, nb, regs)
             : nb == 1           ? modbus_write_register (m->ctx, addr, regs[0])
                                 : modbus_write_registers (m->ctx, addr, nb, regs);
    if (rc == nb)
      return TRUE;
    g_free (why);
    if (rc >= 0) {
      if (last_errno)
        *last_errno = 0;
      code = DS_DEVICE_ERROR_INCOMPLETE;
      why = g_strdup_printf ("short answer: %d of %d registers", rc, nb);
      note_failed_attempt (m, verb, name, why);
      disconnect (m);
      continue;
    }
    int e = errno;
    if (last_errno)
      *last_errno = e;
    gboolean retry, relink;
    code = classify (e, &retry, &relink);
    why = g_strdup (exception_text (e));
    note_failed_attempt (m, verb, name, why);
    if (relink) {
      if (m->uri.transport == DS_MODBUS_RTU && e == ETIMEDOUT)
        modbus_flush (m->ctx);
      else
        disconnect (m);
    }
    if (!retry)
      break;
  }
  m->failed_accesses++;
  g_set_error (error, DS_ILLUMINATOR_ERROR, code, "Modbus %s unit %u: %s register %s (0x%04x): %s (%u attempt%s)",
               m->uri_text, m->unit_id, verb, name, (guint) addr, why ? why : "no attempt in time",
               made, made == 1 ? "" : "s");
  return FALSE;
}

static gboolean
mb_access (ModbusIlluminator *m, Access access, int addr, int nb, guint16 *regs, GError **error)
{
  return mb_access_errno (m, access, addr, nb, regs, NULL, error);
}

/* ---- ops ---------------------------------------------------------------------------------- */

static gboolean
check_status_bits (ModbusIlluminator *m, guint16 status, GError **error)
{
  if (status & (DS_MB_STATUS_FAULT | DS_MB_STATUS_OVER_TEMPERATURE)) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_FAULT,
                 "Modbus %s: register STATUS 0x%04x reports %s", m->uri_text, status,
                 (status & DS_MB_STATUS_FAULT) ? "a driver fault" : "over-temperature");
    return FALSE;
  }
  return TRUE;
}

/* Writes regs at addr, then polls until APPLY_COUNT advanced with the device ready and
 * APPLIED_PHASE == expect, or the deadline.
 *
 * "Advanced" is counted from APPLY_COUNT read before the write. Right after an apply of ours
 * that this function confirmed, that read is skipped (one round trip of three at settle 0) and
 * the count that confirmation read stands in for it: then only an advance of exactly one, with
 * the device ready, is our write's. Any other count once ready, the same count included, means
 * that the count moved without us since (another master wrote, the controller restarted and
 * counts from 0 again): whether our write is among the applies cannot be told, so the count
 * read then becomes the reference and the write goes out again, as if the first read had been
 * made (docs/registers.md: every write schedules one apply, a write during the settle time
 * restarts it). What is lit is always checked the same way: READY, the count advanced,
 * APPLIED_PHASE the phase asked for. A fault that appeared since our last apply is then seen at
 * the first poll, after the write (which a faulted controller holds without applying it). */
static gboolean
apply_and_wait (ModbusIlluminator *m, int addr, int nb, guint16 *regs, guint expect,
                     guint timeout_ms, GError **error)
{
  gint64 deadline = g_get_monotonic_time () + (gint64) timeout_ms * 1000;
  guint16 in[3]; /* STATUS, APPLIED_PHASE, APPLY_COUNT */
  gboolean from_confirmed = m->count_known;
  guint16 count0 = m->count_confirmed;
  m->count_known = FALSE;
  if (!from_confirmed) {
    if (!mb_access (m, READ_INPUT, DS_MB_INPUT_STATUS, 3, in, error) ||
        !check_status_bits (m, in[0], error))
      return FALSE;
    count0 = in[2];
  }
  if (!mb_access (m, WRITE_HOLDING, addr, nb, regs, error))
    return FALSE;
  for (;;) {
    if (!mb_access (m, READ_INPUT, DS_MB_INPUT_STATUS, 3, in, error) ||
        !check_status_bits (m, in[0], error))
      return FALSE;
    gboolean ready = (in[0] & DS_MB_STATUS_READY) != 0;
    if (ready && from_confirmed && in[2] != (guint16) (count0 + 1)) {
      /* Not exactly our one apply: start over from this count, as a first read would. */
      from_confirmed = FALSE;
      count0 = in[2];
      if (!mb_access (m, WRITE_HOLDING, addr, nb, regs, error))
        return FALSE;
      continue;
    }
    if (ready && in[2] != count0) {
      if (in[1] == expect) {
        m->count_known = TRUE;
        m->count_confirmed = in[2];
        return TRUE;
      }
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                   "Modbus %s: register APPLIED_PHASE reads %s%u, expected %s%u", m->uri_text,
                   in[1] == DS_MB_PHASE_OFF ? "off " : "", in[1] == DS_MB_PHASE_OFF ? 0 : in[1],
                   expect == DS_MB_PHASE_OFF ? "off " : "", expect == DS_MB_PHASE_OFF ? 0 : expect);
      return FALSE;
    }
    if (g_get_monotonic_time () >= deadline) {
      if (!ready)
        g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_BUSY,
                     "Modbus %s: register STATUS 0x%04x still not ready after %u ms", m->uri_text,
                     in[0], timeout_ms);
      else
        g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_TIMEOUT,
                     "Modbus %s: register APPLY_COUNT stayed at %u for %u ms: write not applied",
                     m->uri_text, count0, timeout_ms);
      return FALSE;
    }
    g_usleep (POLL_INTERVAL_US);
  }
}

/* CAPABILITIES, PERIOD_MIN_CENTIPX, PERIOD_MAX_CENTIPX; a controller of map revision 1 answers
 * exception 02 (no such register): a fixed period it does not state. */
static gboolean
read_capabilities (ModbusIlluminator *m, GError **error)
{
  guint16 caps[3];
  int e = 0;
  g_autoptr (GError) local = NULL;
  if (!mb_access_errno (m, READ_INPUT, DS_MB_INPUT_CAPABILITIES, 3, caps, &e, &local)) {
    if (e != EMBXILADD) {
      g_propagate_error (error, g_steal_pointer (&local));
      return FALSE;
    }
    m->rev1 = TRUE;
    m->capabilities = m->period_min = m->period_max = 0;
    return TRUE;
  }
  if (caps[1] < DS_MB_CENTIPX_MIN || caps[2] < caps[1] ||
      (!(caps[0] & DS_MB_CAP_PERIOD_ADJUSTABLE) && caps[1] != caps[2])) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "Modbus %s unit %u: input registers PERIOD_MIN_CENTIPX %u, PERIOD_MAX_CENTIPX %u with "
                 "CAPABILITIES 0x%04x: not a range of periods (docs/registers.md)", m->uri_text, m->unit_id,
                 caps[1], caps[2], caps[0]);
    return FALSE;
  }
  m->rev1 = FALSE;
  m->capabilities = caps[0];
  m->period_min = caps[1];
  m->period_max = caps[2];
  return TRUE;
}

/* Whether the projector can draw this period (register units), before anything is written. */
static gboolean
check_period (ModbusIlluminator *m, guint16 centipx, GError **error)
{
  if (m->rev1) {
    if (m->first_period == 0 || centipx == m->first_period)
      return TRUE;
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "Modbus %s unit %u: register PERIOD_CENTIPX: the controller cannot change its stripe period: "
                 "it has no input register CAPABILITIES (exception 02: register map revision 1), so its "
                 "period is the %.2f px it was first given; asked for %.2f px", m->uri_text, m->unit_id,
                 m->first_period / 100.0, centipx / 100.0);
    return FALSE;
  }
  if (centipx >= m->period_min && centipx <= m->period_max)
    return TRUE;
  if (m->capabilities & DS_MB_CAP_PERIOD_ADJUSTABLE)
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "Modbus %s unit %u: register PERIOD_CENTIPX: the projector draws periods of %.2f .. %.2f px "
                 "(input registers PERIOD_MIN_CENTIPX, PERIOD_MAX_CENTIPX); asked for %.2f px", m->uri_text,
                 m->unit_id, m->period_min / 100.0, m->period_max / 100.0, centipx / 100.0);
  else
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "Modbus %s unit %u: register PERIOD_CENTIPX: the projector's period is fixed at %.2f px "
                 "(CAPABILITIES 0x%04x without PERIOD_ADJUSTABLE); asked for %.2f px", m->uri_text, m->unit_id,
                 m->period_min / 100.0, m->capabilities, centipx / 100.0);
  return FALSE;
}

static gboolean
modbus_set_pattern (gpointer backend, const DsStripePattern *pattern, GError **error)
{
  ModbusIlluminator *m = backend;
  guint16 regs[DS_MB_HOLD_COUNT];
  if (!ds_modbus_pattern_to_registers (pattern, regs, error) ||
      !check_period (m, regs[DS_MB_HOLD_PERIOD_CENTIPX], error))
    return FALSE;
  /* This write schedules an apply that nobody waits for: the count moves unseen. */
  m->count_known = FALSE;
  if (!mb_access (m, WRITE_HOLDING, DS_MB_HOLD_PHASE, DS_MB_HOLD_COUNT, regs, error))
    return FALSE;
  m->n_phases = pattern->n_phases;
  m->lit = FALSE;
  if (m->rev1 && m->first_period == 0)
    m->first_period = regs[DS_MB_HOLD_PERIOD_CENTIPX];
  return TRUE;
}

static gboolean
modbus_set_phase (gpointer backend, guint phase, guint timeout_ms, GError **error)
{
  ModbusIlluminator *m = backend;
  if (m->n_phases == 0 || phase >= m->n_phases) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "Modbus %s: phase %u outside the pattern's %u phases (set_pattern first)",
                 m->uri_text, phase, m->n_phases);
    return FALSE;
  }
  guint16 regs[2] = { (guint16) phase, 1 };
  if (!apply_and_wait (m, DS_MB_HOLD_PHASE, 2, regs, phase, timeout_ms, error))
    return FALSE;
  m->lit = TRUE;
  return TRUE;
}

static gboolean
modbus_off (gpointer backend, guint timeout_ms, GError **error)
{
  ModbusIlluminator *m = backend;
  guint16 v = 0;
  if (!apply_and_wait (m, DS_MB_HOLD_ENABLE, 1, &v, DS_MB_PHASE_OFF, timeout_ms, error))
    return FALSE;
  m->lit = FALSE;
  return TRUE;
}

/* ENABLE = 2: every stripe lit, confirmed as a phase is (APPLIED_PHASE reads DS_MB_PHASE_ALL).
 * Acquisition thread; blocks like set_phase, fails like it; UNSUPPORTED, before anything is
 * written, on a controller without CAPABILITIES bit ALL_ON (docs/registers.md). */
static gboolean
modbus_all_on (gpointer backend, guint timeout_ms, GError **error)
{
  ModbusIlluminator *m = backend;
  if (!(m->capabilities & DS_MB_CAP_ALL_ON)) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "Modbus %s unit %u: register ENABLE: the controller cannot light every stripe at once "
                 "(CAPABILITIES 0x%04x without ALL_ON)", m->uri_text, m->unit_id, m->capabilities);
    return FALSE;
  }
  guint16 v = 2;
  if (!apply_and_wait (m, DS_MB_HOLD_ENABLE, 1, &v, DS_MB_PHASE_ALL, timeout_ms, error))
    return FALSE;
  m->lit = TRUE;
  return TRUE;
}

static gboolean
modbus_get_status (gpointer backend, DsIlluminatorStatus *st, GError **error)
{
  ModbusIlluminator *m = backend;
  guint16 in[DS_MB_INPUT_REV1_COUNT];
  if (!mb_access (m, READ_INPUT, 0, DS_MB_INPUT_REV1_COUNT, in, error))
    return FALSE;
  guint16 s = in[DS_MB_INPUT_STATUS];
  st->ready = (s & DS_MB_STATUS_READY) != 0;
  st->enabled = (s & DS_MB_STATUS_ENABLED) != 0;
  st->fault = (s & DS_MB_STATUS_FAULT) != 0;
  st->over_temperature = (s & DS_MB_STATUS_OVER_TEMPERATURE) != 0;
  /* Dark, or every stripe lit: no one phase. */
  st->applied_phase = in[DS_MB_INPUT_APPLIED_PHASE] >= DS_MB_PHASE_ALL ? -1 : in[DS_MB_INPUT_APPLIED_PHASE];
  st->apply_count = in[DS_MB_INPUT_APPLY_COUNT];
  st->temperature_c = (gint16) in[DS_MB_INPUT_TEMPERATURE] / 10.0;
  st->firmware_version = in[DS_MB_INPUT_FIRMWARE_VERSION];
  st->period_adjustable = (m->capabilities & DS_MB_CAP_PERIOD_ADJUSTABLE) != 0;
  st->period_min_px = m->period_min / 100.0;
  st->period_max_px = m->period_max / 100.0;
  st->failed_attempts = m->failed_attempts;
  st->failed_accesses = m->failed_accesses;
  g_strlcpy (st->last_link_problem, m->last_link_problem, sizeof st->last_link_problem);
  return TRUE;
}

static gboolean
check_magic (ModbusIlluminator *m, GError **error)
{
  guint16 magic;
  if (!mb_access (m, READ_INPUT, DS_MB_INPUT_MAGIC, 1, &magic, error))
    return FALSE;
  if (magic != DS_MB_MAGIC) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "Modbus %s unit %u: register MAGIC reads 0x%04x, expected 0x%04x: not a descatter "
                 "illuminator controller (docs/registers.md)", m->uri_text, m->unit_id, magic, DS_MB_MAGIC);
    return FALSE;
  }
  return TRUE;
}

static gboolean
modbus_reconnect (gpointer backend, GError **error)
{
  ModbusIlluminator *m = backend;
  disconnect (m);
  if (!connect_link (m, error))
    return FALSE;
  return check_magic (m, error) && read_capabilities (m, error);
}

static void
modbus_close_backend (gpointer backend)
{
  ModbusIlluminator *m = backend;
  if (m->ctx) {
    if (m->connected && m->n_phases > 0) {
      /* Dark, best effort and without retries: a dead link must not hold up shutdown. Only a
       * device we configured is written to (a failed open may have reached a foreign one). */
      modbus_write_register (m->ctx, DS_MB_HOLD_ENABLE, 0);
    }
    if (m->connected)
      modbus_close (m->ctx);
    modbus_free (m->ctx);
  }
  g_free (m->uri_text);
  g_free (m);
}

static const DsIlluminatorOps modbus_ops = {
  .name = "modbus",
  .set_pattern = modbus_set_pattern,
  .set_phase = modbus_set_phase,
  .off = modbus_off,
  .all_on = modbus_all_on,
  .get_status = modbus_get_status,
  .reconnect = modbus_reconnect,
  .close = modbus_close_backend,
};

DsIlluminator *
ds_modbus_illuminator_open (const char *uri, guint unit_id, guint response_timeout_ms, GError **error)
{
  DsModbusUri u;
  if (!ds_modbus_uri_parse (uri, &u, error))
    return NULL;
  if (unit_id > 247) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "Modbus %s: unit id %u outside 0..247", uri, unit_id);
    return NULL;
  }
  if (response_timeout_ms < 5 || response_timeout_ms > 10000) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                 "Modbus %s: response timeout %u ms outside 5..10000", uri, response_timeout_ms);
    return NULL;
  }
  ModbusIlluminator *m = g_new0 (ModbusIlluminator, 1);
  m->uri = u;
  m->uri_text = g_strdup (uri);
  m->unit_id = unit_id;
  m->timeout_ms = response_timeout_ms;
  if (u.transport == DS_MODBUS_TCP) {
    char port[16];
    g_snprintf (port, sizeof port, "%u", u.port);
    m->ctx = modbus_new_tcp_pi (u.host, port);
  } else
    m->ctx = modbus_new_rtu (u.device, (int) u.baud, u.parity, (int) u.data_bits, (int) u.stop_bits);
  if (!m->ctx) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID, "Modbus %s: %s", uri,
                 modbus_strerror (errno));
    modbus_close_backend (m);
    return NULL;
  }
  modbus_set_slave (m->ctx, (int) unit_id);
  modbus_set_error_recovery (m->ctx, MODBUS_ERROR_RECOVERY_NONE);
  modbus_set_response_timeout (m->ctx, response_timeout_ms / 1000, (response_timeout_ms % 1000) * 1000);
  /* Between two bytes of one answer (libmodbus waits 0.5 s by default): a stalled answer must
   * not stretch an attempt far past the response timeout. Generous for USB serial adapters,
   * whose latency timer holds bytes up to 16 ms. */
  guint byte_ms = MIN (response_timeout_ms, 50u);
  modbus_set_byte_timeout (m->ctx, 0, byte_ms * 1000);
  if (!connect_link (m, error) || !check_magic (m, error) || !read_capabilities (m, error)) {
    modbus_close_backend (m);
    return NULL;
  }
  DsIlluminator *ill = g_new0 (DsIlluminator, 1);
  ill->ops = &modbus_ops;
  ill->backend = m;
  return ill;
}
