/* boards_io.c - the boards program's inputs: the rt_monitor configuration and the run's data.csv. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boards_tool.h"

#define LINE_LEN 65536
static char g_line[LINE_LEN]; /* one CSV or configuration line; rows longer than this are refused */

static int bus_index(const boards_conf_t *c, const char *name)
{
    int i;
    for (i = 0; i < c->n_buses; ++i) {
        if (strcmp(c->buses[i], name) == 0) {
            return i;
        }
    }
    return -1;
}

static int parse_double(const char *s, double *out)
{
    char *end = 0;
    errno = 0;
    *out = strtod(s, &end);
    return end != s && *end == '\0' && errno != ERANGE;
}

static int parse_address(const char *s, uint8_t *out)
{
    char *end = 0;
    const long v = strtol(s, &end, 10);
    if (end == s || *end != '\0' || v < 0 || v > 15) {
        return 0;
    }
    *out = (uint8_t)v;
    return 1;
}

static boards_mc_conf_t *mc_board(boards_conf_t *c, int bus, uint8_t address)
{
    int i;
    for (i = 0; i < c->n_mc; ++i) {
        if (c->mc[i].bus == bus && c->mc[i].address == address) {
            return &c->mc[i];
        }
    }
    if (c->n_mc == BOARDS_MAX_MC) {
        return 0;
    }
    memset(&c->mc[c->n_mc], 0, sizeof c->mc[0]);
    c->mc[c->n_mc].bus = bus;
    c->mc[c->n_mc].address = address;
    return &c->mc[c->n_mc++];
}

/* The keys of the rt_monitor configuration that only the monitor reads. */
static int is_monitor_key(const char *key)
{
    static const char *const keys[] = {"robot", "lcm_url", "stale_ms", "pair_us", "status_hz", "residual_every"};
    size_t i;
    for (i = 0; i < sizeof keys / sizeof keys[0]; ++i) {
        if (strcmp(key, keys[i]) == 0) {
            return 1;
        }
    }
    return 0;
}

/* A name from the file for a message: at most 64 bytes, control bytes as '?' (the refusal stays one line). */
static const char *shown(const char *name)
{
    static char out[65];
    size_t i;
    for (i = 0; name[i] && i < sizeof out - 1; ++i) {
        const unsigned char ch = (unsigned char)name[i];
        out[i] = (char)(ch < 0x20 || ch == 0x7f ? '?' : ch);
    }
    out[i] = '\0';
    return out;
}

/* Some board already maps the joint (axis) or the motor (pwm) `name`. */
static int mapped_twice(const boards_conf_t *c, int axis, const char *name)
{
    int i;
    unsigned s;
    for (i = 0; i < c->n_mc; ++i) {
        for (s = 0; s < BOARD_MC_AXES; ++s) {
            if (axis ? (c->mc[i].axis[s].used && strcmp(c->mc[i].joint[s], name) == 0)
                     : (c->mc[i].axis[s].has_pwm && strcmp(c->mc[i].motor[s], name) == 0)) {
                return 1;
            }
        }
    }
    return 0;
}

#define MAX_TOK 12
/* One pass over the configuration: pass 0 reads the 'buses' line, pass 1 the board lines that name its buses
 * (so keys come in any order). 0, or an exit code with err set. */
static int read_conf_pass(FILE *f, const char *path, int pass, boards_conf_t *c, long *buses_line,
                          char err[BOARDS_ERR_LEN])
{
    long line = 0;
    char why[BOARDS_ERR_LEN / 2];
#define BAD(text) do { snprintf(err, BOARDS_ERR_LEN, "%s:%ld: %s", path, line, text); \
                       return BOARDS_EXIT_BADDATA; } while (0)
    while (fgets(g_line, LINE_LEN, f)) {
        char *tok[MAX_TOK];
        int n = 0, i, bus = -1;
        char *save = 0, *p;
        ++line;
        if (!strchr(g_line, '\n') && !feof(f)) { /* its rest would be read as a line of its own */
            snprintf(why, sizeof why, "line longer than %d bytes, or with a NUL byte", LINE_LEN - 1);
            BAD(why);
        }
        if ((p = strchr(g_line, '#')) != 0) {
            *p = '\0';
        }
        for (p = strtok_r(g_line, " \t\r\n", &save); p && n < MAX_TOK; p = strtok_r(0, " \t\r\n", &save)) {
            tok[n++] = p;
        }
        if (n == 0 || (strcmp(tok[0], "buses") == 0) != (pass == 0)) {
            continue; /* blank, or the other pass's */
        }
        if (pass == 0) {
            if (*buses_line) {
                snprintf(why, sizeof why, "a second 'buses' line (the first is line %ld)", *buses_line);
                BAD(why);
            }
            if (n - 1 > BOARDS_MAX_BUSES || n < 2) BAD("'buses' needs 1 to 8 names");
            for (i = 1; i < n; ++i) {
                if (strlen(tok[i]) >= BOARDS_NAME_LEN) BAD("bus name too long");
                if (bus_index(c, tok[i]) >= 0) BAD("a bus named twice in the 'buses' line");
                strcpy(c->buses[i - 1], tok[i]);
                c->n_buses = i;
            }
            *buses_line = line;
            continue;
        }
        if (strcmp(tok[0], "strain") != 0 && strcmp(tok[0], "axis") != 0 && strcmp(tok[0], "pwm") != 0 &&
            strcmp(tok[0], "skin") != 0) {
            if (is_monitor_key(tok[0])) {
                continue; /* the monitor's own settings */
            }
            /* A misspelt board line was skipped without a word (rt_monitor refuses it): the board went missing. */
            snprintf(why, sizeof why, "unknown key '%s'", shown(tok[0]));
            BAD(why);
        }
        if (n < 3) BAD("a board line needs a bus and an address");
        bus = bus_index(c, tok[1]);
        if (bus < 0) {
            snprintf(why, sizeof why, "bus '%.64s' is not in the 'buses' line (line %ld)", tok[1], *buses_line);
            BAD(why);
        }
        if (strcmp(tok[0], "strain") == 0) {
            if (n != 9) BAD("'strain BUS ADDRESS FS*6' expected");
            if (c->has_strain) BAD("a second strain board");
            if (!parse_address(tok[2], &c->strain_address)) BAD("board address must be 0..15");
            for (i = 0; i < 6; ++i) {
                if (!parse_double(tok[3 + i], &c->strain_fs[i]) || !(c->strain_fs[i] > 0.0) ||
                    !isfinite(c->strain_fs[i])) BAD("full scales must be numbers > 0");
            }
            c->has_strain = 1;
            c->strain_bus = bus;
        } else if (strcmp(tok[0], "skin") == 0) {
            if (n != 5) BAD("'skin BUS ADDRESS PATCH SIDE' expected");
            if (c->n_skin == BOARDS_MAX_SKIN) BAD("too many skin boards");
            if (!parse_address(tok[2], &c->skin_address[c->n_skin])) BAD("board address must be 0..15");
            for (i = 0; i < c->n_skin; ++i) { /* one board, two patches: its frames would be sent twice */
                if (c->skin_bus[i] == bus && c->skin_address[i] == c->skin_address[c->n_skin]) {
                    snprintf(why, sizeof why, "skin board %.64s %u has a second 'skin' line", tok[1],
                             (unsigned)c->skin_address[i]);
                    BAD(why);
                }
            }
            c->skin_bus[c->n_skin++] = bus;
        } else {
            uint8_t address;
            long slot;
            char *end = 0;
            boards_mc_conf_t *b;
            board_mc_axis_t *a;
            if (!parse_address(tok[2], &address)) BAD("board address must be 0..15");
            slot = (n > 3) ? strtol(tok[3], &end, 10) : -1;
            if (n > 3 && (*end != '\0' || slot < 0 || slot > 1)) BAD("axis slot must be 0 or 1");
            if (strcmp(tok[0], "axis") == 0 && n != 7) BAD("'axis BUS ADDRESS SLOT JOINT TICKS_PER_DEG ZERO_DEG' expected");
            if (strcmp(tok[0], "pwm") == 0 && n != 6) BAD("'pwm BUS ADDRESS SLOT MOTOR FULL_SCALE' expected");
            if (strlen(tok[4]) >= BOARDS_NAME_LEN) BAD("name too long");
            if (mapped_twice(c, strcmp(tok[0], "axis") == 0, tok[4])) {
                /* rt_monitor refuses a joint or a motor on two boards; the boards sent both without a word */
                snprintf(why, sizeof why, "%s '%s' has a second '%s' line", strcmp(tok[0], "axis") == 0 ? "joint" : "motor",
                         shown(tok[4]), tok[0]);
                BAD(why);
            }
            b = mc_board(c, bus, address);
            if (!b) BAD("too many motor-control boards");
            a = &b->axis[slot];
            if (strcmp(tok[0], "axis") == 0) {
                if (a->used) BAD("axis slot given twice");
                if (!parse_double(tok[5], &a->ticks_per_degree) || !(a->ticks_per_degree > 0.0) ||
                    !parse_double(tok[6], &a->zero_deg)) BAD("ticks per degree must be > 0, zero a number");
                a->used = 1u;
                strcpy(b->joint[slot], tok[4]);
            } else {
                if (a->has_pwm) BAD("pwm slot given twice");
                if (!parse_double(tok[5], &a->pwm_full_scale) || !(a->pwm_full_scale > 0.0) ||
                    a->pwm_full_scale > 32767.0) BAD("PWM full scale must be in (0, 32767]");
                a->has_pwm = 1u;
                strcpy(b->motor[slot], tok[4]);
            }
        }
    }
#undef BAD
    return 0;
}

int boards_read_conf(const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN])
{
    FILE *f = fopen(path, "r");
    int rc;
    if (!f) {
        memset(c, 0, sizeof *c);
        snprintf(err, BOARDS_ERR_LEN, "%s: %s", path, strerror(errno));
        return BOARDS_EXIT_NOFILE;
    }
    rc = boards_read_conf_stream(f, path, c, err);
    fclose(f);
    return rc;
}

int boards_read_conf_stream(FILE *f, const char *path, boards_conf_t *c, char err[BOARDS_ERR_LEN])
{
    long buses_line = 0;
    int rc;
    memset(c, 0, sizeof *c);
    rc = read_conf_pass(f, path, 0, c, &buses_line, err);
    if (rc == 0 && ferror(f)) { /* a directory reads as an error, not as an empty file without 'buses' */
        snprintf(err, BOARDS_ERR_LEN, "%s: read error: %s", path, strerror(errno));
        return BOARDS_EXIT_NOFILE;
    }
    if (rc == 0 && c->n_buses == 0) {
        snprintf(err, BOARDS_ERR_LEN, "%s: no 'buses' line", path);
        rc = BOARDS_EXIT_BADDATA;
    }
    if (rc == 0) {
        rewind(f);
        rc = read_conf_pass(f, path, 1, c, &buses_line, err);
    }
    if (rc == 0 && ferror(f)) {
        snprintf(err, BOARDS_ERR_LEN, "%s: read error", path);
        rc = BOARDS_EXIT_NOFILE;
    }
    if (rc != 0) {
        return rc;
    }
    if (!c->has_strain) {
        snprintf(err, BOARDS_ERR_LEN, "%s: no strain board", path);
        return BOARDS_EXIT_BADDATA;
    }
    {
        int i, s;
        for (i = 0; i < c->n_mc; ++i) {
            for (s = 0; s < 2; ++s) {
                if (c->mc[i].axis[s].has_pwm && !c->mc[i].axis[s].used) {
                    snprintf(err, BOARDS_ERR_LEN, "%s: pwm on board %u slot %d without an axis line", path,
                             (unsigned)c->mc[i].address, s);
                    return BOARDS_EXIT_BADDATA;
                }
            }
        }
    }
    return 0;
}

/* Split g_line at commas in place; returns the field count (or -1 when more than BOARDS_MAX_COLS). */
static int split(char *line, char *field[BOARDS_MAX_COLS])
{
    int n = 0;
    char *p = line;
    size_t len = strlen(p);
    while (len && (p[len - 1] == '\n' || p[len - 1] == '\r')) {
        p[--len] = '\0';
    }
    for (;;) {
        char *comma = strchr(p, ',');
        if (n == BOARDS_MAX_COLS) {
            return -1;
        }
        field[n++] = p;
        if (!comma) {
            return n;
        }
        *comma = '\0';
        p = comma + 1;
    }
}

static int find(char *field[], int n, const char *name)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (strcmp(field[i], name) == 0) {
            return i;
        }
    }
    return -1;
}

int boards_csv_open(boards_csv_t *csv, const char *path, const boards_conf_t *c, const char *sensor,
                    boards_columns_t *cols, char err[BOARDS_ERR_LEN])
{
    FILE *f = fopen(path, "r");
    if (!f) {
        csv->f = 0;
        snprintf(err, BOARDS_ERR_LEN, "%s: %s", path, strerror(errno));
        return BOARDS_EXIT_NOFILE;
    }
    return boards_csv_open_stream(csv, f, path, c, sensor, cols, err);
}

int boards_csv_open_stream(boards_csv_t *csv, FILE *f, const char *path, const boards_conf_t *c, const char *sensor,
                           boards_columns_t *cols, char err[BOARDS_ERR_LEN])
{
    static const char *axes[6] = {"fx", "fy", "fz", "tx", "ty", "tz"};
    static char *field[BOARDS_MAX_COLS];
    char name[2 * BOARDS_NAME_LEN + 16];
    char found[BOARDS_NAME_LEN] = "";
    int n, i, s;
    csv->path = path;
    csv->line = 1;
    csv->f = f;
#define BAD(...) do { snprintf(err, BOARDS_ERR_LEN, __VA_ARGS__); fclose(csv->f); csv->f = 0; \
                      return BOARDS_EXIT_BADDATA; } while (0)
    if (!fgets(g_line, LINE_LEN, csv->f)) BAD("%s: empty file, no CSV header", path);
    if (!strchr(g_line, '\n')) BAD("%s:1: header line too long", path);
    n = split(g_line, field);
    if (n < 0) BAD("%s:1: more than %d columns", path, BOARDS_MAX_COLS);
    cols->n_cols = n;
    for (i = 1; i < n; ++i) { /* which of two 'q.r_elbow' columns is the joint's? dynid refuses it, so do the boards */
        if (find(field, i, field[i]) >= 0) BAD("%s:1: column '%s' appears twice in the header", path, shown(field[i]));
    }
    cols->t = find(field, n, "t");
    if (cols->t < 0) BAD("%s: no column 't'", path);
    if (!sensor) { /* the one F/T sensor of the data */
        for (i = 0; i < n; ++i) {
            const size_t len = strlen(field[i]);
            if (strncmp(field[i], "ft.", 3) == 0 && len > 6 && strcmp(field[i] + len - 3, ".fx") == 0) {
                if (found[0]) BAD("%s: several F/T sensors; name one with --sensor", path);
                if (len - 6 >= BOARDS_NAME_LEN) BAD("%s: sensor name too long", path);
                memcpy(found, field[i] + 3, len - 6);
                found[len - 6] = '\0';
            }
        }
        if (!found[0]) BAD("%s: no F/T sensor columns (ft.<sensor>.fx ...)", path);
        sensor = found;
    }
    for (i = 0; i < 6; ++i) {
        snprintf(name, sizeof name, "ft.%s.%s", sensor, axes[i]);
        cols->ft[i] = find(field, n, name);
        if (cols->ft[i] < 0) BAD("%s: no column '%s'", path, name);
    }
    for (i = 0; i < c->n_mc; ++i) {
        for (s = 0; s < 2; ++s) {
            cols->q[i][s] = cols->pwm[i][s] = -1;
            if (c->mc[i].axis[s].used) {
                snprintf(name, sizeof name, "q.%s", c->mc[i].joint[s]);
                cols->q[i][s] = find(field, n, name);
                if (cols->q[i][s] < 0) BAD("%s: no column '%s'", path, name);
            }
            if (c->mc[i].axis[s].has_pwm) {
                snprintf(name, sizeof name, "pwm.%s", c->mc[i].motor[s]);
                cols->pwm[i][s] = find(field, n, name);
                if (cols->pwm[i][s] < 0) BAD("%s: no column '%s'", path, name);
            }
        }
    }
    cols->contact = find(field, n, "contact");
    cols->patch = find(field, n, "skin.patch");
#undef BAD
    return 0;
}

int boards_csv_row(boards_csv_t *csv, const boards_columns_t *cols, char err[BOARDS_ERR_LEN])
{
    static char *field[BOARDS_MAX_COLS];
    int n, i;
    for (;;) {
        if (!fgets(g_line, LINE_LEN, csv->f)) {
            if (ferror(csv->f)) {
                snprintf(err, BOARDS_ERR_LEN, "%s: read error", csv->path);
                return -BOARDS_EXIT_NOFILE;
            }
            return 0;
        }
        ++csv->line;
        if (g_line[0] != '\n' && !(g_line[0] == '\r' && g_line[1] == '\n')) {
            break; /* blank lines are skipped */
        }
    }
    if (!strchr(g_line, '\n') && !feof(csv->f)) {
        snprintf(err, BOARDS_ERR_LEN, "%s:%ld: line longer than %d bytes, or with a NUL byte", csv->path, csv->line,
                 LINE_LEN - 1);
        return -BOARDS_EXIT_BADDATA;
    }
    n = split(g_line, field);
    if (n != cols->n_cols) {
        snprintf(err, BOARDS_ERR_LEN, "%s:%ld: %d fields, the header has %d", csv->path, csv->line, n, cols->n_cols);
        return -BOARDS_EXIT_BADDATA;
    }
    for (i = 0; i < n; ++i) {
        if (!parse_double(field[i], &csv->v[i]) || !isfinite(csv->v[i])) {
            snprintf(err, BOARDS_ERR_LEN, "%s:%ld: column %d is not a finite number: '%.40s'", csv->path, csv->line,
                     i + 1, field[i]);
            return -BOARDS_EXIT_BADDATA;
        }
    }
    return 1;
}

int boards_csv_rewind(boards_csv_t *csv, char err[BOARDS_ERR_LEN])
{
    if (fseek(csv->f, 0L, SEEK_SET) != 0 || !fgets(g_line, LINE_LEN, csv->f)) {
        snprintf(err, BOARDS_ERR_LEN, "%s: cannot rewind", csv->path);
        return BOARDS_EXIT_NOFILE;
    }
    csv->line = 1;
    return 0;
}

int boards_csv_check_time(const boards_csv_t *csv, long n, double t, double t_first, double t_prev,
                          char err[BOARDS_ERR_LEN])
{
    if (n > 0 && !(t > t_prev)) {
        snprintf(err, BOARDS_ERR_LEN, "%s:%ld: t is not strictly increasing", csv->path, csv->line);
        return -BOARDS_EXIT_BADDATA;
    }
    if (n > 0 && !(t - t_first <= BOARDS_MAX_SPAN_S)) {
        snprintf(err, BOARDS_ERR_LEN, "%s:%ld: t is %g s after the first row, more than the %g s a run may span",
                 csv->path, csv->line, t - t_first, BOARDS_MAX_SPAN_S);
        return -BOARDS_EXIT_BADDATA;
    }
    return 0;
}

int64_t boards_time_us(double t, double t_first, double t0, double shift)
{
    /* |t - t_first| <= BOARDS_MAX_SPAN_S, t0 < BOARDS_MAX_T0_S, shift < 2 BOARDS_MAX_REPEAT spans: < 2.1e18 us. */
    return (int64_t)rint((t - t_first + t0 + shift) * 1e6);
}
