/*
 * fuzz_boards_conf.c - libFuzzer harness: the boards program's reader of the rt_monitor configuration and its bus
 * table (boards_read_conf_stream) on any bytes. An accepted configuration keeps its tables' bounds; the player sets up
 * from it with the generic encoder (and the iCub emulators where the table is theirs) and plays samples (extreme
 * values, restarts of every node, long forms on and off) into frames of the table that decode.
 */
#define _POSIX_C_SOURCE 200809L
#include "fuzz_boards.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static boards_conf_t conf;
    static boards_player_t player;
    static boards_columns_t cols;
    static uint8_t long_node[BOARDS_MAX_FRAMES];
    static double row[BOARDS_MAX_SIGNALS + 3];
    static const double values[] = {0.0, 0.5, -1.0, 3.3e4, -1e6, 1e300, -1e300};
    char err[BOARDS_ERR_LEN];
    FILE *f = fuzz_boards_open(data, size);
    int rc, i, k, enc;
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
    FUZZ_CHECK(conf.n_buses >= 1 && conf.n_buses <= BOARDS_MAX_BUSES && conf.n_frames >= 1);
    FUZZ_CHECK(conf.clock >= 0 && conf.clock < conf.n_frames && conf.n_signals <= BOARDS_MAX_SIGNALS);
    for (i = 0; i < conf.n_frames; ++i) {
        const boards_table_frame_t *fr = &conf.frames[i];
        FUZZ_CHECK(fr->bus >= 0 && fr->bus < conf.n_buses && fr->id <= 0x7FF && fr->dlc <= 8 && fr->n_signals >= 1);
        FUZZ_CHECK(fr->node >= 0 && fr->node < conf.n_nodes && fr->first_signal + fr->n_signals <= conf.n_signals);
    }
    /* The columns: the row's values in order, then contact and skin.patch. */
    cols.n_cols = conf.n_values + 3;
    cols.t = conf.n_values;
    for (i = 0; i < conf.n_values; ++i) {
        cols.value[i] = i;
    }
    cols.contact = conf.n_values + 1;
    cols.patch = conf.n_values + 2;
    memset(long_node, (int)(size & 1u), sizeof long_node);
    for (enc = BOARDS_ENCODER_GENERIC; enc <= BOARDS_ENCODER_ICUB; ++enc) {
        if (enc == BOARDS_ENCODER_ICUB && boards_default_encoder(&conf) != BOARDS_ENCODER_ICUB) {
            break;
        }
        if (boards_player_init(&player, &conf, enc, 1e-3, long_node, err) != 0) {
            FUZZ_CHECK(enc == BOARDS_ENCODER_ICUB && err[0] != '\0' && strchr(err, '\n') == 0);
            break;
        }
        for (k = 0; k < 12; ++k) {
            int node = k % (conf.n_nodes ? conf.n_nodes : 1);
            for (i = 0; i < conf.n_values; ++i) {
                row[i] = values[(k + i) % 7];
            }
            row[cols.t] = 1e-3 * k;
            row[cols.contact] = (double)(k & 1);
            row[cols.patch] = (double)(k % 4);
            if (conf.n_values) boards_long_needed(&conf, row, &cols, long_node);
            FUZZ_CHECK(boards_player_sample(&player, row, &cols, 1000 * k, &node, k == 5, fuzz_boards_check_frame,
                                            &conf) == 0);
        }
    }
    return 0;
}
