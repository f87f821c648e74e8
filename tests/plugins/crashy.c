/*
 * A test plugin that misbehaves on purpose (tests/it/isolation.rs): a P law u = gain (F_d - F)
 * (gain default 1e-6) until t >= at_s (default 0.005 s), then, by `crash`:
 *   0 nothing, 1 a segmentation fault, 2 abort(), 3 exit(7), 4 an endless loop.
 * With `crash_gain` set, it misbehaves only in the run whose `gain` equals it (a sweep with one
 * bad run). Test-only.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "exoleg_controller.h"

typedef struct {
    int crash, only_if;
    double gain, at_s, crash_gain;
} Crashy;

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
    }
    return c;
}

int32_t exoleg_reset(void *instance) {
    (void)instance;
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
            for (volatile unsigned long i = 0;; i++) {
            }
        default:
            break;
        }
    }
    double fd = isnan(r->ref_force_n) ? 0.0 : r->ref_force_n;
    cmd->valve_command = c->gain * (fd - r->force_n);
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) { free(instance); }
