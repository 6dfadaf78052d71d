/* boards_io.c - the boards player's data input: a run's data.csv, its columns found by the bus table's targets. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boards_tool.h"

#define LINE_LEN 65536
static char g_line[LINE_LEN]; /* one CSV line; rows longer than this are refused */

static int parse_double(const char *s, double *out)
{
    char *end = 0;
    errno = 0;
    *out = strtod(s, &end);
    return end != s && *end == '\0' && errno != ERANGE;
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
    static char *field[BOARDS_MAX_COLS];
    char name[3 * BOARDS_NAME_LEN];
    char table_sensor[BOARDS_NAME_LEN] = "";
    int n, i;
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
    if (sensor) { /* the data's sensor NAME feeds the table's one F/T sensor */
        for (i = 0; i < c->n_values; ++i) {
            if (strncmp(c->values[i], "ft.", 3) == 0) {
                const size_t len = strlen(c->values[i]) - 6; /* "ft." + S + ".fx" */
                if (table_sensor[0] && (strlen(table_sensor) != len || strncmp(table_sensor, c->values[i] + 3, len)))
                    BAD("%s: --sensor needs a bus with one F/T sensor; it has several", path);
                memcpy(table_sensor, c->values[i] + 3, len);
                table_sensor[len] = '\0';
            }
        }
        if (!table_sensor[0]) BAD("%s: --sensor %s: the bus carries no F/T sensor", path, shown(sensor));
    }
    for (i = 0; i < c->n_values; ++i) {
        if (sensor && strncmp(c->values[i], "ft.", 3) == 0) {
            snprintf(name, sizeof name, "ft.%s%s", sensor, strrchr(c->values[i], '.'));
        } else {
            snprintf(name, sizeof name, "%s", c->values[i]);
        }
        cols->value[i] = find(field, n, name);
        if (cols->value[i] < 0) BAD("%s: no column '%s'", path, shown(name));
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
