/*
 * fuzz_boards_conf.c - libFuzzer harness: the boards program's reader of the rt_monitor configuration
 * (boards_read_conf_stream) on any bytes. An accepted configuration keeps its tables' bounds and sets up boards
 * that play samples (extreme positions, duties and wrenches included) into frames that decode.
 */
#define _POSIX_C_SOURCE 200809L
#include "fuzz_boards.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static boards_conf_t conf;
    static fuzz_boards_t boards;
    static double q[BOARDS_MAX_MC][2], duty[BOARDS_MAX_MC][2];
    static const double values[] = {0.0, 0.5, -1.0, 3.3e4, -1e6, 1e300, -1e300};
    char err[BOARDS_ERR_LEN];
    FILE *f = fuzz_boards_open(data, size);
    int rc, i, k;
    if (!f) {
        return 0;
    }
    err[0] = '\0';
    rc = boards_read_conf_stream(f, "fuzz.conf", &conf, err);
    fclose(f);
    if (rc != 0) {
        FUZZ_CHECK(rc == BOARDS_EXIT_BADDATA || rc == BOARDS_EXIT_NOFILE);
        FUZZ_CHECK(err[0] != '\0' && strchr(err, '\n') == 0); /* one line */
        return 0;
    }
    FUZZ_CHECK(conf.n_buses >= 1 && conf.n_buses <= BOARDS_MAX_BUSES && conf.has_strain);
    FUZZ_CHECK(conf.strain_bus >= 0 && conf.strain_bus < conf.n_buses && conf.strain_address <= 15);
    FUZZ_CHECK(conf.n_mc >= 0 && conf.n_mc <= BOARDS_MAX_MC && conf.n_skin >= 0 && conf.n_skin <= BOARDS_MAX_SKIN);
    for (i = 0; i < conf.n_mc; ++i) {
        FUZZ_CHECK(conf.mc[i].bus >= 0 && conf.mc[i].bus < conf.n_buses && conf.mc[i].address <= 15);
    }
    for (i = 0; i < conf.n_skin; ++i) {
        FUZZ_CHECK(conf.skin_bus[i] >= 0 && conf.skin_bus[i] < conf.n_buses && conf.skin_address[i] <= 15);
    }
    fuzz_boards_init(&boards, &conf, (uint8_t)(size & 1u));
    if (!boards.ready) {
        return 0;
    }
    for (k = 0; k < 12; ++k) {
        const double w[6] = {values[k % 7], values[(k + 1) % 7], values[(k + 2) % 7],
                             values[(k + 3) % 7], values[(k + 4) % 7], values[(k + 5) % 7]};
        for (i = 0; i < conf.n_mc; ++i) {
            q[i][0] = values[(k + i) % 7];
            q[i][1] = values[(k + 2 * i + 1) % 7];
            duty[i][0] = values[(k + 3 * i) % 7];
            duty[i][1] = values[(k + i + 5) % 7];
        }
        fuzz_boards_play(&boards, &conf, (const double(*)[2])q, (const double(*)[2])duty, w, (uint16_t)k, k == 5 ? 0 : -1);
    }
    return 0;
}
