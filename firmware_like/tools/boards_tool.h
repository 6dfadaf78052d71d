/*
 * boards_tool.h - the host side of the `boards` program: its inputs (the rt_monitor configuration that maps
 * boards to buses, the run's data.csv) and its frame sinks. Fixed-size tables, no heap.
 */
#ifndef BOARDS_TOOL_H
#define BOARDS_TOOL_H

#include <stdint.h>
#include <stdio.h>
#include <sys/un.h>

#include "board_frame.h"
#include "board_mc.h"

/* Exit codes: each kind of failure its own, so scripts can tell them apart. */
#define BOARDS_EXIT_USAGE   2 /* bad flag or value */
#define BOARDS_EXIT_NOFILE  3 /* an input file is missing or unreadable */
#define BOARDS_EXIT_BADDATA 4 /* the CSV or the configuration is malformed */
#define BOARDS_EXIT_SINK    5 /* the sink cannot be opened or refuses a frame */
#define BOARDS_EXIT_LOAD    6 /* a bus would be loaded at 70 % or more */
#define BOARDS_EXIT_SCHED   7 /* the system refused --rt-priority */

#define BOARDS_MAX_BUSES 8
#define BOARDS_MAX_MC    16
#define BOARDS_MAX_SKIN  16
#define BOARDS_NAME_LEN  64
#define BOARDS_MAX_COLS  512
#define BOARDS_ERR_LEN   512

typedef struct {
    int bus;
    uint8_t address;
    board_mc_axis_t axis[BOARD_MC_AXES];
    char joint[BOARD_MC_AXES][BOARDS_NAME_LEN];
    char motor[BOARD_MC_AXES][BOARDS_NAME_LEN];
} boards_mc_conf_t;

typedef struct {
    char buses[BOARDS_MAX_BUSES][BOARDS_NAME_LEN];
    int n_buses;
    int has_strain;
    int strain_bus;
    uint8_t strain_address;
    double strain_fs[6];
    boards_mc_conf_t mc[BOARDS_MAX_MC];
    int n_mc;
    int skin_bus[BOARDS_MAX_SKIN];
    uint8_t skin_address[BOARDS_MAX_SKIN];
    int n_skin;
} boards_conf_t;

/* Column indices of what the boards send (-1: absent). */
typedef struct {
    int n_cols;
    int t;
    int q[BOARDS_MAX_MC][BOARD_MC_AXES];
    int pwm[BOARDS_MAX_MC][BOARD_MC_AXES];
    int ft[6];
    int contact;
    int patch;
} boards_columns_t;

/* Read the rt_monitor configuration (rt_monitor/README.md, "Configuration"); 0 or an exit code, err set. */
int boards_read_conf(const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN]);
/* The same from an open stream (read twice: it is rewound; not closed); `path` names it in messages. */
int boards_read_conf_stream(FILE *f, const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN]);

/* The CSV: header, then rows of numbers (docs/design.md §4). */
typedef struct {
    FILE *f;
    const char *path;
    long line;
    double v[BOARDS_MAX_COLS];
} boards_csv_t;
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
