/*
 * fuzz_boards_csv.c - libFuzzer harness: the boards program's reader of a run's data.csv (boards_csv_open_stream,
 * boards_csv_row, the time checks) on any bytes, with the bundled arm's configuration, then, for a file that
 * passes, both passes as boards.c makes them: every row through the emulators into frames that decode, and every
 * timestamp at the limits of --t0 and --repeat (which must fit int64 µs).
 */
#define _POSIX_C_SOURCE 200809L
#include "fuzz_boards.h"

#ifndef FUZZ_MONITOR_CONF
#error "FUZZ_MONITOR_CONF: the bundled configuration's path"
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static boards_conf_t conf;
    static int conf_read;
    static boards_columns_t cols;
    static boards_csv_t csv;
    static fuzz_boards_t boards;
    static double q[BOARDS_MAX_MC][2], duty[BOARDS_MAX_MC][2];
    char err[BOARDS_ERR_LEN];
    double t_first = 0.0, t_prev = 0.0;
    long n = 0;
    int rc, i, s, pass;
    FILE *f;
    if (!conf_read) {
        if (boards_read_conf(FUZZ_MONITOR_CONF, &conf, err) != 0) {
            fprintf(stderr, "fuzz_boards_csv: %s\n", err);
            abort();
        }
        conf_read = 1;
    }
    f = fuzz_boards_open(data, size);
    if (!f) {
        return 0;
    }
    err[0] = '\0';
    /* Sensor by name when the first byte is odd, else the data's only one (both of the program's ways). */
    rc = boards_csv_open_stream(&csv, f, "fuzz.csv", &conf, (size && (data[0] & 1u)) ? "r_arm_ft" : 0, &cols, err);
    if (rc != 0) {
        FUZZ_CHECK(rc == BOARDS_EXIT_BADDATA && err[0] != '\0' && strchr(err, '\n') == 0 && csv.f == 0);
        return 0;
    }
    FUZZ_CHECK(cols.t >= 0 && cols.t < cols.n_cols && cols.n_cols <= BOARDS_MAX_COLS);
    for (pass = 0; pass < 2; ++pass) {
        long k = 0;
        while ((rc = boards_csv_row(&csv, &cols, err)) == 1) {
            const double t = csv.v[cols.t];
            double w[6];
            uint16_t skin = 0;
            for (i = 0; i < 6; ++i) {
                FUZZ_CHECK(cols.ft[i] >= 0 && cols.ft[i] < cols.n_cols);
                w[i] = csv.v[cols.ft[i]];
            }
            if (pass == 0) {
                if (boards_csv_check_time(&csv, n, t, t_first, t_prev, err) != 0) {
                    rc = -BOARDS_EXIT_BADDATA;
                    break;
                }
                if (n == 0) {
                    t_first = t;
                }
                t_prev = t;
                ++n;
                continue;
            }
            /* The timestamps at the limits: the last repetition, the largest --t0. */
            (void)boards_time_us(t, t_first, BOARDS_MAX_T0_S * (1.0 - 1e-15),
                                 (double)(BOARDS_MAX_REPEAT - 1) *
                                     (n > 1 ? (t_prev - t_first) * (double)n / (double)(n - 1) : 1e-3));
            (void)boards_time_us(t, t_first, 0.0, 0.0);
            for (i = 0; i < conf.n_mc; ++i) {
                for (s = 0; s < 2; ++s) {
                    q[i][s] = cols.q[i][s] >= 0 ? csv.v[cols.q[i][s]] : 0.0;
                    duty[i][s] = cols.pwm[i][s] >= 0 ? csv.v[cols.pwm[i][s]] : 0.0;
                }
            }
            for (i = 0; i < conf.n_skin; ++i) {
                const int on = cols.contact >= 0 && csv.v[cols.contact] != 0.0 &&
                               (cols.patch >= 0 ? csv.v[cols.patch] == (double)(i + 1) : i == 0);
                skin = (uint16_t)(skin | (on ? 1u << i : 0u));
            }
            fuzz_boards_play(&boards, &conf, (const double(*)[2])q, (const double(*)[2])duty, w, skin,
                             k == 3 ? 0 : -1);
            ++k;
        }
        if (rc != 0) {
            FUZZ_CHECK(rc < 0 && err[0] != '\0' && strchr(err, '\n') == 0);
            break;
        }
        if (pass == 0) {
            if (n == 0) {
                break;
            }
            FUZZ_CHECK(boards_csv_rewind(&csv, err) == 0);
            fuzz_boards_init(&boards, &conf, (uint8_t)(size & 2u));
            FUZZ_CHECK(boards.ready);
        }
    }
    fclose(csv.f);
    csv.f = 0;
    return 0;
}
