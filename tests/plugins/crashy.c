/*
 * A test plugin that misbehaves on purpose (tests/it/isolation.rs, hardening4_link.rs): a P law
 * u = gain (F_d - F) (gain default 1e-6) until t >= at_s (default 0.005 s), then, by `crash`:
 *   0 nothing, 1 a segmentation fault, 2 abort(), 3 exit(7), 4 an endless loop,
 *   5 a leak (64 MiB more at every sample, touched; a failed allocation segfaults),
 *   6 raise(SIGSEGV) once and go on (a firmware fault handler's way),
 *   7 fork() once: the grandchild sleeps 30 s (it holds the socket), the step goes on,
 *   8 fork() as 7, then a segmentation fault,
 *   9 an endless loop in exoleg_reset, 10 an endless loop in exoleg_create,
 *   11 the stop status with the message "overpressure".
 * With `crash_gain` set, it misbehaves only in the run whose `gain` equals it (a sweep with one
 * bad run). `busy_us` spins that long in every step (a run that lasts). Test-only.
 */
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "exoleg_controller.h"

typedef struct {
    int crash, only_if, done;
    double gain, at_s, crash_gain, busy_us;
} Crashy;

static void spin_forever(void) {
    for (volatile unsigned long i = 0;; i++) {
    }
}

static void busy(double us) {
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    do {
        clock_gettime(CLOCK_MONOTONIC, &b);
    } while ((b.tv_sec - a.tv_sec) * 1e6 + (b.tv_nsec - a.tv_nsec) * 1e-3 < us);
}

static void fork_sleeper(void) {
    pid_t p = fork();
    if (p == 0) {
        sleep(30);
        _exit(0);
    }
}

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }

void *exoleg_create(const ExolegInfo *info) {
    Crashy *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    c->gain = 1e-6;
    c->at_s = 0.005;
    for (uint32_t i = 0; i < info->n_params; i++) {
        const char *n = info->params[i].name;
        double v = info->params[i].value;
        if (strcmp(n, "crash") == 0) c->crash = (int)v;
        if (strcmp(n, "gain") == 0) c->gain = v;
        if (strcmp(n, "at_s") == 0) c->at_s = v;
        if (strcmp(n, "crash_gain") == 0) {
            c->crash_gain = v;
            c->only_if = 1;
        }
        if (strcmp(n, "busy_us") == 0) c->busy_us = v;
    }
    if (c->crash == 10) spin_forever();
    return c;
}

int32_t exoleg_reset(void *instance) {
    Crashy *c = instance;
    if (c->crash == 9) spin_forever();
    return EXOLEG_OK;
}

int32_t exoleg_step(void *instance, const ExolegReadings *r, ExolegCommand *cmd) {
    Crashy *c = instance;
    int armed = r->t_s >= c->at_s && (!c->only_if || c->gain == c->crash_gain);
    if (armed) {
        switch (c->crash) {
        case 1: {
            volatile int *p = NULL;
            *p = 1;
            break;
        }
        case 2:
            abort();
        case 3:
            exit(7);
        case 4:
            spin_forever();
            break;
        case 5: {
            size_t n = (size_t)64 << 20;
            volatile char *p = malloc(n);
            for (size_t i = 0; i < n; i += 4096) p[i] = 1;
            break;
        }
        case 6:
            if (!c->done) raise(SIGSEGV);
            break;
        case 7:
            if (!c->done) fork_sleeper();
            break;
        case 8: {
            fork_sleeper();
            volatile int *p = NULL;
            *p = 1;
            break;
        }
        case 11:
            strncpy(cmd->message, "overpressure", sizeof cmd->message - 1);
            return EXOLEG_STOP;
        default:
            break;
        }
        c->done = 1;
    }
    if (c->busy_us > 0) busy(c->busy_us);
    double fd = isnan(r->ref_force_n) ? 0.0 : r->ref_force_n;
    cmd->valve_command = c->gain * (fd - r->force_n);
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) { free(instance); }
