/*
 * boards - play a simulated experiment through the board emulators as CAN frames.
 *
 *   boards --config MONITOR.conf --data RUN_DIR|data.csv --sink candump:PATH|loopback:DIR|socketcan
 *          [--realtime] [--t0 SECONDS] [--sensor NAME] [--strain-sat auto|on|off] [--restart ADDR@SAMPLE]
 *          [--repeat N] [--rt-priority P] [--help]
 *
 * The configuration is rt_monitor's (rt_monitor/README.md, "Configuration"; `dynid` writes it from the robot
 * configuration): buses, the strain board, the motor-control boards' axes and PWMs, the skin boards. Per sample
 * k at time t_k, on each board's bus, the frames go out in this order (the same as dynid.io.candump):
 *   t_k - 300 us  POSITION and PID_VAL of every motor-control board;
 *   t_k - 250 us  STATUS of every motor-control board, every 10th sample;
 *   t_k - 200 us  TAXELS of every skin board (group 0 = the run's contact on that board's patch);
 *   t_k - 100 us  strain force half;  t_k  strain torque half (it closes the sample).
 * --repeat plays the run N times back to back (time continues; benchmarks that need many contacts).
 * --realtime wakes once per sample at its first frame's time (absolute CLOCK_MONOTONIC sleeps) and sends the
 * sample's frames back to back; else as fast as possible. A live transport stamps frames when they are sent, so
 * the monitor needs --realtime over loopback and SocketCAN; fast mode is for candump logs. --rt-priority runs
 * the sender SCHED_FIFO so that its wake-ups keep the 1 kHz tick on a loaded machine (refused cleanly where
 * the system does not allow it). Paced runs print the CLOCK_REALTIME µs of sample 0 (the monitor's clock).
 * Bus load: worst-case bit stuffing at 1 Mbit/s (board_frame_bits_worst), over the run's duration.
 * --sink candump:- streams the log to standard output (a pipe into a fault injector or a monitor: an hour of frames
 * needs no 2 GB file); the summary then goes to stderr.
 */
#define _GNU_SOURCE /* sched_setscheduler, CLOCK_REALTIME stamps */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sched.h>
#include <sys/stat.h>
#include <time.h>

#include "board_mc.h"
#include "board_skin.h"
#include "board_strain.h"
#include "boards_tool.h"
#include "icub_can.h"

#define BITRATE 1000000.0
#define LOAD_LIMIT 0.70
/* The sample periods rt_monitor's coefficient loader accepts (kMinSamplePeriod, kMaxSamplePeriod), 1 s excluded. */
#define MIN_PERIOD_S 1e-5
#define MAX_PERIOD_S 1.0

static boards_conf_t g_conf;
static boards_columns_t g_cols;
static boards_csv_t g_csv;
static boards_sink_t g_sink;
static board_strain_t g_strain;
static board_mc_t g_mc[BOARDS_MAX_MC];
static board_skin_t g_skin[BOARDS_MAX_SKIN];
static uint64_t g_bits[BOARDS_MAX_BUSES];
static uint64_t g_frames[BOARDS_MAX_BUSES];
static char g_err[BOARDS_ERR_LEN];

#define SYNOPSIS "usage: boards --config MONITOR.conf --data RUN_DIR|data.csv --sink candump:PATH|loopback:DIR|socketcan " \
                 "[--realtime] [--rt-priority P] [--t0 S] [--sensor NAME] [--strain-sat auto|on|off] " \
                 "[--restart ADDRESS@SAMPLE] [--repeat N] [--help]\n"

/* --help, line by line (C99 guarantees string literals of 4095 characters only). */
static const char *const k_help[] = {
    "",
    "Play a simulated run (data.csv, docs/design.md §4) through the C board emulators (strain, motor-control,",
    "skin) as iCub CAN frames, on the buses of the rt_monitor configuration; then print each bus's load.",
    "",
    "required:",
    "  --config MONITOR.conf     the rt_monitor configuration: buses, which board is on which bus at which address,",
    "                            strain full scales, ticks per degree, PWM full scales, skin patches",
    "                            (dynid writes it from the robot configuration; rt_monitor/README.md)",
    "  --data RUN_DIR|data.csv   a run directory (its data.csv is read) or a CSV file; every row is checked",
    "                            before any frame is sent",
    "  --sink SINK               where the frames go:",
    "                              candump:PATH  a candump -L log file (written beside PATH, renamed into place);",
    "                                            candump:- streams it to standard output (the summary to stderr)",
    "                              loopback:DIR  one struct can_frame datagram per frame to DIR/<bus>.can, the",
    "                                            sockets `rt_monitor --loopback DIR` binds",
    "                              socketcan     raw CAN sockets on the interfaces named as the configured buses",
    "",
    "options:",
    "  --realtime                pace the samples at the data's times (one absolute CLOCK_MONOTONIC sleep per",
    "                            sample); live sinks need it, candump logs do not (default: as fast as possible)",
    "  --rt-priority P           run the sender SCHED_FIFO at priority P, 1..99 (exit 7 if the system refuses)",
    "  --t0 S                    timestamp of the first sample, in seconds (default 1700000000)",
    "  --sensor NAME             the F/T sensor whose ft.NAME.* columns feed the strain board (default: the",
    "                            data's only one)",
    "  --strain-sat auto|on|off  7-byte strain frames with saturation flags in byte 6: when a channel clamps",
    "                            somewhere in the run (auto, the default), always (on), never (off: 6 bytes)",
    "  --restart ADDRESS@SAMPLE  reset the motor-control board at ADDRESS (0..15) before sample SAMPLE (from 0):",
    "                            its next STATUS carries RESTARTED and sequence 0",
    "  --repeat N                play the run N times back to back, time continuing (1..100000, default 1)",
    "  -h, --help                print this help on stdout and exit 0",
    "",
    "exit codes: 0 done; 2 bad flag or value; 3 an input file is missing or unreadable; 4 a malformed CSV or",
    "configuration; 5 the sink cannot be opened or refuses a frame; 6 a bus loaded at 70 % or more (worst-case",
    "bit stuffing, 1 Mbit/s); 7 SCHED_FIFO refused.",
};

static int usage(const char *why)
{
    fprintf(stderr, "boards: error: %s\n" SYNOPSIS, why);
    return BOARDS_EXIT_USAGE;
}

static int help(void)
{
    size_t i;
    fputs(SYNOPSIS, stdout);
    for (i = 0; i < sizeof k_help / sizeof k_help[0]; ++i) {
        puts(k_help[i]);
    }
    return fflush(stdout) == 0 ? 0 : 1;
}

static int fail(int code)
{
    fprintf(stderr, "boards: error: %s\n", g_err);
    return code;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Sleep until `start` + `offset_us` on CLOCK_MONOTONIC (absolute: no drift accumulates). */
static void sleep_until(const struct timespec *start, int64_t offset_us)
{
    struct timespec at = *start;
    int64_t ns = (int64_t)at.tv_nsec + (offset_us % 1000000) * 1000;
    at.tv_sec += (time_t)(offset_us / 1000000 + ns / 1000000000);
    at.tv_nsec = (long)(ns % 1000000000);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, 0) == EINTR) {
    }
}

typedef struct {
    int realtime;
    int64_t first_us;
    struct timespec start;
} pace_t;

static int emit(pace_t *p, int bus, const board_frame_t *f, int64_t t_us)
{
    int rc;
    (void)p;
    rc = boards_sink_send(&g_sink, bus, f, t_us, g_err);
    if (rc == 0) {
        g_bits[bus] += board_frame_bits_worst(f->dlc);
        ++g_frames[bus];
    }
    return rc;
}

/* One sample through every board, in the bus order documented above. */
static int play_sample(pace_t *p, const double *v, int64_t t_us, long restart_addr)
{
    board_frame_t f;
    double w[6];
    int i, s, rc;
    if (p->realtime) {
        /* One wake-up per sample, then its frames back to back: the boards share one 1 kHz tick, and a
         * sleep per frame would only add scheduling jitter between the halves the monitor pairs. */
        sleep_until(&p->start, t_us - 300 - p->first_us);
    }
    for (i = 0; i < g_conf.n_mc; ++i) {
        double q[2] = {0.0, 0.0}, duty[2] = {0.0, 0.0};
        for (s = 0; s < 2; ++s) {
            q[s] = g_cols.q[i][s] >= 0 ? v[g_cols.q[i][s]] : 0.0;
            duty[s] = g_cols.pwm[i][s] >= 0 ? v[g_cols.pwm[i][s]] : 0.0;
        }
        if (restart_addr == (long)g_mc[i].address) {
            board_mc_restart(&g_mc[i]);
        }
        board_mc_sample(&g_mc[i], q, duty);
        board_mc_position_frame(&g_mc[i], &f);
        if ((rc = emit(p, g_conf.mc[i].bus, &f, t_us - 300)) != 0) return rc;
        board_mc_pid_frame(&g_mc[i], &f);
        if ((rc = emit(p, g_conf.mc[i].bus, &f, t_us - 300)) != 0) return rc;
    }
    for (i = 0; i < g_conf.n_mc; ++i) {
        if (board_mc_status_due(&g_mc[i])) {
            board_mc_status_frame(&g_mc[i], &f);
            if ((rc = emit(p, g_conf.mc[i].bus, &f, t_us - 250)) != 0) return rc;
        }
    }
    for (i = 0; i < g_conf.n_skin; ++i) {
        const int on = g_cols.contact >= 0 && v[g_cols.contact] != 0.0 &&
                       (g_cols.patch >= 0 ? v[g_cols.patch] == (double)(i + 1) : i == 0);
        board_skin_sample(&g_skin[i], (uint16_t)(on ? 1u : 0u));
        board_skin_frame(&g_skin[i], &f);
        if ((rc = emit(p, g_conf.skin_bus[i], &f, t_us - 200)) != 0) return rc;
    }
    for (i = 0; i < 6; ++i) {
        w[i] = v[g_cols.ft[i]];
    }
    board_strain_sample(&g_strain, w); /* finite: the CSV reader refuses NaN */
    board_strain_frame(&g_strain, BOARD_STRAIN_HALF_FORCE, &f);
    if ((rc = emit(p, g_conf.strain_bus, &f, t_us - 100)) != 0) return rc;
    board_strain_frame(&g_strain, BOARD_STRAIN_HALF_TORQUE, &f);
    return emit(p, g_conf.strain_bus, &f, t_us);
}

int main(int argc, char **argv)
{
    const char *conf = 0, *data = 0, *sink = 0, *sensor = 0, *sat = "auto";
    static char csv_path[4200];
    double t0 = 1700000000.0, t_first = 0.0, t_prev = 0.0, wall;
    long n = 0, k = 0, restart_addr = -1, restart_at = -1, repeat = 1, r, rt_priority = 0;
    long long real0_us = 0;
    int realtime = 0, rc, i, any_sat = 0, overloaded = 0;
    pace_t pace;
    struct stat st;

    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const int has = i + 1 < argc;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) return help();
        if (strcmp(a, "--realtime") == 0) { realtime = 1; continue; }
        if (strcmp(a, "--config") && strcmp(a, "--data") && strcmp(a, "--sink") && strcmp(a, "--t0") &&
            strcmp(a, "--sensor") && strcmp(a, "--strain-sat") && strcmp(a, "--restart") && strcmp(a, "--repeat") &&
            strcmp(a, "--rt-priority")) {
            snprintf(g_err, sizeof g_err, "unknown argument '%s'", a);
            return usage(g_err);
        }
        if (!has) {
            snprintf(g_err, sizeof g_err, "'%s' needs a value", a);
            return usage(g_err);
        }
        ++i;
        if (strcmp(a, "--config") == 0) conf = argv[i];
        else if (strcmp(a, "--data") == 0) data = argv[i];
        else if (strcmp(a, "--sink") == 0) sink = argv[i];
        else if (strcmp(a, "--sensor") == 0) sensor = argv[i];
        else if (strcmp(a, "--strain-sat") == 0) sat = argv[i];
        else if (strcmp(a, "--rt-priority") == 0) {
            char *end = 0;
            rt_priority = strtol(argv[i], &end, 10);
            if (*end || rt_priority < 1 || rt_priority > 99) return usage("--rt-priority P needs 1 <= P <= 99");
        } else if (strcmp(a, "--repeat") == 0) {
            char *end = 0;
            repeat = strtol(argv[i], &end, 10);
            if (*end || repeat < 1 || repeat > BOARDS_MAX_REPEAT) return usage("--repeat N needs 1 <= N <= 100000");
        } else if (strcmp(a, "--t0") == 0) {
            char *end = 0;
            t0 = strtod(argv[i], &end);
            if (*end || !(t0 >= 0.0 && t0 < BOARDS_MAX_T0_S)) return usage("--t0 must be seconds >= 0");
        } else {
            char *end = 0;
            restart_addr = strtol(argv[i], &end, 10);
            if (*end != '@' || restart_addr < 0 || restart_addr > 15) return usage("--restart ADDRESS@SAMPLE");
            restart_at = strtol(end + 1, &end, 10);
            if (*end || restart_at < 0) return usage("--restart ADDRESS@SAMPLE");
        }
    }
    if (!conf || !data || !sink) return usage("--config, --data and --sink are required");
    if (strcmp(sat, "auto") && strcmp(sat, "on") && strcmp(sat, "off")) return usage("--strain-sat auto|on|off");

    if ((rc = boards_read_conf(conf, &g_conf, g_err)) != 0) return fail(rc);
    if (restart_addr >= 0) { /* a board that is not there cannot restart: the flag did nothing, silently */
        for (i = 0; i < g_conf.n_mc && g_conf.mc[i].address != (uint8_t)restart_addr; ++i) {
        }
        if (i == g_conf.n_mc) {
            snprintf(g_err, sizeof g_err, "--restart %ld@%ld: no motor-control board at address %ld in %.300s",
                     restart_addr, restart_at, restart_addr, conf);
            return usage(g_err);
        }
    }
    /* A run directory (docs/design.md §4) holds data.csv. */
    snprintf(csv_path, sizeof csv_path, "%s%s", data,
             (stat(data, &st) == 0 && S_ISDIR(st.st_mode)) ? "/data.csv" : "");
    if ((rc = boards_csv_open(&g_csv, csv_path, &g_conf, sensor, &g_cols, g_err)) != 0) return fail(rc);

    /* Pass 1: check every row before any frame leaves, and find whether the strain channels ever clamp. */
    while ((rc = boards_csv_row(&g_csv, &g_cols, g_err)) == 1) {
        const double t = g_csv.v[g_cols.t];
        if ((rc = boards_csv_check_time(&g_csv, n, t, t_first, t_prev, g_err)) != 0) {
            return fail(-rc);
        }
        for (i = 0; i < 6; ++i) {  /* the strain board's own conversion decides what clamps */
            int16_t count;
            uint8_t clamped = 0u;
            if (icub_can_strain_count(g_csv.v[g_cols.ft[i]], g_conf.strain_fs[i], &count, &clamped) == ICUB_CAN_OK)
                any_sat |= clamped;
        }
        if (n == 0) t_first = t;
        t_prev = t;
        ++n;
    }
    if (rc < 0) return fail(-rc);
    if (n == 0) {
        snprintf(g_err, sizeof g_err, "%.400s: no data rows", csv_path);
        return fail(BOARDS_EXIT_BADDATA);
    }
    /* One row has no sample period (its bus load came out at 94 %, exit 6); a mean period outside the monitor's
     * 10 us to 1 s is a time column in another unit than seconds (t in ms played 3 s of data as 50 minutes). */
    if (n < 2) {
        snprintf(g_err, sizeof g_err, "%.400s: one data row: a run needs at least two (a sample period)", csv_path);
        return fail(BOARDS_EXIT_BADDATA);
    }
    {
        const double mean = (t_prev - t_first) / (double)(n - 1);
        if (!(mean >= MIN_PERIOD_S && mean < MAX_PERIOD_S)) {
            snprintf(g_err, sizeof g_err, "%.300s: t steps by %g s on average, outside 10 us to under 1 s: the t "
                     "column must be in seconds%s", csv_path, mean,
                     mean >= MAX_PERIOD_S && mean * 1e-3 < 0.1 ? " (is it in milliseconds?)" : "");
            return fail(BOARDS_EXIT_BADDATA);
        }
    }
    if (restart_at >= n * repeat) {
        snprintf(g_err, sizeof g_err, "--restart %ld@%ld: the run has %ld samples", restart_addr, restart_at,
                 n * repeat);
        return usage(g_err);
    }
    if ((rc = boards_csv_rewind(&g_csv, g_err)) != 0) return fail(rc);

    /* The saturation variant (7-byte strain frames) when asked, or in auto when some channel clamps. */
    {
        const uint8_t variant = (uint8_t)(strcmp(sat, "on") == 0 || (strcmp(sat, "auto") == 0 && any_sat));
        if (board_strain_init(&g_strain, g_conf.strain_address, g_conf.strain_fs, variant) != 0) {
            snprintf(g_err, sizeof g_err, "%s: bad strain board", conf);
            return fail(BOARDS_EXIT_BADDATA);
        }
    }
    for (i = 0; i < g_conf.n_mc; ++i) {
        if (board_mc_init(&g_mc[i], g_conf.mc[i].address, g_conf.mc[i].axis) != 0) {
            snprintf(g_err, sizeof g_err, "%s: bad motor-control board %u", conf, (unsigned)g_conf.mc[i].address);
            return fail(BOARDS_EXIT_BADDATA);
        }
    }
    for (i = 0; i < g_conf.n_skin; ++i) {
        board_skin_init(&g_skin[i], g_conf.skin_address[i]);
    }

    if ((rc = boards_sink_open(&g_sink, sink, &g_conf, g_err)) != 0) {
        return rc == BOARDS_EXIT_USAGE ? usage(g_err) : fail(rc);
    }
    if (rt_priority > 0) {
        struct sched_param sp;
        memset(&sp, 0, sizeof sp);
        sp.sched_priority = (int)rt_priority;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
            snprintf(g_err, sizeof g_err, "--rt-priority %ld: SCHED_FIFO refused: %s", rt_priority, strerror(errno));
            char ignore[BOARDS_ERR_LEN];
            boards_sink_close(&g_sink, 0, ignore);
            return fail(BOARDS_EXIT_SCHED);
        }
    }
    pace.realtime = realtime;
    pace.first_us = 0;
    wall = now_s();
    for (r = 0, rc = 0; r < repeat && rc == 0; ++r) {
        /* a repetition starts one mean period after the last sample of the one before */
        const double shift = (double)r * (n > 1 ? (t_prev - t_first) * (double)n / (double)(n - 1) : 1e-3);
        if (r > 0 && (rc = boards_csv_rewind(&g_csv, g_err)) != 0) break;
        while ((rc = boards_csv_row(&g_csv, &g_cols, g_err)) == 1) {
            /* µs timestamps as dynid.io.candump computes them (rint: numpy's round, half to even) */
            const int64_t t_us = boards_time_us(g_csv.v[g_cols.t], t_first, t0, shift);
            if (k == 0) {
                struct timespec rt;
                pace.first_us = t_us - 300;
                clock_gettime(CLOCK_MONOTONIC, &pace.start);
                clock_gettime(CLOCK_REALTIME, &rt);
                real0_us = (long long)rt.tv_sec * 1000000LL + rt.tv_nsec / 1000 + 300;
            }
            rc = play_sample(&pace, g_csv.v, t_us, k == restart_at ? restart_addr : -1);
            if (rc != 0) break;
            ++k;
        }
    }
    wall = now_s() - wall;
    fclose(g_csv.f);
    if (rc != 0) {
        char ignore[BOARDS_ERR_LEN];
        boards_sink_close(&g_sink, 0, ignore);
        return fail(rc < 0 ? -rc : rc);
    }

    {
        /* Duration: n sample periods (the mean period of the run). With the log on standard output, the summary
         * goes to stderr. */
        FILE *out = g_sink.to_stdout ? stderr : stdout;
        const double period = n > 1 ? (t_prev - t_first) / (double)(n - 1) : 1e-3;
        const double duration = period * (double)n * (double)repeat;
        fprintf(out, "boards: %ld samples, %llu frames, %.3f s of data in %.3f s (%.1fx real time)\n", k,
               (unsigned long long)g_sink.sent, duration, wall, wall > 0.0 ? duration / wall : 0.0);
        if (realtime) {
            fprintf(out, "boards: sample 0 at CLOCK_REALTIME %lld us\n", real0_us);
        }
        for (i = 0; i < g_conf.n_buses; ++i) {
            const double load = (double)g_bits[i] / (duration * BITRATE);
            fprintf(out, "boards: bus %s load %.1f %% (%llu frames; worst-case bit stuffing, 1 Mbit/s)\n", g_conf.buses[i],
                   100.0 * load, (unsigned long long)g_frames[i]);
            overloaded |= load >= LOAD_LIMIT;
        }
    }
    /* An overloaded run is refused, so its candump log is not committed (it was renamed into place first). */
    if ((rc = boards_sink_close(&g_sink, !overloaded, g_err)) != 0) return fail(rc);
    if (overloaded) {
        snprintf(g_err, sizeof g_err, "a bus is loaded at 70 %% or more: move boards to another bus");
        return fail(BOARDS_EXIT_LOAD);
    }
    return 0;
}
