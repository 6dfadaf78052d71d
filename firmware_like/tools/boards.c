/*
 * boards - play a run through the robot's bus description as CAN frames.
 *
 *   boards --config MONITOR.conf --data RUN_DIR|data.csv --sink candump:PATH|loopback:DIR|socketcan
 *          [--realtime] [--t0 SECONDS] [--sensor NAME] [--strain-sat auto|on|off] [--restart NODE|ADDR@SAMPLE]
 *          [--repeat N] [--encoder auto|generic|icub] [--bitrate BIT_S] [--rt-priority P] [--help]
 *
 * The configuration is rt_monitor's (docs/formats.md, "rt_monitor configuration"; `dynid` writes it from the robot
 * configuration): the buses and the compiled bus table, which frame carries which signal. Per sample k at time t_k,
 * every frame of the table goes out on its bus at t_k + its offset, in the table's send order (by offset, then as
 * listed; the same as dynid.io.candump), a frame with a period every round(period / the mean sample period) samples.
 * For the iCub arm: POSITION and PID_VAL at t_k - 300 us, STATUS at t_k - 250 us every 10 ms, skin at t_k - 200 us,
 * strain force t_k - 100 us and torque at t_k (it closes the sample).
 * Encoders (boards_play.c): the iCub board emulators for a table of the iCub protocol (the default there), the generic
 * encoder for any other (the same bytes on the iCub arm's simulated runs). `dynid play` hands it any run dynid reads.
 * --repeat plays the run N times back to back (time continues; benchmarks that need many contacts).
 * --realtime wakes once per sample at its first frame's time (absolute CLOCK_MONOTONIC sleeps) and sends the
 * sample's frames back to back; else as fast as possible. A live transport stamps frames when they are sent, so
 * the monitor needs --realtime over loopback and SocketCAN; fast mode is for candump logs. --rt-priority runs
 * the sender SCHED_FIFO so that its wake-ups keep the tick on a loaded machine (refused cleanly where the system
 * does not allow it). Paced runs print the CLOCK_REALTIME us of sample 0 (the monitor's clock).
 * Bus load: worst-case bit stuffing at the buses' bit rate (--bitrate, default 1 Mbit/s; board_frame_bits_worst), over
 * the run's duration.
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

#include "boards_tool.h"

#define DEFAULT_BITRATE 1000000.0
#define LOAD_LIMIT 0.70
/* The sample periods rt_monitor's coefficient loader accepts (kMinSamplePeriod, kMaxSamplePeriod), 1 s excluded. */
#define MIN_PERIOD_S 1e-5
#define MAX_PERIOD_S 1.0

static boards_conf_t g_conf;
static boards_columns_t g_cols;
static boards_csv_t g_csv;
static boards_sink_t g_sink;
static boards_player_t g_player;
static uint8_t g_long_node[BOARDS_MAX_FRAMES];
static uint64_t g_bits[BOARDS_MAX_BUSES];
static uint64_t g_frames[BOARDS_MAX_BUSES];
static char g_err[BOARDS_ERR_LEN];

#define SYNOPSIS "usage: boards --config MONITOR.conf --data RUN_DIR|data.csv --sink candump:PATH|loopback:DIR|socketcan " \
                 "[--realtime] [--rt-priority P] [--t0 S] [--sensor NAME] [--strain-sat auto|on|off] " \
                 "[--restart NODE|ADDRESS@SAMPLE] [--repeat N] [--encoder auto|generic|icub] [--bitrate BIT_S] [--help]\n"

/* --help, line by line (C99 guarantees string literals of 4095 characters only). */
static const char *const k_help[] = {
    "",
    "Play a run (data.csv, docs/design.md §4; `dynid play` writes one from any run dynid reads) as the CAN frames of",
    "the robot's bus, as the rt_monitor configuration's compiled bus table describes them; then print each bus's load.",
    "",
    "required:",
    "  --config MONITOR.conf     the rt_monitor configuration: buses and the bus table (which frame, on which bus, with",
    "                            which ID, carries which signal; `dynid export --robot CFG --monitor-config FILE`)",
    "  --data RUN_DIR|data.csv   a run directory (its data.csv is read) or a CSV file with a column per value the",
    "                            table carries (q.J, dq.J, pwm.M, current.M, tau.J, ft.S.C), and contact, skin.patch",
    "                            (without a contact column the skin's frames are not sent); every row is checked",
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
    "  --sensor NAME             the data's F/T sensor whose ft.NAME.* columns feed the bus's one F/T sensor",
    "                            (default: the columns the table names)",
    "  --strain-sat auto|on|off  frames' long forms (the iCub strain board's 7-byte saturation variant, flags in",
    "                            byte 6): when one of their flags would be set somewhere in the run (auto, the",
    "                            default), always (on), never (off)",
    "  --restart WHAT@SAMPLE     reset a node before sample SAMPLE (from 0): WHAT a node of the table, or an iCub",
    "                            motor-control board's ADDRESS (0..15); its next frame with a restart flag carries it",
    "                            and its sequence counters start again at 0",
    "  --repeat N                play the run N times back to back, time continuing (1..100000, default 1)",
    "  --encoder E               auto (default: the iCub board emulators for a table of the iCub protocol, the",
    "                            generic encoder for any other), generic, or icub",
    "  --bitrate BIT_S           the buses' bit rate, 10000..1000000 (default 1000000): what their load is of",
    "  -h, --help                print this help on stdout and exit 0",
    "",
    "exit codes: 0 done; 2 bad flag or value; 3 an input file is missing or unreadable; 4 a malformed CSV or",
    "configuration; 5 the sink cannot be opened or refuses a frame; 6 a bus loaded at 70 % or more (worst-case",
    "bit stuffing, at --bitrate); 7 SCHED_FIFO refused.",
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

static int emit(void *ctx, int bus, const board_frame_t *f, int64_t t_us)
{
    int rc;
    (void)ctx;
    rc = boards_sink_send(&g_sink, bus, f, t_us, g_err);
    if (rc == 0) {
        g_bits[bus] += board_frame_bits_worst(f->dlc);
        ++g_frames[bus];
    }
    return rc;
}

int main(int argc, char **argv)
{
    const char *conf = 0, *data = 0, *sink = 0, *sensor = 0, *sat = "auto", *encoder = "auto", *restart = 0;
    static char csv_path[4200];
    static char restart_what[BOARDS_NAME_LEN];
    static int restart_nodes[BOARDS_MAX_FRAMES];
    int n_restart = 0;
    double t0 = 1700000000.0, t_first = 0.0, t_prev = 0.0, min_step = 1e300, wall;
    long n = 0, k = 0, restart_at = -1, repeat = 1, r, rt_priority = 0;
    long long real0_us = 0;
    int64_t spread = 0, first_offset = 0;
    int realtime = 0, rc, i, overloaded = 0, enc, worst = 0;
    double bitrate = DEFAULT_BITRATE, worst_load = 0.0;
    pace_t pace;
    struct stat st;

    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const int has = i + 1 < argc;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) return help();
        if (strcmp(a, "--realtime") == 0) { realtime = 1; continue; }
        if (strcmp(a, "--config") && strcmp(a, "--data") && strcmp(a, "--sink") && strcmp(a, "--t0") &&
            strcmp(a, "--sensor") && strcmp(a, "--strain-sat") && strcmp(a, "--restart") && strcmp(a, "--repeat") &&
            strcmp(a, "--rt-priority") && strcmp(a, "--encoder") && strcmp(a, "--bitrate")) {
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
        else if (strcmp(a, "--encoder") == 0) encoder = argv[i];
        else if (strcmp(a, "--rt-priority") == 0) {
            char *end = 0;
            rt_priority = strtol(argv[i], &end, 10);
            if (*end || rt_priority < 1 || rt_priority > 99) return usage("--rt-priority P needs 1 <= P <= 99");
        } else if (strcmp(a, "--repeat") == 0) {
            char *end = 0;
            repeat = strtol(argv[i], &end, 10);
            if (*end || repeat < 1 || repeat > BOARDS_MAX_REPEAT) return usage("--repeat N needs 1 <= N <= 100000");
        } else if (strcmp(a, "--bitrate") == 0) {
            char *end = 0;
            bitrate = strtod(argv[i], &end);
            if (*end || !(bitrate >= 10000.0 && bitrate <= 1000000.0) || bitrate != (double)(long)bitrate)
                return usage("--bitrate BIT_S needs a whole number of bit/s, 10000 to 1000000");
        } else if (strcmp(a, "--t0") == 0) {
            char *end = 0;
            t0 = strtod(argv[i], &end);
            if (*end || !(t0 >= 0.0 && t0 < BOARDS_MAX_T0_S)) return usage("--t0 must be seconds >= 0");
        } else {
            const char *at = strchr(argv[i], '@');
            char *end = 0;
            restart = argv[i];
            if (!at || at == argv[i] || (size_t)(at - argv[i]) >= sizeof restart_what) {
                return usage("--restart NODE|ADDRESS@SAMPLE");
            }
            memcpy(restart_what, argv[i], (size_t)(at - argv[i]));
            restart_what[at - argv[i]] = '\0';
            restart_at = strtol(at + 1, &end, 10);
            if (*end || end == at + 1 || restart_at < 0) return usage("--restart NODE|ADDRESS@SAMPLE");
        }
    }
    if (!conf || !data || !sink) return usage("--config, --data and --sink are required");
    if (strcmp(sat, "auto") && strcmp(sat, "on") && strcmp(sat, "off")) return usage("--strain-sat auto|on|off");
    if (strcmp(encoder, "auto") && strcmp(encoder, "generic") && strcmp(encoder, "icub"))
        return usage("--encoder auto|generic|icub");

    if ((rc = boards_read_conf(conf, &g_conf, g_err)) != 0) return fail(rc);
    if (restart) { /* a node that is not there cannot restart: the flag did nothing, silently */
        const int address = strspn(restart_what, "0123456789") == strlen(restart_what);
        n_restart = boards_restart_nodes(&g_conf, restart_what, restart_nodes);
        if (address && (strlen(restart_what) > 2 || atoi(restart_what) > 15)) n_restart = -1;
        if (n_restart <= 0) {
            if (address && n_restart < 0) {
                return usage("--restart NODE|ADDRESS@SAMPLE");
            }
            snprintf(g_err, sizeof g_err, address ? "--restart %.64s: no motor-control board at address %.64s in %.300s"
                                                  : "--restart %.64s: no node %.64s in %.300s",
                     restart, restart_what, conf);
            return usage(g_err);
        }
    }
    enc = strcmp(encoder, "generic") == 0 ? BOARDS_ENCODER_GENERIC
          : strcmp(encoder, "icub") == 0  ? BOARDS_ENCODER_ICUB
                                          : boards_default_encoder(&g_conf);
    for (i = 0; i < g_conf.n_frames; ++i) { /* how far apart one sample's frames are sent */
        const int64_t off = g_conf.frames[i].offset_us;
        if (i == 0 || off < first_offset) first_offset = off;
        if (-off > spread) spread = -off;
    }
    /* A run directory (docs/design.md §4) holds data.csv. */
    snprintf(csv_path, sizeof csv_path, "%s%s", data,
             (stat(data, &st) == 0 && S_ISDIR(st.st_mode)) ? "/data.csv" : "");
    if ((rc = boards_csv_open(&g_csv, csv_path, &g_conf, sensor, &g_cols, g_err)) != 0) return fail(rc);

    /* Pass 1: check every row before any frame leaves, and find which long forms the run needs. */
    while ((rc = boards_csv_row(&g_csv, &g_cols, g_err)) == 1) {
        const double t = g_csv.v[g_cols.t];
        if ((rc = boards_csv_check_time(&g_csv, n, t, t_first, t_prev, g_err)) != 0) {
            return fail(-rc);
        }
        if (strcmp(sat, "auto") == 0) boards_long_needed(&g_conf, g_csv.v, &g_cols, g_long_node);
        if (n > 0 && t - t_prev < min_step) min_step = t - t_prev;
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
        /* A sample's frames are sent within `spread` us before its time: samples closer than that would mix. */
        if (min_step * 1e6 <= (double)spread) {
            snprintf(g_err, sizeof g_err, "%.300s: two samples %.0f us apart, while the bus table sends a sample's "
                     "frames over %lld us: they would mix", csv_path, min_step * 1e6, (long long)spread);
            return fail(BOARDS_EXIT_BADDATA);
        }
        if (strcmp(sat, "on") == 0) memset(g_long_node, 1, sizeof g_long_node);
        if ((rc = boards_player_init(&g_player, &g_conf, enc, mean, g_long_node, g_err)) != 0) return fail(rc);
    }
    if (restart_at >= n * repeat) {
        snprintf(g_err, sizeof g_err, "--restart %.64s: the run has %ld samples", restart, n * repeat);
        return usage(g_err);
    }
    if ((rc = boards_csv_rewind(&g_csv, g_err)) != 0) return fail(rc);

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
                pace.first_us = t_us + first_offset;
                clock_gettime(CLOCK_MONOTONIC, &pace.start);
                clock_gettime(CLOCK_REALTIME, &rt);
                real0_us = (long long)rt.tv_sec * 1000000LL + rt.tv_nsec / 1000 - first_offset;
            }
            if (pace.realtime) {
                /* One wake-up per sample, then its frames back to back: the nodes share one tick, and a sleep per
                 * frame would only add scheduling jitter between the halves the monitor pairs. */
                sleep_until(&pace.start, t_us + first_offset - pace.first_us);
            }
            rc = boards_player_sample(&g_player, g_csv.v, &g_cols, t_us, restart_nodes, k == restart_at ? n_restart : 0,
                                      emit, 0);
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
        if (g_player.n_clamped) { /* data lost: a value beyond its signal's range was sent at the range's end */
            fprintf(out, "boards: %llu values clamped at their signal's range (the first: %s)\n",
                    (unsigned long long)g_player.n_clamped, g_conf.values[g_player.first_clamped]);
        }
        for (i = 0; i < g_conf.n_buses; ++i) {
            const double load = (double)g_bits[i] / (duration * bitrate);
            fprintf(out, "boards: bus %s load %.1f %% (%llu frames; worst-case bit stuffing, %g Mbit/s)\n", g_conf.buses[i],
                   100.0 * load, (unsigned long long)g_frames[i], bitrate / 1e6);
            if (load >= LOAD_LIMIT && !overloaded) { /* the first: named in the refusal */
                overloaded = 1;
                worst = i;
                worst_load = load;
            }
        }
    }
    /* An overloaded run is refused, so its candump log is not committed (it was renamed into place first). */
    if ((rc = boards_sink_close(&g_sink, !overloaded, g_err)) != 0) return fail(rc);
    if (overloaded) {
        snprintf(g_err, sizeof g_err, "bus %s is loaded at %.0f %% (70 %% or more at %g Mbit/s): move frames to another "
                 "bus, or raise its bitrate", g_conf.buses[worst], 100.0 * worst_load, bitrate / 1e6);
        return fail(BOARDS_EXIT_LOAD);
    }
    return 0;
}
