/* The illuminator controller's Modbus register map, shared by the backend (drivers/modbus) and
 * the lab's controller (drivers/labsim/modbus_server.c). docs/registers.md is the reference:
 * it says what each register means, its range and unit; this header only names the
 * addresses. Addresses are 0-based protocol addresses (PDU), as libmodbus takes them.
 *
 * Semantics in one paragraph: every write request that touches a holding register schedules
 * exactly one "apply" of the resulting pattern; while it is pending STATUS has APPLYING set
 * and READY clear; when the settle time has passed the device lights the pattern,
 * APPLIED_PHASE shows the lit phase (DS_MB_PHASE_OFF when ENABLE = 0), APPLY_COUNT
 * increments by one (mod 2^16), READY is set. A value out of range is refused with exception
 * 03 (illegal data value) and changes nothing; for PERIOD_CENTIPX the range is the projector's
 * (PERIOD_MIN_CENTIPX .. PERIOD_MAX_CENTIPX: one value for a projector whose period is fixed). */
#pragma once

/* Holding registers (function codes 03, 06, 16). PHASE and ENABLE are adjacent so that one
 * write-multiple request lights a phase. */
#define DS_MB_HOLD_PHASE 0x0000              /* 0 .. NUM_PHASES-1 */
#define DS_MB_HOLD_ENABLE 0x0001             /* 0 = off (dark), 1 = PHASE lit, 2 = every stripe lit
                                              * (DS_MB_CAP_ALL_ON) */
#define DS_MB_HOLD_NUM_PHASES 0x0002         /* 2 .. 64 */
#define DS_MB_HOLD_PATTERN_KIND 0x0003       /* 0 = square, 1 = sine */
#define DS_MB_HOLD_PERIOD_CENTIPX 0x0004     /* stripe period on the sensor, 1/100 px: PERIOD_MIN .. MAX */
#define DS_MB_HOLD_DUTY_PERMILLE 0x0005      /* lit fraction, 1 .. 999 */
#define DS_MB_HOLD_BLACK_PERMILLE 0x0006     /* off-stripe leakage, 0 .. 999 */
#define DS_MB_HOLD_INTENSITY_PERMILLE 0x0007 /* 0 .. 1000 of the maximum */
#define DS_MB_HOLD_COUNT 8

/* Input registers (function code 04). */
#define DS_MB_INPUT_MAGIC 0x0000             /* always DS_MB_MAGIC */
#define DS_MB_INPUT_FIRMWARE_VERSION 0x0001  /* major << 8 | minor */
#define DS_MB_INPUT_STATUS 0x0002            /* DS_MB_STATUS_* bits */
#define DS_MB_INPUT_APPLIED_PHASE 0x0003     /* lit phase, DS_MB_PHASE_OFF when dark */
#define DS_MB_INPUT_APPLY_COUNT 0x0004       /* patterns applied since power-up, mod 2^16 */
#define DS_MB_INPUT_TEMPERATURE 0x0005       /* LED board, 0.1 degC, two's complement */
/* Map revision 2: what the projector can do. A revision-1 controller answers exception 02. */
#define DS_MB_INPUT_CAPABILITIES 0x0006      /* DS_MB_CAP_* bits */
#define DS_MB_INPUT_PERIOD_MIN_CENTIPX 0x0007 /* shortest period it projects, 1/100 px */
#define DS_MB_INPUT_PERIOD_MAX_CENTIPX 0x0008 /* longest; equal to MIN for a fixed period */
#define DS_MB_INPUT_COUNT 9
#define DS_MB_INPUT_REV1_COUNT 6             /* MAGIC .. TEMPERATURE: every revision has them */

#define DS_MB_MAGIC 0x4453                   /* "DS" */
#define DS_MB_PHASE_OFF 0xFFFF
#define DS_MB_PHASE_ALL 0xFFFE               /* APPLIED_PHASE with ENABLE = 2 */

#define DS_MB_STATUS_READY 0x0001            /* idle: the last write is applied */
#define DS_MB_STATUS_FAULT 0x0002            /* driver fault: the LEDs are off */
#define DS_MB_STATUS_OVER_TEMPERATURE 0x0004 /* thermal cut-out: the LEDs are off */
#define DS_MB_STATUS_APPLYING 0x0008         /* a write is settling */
#define DS_MB_STATUS_ENABLED 0x0010          /* the applied pattern is lit */

/* CAPABILITIES bits. */
#define DS_MB_CAP_PERIOD_ADJUSTABLE 0x0001   /* PERIOD_CENTIPX sets the projected period */
#define DS_MB_CAP_ALL_ON 0x0002              /* ENABLE = 2 lights every stripe at once */

#define DS_MB_MAX_PHASES 64
#define DS_MB_CENTIPX_MIN 200                /* PERIOD_CENTIPX can hold 2.00 .. 655.35 px */
#define DS_MB_CENTIPX_MAX 65535

/* Register names as the backend's error messages and docs/registers.md spell them. */
static inline const char *
ds_mb_holding_name (int address)
{
  static const char *const names[DS_MB_HOLD_COUNT] = {
    "PHASE", "ENABLE", "NUM_PHASES", "PATTERN_KIND", "PERIOD_CENTIPX", "DUTY_PERMILLE",
    "BLACK_PERMILLE", "INTENSITY_PERMILLE",
  };
  return address >= 0 && address < DS_MB_HOLD_COUNT ? names[address] : "unknown holding register";
}

static inline const char *
ds_mb_input_name (int address)
{
  static const char *const names[DS_MB_INPUT_COUNT] = {
    "MAGIC", "FIRMWARE_VERSION", "STATUS", "APPLIED_PHASE", "APPLY_COUNT", "TEMPERATURE",
    "CAPABILITIES", "PERIOD_MIN_CENTIPX", "PERIOD_MAX_CENTIPX",
  };
  return address >= 0 && address < DS_MB_INPUT_COUNT ? names[address] : "unknown input register";
}
