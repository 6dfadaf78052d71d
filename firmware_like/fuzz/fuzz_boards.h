/*
 * fuzz_boards.h - shared by the boards program's harnesses: the player set up from a configuration's bus table and
 * played one sample, every frame it sends checked against the table (a frame the boards send is one the monitor
 * reads: its ID is the table's on that bus, its length the frame's or its long form's, and its bits decode back to
 * what was packed). Static buffers only (C99, no heap).
 */
#ifndef FUZZ_BOARDS_H
#define FUZZ_BOARDS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boards_tool.h"

#define FUZZ_CHECK(cond) do { if (!(cond)) abort(); } while (0)

/* An emitted frame: the table's, at a sane length, its signals each within its raw range. */
static int fuzz_boards_check_frame(void *ctx, int bus, const board_frame_t *f, int64_t t_us)
{
    const boards_conf_t *c = (const boards_conf_t *)ctx;
    int i, k, found = -1;
    (void)t_us;
    FUZZ_CHECK(bus >= 0 && bus < c->n_buses);
    for (i = 0; i < c->n_frames; ++i) {
        if (c->frames[i].bus == bus && c->frames[i].id == f->id) found = i;
    }
    FUZZ_CHECK(found >= 0);
    FUZZ_CHECK(f->dlc == c->frames[found].dlc || (c->frames[found].long_dlc && f->dlc == c->frames[found].long_dlc));
    for (k = c->frames[found].first_signal; k < c->frames[found].first_signal + c->frames[found].n_signals; ++k) {
        const boards_signal_t *s = &c->signals[k];
        if (s->end_byte <= f->dlc && s->layout.length < 64) {
            FUZZ_CHECK(bus_signal_unpack(f->data, &s->layout) < ((uint64_t)1 << s->layout.length));
        }
    }
    return 0;
}

/* fmemopen over a copy of the input (fmemopen wants a writable buffer; a zero size is not portable). */
static FILE *fuzz_boards_open(const uint8_t *data, size_t size)
{
    static char buf[1L << 20];
    if (size > sizeof buf) {
        return 0;
    }
    memcpy(buf, data, size);
    return fmemopen(buf, size ? size : 1, "r");
}

#endif /* FUZZ_BOARDS_H */
