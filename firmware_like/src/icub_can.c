/*
 * icub_can.c - see icub_can.h. C99, no heap, no libm, no host-endian memcpy.
 */
#include "icub_can.h"

#ifndef ICUB_CAN_NO_FLOAT
#include <float.h>
#endif

/* ---- little-endian byte access ------------------------------------------ */
/* Signed <-> unsigned goes through the two's-complement arithmetic explicitly:
 * casting an out-of-range unsigned to a signed type is implementation-defined
 * in C99, and a firmware library must not lean on that. */

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

static void put_i16(uint8_t *p, int16_t v)
{
    put_u16(p, (uint16_t)v); /* signed -> unsigned is defined: modulo 2^16 */
}

static int16_t get_i16(const uint8_t *p)
{
    uint16_t u = get_u16(p);
    return (int16_t)((int32_t)u - ((u & 0x8000u) ? 0x10000L : 0L));
}

static void put_i32(uint8_t *p, int32_t v)
{
    uint32_t u = (uint32_t)v;
    p[0] = (uint8_t)(u & 0xFFu);
    p[1] = (uint8_t)((u >> 8) & 0xFFu);
    p[2] = (uint8_t)((u >> 16) & 0xFFu);
    p[3] = (uint8_t)(u >> 24);
}

static int32_t get_i32(const uint8_t *p)
{
    uint32_t u = (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
                 ((uint32_t)p[3] << 24);
    return (int32_t)((int64_t)u - ((u & 0x80000000u) ? (int64_t)0x100000000LL : 0));
}

/* Round num/den half away from zero; den > 0. C99 '/' truncates toward zero. */
static int64_t div_round(int64_t num, int64_t den)
{
    int64_t q = num / den;
    int64_t r = num % den;
    if (r < 0)
        r = -r;
    if (2 * r >= den)
        q += (num < 0) ? -1 : 1;
    return q;
}

static int16_t clamp_i16(int64_t v, uint8_t *saturated)
{
    uint8_t sat = 0;
    if (v > INT16_MAX) {
        v = INT16_MAX;
        sat = 1;
    } else if (v < INT16_MIN) {
        v = INT16_MIN;
        sat = 1;
    }
    if (saturated)
        *saturated = sat;
    return (int16_t)v;
}

/* ---- identifiers ------------------------------------------------------- */

uint16_t icub_can_id(uint8_t cls, uint8_t src, uint8_t type)
{
    if (cls > ICUB_CAN_CLASS_MAX || src > ICUB_CAN_SRC_MAX || type > ICUB_CAN_TYPE_MAX)
        return ICUB_CAN_ID_INVALID;
    return (uint16_t)(((unsigned)cls << 8) | ((unsigned)src << 4) | (unsigned)type);
}

int icub_can_id_split(uint16_t id, uint8_t *cls, uint8_t *src, uint8_t *type)
{
    if (id > ICUB_CAN_ID_MAX)
        return ICUB_CAN_ERANGE;
    if (cls)
        *cls = (uint8_t)((id >> 8) & ICUB_CAN_CLASS_MAX);
    if (src)
        *src = (uint8_t)((id >> 4) & ICUB_CAN_SRC_MAX);
    if (type)
        *type = (uint8_t)(id & ICUB_CAN_TYPE_MAX);
    return ICUB_CAN_OK;
}

/* ---- offset binary ------------------------------------------------------ */

uint16_t icub_can_ob_encode(int16_t s)
{
    return (uint16_t)((int32_t)s + 0x8000);
}

int16_t icub_can_ob_decode(uint16_t raw)
{
    return (int16_t)((int32_t)raw - 0x8000);
}

/* ---- strain payload ----------------------------------------------------- */

int icub_can_strain_pack(uint8_t payload[8], const int16_t s[3])
{
    int i;
    if (!payload || !s)
        return ICUB_CAN_EINVAL;
    for (i = 0; i < 3; ++i)
        put_u16(&payload[2 * i], icub_can_ob_encode(s[i]));
    return (int)ICUB_CAN_STRAIN_DLC;
}

int icub_can_strain_pack_sat(uint8_t payload[8], const int16_t s[3], uint8_t flags)
{
    int rc;
    if (flags & (uint8_t)~ICUB_CAN_STRAIN_SAT_MASK)
        return ICUB_CAN_ERANGE;
    rc = icub_can_strain_pack(payload, s);
    if (rc < 0)
        return rc;
    payload[6] = flags;
    return (int)ICUB_CAN_STRAIN_DLC_SAT;
}

int icub_can_strain_unpack(const uint8_t payload[8], uint8_t dlc, int16_t s[3], uint8_t *flags)
{
    uint8_t f = 0;
    int i;
    if (!payload || !s)
        return ICUB_CAN_EINVAL;
    if (dlc != ICUB_CAN_STRAIN_DLC && dlc != ICUB_CAN_STRAIN_DLC_SAT)
        return ICUB_CAN_EBADLEN;
    if (dlc == ICUB_CAN_STRAIN_DLC_SAT) {
        f = payload[6];
        if (f & (uint8_t)~ICUB_CAN_STRAIN_SAT_MASK)
            return ICUB_CAN_ERANGE;
    }
    for (i = 0; i < 3; ++i)
        s[i] = icub_can_ob_decode(get_u16(&payload[2 * i]));
    if (flags)
        *flags = f;
    return ICUB_CAN_OK;
}

/* ---- motor-control payloads -------------------------------------------- */

int icub_can_mc_position_pack(uint8_t payload[8], int32_t axis0, int32_t axis1)
{
    if (!payload)
        return ICUB_CAN_EINVAL;
    put_i32(&payload[0], axis0);
    put_i32(&payload[4], axis1);
    return (int)ICUB_CAN_MC_POSITION_DLC;
}

int icub_can_mc_position_unpack(const uint8_t payload[8], uint8_t dlc, int32_t *axis0, int32_t *axis1)
{
    if (!payload || !axis0 || !axis1)
        return ICUB_CAN_EINVAL;
    if (dlc != ICUB_CAN_MC_POSITION_DLC)
        return ICUB_CAN_EBADLEN;
    *axis0 = get_i32(&payload[0]);
    *axis1 = get_i32(&payload[4]);
    return ICUB_CAN_OK;
}

int icub_can_mc_pid_val_pack(uint8_t payload[8], int16_t axis0, int16_t axis1)
{
    if (!payload)
        return ICUB_CAN_EINVAL;
    put_i16(&payload[0], axis0);
    put_i16(&payload[2], axis1);
    return (int)ICUB_CAN_MC_PID_VAL_DLC;
}

int icub_can_mc_pid_val_unpack(const uint8_t payload[8], uint8_t dlc, int16_t *axis0, int16_t *axis1)
{
    if (!payload || !axis0 || !axis1)
        return ICUB_CAN_EINVAL;
    if (dlc != ICUB_CAN_MC_PID_VAL_DLC)
        return ICUB_CAN_EBADLEN;
    *axis0 = get_i16(&payload[0]);
    *axis1 = get_i16(&payload[2]);
    return ICUB_CAN_OK;
}

int icub_can_mc_status_pack(uint8_t payload[8], uint8_t faults0, uint8_t faults1, uint8_t board, uint8_t seq)
{
    if (!payload)
        return ICUB_CAN_EINVAL;
    if ((faults0 | faults1) & (uint8_t)~ICUB_CAN_MC_FAULT_MASK || board & (uint8_t)~ICUB_CAN_MC_BOARD_MASK)
        return ICUB_CAN_ERANGE;
    payload[0] = faults0;
    payload[1] = faults1;
    payload[2] = board;
    payload[3] = seq;
    return (int)ICUB_CAN_MC_STATUS_DLC;
}

int icub_can_mc_status_unpack(const uint8_t payload[8], uint8_t dlc, uint8_t *faults0, uint8_t *faults1,
                              uint8_t *board, uint8_t *seq)
{
    if (!payload)
        return ICUB_CAN_EINVAL;
    if (dlc != ICUB_CAN_MC_STATUS_DLC)
        return ICUB_CAN_EBADLEN;
    if ((payload[0] | payload[1]) & (uint8_t)~ICUB_CAN_MC_FAULT_MASK ||
        payload[2] & (uint8_t)~ICUB_CAN_MC_BOARD_MASK)
        return ICUB_CAN_ERANGE;
    if (faults0)
        *faults0 = payload[0];
    if (faults1)
        *faults1 = payload[1];
    if (board)
        *board = payload[2];
    if (seq)
        *seq = payload[3];
    return ICUB_CAN_OK;
}

/* ---- skin payload ------------------------------------------------------- */

int icub_can_skin_pack(uint8_t payload[8], uint16_t taxels)
{
    if (!payload)
        return ICUB_CAN_EINVAL;
    put_u16(&payload[0], taxels);
    return (int)ICUB_CAN_SKIN_TAXELS_DLC;
}

int icub_can_skin_unpack(const uint8_t payload[8], uint8_t dlc, uint16_t *taxels)
{
    if (!payload || !taxels)
        return ICUB_CAN_EINVAL;
    if (dlc != ICUB_CAN_SKIN_TAXELS_DLC)
        return ICUB_CAN_EBADLEN;
    *taxels = get_u16(&payload[0]);
    return ICUB_CAN_OK;
}

/* ---- strain conversions ------------------------------------------------- */

int icub_can_strain_count_fx(int32_t value, int32_t fs, int16_t *s, uint8_t *saturated)
{
    if (!s)
        return ICUB_CAN_EINVAL;
    if (fs <= 0)
        return ICUB_CAN_ERANGE;
    /* |value * 32768| <= 2^46: no overflow in int64. */
    *s = clamp_i16(div_round((int64_t)value * 32768, fs), saturated);
    return ICUB_CAN_OK;
}

int32_t icub_can_strain_value_fx(int16_t s, int32_t fs)
{
    /* |s| <= 32768, so |result| <= |fs|: always fits int32. */
    return (int32_t)div_round((int64_t)s * fs, 32768);
}

#ifndef ICUB_CAN_NO_FLOAT
int icub_can_strain_count(double value, double fs, int16_t *s, uint8_t *saturated)
{
    double x;
    int32_t t;
    double frac;
    if (!s)
        return ICUB_CAN_EINVAL;
    if (!(fs > 0.0 && fs <= DBL_MAX)) /* also rejects NaN and inf */
        return ICUB_CAN_ERANGE;
    if (value != value) /* NaN: never turn it into a plausible count */
        return ICUB_CAN_EINVAL;
    x = value * 32768.0 / fs;
    /* Decide saturation in floating point, before any cast: converting an
     * out-of-range double to an integer is undefined behaviour. */
    if (x >= 32767.5 || x <= -32768.5) {
        *s = (x > 0.0) ? INT16_MAX : INT16_MIN;
        if (saturated)
            *saturated = 1;
        return ICUB_CAN_OK;
    }
    /* Not x + 0.5 then truncate: that gets 0.49999999999999994 wrong (the sum
     * rounds up to 1.0). x - trunc(x) is exact for |x| < 2^52. */
    t = (int32_t)x;
    frac = x - (double)t;
    if (frac >= 0.5)
        ++t;
    else if (frac <= -0.5)
        --t;
    *s = clamp_i16(t, saturated); /* in range here; clamp only sets *saturated = 0 */
    return ICUB_CAN_OK;
}

double icub_can_strain_value(int16_t s, double fs)
{
    return (double)s * fs / 32768.0;
}
#endif
