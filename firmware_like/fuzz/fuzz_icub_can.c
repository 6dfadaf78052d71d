/*
 * fuzz_icub_can.c - libFuzzer harness: the CAN codec (icub_can.h) on any frame, every message class of the DBC.
 *
 * Input: bytes 0-1 an ID (little-endian, 16 bits: IDs above 0x7FF included), byte 2 a DLC (0-255), bytes 3-10 the
 * payload (missing bytes are 0), bytes 11-18 and 19-26 two doubles and 27-34 two int32 for the conversions.
 * Properties (abort on a violation): a split ID composes back to itself; every payload a decoder accepts packs back
 * to the same bytes with the same DLC; a refused one is refused with a negative code and leaves the outputs alone;
 * a count's value converts back to the count for full scales in [1e-3, 1e6]. Sanitizers see the rest.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "icub_can.h"

#define CHECK(cond) do { if (!(cond)) abort(); } while (0)

static void take(const uint8_t **p, size_t *left, void *out, size_t n)
{
    size_t k = n < *left ? n : *left;
    memset(out, 0, n);
    memcpy(out, *p, k);
    *p += k;
    *left -= k;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const uint8_t *p = data;
    size_t left = size;
    uint8_t idb[2], dlc, pl[8], out[8];
    uint16_t id;
    uint8_t cls = 0xEE, src = 0xEE, type = 0xEE;
    double dv[2];
    int32_t iv[2];
    int rc;

    take(&p, &left, idb, 2);
    take(&p, &left, &dlc, 1);
    take(&p, &left, pl, 8);
    take(&p, &left, dv, sizeof dv);
    take(&p, &left, iv, sizeof iv);
    id = (uint16_t)(idb[0] | (idb[1] << 8));

    rc = icub_can_id_split(id, &cls, &src, &type);
    if (rc == ICUB_CAN_OK) {
        CHECK(icub_can_id(cls, src, type) == id);
    } else {
        CHECK(rc < 0 && id > ICUB_CAN_ID_MAX && cls == 0xEE && src == 0xEE && type == 0xEE);
    }
    CHECK(icub_can_id(cls, src, type) == ICUB_CAN_ID_INVALID || rc == ICUB_CAN_OK);

    { /* strain, both halves (the same layout), 6 and 7 bytes */
        int16_t s[3] = {1, 2, 3};
        uint8_t flags = 0xAA;
        rc = icub_can_strain_unpack(pl, dlc, s, &flags);
        if (rc == ICUB_CAN_OK) {
            const int n = dlc == ICUB_CAN_STRAIN_DLC_SAT ? icub_can_strain_pack_sat(out, s, flags)
                                                         : icub_can_strain_pack(out, s);
            CHECK(n == (int)dlc && memcmp(out, pl, dlc) == 0);
            CHECK(icub_can_strain_unpack(pl, dlc, s, 0) == ICUB_CAN_OK);
            {   /* each count's value back to the count */
                int i;
                double fs = dv[0] < 0 ? -dv[0] : dv[0];
                for (i = 0; i < 3; ++i) {
                    int16_t back = 0;
                    uint8_t sat = 9;
                    if (fs >= 1e-3 && fs <= 1e6) {
                        CHECK(icub_can_strain_count(icub_can_strain_value(s[i], fs), fs, &back, &sat) == ICUB_CAN_OK);
                        CHECK(back == s[i] && sat == 0);
                    }
                    CHECK(icub_can_ob_decode(icub_can_ob_encode(s[i])) == s[i]);
                }
            }
        } else {
            CHECK(rc < 0 && s[0] == 1 && s[1] == 2 && s[2] == 3 && flags == 0xAA);
        }
    }
    { /* motor control: POSITION, PID_VAL, STATUS */
        int32_t a0 = 7, a1 = 8;
        int16_t v0 = 7, v1 = 8;
        uint8_t f0 = 1, f1 = 2, b = 3, seq = 4;
        rc = icub_can_mc_position_unpack(pl, dlc, &a0, &a1);
        if (rc == ICUB_CAN_OK) {
            CHECK(icub_can_mc_position_pack(out, a0, a1) == (int)dlc && memcmp(out, pl, dlc) == 0);
        } else {
            CHECK(rc < 0 && a0 == 7 && a1 == 8);
        }
        rc = icub_can_mc_pid_val_unpack(pl, dlc, &v0, &v1);
        if (rc == ICUB_CAN_OK) {
            CHECK(icub_can_mc_pid_val_pack(out, v0, v1) == (int)dlc && memcmp(out, pl, dlc) == 0);
        } else {
            CHECK(rc < 0 && v0 == 7 && v1 == 8);
        }
        rc = icub_can_mc_status_unpack(pl, dlc, &f0, &f1, &b, &seq);
        if (rc == ICUB_CAN_OK) {
            CHECK(icub_can_mc_status_pack(out, f0, f1, b, seq) == (int)dlc && memcmp(out, pl, dlc) == 0);
            CHECK(icub_can_mc_status_unpack(pl, dlc, 0, 0, 0, 0) == ICUB_CAN_OK);
        } else {
            CHECK(rc < 0 && f0 == 1 && f1 == 2 && b == 3 && seq == 4);
        }
    }
    { /* skin */
        uint16_t taxels = 0x5A5A;
        rc = icub_can_skin_unpack(pl, dlc, &taxels);
        if (rc == ICUB_CAN_OK) {
            CHECK(icub_can_skin_pack(out, taxels) == (int)dlc && memcmp(out, pl, dlc) == 0);
        } else {
            CHECK(rc < 0 && taxels == 0x5A5A);
        }
    }
    { /* conversions on any numbers: never undefined, a clamp is reported */
        int16_t s = 0;
        uint8_t sat = 9;
        rc = icub_can_strain_count(dv[0], dv[1], &s, &sat);
        CHECK(rc == ICUB_CAN_OK ? sat <= 1 : rc < 0);
        (void)icub_can_strain_value(s, dv[1]);
        rc = icub_can_strain_count_fx(iv[0], iv[1], &s, &sat);
        CHECK(rc == ICUB_CAN_OK ? sat <= 1 : (rc < 0 && iv[1] <= 0));
        (void)icub_can_strain_value_fx(s, iv[1]);
    }
    return 0;
}
