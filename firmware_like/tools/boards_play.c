/* boards_play.c - one row of a run into the frames of one sample, through the bus table (boards_tool.h).
 *
 * Both encoders send the table's frames in its send order (by offset, then as listed), each at the sample's time plus
 * its offset, a frame with a period every round(period / the run's mean sample period) samples of its node (from its
 * start or restart). What goes in a frame:
 * - generic (any robot): every signal from the table: a value's column through bus_signal_raw (cantools' rounding,
 *   clamped), a skin patch's contact, a flag of a target set where that target clamped in this sample, the node's
 *   restart flag once after a restart, a sequence counter per frame (back to 0 at a restart), 0 elsewhere;
 * - icub: the iCub board emulators (fixed-point strain conversion, saturation flags, STATUS faults and sequence,
 *   restarts), set up from the table of the iCub protocol (nodes named icub_mc_*, icub_strain_*, icub_skin_*, as dynid
 *   writes the `can:` section's boards) and latched once per sample.
 * On a simulated run of the iCub arm both give the same bytes (tools/tests/test_boards.py). A run without a contact
 * column sends no frame that carries skin bits and no value: it has no contact ground truth to give.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "boards_tool.h"
#include "icub_can.h"

#define PI 3.14159265358979323846

static int starts_with(const char *s, const char *prefix)
{
    return strncmp(s, prefix, strlen(prefix)) == 0;
}

int boards_default_encoder(const boards_conf_t *c)
{
    int i;
    for (i = 0; i < c->n_nodes; ++i) {
        if (!starts_with(c->nodes[i], "icub_mc_") && !starts_with(c->nodes[i], "icub_strain_") &&
            !starts_with(c->nodes[i], "icub_skin_")) {
            return BOARDS_ENCODER_GENERIC;
        }
    }
    return BOARDS_ENCODER_ICUB;
}

int boards_restart_nodes(const boards_conf_t *c, const char *what, int nodes[BOARDS_MAX_FRAMES])
{
    int i, n = 0;
    const size_t len = strlen(what);
    const int address = len > 0 && strspn(what, "0123456789") == len;
    for (i = 0; i < c->n_nodes; ++i) {
        const char *name = c->nodes[i];
        const size_t nl = strlen(name);
        if (address ? starts_with(name, "icub_mc_") && nl > len + 9 && strcmp(name + nl - len, what) == 0 &&
                          name[nl - len - 1] == '_' /* icub_mc_<bus>_<address> */
                    : strcmp(name, what) == 0) {
            nodes[n++] = i;
        }
    }
    return n;
}

/* The contact of patch k in a row: the run's contact on that patch (skin.patch = k + 1), or, without skin.patch,
 * every contact on the first patch. */
static int skin_on(const double *row, const boards_columns_t *cols, int k)
{
    if (cols->contact < 0 || row[cols->contact] == 0.0) {
        return 0;
    }
    return cols->patch >= 0 ? row[cols->patch] == (double)(k + 1) : k == 0;
}

void boards_long_needed(const boards_conf_t *c, const double *row, const boards_columns_t *cols,
                        uint8_t long_node[BOARDS_MAX_FRAMES])
{
    int i, k;
    for (i = 0; i < c->n_frames; ++i) {
        const boards_table_frame_t *f = &c->frames[i];
        if (!f->long_dlc) continue;
        for (k = f->first_signal; k < f->first_signal + f->n_signals; ++k) {
            const boards_signal_t *s = &c->signals[k];
            if (s->end_byte > f->dlc && (s->kind == BOARDS_T_SATURATED || s->kind == BOARDS_T_FAULT) && s->value >= 0) {
                int v;
                uint8_t clamped = 0u;
                for (v = 0; v < c->n_signals; ++v) { /* the signal carrying the flag's target */
                    if (c->signals[v].kind == BOARDS_T_VALUE && c->signals[v].value == s->value) break;
                }
                if (v < c->n_signals) (void)bus_signal_raw(&c->signals[v].layout, row[cols->value[s->value]], &clamped);
                if (clamped) long_node[f->node] = 1u;
            }
        }
    }
}

/* ---- the iCub emulators, from the table ---- */

static const boards_signal_t *signal_at(const boards_conf_t *c, const boards_table_frame_t *f, int start)
{
    int k;
    for (k = f->first_signal; k < f->first_signal + f->n_signals; ++k) {
        if (c->signals[k].layout.start == start) return &c->signals[k];
    }
    return 0;
}

/* Each frame of the table to its emulator; 0, or BOARDS_EXIT_BADDATA where the table is not the iCub protocol's. */
static int icub_setup(boards_player_t *p, const boards_conf_t *c, char err[BOARDS_ERR_LEN])
{
    int i, k;
#define NOT_ICUB(why) do { snprintf(err, BOARDS_ERR_LEN, "frame '%s' is not the iCub protocol's (%s): play it with " \
                                    "--encoder generic", f->name, why); return BOARDS_EXIT_BADDATA; } while (0)
    for (i = 0; i < c->n_frames; ++i) {
        const boards_table_frame_t *f = &c->frames[i];
        const char *node = c->nodes[f->node];
        const uint8_t cls = (uint8_t)(f->id >> 8), address = (uint8_t)((f->id >> 4) & 0xFu), type = (uint8_t)(f->id & 0xFu);
        boards_icub_frame_t *e = &p->icub[i];
        e->frame = i;
        e->board = -1;
        if (starts_with(node, "icub_mc_") && cls == ICUB_CAN_CLASS_MC) {
            for (k = 0; k < p->n_mc && p->mc_node[k] != f->node; ++k) {
            }
            if (k == p->n_mc) {
                memset(&p->mc[k], 0, sizeof p->mc[k]);
                p->mc[k].address = address;
                p->mc_node[k] = f->node;
                p->mc_value[k][0][0] = p->mc_value[k][0][1] = p->mc_value[k][1][0] = p->mc_value[k][1][1] = -1;
                ++p->n_mc;
            }
            e->board = k;
            e->kind = type;
            if (p->mc[k].address != address) NOT_ICUB("its node's other frames are another board address's");
            if (type == ICUB_CAN_MC_POSITION || type == ICUB_CAN_MC_PID_VAL) {
                const int width = type == ICUB_CAN_MC_POSITION ? 32 : 16;
                int slot;
                if (f->dlc != width / 4 || f->long_dlc) NOT_ICUB("length");
                for (slot = 0; slot < 2; ++slot) {
                    const boards_signal_t *s = signal_at(c, f, slot * width);
                    board_mc_axis_t *a = &p->mc[k].axis[slot];
                    if (!s || s->layout.length != width || s->layout.big_endian || s->layout.type != BUS_SIGNED)
                        NOT_ICUB("its two axes");
                    if (s->kind != BOARDS_T_VALUE) continue;
                    if (type == ICUB_CAN_MC_POSITION) { /* rad = (ticks / tpd - zero) * pi / 180 */
                        a->used = 1u;
                        a->ticks_per_degree = (PI / 180.0) / s->layout.scale;
                        a->zero_deg = -s->layout.offset * (180.0 / PI);
                        p->mc_value[k][slot][0] = s->value;
                    } else { /* duty = count / full scale */
                        a->has_pwm = 1u;
                        a->pwm_full_scale = 1.0 / s->layout.scale;
                        p->mc_value[k][slot][1] = s->value;
                    }
                }
            } else if (type != ICUB_CAN_MC_STATUS || f->dlc != ICUB_CAN_MC_STATUS_DLC) {
                NOT_ICUB("type");
            }
        } else if (starts_with(node, "icub_strain_") && cls == ICUB_CAN_CLASS_STRAIN &&
                   (type == ICUB_CAN_STRAIN_FORCE || type == ICUB_CAN_STRAIN_TORQUE)) {
            const int half = type == ICUB_CAN_STRAIN_TORQUE;
            int ch;
            for (k = 0; k < p->n_strain && p->strain_node[k] != f->node; ++k) {
            }
            if (k == p->n_strain) {
                memset(&p->strain[k], 0, sizeof p->strain[k]);
                p->strain[k].address = address;
                p->strain_node[k] = f->node;
                ++p->n_strain;
            }
            e->board = k;
            e->kind = 10 + half;
            if (p->strain[k].address != address) NOT_ICUB("its node's other frame is another board address's");
            if (f->dlc != ICUB_CAN_STRAIN_DLC && f->dlc != ICUB_CAN_STRAIN_DLC_SAT) NOT_ICUB("length");
            /* the board's saturated form is 7 bytes: a long form of another length is not this board's (fuzzer) */
            if (f->long_dlc && f->long_dlc != ICUB_CAN_STRAIN_DLC_SAT) NOT_ICUB("long length");
            for (ch = 0; ch < 3; ++ch) { /* offset binary: (raw - 0x8000) * FS / 32768 */
                const boards_signal_t *s = signal_at(c, f, 16 * ch);
                if (!s || s->kind != BOARDS_T_VALUE || s->layout.length != 16 || s->layout.type != BUS_UNSIGNED ||
                    s->layout.offset != -s->layout.scale * 32768.0)
                    NOT_ICUB("offset-binary channels");
                p->strain[k].full_scale[3 * half + ch] = s->layout.scale * 32768.0;
                p->strain_value[k][3 * half + ch] = s->value;
            }
        } else if (starts_with(node, "icub_skin_") && cls == ICUB_CAN_CLASS_SKIN && type == ICUB_CAN_SKIN_TAXELS) {
            const boards_signal_t *s = signal_at(c, f, 0);
            if (!s || s->kind != BOARDS_T_SKIN || f->dlc != ICUB_CAN_SKIN_TAXELS_DLC) NOT_ICUB("taxels");
            if (p->n_skin == BOARDS_MAX_PATCHES) NOT_ICUB("skin boards");
            e->board = p->n_skin;
            e->kind = 20;
            p->skin_patch[p->n_skin] = s->value;
            board_skin_init(&p->skin[p->n_skin++], address);
        } else {
            NOT_ICUB("node and ID");
        }
    }
    for (k = 0; k < p->n_mc; ++k) {
        board_mc_axis_t axis[2];
        memcpy(axis, p->mc[k].axis, sizeof axis);
        if (board_mc_init(&p->mc[k], p->mc[k].address, axis) != 0) {
            snprintf(err, BOARDS_ERR_LEN, "motor-control board %u: bad ticks per degree or PWM full scale",
                     (unsigned)p->mc[k].address);
            return BOARDS_EXIT_BADDATA;
        }
    }
    for (k = 0; k < p->n_strain; ++k) {
        double fs[6];
        memcpy(fs, p->strain[k].full_scale, sizeof fs);
        if (board_strain_init(&p->strain[k], p->strain[k].address, fs, p->long_node[p->strain_node[k]]) != 0) {
            snprintf(err, BOARDS_ERR_LEN, "strain board %u: bad full scales", (unsigned)p->strain[k].address);
            return BOARDS_EXIT_BADDATA;
        }
        for (i = 0; i < c->n_frames; ++i) { /* the 7-byte variant as the only form */
            if (c->frames[i].node == p->strain_node[k] && c->frames[i].dlc == ICUB_CAN_STRAIN_DLC_SAT)
                p->strain[k].sat_variant = 1u;
        }
    }
#undef NOT_ICUB
    return 0;
}

int boards_player_init(boards_player_t *p, const boards_conf_t *c, int encoder, double mean_period_s,
                       const uint8_t long_node[BOARDS_MAX_FRAMES], char err[BOARDS_ERR_LEN])
{
    int i, k;
    memset(p, 0, sizeof *p);
    p->conf = c;
    p->encoder = encoder;
    memcpy(p->long_node, long_node, sizeof p->long_node);
    p->first_clamped = -1;
    for (i = 0; i < c->n_frames; ++i) { /* send order: by offset, ties as listed (an insertion sort: stable) */
        const int64_t off = c->frames[i].offset_us;
        for (k = i; k > 0 && c->frames[p->order[k - 1]].offset_us > off; --k) {
            p->order[k] = p->order[k - 1];
        }
        p->order[k] = i;
        p->every[i] = c->frames[i].period_us ? (long)rint((double)c->frames[i].period_us * 1e-6 / mean_period_s) : 1;
        if (p->every[i] < 1) p->every[i] = 1;
    }
    for (i = 0; i < c->n_values; ++i) {
        p->value_signal[i] = -1;
    }
    for (i = 0; i < c->n_signals; ++i) {
        if (c->signals[i].kind == BOARDS_T_VALUE) p->value_signal[c->signals[i].value] = i;
    }
    for (i = 0; i < c->n_frames; ++i) { /* skin bits and no value: the frame says only where contact is */
        int skin = 0, value = 0;
        for (k = c->frames[i].first_signal; k < c->frames[i].first_signal + c->frames[i].n_signals; ++k) {
            skin |= c->signals[k].kind == BOARDS_T_SKIN;
            value |= c->signals[k].kind == BOARDS_T_VALUE;
        }
        p->skin_only[i] = (uint8_t)(skin && !value);
    }
    return encoder == BOARDS_ENCODER_ICUB ? icub_setup(p, c, err) : 0;
}

/* The generic payload of frame i in this sample. */
static void generic_frame(boards_player_t *p, int i, const double *row, const boards_columns_t *cols,
                          board_frame_t *out)
{
    const boards_conf_t *c = p->conf;
    const boards_table_frame_t *f = &c->frames[i];
    const int use_long = f->long_dlc && p->long_node[f->node];
    int k, restart_sent = 0;
    memset(out, 0, sizeof *out);
    out->id = f->id;
    out->dlc = use_long ? f->long_dlc : f->dlc;
    for (k = f->first_signal; k < f->first_signal + f->n_signals; ++k) {
        const boards_signal_t *s = &c->signals[k];
        uint64_t raw = 0u;
        if (s->end_byte > out->dlc) continue; /* an optional signal of the short form */
        switch (s->kind) {
        case BOARDS_T_VALUE:
            raw = bus_signal_raw(&s->layout, row[cols->value[s->value]], 0);
            break;
        case BOARDS_T_SKIN:
            raw = bus_signal_raw(&s->layout, skin_on(row, cols, s->value) ? 1.0 : 0.0, 0);
            break;
        case BOARDS_T_SATURATED:
        case BOARDS_T_FAULT:
            raw = s->value >= 0 && p->clamped[s->value];
            break;
        case BOARDS_T_RESTART:
            raw = p->node_restarted[f->node];
            restart_sent = 1;
            break;
        case BOARDS_T_SEQ:
            raw = p->seq[i] & (((uint64_t)1 << s->layout.length) - 1u);
            break;
        default:
            break;
        }
        bus_signal_pack(out->data, &s->layout, raw);
    }
    ++p->seq[i];
    if (restart_sent) p->node_restarted[f->node] = 0u;
}

/* The emulators' payload of frame i (latched for this sample already). */
static void icub_frame(boards_player_t *p, int i, board_frame_t *out)
{
    const boards_icub_frame_t *e = &p->icub[i];
    switch (e->kind) {
    case ICUB_CAN_MC_POSITION: board_mc_position_frame(&p->mc[e->board], out); break;
    case ICUB_CAN_MC_PID_VAL: board_mc_pid_frame(&p->mc[e->board], out); break;
    case ICUB_CAN_MC_STATUS: board_mc_status_frame(&p->mc[e->board], out); break;
    case 10: board_strain_frame(&p->strain[e->board], BOARD_STRAIN_HALF_FORCE, out); break;
    case 11: board_strain_frame(&p->strain[e->board], BOARD_STRAIN_HALF_TORQUE, out); break;
    default: board_skin_frame(&p->skin[e->board], out); break;
    }
}

static void icub_latch(boards_player_t *p, const double *row, const boards_columns_t *cols)
{
    int k, s, ch;
    for (k = 0; k < p->n_mc; ++k) {
        double q[2] = {0.0, 0.0}, duty[2] = {0.0, 0.0};
        for (s = 0; s < 2; ++s) {
            if (p->mc_value[k][s][0] >= 0) q[s] = row[cols->value[p->mc_value[k][s][0]]];
            if (p->mc_value[k][s][1] >= 0) duty[s] = row[cols->value[p->mc_value[k][s][1]]];
        }
        board_mc_sample(&p->mc[k], q, duty);
    }
    for (k = 0; k < p->n_strain; ++k) {
        double w[6];
        for (ch = 0; ch < 6; ++ch) {
            w[ch] = row[cols->value[p->strain_value[k][ch]]];
        }
        board_strain_sample(&p->strain[k], w); /* finite: the CSV reader refuses NaN */
    }
    for (k = 0; k < p->n_skin; ++k) {
        board_skin_sample(&p->skin[k], (uint16_t)(skin_on(row, cols, p->skin_patch[k]) ? 1u : 0u));
    }
}

int boards_player_sample(boards_player_t *p, const double *row, const boards_columns_t *cols, int64_t t_us,
                         const int *restart, int n_restart, boards_emit_fn emit, void *ctx)
{
    const boards_conf_t *c = p->conf;
    board_frame_t f;
    int i, k, rc;
    for (k = 0; k < n_restart; ++k) { /* a reset: counters restart, the next frame with a restart flag carries it */
        const int node = restart[k];
        p->node_periods[node] = 0u;
        p->node_restarted[node] = 1u;
        for (i = 0; i < c->n_frames; ++i) {
            if (c->frames[i].node == node) p->seq[i] = 0u;
        }
        for (i = 0; i < p->n_mc; ++i) {
            if (p->encoder == BOARDS_ENCODER_ICUB && p->mc_node[i] == node) board_mc_restart(&p->mc[i]);
        }
    }
    for (i = 0; i < c->n_nodes; ++i) {
        ++p->node_periods[i];
    }
    for (i = 0; i < c->n_values; ++i) { /* which values clamp in this sample (their flags, wherever they are) */
        uint8_t clamped = 0u;
        (void)bus_signal_raw(&c->signals[p->value_signal[i]].layout, row[cols->value[i]], &clamped);
        p->clamped[i] = clamped;
        if (clamped && p->n_clamped++ == 0u) p->first_clamped = i;
    }
    ++p->samples;
    if (p->encoder == BOARDS_ENCODER_ICUB) icub_latch(p, row, cols);
    for (k = 0; k < c->n_frames; ++k) {
        const int i2 = p->order[k];
        const boards_table_frame_t *fr = &c->frames[i2];
        if ((p->node_periods[fr->node] - 1u) % (uint64_t)p->every[i2] != 0u) continue;
        /* A run without a contact column knows nothing of contact: its skin frames are not sent, so that what reads
         * the log finds no contact ground truth (dynid.io.candump), rather than "no contact" everywhere. */
        if (cols->contact < 0 && p->skin_only[i2]) continue;
        if (p->encoder == BOARDS_ENCODER_ICUB) icub_frame(p, i2, &f);
        else generic_frame(p, i2, row, cols, &f);
        if ((rc = emit(ctx, fr->bus, &f, t_us + fr->offset_us)) != 0) return rc;
    }
    return 0;
}
