/*
 * fuzz_boards_csv.c - libFuzzer harness: the boards program's reader of a run's data.csv (boards_csv_open_stream,
 * boards_csv_row, the time checks) on any bytes, with the bundled arm's configuration, then, for a file that
 * passes, both passes as boards.c makes them: every row through the player (both encoders) into frames of the table
 * that decode, and every timestamp at the limits of --t0 and --repeat (which must fit int64 µs).
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
    static boards_player_t player;
    static uint8_t long_node[BOARDS_MAX_FRAMES];
    char err[BOARDS_ERR_LEN];
    double t_first = 0.0, t_prev = 0.0;
    long n = 0;
    int rc, pass, restart[1] = {0};
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
    /* Sensor by name when the first byte is odd, else the table's names (both of the program's ways). */
    rc = boards_csv_open_stream(&csv, f, "fuzz.csv", &conf, (size && (data[0] & 1u)) ? "r_arm_ft" : 0, &cols, err);
    if (rc != 0) {
        FUZZ_CHECK(rc == BOARDS_EXIT_BADDATA && err[0] != '\0' && strchr(err, '\n') == 0 && csv.f == 0);
        return 0;
    }
    FUZZ_CHECK(cols.t >= 0 && cols.t < cols.n_cols && cols.n_cols <= BOARDS_MAX_COLS);
    memset(long_node, 0, sizeof long_node);
    for (pass = 0; pass < 2; ++pass) {
        long k = 0;
        while ((rc = boards_csv_row(&csv, &cols, err)) == 1) {
            const double t = csv.v[cols.t];
            if (pass == 0) {
                if (boards_csv_check_time(&csv, n, t, t_first, t_prev, err) != 0) {
                    rc = -BOARDS_EXIT_BADDATA;
                    break;
                }
                boards_long_needed(&conf, csv.v, &cols, long_node);
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
            FUZZ_CHECK(boards_player_sample(&player, csv.v, &cols, boards_time_us(t, t_first, 0.0, 0.0), restart,
                                            k == 3, fuzz_boards_check_frame, &conf) == 0);
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
            FUZZ_CHECK(boards_player_init(&player, &conf, (size & 2u) ? BOARDS_ENCODER_GENERIC : BOARDS_ENCODER_ICUB,
                                          1e-3, long_node, err) == 0);
        }
    }
    fclose(csv.f);
    csv.f = 0;
    return 0;
}
