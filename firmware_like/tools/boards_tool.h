/*
 * boards_tool.h - the host side of the `boards` player: its inputs (the rt_monitor configuration, whose compiled bus
 * table says which frame carries which signal, and a run's data.csv), the player that turns a row into the frames of
 * one sample (the generic encoder on any table; the iCub board emulators on the iCub protocol's), and its frame sinks.
 * Fixed-size tables, no heap.
 */
#ifndef BOARDS_TOOL_H
#define BOARDS_TOOL_H

#include <stdint.h>
#include <stdio.h>
#include <sys/un.h>

#include "board_frame.h"
#include "board_mc.h"
#include "board_skin.h"
#include "board_strain.h"
#include "bus_encoder.h"

/* Exit codes: each kind of failure its own, so scripts can tell them apart. */
#define BOARDS_EXIT_USAGE   2 /* bad flag or value */
#define BOARDS_EXIT_NOFILE  3 /* an input file is missing or unreadable */
#define BOARDS_EXIT_BADDATA 4 /* the CSV or the configuration is malformed */
#define BOARDS_EXIT_SINK    5 /* the sink cannot be opened or refuses a frame */
#define BOARDS_EXIT_LOAD    6 /* a bus would be loaded at 70 % or more */
#define BOARDS_EXIT_SCHED   7 /* the system refused --rt-priority */

/* The monitor's capacities (rt_monitor/include/rt_monitor/capacity.hpp): a table dynid exports fits them. */
#define BOARDS_MAX_BUSES   8
#define BOARDS_MAX_FRAMES  256
#define BOARDS_MAX_SIGNALS 1024
#define BOARDS_MAX_PATCHES 16
#define BOARDS_NAME_LEN    64
#define BOARDS_MAX_COLS    512
#define BOARDS_ERR_LEN     512

/* What a signal is: a value (a CSV column), a skin patch's contact, a flag, a counter, reserved bits, or nothing. */
enum { BOARDS_T_NONE, BOARDS_T_VALUE, BOARDS_T_SKIN, BOARDS_T_SATURATED, BOARDS_T_FAULT, BOARDS_T_RESTART,
       BOARDS_T_SEQ, BOARDS_T_RESERVED };

typedef struct {
    bus_signal_t layout;
    uint8_t kind;    /* BOARDS_T_* */
    uint8_t end_byte;
    int value;       /* VALUE: index into values; SATURATED/FAULT: the target's value index or -1; SKIN: patch index */
} boards_signal_t;

typedef struct {
    char name[BOARDS_NAME_LEN];
    int bus;
    uint16_t id;
    uint8_t dlc, long_dlc; /* long_dlc: the long form's length (its optional signals), 0 none */
    int node;
    int64_t period_us;     /* 0: every sample */
    int64_t offset_us;     /* its send time relative to the sample's, <= 0 */
    int first_signal, n_signals;
} boards_table_frame_t;

typedef struct {
    char buses[BOARDS_MAX_BUSES][BOARDS_NAME_LEN];
    int n_buses;
    boards_table_frame_t frames[BOARDS_MAX_FRAMES];
    int n_frames;
    boards_signal_t signals[BOARDS_MAX_SIGNALS]; /* grouped by frame, each frame's in file order */
    int n_signals;
    char values[BOARDS_MAX_SIGNALS][2 * BOARDS_NAME_LEN]; /* value targets: q.J dq.J pwm.M current.M tau.J ft.S.C */
    int n_values;
    char nodes[BOARDS_MAX_FRAMES][BOARDS_NAME_LEN];
    int n_nodes;
    char patches[BOARDS_MAX_PATCHES][BOARDS_NAME_LEN];
    int n_patches;
    int clock; /* the frame that completes a sample */
} boards_conf_t;

/* Read the rt_monitor configuration (docs/formats.md, "rt_monitor configuration"); 0 or an exit code, err set. */
int boards_read_conf(const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN]);
/* The same from an open stream (read three times: it is rewound; not closed); `path` names it in messages. */
int boards_read_conf_stream(FILE *f, const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN]);

/* Column indices of what the boards send (-1: absent). */
typedef struct {
    int n_cols;
    int t;
    int value[BOARDS_MAX_SIGNALS]; /* per value target of the table */
    int contact;
    int patch;
} boards_columns_t;

/* The CSV: header, then rows of numbers (docs/design.md §4). */
typedef struct {
    FILE *f;
    const char *path;
    long line;
    double v[BOARDS_MAX_COLS];
} boards_csv_t;
/* `sensor`: the data's F/T sensor whose ft.NAME.* columns feed the table's one sensor (NULL: the table's names). */
int boards_csv_open(boards_csv_t *csv, const char *path, const boards_conf_t *c, const char *sensor,
                    boards_columns_t *cols, char err[BOARDS_ERR_LEN]);
/* The same on an open stream, which csv->f then owns (closed on error here, else by the caller). */
int boards_csv_open_stream(boards_csv_t *csv, FILE *f, const char *path, const boards_conf_t *c, const char *sensor,
                           boards_columns_t *cols, char err[BOARDS_ERR_LEN]);
/* 1: a row in csv->v; 0: end of file; negative exit code on a bad row (err set). */
int boards_csv_row(boards_csv_t *csv, const boards_columns_t *cols, char err[BOARDS_ERR_LEN]);
/* Back to the first data row (the second pass). */
int boards_csv_rewind(boards_csv_t *csv, char err[BOARDS_ERR_LEN]);

/* Times: a run spans at most BOARDS_MAX_SPAN_S seconds (116 days), --t0 is below BOARDS_MAX_T0_S and --repeat at
 * most BOARDS_MAX_REPEAT, so that every frame's µs timestamp fits int64 with room to spare. */
#define BOARDS_MAX_SPAN_S 1e7
#define BOARDS_MAX_T0_S 1e11
#define BOARDS_MAX_REPEAT 100000L
/* Pass 1's check of row n's time t (n from 0; t_first, t_prev the first and the previous row's): strictly
 * increasing, within the span. 0, or -BOARDS_EXIT_BADDATA with err naming the file and line. */
int boards_csv_check_time(const boards_csv_t *csv, long n, double t, double t_first, double t_prev,
                          char err[BOARDS_ERR_LEN]);
/* A row's µs timestamp, as dynid.io.candump computes it (rint: half to even), for rows that passed the check. */
int64_t boards_time_us(double t, double t_first, double t0, double shift);

/* ---- the player (boards_play.c): one row into the frames of one sample ---- */
#define BOARDS_ENCODER_GENERIC 0 /* any table: bus_encoder.h */
#define BOARDS_ENCODER_ICUB    1 /* the iCub protocol's table: firmware_like's board emulators */

typedef struct {
    int frame; /* the table's frame */
    int kind;  /* icub: 1 POSITION, 2 PID_VAL, 3 STATUS, 10/11 strain force/torque half, 20 skin */
    int board; /* index into mc, strain or skin */
} boards_icub_frame_t;

typedef struct {
    const boards_conf_t *conf;
    int encoder;
    int order[BOARDS_MAX_FRAMES];       /* the frames of a sample in send order: by offset, then as listed */
    long every[BOARDS_MAX_FRAMES];      /* samples between two frames of each (its period at the run's rate) */
    uint8_t long_node[BOARDS_MAX_FRAMES]; /* per node: its frames go in their long form */
    uint64_t node_periods[BOARDS_MAX_FRAMES]; /* per node: samples since its start or restart */
    uint8_t node_restarted[BOARDS_MAX_FRAMES]; /* a restart flag pending for the node's next frame that has one */
    uint64_t seq[BOARDS_MAX_FRAMES];
    uint8_t skin_only[BOARDS_MAX_FRAMES]; /* per frame: skin bits and no value (not sent without a contact column) */
    uint8_t clamped[BOARDS_MAX_SIGNALS]; /* per value: it clamped in this sample */
    uint64_t n_clamped;                  /* values clamped at their signal's range, over the run */
    int first_clamped;                   /* the first value that did (-1: none) */
    uint64_t samples;
    int value_signal[BOARDS_MAX_SIGNALS]; /* per value: the signal carrying it */
    /* iCub emulators */
    board_mc_t mc[BOARDS_MAX_FRAMES];
    int mc_node[BOARDS_MAX_FRAMES], mc_value[BOARDS_MAX_FRAMES][2][2]; /* per board, slot: q and pwm value or -1 */
    int n_mc;
    board_strain_t strain[BOARDS_MAX_FRAMES];
    int strain_node[BOARDS_MAX_FRAMES], strain_value[BOARDS_MAX_FRAMES][6];
    int n_strain;
    board_skin_t skin[BOARDS_MAX_PATCHES];
    int skin_patch[BOARDS_MAX_PATCHES];
    int n_skin;
    boards_icub_frame_t icub[BOARDS_MAX_FRAMES];
} boards_player_t;

/* Set up for a table and an encoder; mean_period_s: the run's mean sample period (the frames' `every`); long_node:
 * per node, long forms on. BOARDS_EXIT_BADDATA with err set if the iCub encoder is asked for a table that is not the
 * iCub protocol's. */
int boards_player_init(boards_player_t *p, const boards_conf_t *c, int encoder, double mean_period_s,
                       const uint8_t long_node[BOARDS_MAX_FRAMES], char err[BOARDS_ERR_LEN]);
/* BOARDS_ENCODER_ICUB if every node of the table is one of the iCub boards' (named icub_mc_*, icub_strain_*,
 * icub_skin_*, as dynid names the `can:` section's boards), else BOARDS_ENCODER_GENERIC. */
int boards_default_encoder(const boards_conf_t *c);
/* Pass 1: marks the nodes whose long form a row needs (one of their optional flags would be set). */
void boards_long_needed(const boards_conf_t *c, const double *row, const boards_columns_t *cols,
                        uint8_t long_node[BOARDS_MAX_FRAMES]);
/* The node of `--restart WHAT`: a node's name, or an iCub motor-control board's address (every icub_mc_*_ADDRESS);
 * fills nodes[] (up to BOARDS_MAX_FRAMES) and returns how many. */
int boards_restart_nodes(const boards_conf_t *c, const char *what, int nodes[BOARDS_MAX_FRAMES]);
typedef int (*boards_emit_fn)(void *ctx, int bus, const board_frame_t *f, int64_t t_us);
/* One sample: the row's values, its time; the nodes restarted before it (n_restart of them); every due frame to emit
 * in send order. 0, or emit's non-zero return. */
int boards_player_sample(boards_player_t *p, const double *row, const boards_columns_t *cols, int64_t t_us,
                         const int *restart, int n_restart, boards_emit_fn emit, void *ctx);

/* ---- sinks: "candump:PATH" ("candump:-": standard output), "loopback:DIR", "socketcan" (interfaces named as
 * the configured buses) ---- */
typedef struct {
    int kind;
    FILE *f;
    int to_stdout; /* candump:- : the log streams to standard output (the summary then goes to stderr) */
    char path[4096];
    char tmp[4096];
    int fd;
    int can_fd[BOARDS_MAX_BUSES];
    struct sockaddr_un dest[BOARDS_MAX_BUSES]; /* loopback: each bus's socket address, made at open */
    const boards_conf_t *conf;
    uint64_t sent;
} boards_sink_t;
int boards_sink_open(boards_sink_t *s, const char *spec, const boards_conf_t *c, char err[BOARDS_ERR_LEN]);
int boards_sink_send(boards_sink_t *s, int bus, const board_frame_t *f, int64_t t_us, char err[BOARDS_ERR_LEN]);
/* ok: commit (a candump log is renamed into place); else discard. */
int boards_sink_close(boards_sink_t *s, int ok, char err[BOARDS_ERR_LEN]);

#endif /* BOARDS_TOOL_H */
