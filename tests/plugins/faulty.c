/*
 * A test plugin whose behaviour the parameters choose (tests/it/your_controller.rs):
 *   mode 0: a P law u = gain (F_d - F) with gain (default 1e-6);
 *   mode 1: the same, and the stop status from t >= at_s (default 0.05);
 *   mode 2: the same, and a NaN command from t >= at_s;
 *   mode 3: refuses its parameters (exoleg_create returns NULL);
 *   mode 4: the warning status at every sample.
 * With EXOLEG_TEST_COUNTS set, every create and destroy appends a line "c" or "d" to that
 * file (counting instances across a sweep). Test-only: a real plugin keeps no such global.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exoleg_controller.h"

typedef struct {
    int mode;
    double gain, at_s;
} Faulty;

static void count(const char *what) {
    const char *path = getenv("EXOLEG_TEST_COUNTS");
    if (path == NULL) {
        return;
    }
    FILE *f = fopen(path, "a");
    if (f != NULL) {
        fputs(what, f);
        fclose(f);
    }
}

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }

void *exoleg_create(const ExolegInfo *info) {
    Faulty *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    c->gain = 1e-6;
    c->at_s = 0.05;
    for (uint32_t i = 0; i < info->n_params; i++) {
        if (strcmp(info->params[i].name, "mode") == 0) c->mode = (int)info->params[i].value;
        if (strcmp(info->params[i].name, "gain") == 0) c->gain = info->params[i].value;
        if (strcmp(info->params[i].name, "at_s") == 0) c->at_s = info->params[i].value;
    }
    if (c->mode == 3) {
        free(c);
        return NULL;
    }
    count("c\n");
    return c;
}

int32_t exoleg_reset(void *instance) {
    (void)instance;
    return EXOLEG_OK;
}

int32_t exoleg_step(void *instance, const ExolegReadings *y, ExolegCommand *cmd) {
    const Faulty *c = instance;
    cmd->valve_command = c->gain * (y->ref_force_n - y->force_n);
    cmd->log[0] = (double)y->counts[EXOLEG_CH_FORCE];
    cmd->log[1] = (double)(y->counts_valid & 1u);
    if (c->mode == 1 && y->t_s >= c->at_s) {
        snprintf(cmd->message, sizeof cmd->message, "pressure sensor fault at %.3f s", y->t_s);
        return EXOLEG_STOP;
    }
    if (c->mode == 2 && y->t_s >= c->at_s) {
        cmd->valve_command = NAN;
    }
    if (c->mode == 4) {
        snprintf(cmd->message, sizeof cmd->message, "warned at %.3f s", y->t_s);
        return EXOLEG_WARNING;
    }
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) {
    count("d\n");
    free(instance);
}
