/*
 * A plugin that misbehaves with the process (tests/it/hardening3.rs), by its `mode` parameter:
 *   mode 1: exit(0) at the first sample with t >= at_s (a run must never look finished);
 *   mode 2: exit(0) in exoleg_create;
 *   mode 3: chdir("/") at every sample (the outputs must not move);
 *   mode 4: a message full of control characters with the warning status at every sample.
 * With EXOLEG_TEST_CHDIR set, it also changes the working directory to that folder when it
 * is loaded (a constructor). Otherwise a P law u = 1e-6 (F_d - F). Test-only.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exoleg_controller.h"

typedef struct {
    int mode;
    double at_s;
} Rogue;

__attribute__((constructor)) static void on_load(void) {
    const char *dir = getenv("EXOLEG_TEST_CHDIR");
    if (dir != NULL && chdir(dir) != 0) {
        abort();
    }
}

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }

void *exoleg_create(const ExolegInfo *info) {
    Rogue *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    c->at_s = 0.005;
    for (uint32_t i = 0; i < info->n_params; i++) {
        if (strcmp(info->params[i].name, "mode") == 0) c->mode = (int)info->params[i].value;
        if (strcmp(info->params[i].name, "at_s") == 0) c->at_s = info->params[i].value;
    }
    if (c->mode == 2) {
        exit(0);
    }
    return c;
}

int32_t exoleg_reset(void *instance) {
    (void)instance;
    return EXOLEG_OK;
}

int32_t exoleg_step(void *instance, const ExolegReadings *y, ExolegCommand *cmd) {
    const Rogue *c = instance;
    cmd->valve_command = 1e-6 * (y->ref_force_n - y->force_n);
    if (c->mode == 1 && y->t_s >= c->at_s) {
        exit(0);
    }
    if (c->mode == 3 && chdir("/") != 0) {
        return EXOLEG_STOP;
    }
    if (c->mode == 4) {
        snprintf(cmd->message, sizeof cmd->message, "bad\n\x1b[2Jline\rtwo\a");
        return EXOLEG_WARNING;
    }
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) { free(instance); }
