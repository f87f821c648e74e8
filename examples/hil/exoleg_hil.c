/*
 * exoleg_hil.c: a controller peer of exoleg over UDP (see include/exoleg_hil.h). libc and
 * POSIX sockets only; little-endian targets (the structs go on the wire as they lie in memory).
 *
 * Build with any plugin source:
 *   cc -O2 -ffp-contract=off -I include -o hil_erl_smc examples/hil/hil_client.c \
 *      examples/hil/exoleg_hil.c examples/c_controller/erl_smc.c -lm
 */
#define _POSIX_C_SOURCE 200809L
#include "exoleg_hil.h"

#include <errno.h>
#include <netdb.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#define MAX_PARAMS 256
#define MESSAGE_LEN 160

uint64_t exoleg_hil_channel_hash(void) {
    const char *s = EXOLEG_HIL_CHANNELS;
    uint64_t h = 0xcbf29ce484222325ull;
    for (; *s; s++) {
        h ^= (uint8_t)*s;
        h *= 0x100000001b3ull;
    }
    return h;
}

/* The session's state: the socket, the buffers, the knobs' generator. */
typedef struct {
    int fd;
    uint8_t in[EXOLEG_HIL_MAX_DATAGRAM + 1];
    uint8_t out[EXOLEG_HIL_HEADER_LEN + 16 + sizeof(ExolegCommand)];
    size_t out_len;
    uint64_t rng;
    char *err;
    size_t err_len;
} Peer;

static int fail(Peer *p, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    if (p->err != NULL && p->err_len > 0) vsnprintf(p->err, p->err_len, fmt, ap);
    va_end(ap);
    return -1;
}

static double uniform(Peer *p) { /* xorshift64*: [0, 1) */
    p->rng ^= p->rng >> 12;
    p->rng ^= p->rng << 25;
    p->rng ^= p->rng >> 27;
    return (double)((p->rng * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

static uint64_t now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

static size_t header(uint8_t *b, uint16_t type, uint64_t seq, uint64_t sim_time_ns) {
    uint32_t magic = EXOLEG_HIL_MAGIC;
    uint16_t version = EXOLEG_HIL_VERSION;
    memcpy(b, &magic, 4);
    memcpy(b + 4, &version, 2);
    memcpy(b + 6, &type, 2);
    memcpy(b + 8, &seq, 8);
    memcpy(b + 16, &sim_time_ns, 8);
    return EXOLEG_HIL_HEADER_LEN;
}

static int send_ready(Peer *p, int32_t status, const char *message) {
    uint8_t b[EXOLEG_HIL_HEADER_LEN + 8 + MESSAGE_LEN] = {0};
    size_t n = header(b, EXOLEG_HIL_READY, 0, 0);
    memcpy(b + n, &status, 4);
    strncpy((char *)b + n + 8, message, MESSAGE_LEN - 1);
    return send(p->fd, b, sizeof b, 0) == (ssize_t)sizeof b ? 0 : fail(p, "send READY: %s", strerror(errno));
}

/* The next datagram (its length), or -1 after timeout_s. A receive interrupted by a stop and
 * continue of this process (Ctrl-Z, a debugger: EINTR) is retried with the time left. */
static ssize_t receive(Peer *p, double timeout_s) {
    uint64_t end = now_ns() + (uint64_t)(timeout_s * 1e9);
    for (;;) {
        uint64_t now = now_ns();
        double left = now < end ? (double)(end - now) * 1e-9 : 1e-6;
        struct timeval tv = {(time_t)left, (suseconds_t)((left - (double)(time_t)left) * 1e6)};
        if (tv.tv_sec == 0 && tv.tv_usec == 0) tv.tv_usec = 1;
        setsockopt(p->fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        ssize_t r = recv(p->fd, p->in, sizeof p->in, 0);
        if (r >= 0 || errno != EINTR) return r;
        if (now_ns() >= end) {
            errno = EAGAIN;
            return -1;
        }
    }
}

/* The header of the datagram in p->in (type, seq, time), 0 if it is one of ours. */
static int parse_header(const Peer *p, ssize_t n, uint16_t *type, uint64_t *seq, uint64_t *t_ns) {
    uint32_t magic;
    uint16_t version;
    if (n < EXOLEG_HIL_HEADER_LEN) return -1;
    memcpy(&magic, p->in, 4);
    memcpy(&version, p->in + 4, 2);
    memcpy(type, p->in + 6, 2);
    memcpy(seq, p->in + 8, 8);
    memcpy(t_ns, p->in + 16, 8);
    return magic == EXOLEG_HIL_MAGIC && version == EXOLEG_HIL_VERSION ? 0 : -1;
}

/* Connect to host:port. */
static int open_socket(Peer *p, const char *host, const char *port) {
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    int e = getaddrinfo(host, port, &hints, &res);
    if (e != 0) return fail(p, "%s:%s: %s", host, port, gai_strerror(e));
    p->fd = socket(res->ai_family, res->ai_socktype, res->ai_protocol);
    if (p->fd < 0 || connect(p->fd, res->ai_addr, res->ai_addrlen) != 0) {
        freeaddrinfo(res);
        return fail(p, "connect %s:%s: %s", host, port, strerror(errno));
    }
    freeaddrinfo(res);
    return 0;
}

/* HELLO until SETUP comes; fills info, the parameters and their names. */
static int handshake(Peer *p, double timeout_s, ExolegInfo *info, ExolegParam *params, char names[][256]) {
    uint8_t hello[EXOLEG_HIL_HEADER_LEN + 16] = {0};
    size_t n = header(hello, EXOLEG_HIL_HELLO, 0, 0);
    uint32_t abi = EXOLEG_ABI_VERSION;
    uint64_t hash = exoleg_hil_channel_hash();
    memcpy(hello + n, &abi, 4);
    memcpy(hello + n + 8, &hash, 8);
    uint64_t t0 = now_ns();
    for (;;) {
        if ((double)(now_ns() - t0) * 1e-9 > timeout_s) return fail(p, "no SETUP from exoleg in %g s", timeout_s);
        send(p->fd, hello, sizeof hello, 0);
        ssize_t got = receive(p, 0.2);
        if (got < 0 && errno == ECONNREFUSED) { /* exoleg not listening yet */
            struct timespec ts = {0, 200000000L};
            nanosleep(&ts, NULL);
            continue;
        }
        uint16_t type;
        uint64_t seq, t_ns;
        if (got < 0 || parse_header(p, got, &type, &seq, &t_ns) != 0) continue;
        const uint8_t *b = p->in + EXOLEG_HIL_HEADER_LEN;
        size_t len = (size_t)got - EXOLEG_HIL_HEADER_LEN;
        if (type == EXOLEG_HIL_REFUSE && len >= 8 + MESSAGE_LEN) {
            return fail(p, "exoleg refused: %.*s", MESSAGE_LEN, (const char *)b + 8);
        }
        if (type != EXOLEG_HIL_SETUP || len < 80) continue;
        uint32_t n_params;
        memcpy(&n_params, b + 4, 4);
        if (n_params > MAX_PARAMS) return fail(p, "SETUP: %u parameters", n_params);
        memset(info, 0, sizeof *info);
        info->size = sizeof *info;
        info->abi_version = EXOLEG_ABI_VERSION;
        memcpy(&info->sample_period_s, b + 16, 8);
        memcpy(&info->valve_command_limit, b + 24, 8);
        memcpy(&info->nominal_n1, b + 32, 8);
        memcpy(&info->nominal_n2, b + 40, 8);
        memcpy(&info->nominal_n3, b + 48, 8);
        memcpy(&info->nominal_tau_s, b + 56, 8);
        memcpy(&info->nominal_k_s, b + 64, 8);
        memcpy(&info->seed, b + 72, 8);
        size_t at = 80;
        for (uint32_t i = 0; i < n_params; i++) {
            uint16_t name_len;
            if (at + 2 > len) return fail(p, "SETUP: truncated");
            memcpy(&name_len, b + at, 2);
            if (name_len > 255 || at + 2 + name_len + 8 > len) return fail(p, "SETUP: truncated");
            memcpy(names[i], b + at + 2, name_len);
            names[i][name_len] = 0;
            memcpy(&params[i].value, b + at + 2 + name_len, 8);
            params[i].name = names[i];
            at += 2 + name_len + 8;
        }
        info->n_params = n_params;
        info->params = params;
        return 0;
    }
}

/* The COMMAND of one sample into p->out (the step made here, timed). */
static void answer(Peer *p, const ExolegHilPlugin *pl, void *inst, int *reset, uint64_t seq, uint64_t t_ns) {
    ExolegReadings r;
    ExolegCommand c;
    memcpy(&r, p->in + EXOLEG_HIL_HEADER_LEN, sizeof r);
    memset(&c, 0, sizeof c);
    c.size = sizeof c;
    int32_t status = EXOLEG_OK;
    uint32_t call = 0;
    if (!*reset) {
        *reset = 1;
        status = pl->reset(inst);
        call = 1;
    }
    uint64_t t0 = now_ns();
    if (status == EXOLEG_OK || status == EXOLEG_WARNING) {
        status = pl->step(inst, &r, &c);
        call = 0;
    }
    uint64_t compute_ns = now_ns() - t0;
    size_t n = header(p->out, EXOLEG_HIL_COMMAND, seq, t_ns);
    memcpy(p->out + n, &status, 4);
    memcpy(p->out + n + 4, &call, 4);
    memcpy(p->out + n + 8, &compute_ns, 8);
    memcpy(p->out + n + 16, &c, sizeof c);
    p->out_len = n + 16 + sizeof c;
}

/* Answer READINGS until BYE. */
static int serve(Peer *p, const ExolegHilPlugin *pl, void *inst, const ExolegHilOptions *o, ExolegHilStats *st) {
    int reset = 0, answered = 0;
    uint64_t last_seq = 0;
    double timeout_s = o->timeout_s > 0 ? o->timeout_s : 30.0;
    for (;;) {
        ssize_t got = receive(p, timeout_s);
        if (got < 0) return fail(p, "no message from exoleg in %g s (%s)", timeout_s, strerror(errno));
        uint16_t type;
        uint64_t seq, t_ns;
        if (parse_header(p, got, &type, &seq, &t_ns) != 0) {
            st->malformed++;
            continue;
        }
        if (type == EXOLEG_HIL_BYE) return 0;
        if (type != EXOLEG_HIL_READINGS || (size_t)got != EXOLEG_HIL_HEADER_LEN + sizeof(ExolegReadings)) {
            st->malformed++;
            continue;
        }
        if (answered && seq == last_seq) { /* a resend: the same answer, no second step */
            st->repeats++;
            send(p->fd, p->out, p->out_len, 0);
            continue;
        }
        st->samples++;
        answer(p, pl, inst, &reset, seq, t_ns);
        answered = 1;
        last_seq = seq;
        if (o->sleep_probability > 0 && uniform(p) < o->sleep_probability) {
            double s = uniform(p) * o->sleep_max_s;
            struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
            nanosleep(&ts, NULL);
            st->slept++;
        }
        if (o->drop_probability > 0 && uniform(p) < o->drop_probability) {
            st->dropped++;
            continue;
        }
        send(p->fd, p->out, p->out_len, 0);
    }
}

int exoleg_hil_run(const char *host, const char *port, const ExolegHilPlugin *plugin,
                   const ExolegHilOptions *options, ExolegHilStats *stats, char *err, size_t err_len) {
    static char names[MAX_PARAMS][256];
    ExolegParam params[MAX_PARAMS];
    ExolegHilOptions none = {0};
    const ExolegHilOptions *o = options != NULL ? options : &none;
    ExolegHilStats st_none;
    ExolegHilStats *st = stats != NULL ? stats : &st_none;
    memset(st, 0, sizeof *st);
    Peer *p = calloc(1, sizeof *p);
    if (p == NULL) return -1;
    p->err = err;
    p->err_len = err_len;
    p->rng = o->seed != 0 ? o->seed : 0x9E3779B97F4A7C15ull;
    p->fd = -1;
    int r = open_socket(p, host, port);
    ExolegInfo info;
    if (r == 0) r = handshake(p, o->timeout_s > 0 ? o->timeout_s : 30.0, &info, params, names);
    if (r == 0) {
        void *inst = plugin->create(&info);
        if (inst == NULL) {
            send_ready(p, EXOLEG_STOP, "exoleg_create returned NULL (it refused its parameters)");
            r = fail(p, "exoleg_create returned NULL");
        } else {
            r = send_ready(p, EXOLEG_OK, "");
            if (r == 0) r = serve(p, plugin, inst, o, st);
            plugin->destroy(inst);
        }
    }
    if (p->fd >= 0) close(p->fd);
    free(p);
    return r;
}
