/* boards_sink.c - where the boards' frames go: a candump -L log, the loopback transport, or SocketCAN. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <linux/can.h>
#include <net/if.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "boards_tool.h"

enum { SINK_CANDUMP = 1, SINK_LOOPBACK, SINK_SOCKETCAN };

static void to_can_frame(const board_frame_t *f, struct can_frame *cf)
{
    memset(cf, 0, sizeof *cf);
    cf->can_id = f->id;
    cf->can_dlc = f->dlc;
    memcpy(cf->data, f->data, f->dlc);
}

int boards_sink_open(boards_sink_t *s, const char *spec, const boards_conf_t *c, char err[BOARDS_ERR_LEN])
{
    int i;
    memset(s, 0, sizeof *s);
    s->fd = -1;
    s->conf = c;
    for (i = 0; i < BOARDS_MAX_BUSES; ++i) {
        s->can_fd[i] = -1;
    }
    if (strncmp(spec, "candump:", 8) == 0) {
        int fd;
        const char *path = spec + 8;
        if (!*path || strlen(path) + 16 >= sizeof s->path) {
            snprintf(err, BOARDS_ERR_LEN, "--sink candump:PATH needs a path");
            return BOARDS_EXIT_USAGE;
        }
        strcpy(s->path, path);
        if (strcmp(path, "-") == 0) { /* standard output, streamed: nothing to rename (a pipe into a monitor) */
            s->f = stdout;
            s->to_stdout = 1;
            s->kind = SINK_CANDUMP;
            return 0;
        }
        snprintf(s->tmp, sizeof s->tmp, "%s.XXXXXX", path); /* written beside, renamed into place: atomic */
        fd = mkstemp(s->tmp);
        if (fd < 0 || !(s->f = fdopen(fd, "w"))) {
            snprintf(err, BOARDS_ERR_LEN, "%s: cannot write: %s", path, strerror(errno));
            if (fd >= 0) {
                close(fd);
                unlink(s->tmp);
            }
            return BOARDS_EXIT_SINK;
        }
        s->kind = SINK_CANDUMP;
        return 0;
    }
    if (strncmp(spec, "loopback:", 9) == 0) {
        const char *dir = spec + 9;
        for (i = 0; i < c->n_buses; ++i) {
            /* the monitor's LoopbackSource binds <dir>/<bus>.can (rt_monitor/include/rt_monitor/frame_source.hpp) */
            memset(&s->dest[i], 0, sizeof s->dest[i]);
            s->dest[i].sun_family = AF_UNIX;
            if ((size_t)snprintf(s->dest[i].sun_path, sizeof s->dest[i].sun_path, "%s/%s.can", dir, c->buses[i]) >=
                sizeof s->dest[i].sun_path) {
                snprintf(err, BOARDS_ERR_LEN, "loopback directory too long for a socket path: %s", dir);
                return BOARDS_EXIT_USAGE;
            }
        }
        s->fd = socket(AF_UNIX, SOCK_DGRAM, 0);
        if (s->fd < 0) {
            snprintf(err, BOARDS_ERR_LEN, "loopback: socket(AF_UNIX): %s", strerror(errno));
            return BOARDS_EXIT_SINK;
        }
        s->kind = SINK_LOOPBACK;
        return 0;
    }
    if (strcmp(spec, "socketcan") == 0) {
        static char scratch[BOARDS_ERR_LEN];
        for (i = 0; i < c->n_buses; ++i) {
            struct sockaddr_can a;
            struct ifreq ifr;
            s->can_fd[i] = socket(PF_CAN, SOCK_RAW, CAN_RAW);
            if (s->can_fd[i] < 0) {
                snprintf(err, BOARDS_ERR_LEN, "socketcan: socket(PF_CAN, SOCK_RAW, CAN_RAW): %s%s", strerror(errno),
                         errno == EAFNOSUPPORT ? " (this kernel has no AF_CAN)" : "");
                boards_sink_close(s, 0, scratch); /* closes the sockets opened so far */
                return BOARDS_EXIT_SINK;
            }
            memset(&ifr, 0, sizeof ifr);
            memset(&a, 0, sizeof a);
            strncpy(ifr.ifr_name, c->buses[i], IFNAMSIZ - 1);
            a.can_family = AF_CAN;
            a.can_ifindex = (int)if_nametoindex(c->buses[i]);
            if (a.can_ifindex == 0 || bind(s->can_fd[i], (struct sockaddr *)&a, sizeof a) != 0) {
                snprintf(err, BOARDS_ERR_LEN, "socketcan: interface %s: %s", c->buses[i],
                         a.can_ifindex == 0 ? "no such interface" : strerror(errno));
                s->kind = SINK_SOCKETCAN;
                boards_sink_close(s, 0, scratch);
                return BOARDS_EXIT_SINK;
            }
        }
        s->kind = SINK_SOCKETCAN;
        return 0;
    }
    snprintf(err, BOARDS_ERR_LEN, "unknown sink '%s' (candump:PATH, loopback:DIR or socketcan)", spec);
    return BOARDS_EXIT_USAGE;
}

int boards_sink_send(boards_sink_t *s, int bus, const board_frame_t *f, int64_t t_us, char err[BOARDS_ERR_LEN])
{
    struct can_frame cf;
    if (s->kind == SINK_CANDUMP) {
        char hex[17];
        uint8_t i;
        static const char digits[] = "0123456789ABCDEF";
        for (i = 0u; i < f->dlc; ++i) {
            hex[2 * i] = digits[f->data[i] >> 4];
            hex[2 * i + 1] = digits[f->data[i] & 0xFu];
        }
        hex[2 * f->dlc] = '\0';
        if (fprintf(s->f, "(%lld.%06lld) %s %03X#%s\n", (long long)(t_us / 1000000), (long long)(t_us % 1000000),
                    s->conf->buses[bus], (unsigned)f->id, hex) < 0) {
            snprintf(err, BOARDS_ERR_LEN, "%.400s: write failed: %s", s->path, strerror(errno));
            return BOARDS_EXIT_SINK;
        }
    } else if (s->kind == SINK_LOOPBACK) {
        to_can_frame(f, &cf);
        /* Blocking: a full receive queue makes the boards wait for the monitor instead of dropping frames. */
        if (sendto(s->fd, &cf, sizeof cf, 0, (const struct sockaddr *)&s->dest[bus], sizeof s->dest[bus]) !=
            (ssize_t)sizeof cf) {
            snprintf(err, BOARDS_ERR_LEN, "loopback: %s: %s%s", s->dest[bus].sun_path, strerror(errno),
                     (errno == ENOENT || errno == ECONNREFUSED) ? " (is rt_monitor --loopback running?)" : "");
            return BOARDS_EXIT_SINK;
        }
    } else {
        to_can_frame(f, &cf);
        if (write(s->can_fd[bus], &cf, sizeof cf) != (ssize_t)sizeof cf) {
            snprintf(err, BOARDS_ERR_LEN, "socketcan: %s: %s", s->conf->buses[bus], strerror(errno));
            return BOARDS_EXIT_SINK;
        }
    }
    (void)t_us;
    ++s->sent;
    return 0;
}

int boards_sink_close(boards_sink_t *s, int ok, char err[BOARDS_ERR_LEN])
{
    int i, rc = 0;
    if (s->kind == SINK_CANDUMP && s->f && s->to_stdout) {
        if (fflush(s->f) != 0 || ferror(s->f)) {
            rc = BOARDS_EXIT_SINK;
            snprintf(err, BOARDS_ERR_LEN, "standard output: write failed: %s", strerror(errno));
        }
        s->f = 0;
    } else if (s->kind == SINK_CANDUMP && s->f) {
        if (fclose(s->f) != 0) {
            ok = 0;
            rc = BOARDS_EXIT_SINK;
            snprintf(err, BOARDS_ERR_LEN, "%.400s: write failed: %s", s->path, strerror(errno));
        }
        s->f = 0;
        if (ok) {
            const mode_t mask = umask(0);
            umask(mask);
            chmod(s->tmp, 0666 & ~mask); /* mkstemp's 0600 is not what a log should be */
            if (rename(s->tmp, s->path) != 0) {
                rc = BOARDS_EXIT_SINK;
                snprintf(err, BOARDS_ERR_LEN, "%.400s: %s", s->path, strerror(errno));
            }
        }
        if (!ok || rc) {
            unlink(s->tmp);
        }
    }
    if (s->fd >= 0) {
        close(s->fd);
        s->fd = -1;
    }
    for (i = 0; i < BOARDS_MAX_BUSES; ++i) {
        if (s->can_fd[i] >= 0) {
            close(s->can_fd[i]);
            s->can_fd[i] = -1;
        }
    }
    return rc;
}
