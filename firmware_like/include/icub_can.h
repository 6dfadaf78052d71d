/*
 * icub_can.h - the iCub CAN-era protocol, firmware style (C99, no heap, no structs).
 *
 * Everything works on a caller-owned 8-byte payload buffer plus a DLC, the way a
 * board's CAN driver hands frames over. Multi-byte fields are written and read
 * byte by byte in little-endian order, so the host's endianness never matters.
 *
 * Return convention (POSIX-like):
 *   pack functions    -> the DLC to send (> 0), or a negative ICUB_CAN_E*;
 *   other functions   -> ICUB_CAN_OK (0), or a negative ICUB_CAN_E*.
 * On error no output is written.
 *
 * Define ICUB_CAN_NO_FLOAT to drop the double helpers (a board build: integers only).
 */
#ifndef ICUB_CAN_H
#define ICUB_CAN_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- status codes ------------------------------------------------------- */
#define ICUB_CAN_OK        0
#define ICUB_CAN_EINVAL  (-1) /* NULL pointer, or NaN input */
#define ICUB_CAN_ERANGE  (-2) /* field wider than its bits, reserved bits set, bad full scale */
#define ICUB_CAN_EBADLEN (-3) /* DLC does not match the message type */

/* ---- identifiers: ID = class<<8 | source<<4 | type (11 bits) ------------ */
#define ICUB_CAN_DLC_MAX     8u
#define ICUB_CAN_ID_MAX      0x7FFu
#define ICUB_CAN_ID_INVALID  0xFFFFu /* returned by icub_can_id() on a bad field */
#define ICUB_CAN_CLASS_MAX   0x7u
#define ICUB_CAN_SRC_MAX     0xFu
#define ICUB_CAN_TYPE_MAX    0xFu

/* Message classes (periodic traffic). */
#define ICUB_CAN_CLASS_MC      1u /* motor-control boards */
#define ICUB_CAN_CLASS_STRAIN  3u /* strain (F/T) board, analog-sensor class */
#define ICUB_CAN_CLASS_SKIN    4u /* skin (tactile) boards */

/* Motor-control types. Each board address serves 2 axes. */
#define ICUB_CAN_MC_POSITION   1u /* 8 bytes: int32 LE axis 0, int32 LE axis 1 (encoder ticks) */
#define ICUB_CAN_MC_PID_VAL    2u /* 4 bytes: int16 LE axis 0, int16 LE axis 1 (PWM counts) */
#define ICUB_CAN_MC_STATUS     3u /* 4 bytes: faults axis 0, faults axis 1, board flags, sequence */
#define ICUB_CAN_MC_POSITION_DLC 8u
#define ICUB_CAN_MC_PID_VAL_DLC  4u
#define ICUB_CAN_MC_STATUS_DLC   4u
/* STATUS bytes 0 and 1: per-axis fault bits (bits 5..7 reserved, zero). */
#define ICUB_CAN_MC_FAULT_OVERCURRENT 0x01u
#define ICUB_CAN_MC_FAULT_OVERTEMP    0x02u
#define ICUB_CAN_MC_FAULT_ENCODER     0x04u /* encoder/hall reading invalid: POSITION not to be trusted */
#define ICUB_CAN_MC_FAULT_EXTERNAL    0x08u /* external fault (e-stop) asserted */
#define ICUB_CAN_MC_FAULT_PWM_LIMIT   0x10u /* PWM clamped at the configured limit */
#define ICUB_CAN_MC_FAULT_MASK        0x1Fu
/* STATUS byte 2: board flags (bits 2..7 reserved, zero). */
#define ICUB_CAN_MC_BOARD_RESTARTED   0x01u /* set until the first STATUS after boot has been sent */
#define ICUB_CAN_MC_BOARD_TX_OVERRUN  0x02u /* the board dropped periodic frames (TX queue full) */
#define ICUB_CAN_MC_BOARD_MASK        0x03u
/* STATUS byte 3: sequence counter, +1 per STATUS frame, wraps 255 -> 0, 0 after a restart. */

/* Skin (class 4), simplified layout: one board per patch. */
#define ICUB_CAN_SKIN_TAXELS   0x0u /* 2 bytes: uint16 LE bitmask, bit i = taxel group i in contact */
#define ICUB_CAN_SKIN_TAXELS_DLC 2u

/* Strain types: three channels each, offset binary (raw = s + 0x8000). */
#define ICUB_CAN_STRAIN_FORCE  0xAu /* channels 0-2: Fx Fy Fz */
#define ICUB_CAN_STRAIN_TORQUE 0xBu /* channels 3-5: Tx Ty Tz */
#define ICUB_CAN_STRAIN_DLC      6u
#define ICUB_CAN_STRAIN_DLC_SAT  7u /* byte 6 = saturation flags */
/* Byte 6 layout (ours, documented in the DBC): bit i set = channel i of this
 * frame (0..2) was clamped. Bits 3..7 are reserved and must be zero. */
#define ICUB_CAN_STRAIN_SAT(ch)   ((uint8_t)(1u << (ch)))
#define ICUB_CAN_STRAIN_SAT_MASK  0x07u

/* ---- identifiers -------------------------------------------------------- */
/* Compose an 11-bit ID; ICUB_CAN_ID_INVALID if a field does not fit its bits. */
uint16_t icub_can_id(uint8_t cls, uint8_t src, uint8_t type);
/* Split an ID; ICUB_CAN_ERANGE if id > 0x7FF. Any output pointer may be NULL. */
int icub_can_id_split(uint16_t id, uint8_t *cls, uint8_t *src, uint8_t *type);

/* ---- offset binary (strain) ----------------------------------------------- */
uint16_t icub_can_ob_encode(int16_t s);   /* s + 0x8000, e.g. 0 -> 0x8000 */
int16_t  icub_can_ob_decode(uint16_t raw); /* raw - 0x8000 */

/* ---- strain payload ------------------------------------------------------ */
/* s[3] -> 6 bytes, three LE uint16 in offset binary. Returns 6. */
int icub_can_strain_pack(uint8_t payload[8], const int16_t s[3]);
/* As above plus flags in byte 6. Returns 7, or ERANGE if reserved flag bits are set. */
int icub_can_strain_pack_sat(uint8_t payload[8], const int16_t s[3], uint8_t flags);
/* Accepts DLC 6 (flags = 0) or 7. flags may be NULL. EBADLEN on any other DLC,
 * ERANGE if reserved flag bits are set. */
int icub_can_strain_unpack(const uint8_t payload[8], uint8_t dlc, int16_t s[3], uint8_t *flags);

/* ---- motor-control payloads ---------------------------------------------- */
int icub_can_mc_position_pack(uint8_t payload[8], int32_t axis0, int32_t axis1); /* returns 8 */
int icub_can_mc_position_unpack(const uint8_t payload[8], uint8_t dlc, int32_t *axis0, int32_t *axis1);
int icub_can_mc_pid_val_pack(uint8_t payload[8], int16_t axis0, int16_t axis1);  /* returns 4 */
int icub_can_mc_pid_val_unpack(const uint8_t payload[8], uint8_t dlc, int16_t *axis0, int16_t *axis1);

/* STATUS: ERANGE if reserved bits are set (packing or unpacking). */
int icub_can_mc_status_pack(uint8_t payload[8], uint8_t faults0, uint8_t faults1, uint8_t board, uint8_t seq);
int icub_can_mc_status_unpack(const uint8_t payload[8], uint8_t dlc, uint8_t *faults0, uint8_t *faults1,
                              uint8_t *board, uint8_t *seq); /* any output pointer may be NULL */

/* ---- skin payload --------------------------------------------------------- */
int icub_can_skin_pack(uint8_t payload[8], uint16_t taxels); /* returns 2 */
int icub_can_skin_unpack(const uint8_t payload[8], uint8_t dlc, uint16_t *taxels);

/* ---- strain conversions: s = round(value * 32768 / FS), clamped to int16 ----
 * Rounding is half away from zero. *saturated is set to 1 iff the result was
 * clamped, i.e. the value lies outside what the 16-bit channel can carry
 * ([-FS, FS*32767/32768] up to rounding); it may be NULL.
 *
 * Fixed-point form (what a board does): value and fs are integers in the same
 * unit (e.g. mN, or any Q format); fs > 0 else ERANGE. Exact, int64 inside. */
int icub_can_strain_count_fx(int32_t value, int32_t fs, int16_t *s, uint8_t *saturated);
/* Inverse, exact up to the same rounding: round(s * fs / 32768). */
int32_t icub_can_strain_value_fx(int16_t s, int32_t fs);

#ifndef ICUB_CAN_NO_FLOAT
/* Double form, for the emulators, which get physical values from a simulation.
 * fs must be finite and > 0 (else ERANGE); NaN value -> EINVAL; +-inf saturates.
 * value * 32768 is exact in binary floating point, so the only rounding before
 * the final one is the single division by fs. */
int icub_can_strain_count(double value, double fs, int16_t *s, uint8_t *saturated);
/* Physical value of a count: s * fs / 32768 (section 5 of the design brief). */
double icub_can_strain_value(int16_t s, double fs);
#endif

#ifdef __cplusplus
}
#endif

#endif /* ICUB_CAN_H */
