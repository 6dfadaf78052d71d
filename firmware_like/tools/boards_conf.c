/* boards_conf.c - the boards player's reader of the rt_monitor configuration: the buses and the compiled bus table
 * (frame, signal, clock, pair and patch lines; docs/formats.md, "rt_monitor configuration"). It refuses what
 * rt_monitor refuses in the file both read, with one line naming the file, the line and the problem (exit 4). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boards_tool.h"

#define LINE_LEN 65536
static char g_line[LINE_LEN]; /* one configuration line; longer ones are refused */

static int index_of(const char (*names)[BOARDS_NAME_LEN], int n, const char *name)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (strcmp(names[i], name) == 0) {
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
    return end != s && *end == '\0' && errno != ERANGE && isfinite(*out);
}

/* A whole integer token (decimal, or hex with 0x) within [lo, hi]. */
static int parse_long(const char *s, long lo, long hi, long *out)
{
    char *end = 0;
    const int hex = s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
    errno = 0;
    *out = strtol(s, &end, hex ? 16 : 10);
    return end != s + (hex ? 2 : 0) && end != s && *end == '\0' && errno != ERANGE && *out >= lo && *out <= hi;
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

/* The keys only the monitor reads (the player skips them), and the lines of the format before the bus table. */
static int is_monitor_key(const char *key)
{
    static const char *const keys[] = {"robot", "lcm_url", "stale_ms", "pair_us", "status_hz", "residual_every",
                                       "contact_limit_s"};
    size_t i;
    for (i = 0; i < sizeof keys / sizeof keys[0]; ++i) {
        if (strcmp(key, keys[i]) == 0) {
            return 1;
        }
    }
    return 0;
}

/* A value target: q.J dq.J pwm.M current.M tau.J or ft.S.C (C one of fx fy fz tx ty tz). */
static int is_value_target(const char *t)
{
    static const char *const families[] = {"q.", "dq.", "pwm.", "current.", "tau.", "ft."};
    static const char *const ft[] = {"fx", "fy", "fz", "tx", "ty", "tz"};
    size_t i;
    for (i = 0; i < sizeof families / sizeof families[0]; ++i) {
        const size_t n = strlen(families[i]);
        if (strncmp(t, families[i], n) == 0 && t[n] != '\0') {
            const char *last = strrchr(t, '.');
            size_t k;
            if (i != 5) {
                return 1;
            }
            if (last == t + 2) {
                return 0;
            }
            for (k = 0; k < 6; ++k) {
                if (strcmp(last + 1, ft[k]) == 0) {
                    return 1;
                }
            }
            return 0;
        }
    }
    return 0;
}

static int value_index(const boards_conf_t *c, const char *t)
{
    int i;
    for (i = 0; i < c->n_values; ++i) {
        if (strcmp(c->values[i], t) == 0) {
            return i;
        }
    }
    return -1;
}

#define MAX_TOK 12
typedef struct {
    const char *path;
    long line;
    long buses_line;
    uint64_t used[BOARDS_MAX_FRAMES];           /* per frame: the payload bits its signals occupy */
    uint8_t health[BOARDS_MAX_FRAMES];          /* per frame: 1 a restart signal, 2 a seq signal */
    int frame_of[BOARDS_MAX_SIGNALS];           /* per signal read, in file order: its frame */
    boards_signal_t pending[BOARDS_MAX_SIGNALS]; /* the signals in file order, grouped by frame at the end */
    char flag_target[BOARDS_MAX_SIGNALS][2 * BOARDS_NAME_LEN]; /* a flag's own target, resolved at the end */
    int n_pending;
    int seen_clock;
} conf_state_t;

/* A 'signal FRAME START LENGTH le|be u|s|f SCALE OFFSET TARGET' line. NULL, or what is wrong. */
static const char *signal_line(boards_conf_t *c, conf_state_t *st, char **tok, int n, char *why, size_t len)
{
    boards_signal_t s;
    long start, length;
    uint64_t mask = 0;
    uint8_t data[8], end_byte = 0;
    const char *t = n == 9 ? tok[8] : "";
    int f, i;
    memset(&s, 0, sizeof s);
    if (n != 9) return "'signal FRAME START LENGTH le|be u|s|f SCALE OFFSET TARGET' expected";
    f = -1;
    for (i = 0; i < c->n_frames; ++i) {
        if (strcmp(c->frames[i].name, tok[1]) == 0) f = i;
    }
    if (f < 0) {
        snprintf(why, len, "frame '%s' is not defined by a 'frame' line", shown(tok[1]));
        return why;
    }
    if (st->n_pending == BOARDS_MAX_SIGNALS) return "more than 1024 signals";
    if (!parse_long(tok[2], 0, 63, &start) || !parse_long(tok[3], 1, 64, &length)) return "bad start bit or length";
    if (strcmp(tok[4], "le") != 0 && strcmp(tok[4], "be") != 0) return "byte order is le or be";
    if (strcmp(tok[5], "u") != 0 && strcmp(tok[5], "s") != 0 && strcmp(tok[5], "f") != 0) return "type is u, s or f";
    s.layout.start = (uint8_t)start;
    s.layout.length = (uint8_t)length;
    s.layout.big_endian = (uint8_t)(tok[4][0] == 'b');
    s.layout.type = tok[5][0] == 'u' ? BUS_UNSIGNED : tok[5][0] == 's' ? BUS_SIGNED : BUS_FLOAT;
    if (!parse_double(tok[6], &s.layout.scale) || s.layout.scale == 0.0 || !parse_double(tok[7], &s.layout.offset))
        return "scale must be a finite number other than 0, offset a finite number";
    if (bus_signal_check(&s.layout, &end_byte) != BUS_OK) return "the signal does not fit a frame of 8 bytes";
    s.end_byte = end_byte;
    if (end_byte > (c->frames[f].long_dlc ? c->frames[f].long_dlc : c->frames[f].dlc)) {
        snprintf(why, len, "the signal at bit %ld leaves frame '%s''s bytes", start, c->frames[f].name);
        return why;
    }
    memset(data, 0, sizeof data);
    bus_signal_pack(data, &s.layout, ~(uint64_t)0);
    for (i = 0; i < 8; ++i) mask |= (uint64_t)data[i] << (8 * i);
    if (mask & st->used[f]) {
        snprintf(why, len, "the signal at bit %ld overlaps another signal of frame '%s'", start, c->frames[f].name);
        return why;
    }
    st->used[f] |= mask;
    s.value = -1;
    st->flag_target[st->n_pending][0] = '\0';
    if (strcmp(t, "-") == 0) {
        s.kind = BOARDS_T_NONE;
    } else if (strcmp(t, "restart") == 0 || strcmp(t, "seq") == 0) {
        const uint8_t bit = t[0] == 'r' ? 1u : 2u;
        if (st->health[f] & bit) return "a second restart or seq signal in the frame";
        st->health[f] = (uint8_t)(st->health[f] | bit);
        s.kind = t[0] == 'r' ? BOARDS_T_RESTART : BOARDS_T_SEQ;
        if (s.kind == BOARDS_T_SEQ && (length < 2 || length > 32)) return "a sequence counter is 2 to 32 bits";
    } else if (strcmp(t, "reserved") == 0) {
        s.kind = BOARDS_T_RESERVED;
    } else if (strncmp(t, "fault", 5) == 0 || strncmp(t, "saturated", 9) == 0) {
        const char *of = t + (t[0] == 'f' ? 5 : 9);
        s.kind = t[0] == 'f' ? BOARDS_T_FAULT : BOARDS_T_SATURATED;
        if (*of != '\0' && (*of != '.' || !is_value_target(of + 1))) {
            snprintf(why, len, "'%s': a flag's own target is a value target", shown(t));
            return why;
        }
        if (*of == '.') {
            strncpy(st->flag_target[st->n_pending], of + 1, 2 * BOARDS_NAME_LEN - 1);
            st->flag_target[st->n_pending][2 * BOARDS_NAME_LEN - 1] = '\0';
        }
    } else if (strncmp(t, "skin.", 5) == 0) {
        s.kind = BOARDS_T_SKIN;
        s.value = index_of((const char (*)[BOARDS_NAME_LEN])c->patches, c->n_patches, t + 5);
        if (s.value < 0) {
            snprintf(why, len, "'%s' names a patch no 'patch' line defines", shown(t));
            return why;
        }
    } else if (is_value_target(t)) {
        if (strlen(t) >= 2 * BOARDS_NAME_LEN) return "target name too long";
        if (value_index(c, t) >= 0) {
            snprintf(why, len, "'%s' is carried by another signal already", shown(t));
            return why;
        }
        s.kind = BOARDS_T_VALUE;
        s.value = c->n_values;
        strcpy(c->values[c->n_values++], t);
    } else {
        snprintf(why, len, "'%s' is no signal target", shown(t));
        return why;
    }
    if (s.kind != BOARDS_T_VALUE && s.kind != BOARDS_T_NONE &&
        (s.layout.type == BUS_FLOAT || s.layout.scale != 1.0 || s.layout.offset != 0.0)) {
        snprintf(why, len, "'%s' is a flag or a count: an integer signal with scale 1 and offset 0", shown(t));
        return why;
    }
    st->frame_of[st->n_pending] = f;
    st->pending[st->n_pending++] = s;
    return 0;
}

/* A 'frame NAME BUS ID DLC LONG_DLC NODE PERIOD_US OFFSET_US' line. */
static const char *frame_line(boards_conf_t *c, char **tok, int n, char *why, size_t len)
{
    boards_table_frame_t *f;
    long id, dlc, long_dlc, period, offset;
    int bus, i;
    if (n != 9) return "'frame NAME BUS ID DLC LONG_DLC NODE PERIOD_US OFFSET_US' expected";
    if (c->n_frames == BOARDS_MAX_FRAMES) return "more than 256 frames";
    if (strlen(tok[1]) >= BOARDS_NAME_LEN || strlen(tok[6]) >= BOARDS_NAME_LEN) return "name too long";
    for (i = 0; i < c->n_frames; ++i) {
        if (strcmp(c->frames[i].name, tok[1]) == 0) {
            snprintf(why, len, "a second frame '%s'", shown(tok[1]));
            return why;
        }
    }
    bus = index_of((const char (*)[BOARDS_NAME_LEN])c->buses, c->n_buses, tok[2]);
    if (bus < 0) {
        snprintf(why, len, "bus '%s' is not in the 'buses' line", shown(tok[2]));
        return why;
    }
    if (!parse_long(tok[3], 0, 0x7FF, &id)) return "a frame's ID is 11-bit, 0 to 0x7FF";
    if (!parse_long(tok[4], 0, 8, &dlc) || !parse_long(tok[5], 0, 8, &long_dlc) || (long_dlc && long_dlc <= dlc))
        return "bad DLC or long DLC";
    if (!parse_long(tok[7], 0, 60000000L, &period) || !parse_long(tok[8], -1000000L, 0, &offset))
        return "bad period or send offset";
    for (i = 0; i < c->n_frames; ++i) {
        if (c->frames[i].bus == bus && c->frames[i].id == (uint16_t)id) {
            snprintf(why, len, "ID %s on %s is frame '%s''s already", shown(tok[3]), c->buses[bus], c->frames[i].name);
            return why;
        }
    }
    f = &c->frames[c->n_frames++];
    memset(f, 0, sizeof *f);
    strcpy(f->name, tok[1]);
    f->bus = bus;
    f->id = (uint16_t)id;
    f->dlc = (uint8_t)dlc;
    f->long_dlc = (uint8_t)long_dlc;
    f->period_us = period;
    f->offset_us = offset;
    f->node = index_of((const char (*)[BOARDS_NAME_LEN])c->nodes, c->n_nodes, tok[6]);
    if (f->node < 0) {
        f->node = c->n_nodes;
        strcpy(c->nodes[c->n_nodes++], tok[6]);
    }
    return 0;
}

/* One pass over the configuration: 0 the 'buses' line, 1 the 'patch' and 'frame' lines, 2 every other line (so keys
 * come in any order). 0, or an exit code with err set. */
static int read_conf_pass(FILE *f, conf_state_t *st, int pass, boards_conf_t *c, char err[BOARDS_ERR_LEN])
{
    char why[BOARDS_ERR_LEN / 2];
    st->line = 0;
#define BAD(text) do { snprintf(err, BOARDS_ERR_LEN, "%s:%ld: %s", st->path, st->line, text); \
                       return BOARDS_EXIT_BADDATA; } while (0)
    while (fgets(g_line, LINE_LEN, f)) {
        char *tok[MAX_TOK];
        int n = 0, i, mine;
        char *save = 0, *p;
        const char *problem = 0;
        ++st->line;
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
        if (n == 0) continue;
        mine = pass == 0 ? strcmp(tok[0], "buses") == 0
               : pass == 1 ? strcmp(tok[0], "patch") == 0 || strcmp(tok[0], "frame") == 0
                           : strcmp(tok[0], "buses") != 0 && strcmp(tok[0], "patch") != 0 && strcmp(tok[0], "frame") != 0;
        if (!mine) continue;
        if (pass == 0) {
            if (st->buses_line) {
                snprintf(why, sizeof why, "a second 'buses' line (the first is line %ld)", st->buses_line);
                BAD(why);
            }
            if (n - 1 > BOARDS_MAX_BUSES || n < 2) BAD("'buses' needs 1 to 8 names");
            for (i = 1; i < n; ++i) {
                if (strlen(tok[i]) >= BOARDS_NAME_LEN) BAD("bus name too long");
                if (index_of((const char (*)[BOARDS_NAME_LEN])c->buses, c->n_buses, tok[i]) >= 0)
                    BAD("a bus named twice in the 'buses' line");
                strcpy(c->buses[i - 1], tok[i]);
                c->n_buses = i;
            }
            st->buses_line = st->line;
        } else if (strcmp(tok[0], "frame") == 0) {
            problem = frame_line(c, tok, n, why, sizeof why);
        } else if (strcmp(tok[0], "patch") == 0) {
            if (n < 2 || strlen(tok[1]) >= BOARDS_NAME_LEN) problem = "'patch NAME [SENSOR:SIDE ...]' expected";
            else if (index_of((const char (*)[BOARDS_NAME_LEN])c->patches, c->n_patches, tok[1]) >= 0)
                problem = "a second patch of that name";
            else if (c->n_patches == BOARDS_MAX_PATCHES) problem = "more than 16 skin patches";
            else strcpy(c->patches[c->n_patches++], tok[1]);
        } else if (strcmp(tok[0], "signal") == 0) {
            problem = signal_line(c, st, tok, n, why, sizeof why);
        } else if (strcmp(tok[0], "clock") == 0) {
            if (n != 2) problem = "'clock FRAME' expected";
            else if (st->seen_clock) problem = "a second 'clock' line";
            else {
                for (i = 0; i < c->n_frames && strcmp(c->frames[i].name, tok[1]) != 0; ++i) {
                }
                if (i == c->n_frames) problem = "the clock names no frame";
                c->clock = i;
                st->seen_clock = 1;
            }
        } else if (strcmp(tok[0], "pair") == 0) {
            if (n != 3) problem = "'pair FIRST SECOND' expected"; /* the pairs are the monitor's; sent as listed */
        } else if (strcmp(tok[0], "strain") == 0 || strcmp(tok[0], "axis") == 0 || strcmp(tok[0], "pwm") == 0 ||
                   strcmp(tok[0], "skin") == 0) {
            snprintf(why, sizeof why, "'%s' is a line of the iCub-only format before the bus description: write the "
                     "configuration again (dynid export --robot ROBOT --monitor-config FILE)", tok[0]);
            problem = why;
        } else if (!is_monitor_key(tok[0])) {
            /* A misspelt line was skipped without a word (rt_monitor refuses it): a frame went missing. */
            snprintf(why, sizeof why, "unknown key '%s'", shown(tok[0]));
            problem = why;
        }
        if (problem) BAD(problem);
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
    static conf_state_t st;
    int rc = 0, pass, i, k;
    memset(c, 0, sizeof *c);
    memset(&st, 0, sizeof st);
    st.path = path;
    c->clock = -1;
    for (pass = 0; pass < 3 && rc == 0; ++pass) {
        if (pass > 0) rewind(f);
        rc = read_conf_pass(f, &st, pass, c, err);
        if (rc == 0 && ferror(f)) { /* a directory reads as an error, not as an empty file without 'buses' */
            snprintf(err, BOARDS_ERR_LEN, "%s: read error: %s", path, strerror(errno));
            return BOARDS_EXIT_NOFILE;
        }
        if (rc == 0 && pass == 0 && c->n_buses == 0) {
            snprintf(err, BOARDS_ERR_LEN, "%s: no 'buses' line", path);
            return BOARDS_EXIT_BADDATA;
        }
    }
    if (rc != 0) return rc;
    if (c->n_frames == 0 || st.seen_clock == 0) {
        snprintf(err, BOARDS_ERR_LEN, "%s: no %s", path, c->n_frames ? "'clock' line" : "'frame' line");
        return BOARDS_EXIT_BADDATA;
    }
    /* The signals grouped by frame, in file order within each; the flags' own targets resolved. */
    for (i = 0; i < c->n_frames; ++i) {
        c->frames[i].first_signal = c->n_signals;
        for (k = 0; k < st.n_pending; ++k) {
            if (st.frame_of[k] != i) continue;
            if (st.flag_target[k][0]) {
                st.pending[k].value = value_index(c, st.flag_target[k]);
                if (st.pending[k].value < 0) {
                    snprintf(err, BOARDS_ERR_LEN, "%s: no signal carries '%s', which a flag of frame '%s' names", path,
                             shown(st.flag_target[k]), c->frames[i].name);
                    return BOARDS_EXIT_BADDATA;
                }
            }
            c->signals[c->n_signals++] = st.pending[k];
        }
        c->frames[i].n_signals = c->n_signals - c->frames[i].first_signal;
        if (c->frames[i].n_signals == 0) {
            snprintf(err, BOARDS_ERR_LEN, "%s: frame '%s' has no 'signal' line", path, c->frames[i].name);
            return BOARDS_EXIT_BADDATA;
        }
    }
    return 0;
}
