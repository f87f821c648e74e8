/*
 * ERL-SMC (the paper's baseline, Eq. 50) as a firmware controller plugin for exoleg.
 *
 *   e = F_d - F,  s = e_dot + delta e,  u = tau/(n1 k_s) [F_d'' + delta e_dot + k s
 *       + zeta tanh(s) + n3 F' + n2 a + n1 x_v / tau]
 *
 * the same law, written in the same order, as exoleg's built-in `erl_smc` run sampled, so
 * the two give bit-identical time series. Parameters (controller.plugin.params): k (1/s),
 * delta (1/s), zeta (N/s^2); defaults 100, 15, 10 as the built-in's.
 *
 * Build:  cc -O2 -fPIC -shared -ffp-contract=off -I include \
 *            -o target/libexoleg_erl_smc.so examples/c_controller/erl_smc.c -lm
 * Run:    exoleg run assets/scenarios/paper_2hz_gamma100.toml \
 *            --set controller.kind='"plugin"' --set controller.sample_period_s=0.001 \
 *            --set controller.plugin.library='"target/libexoleg_erl_smc.so"' \
 *            --set 'controller.plugin.params={k=100.0, delta=15.0, zeta=10.0}'
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exoleg_controller.h"

typedef struct {
    double k, delta, zeta;             /* the law's gains */
    double n1, n2, n3, tau, ks, limit; /* the nominal model, from the host */
} ErlSmc;

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }

void *exoleg_create(const ExolegInfo *info) {
    if (info == NULL || info->size < sizeof(ExolegInfo)) {
        return NULL; /* an older host than this plugin was built for */
    }
    ErlSmc *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    c->k = 100.0;
    c->delta = 15.0;
    c->zeta = 10.0;
    for (uint32_t i = 0; i < info->n_params; i++) {
        const ExolegParam *p = &info->params[i];
        if (strcmp(p->name, "k") == 0) {
            c->k = p->value;
        } else if (strcmp(p->name, "delta") == 0) {
            c->delta = p->value;
        } else if (strcmp(p->name, "zeta") == 0) {
            c->zeta = p->value;
        } else {
            free(c); /* an unknown parameter is a mistake: refuse it */
            return NULL;
        }
    }
    c->n1 = info->nominal_n1;
    c->n2 = info->nominal_n2;
    c->n3 = info->nominal_n3;
    c->tau = info->nominal_tau_s;
    c->ks = info->nominal_k_s;
    c->limit = info->valve_command_limit;
    return c;
}

int32_t exoleg_reset(void *instance) {
    (void)instance; /* no state */
    return EXOLEG_OK;
}

int32_t exoleg_step(void *instance, const ExolegReadings *y, ExolegCommand *cmd) {
    const ErlSmc *c = instance;
    double e = y->ref_force_n - y->force_n;
    double e_dot = y->ref_force_rate_n_per_s - y->force_rate_n_per_s;
    double s = e_dot + c->delta * e;
    double accel = y->ref_force_accel_n_per_s2 + c->delta * e_dot + c->k * s + c->zeta * tanh(s);
    /* The nominal model inverted: the command that makes dF'/dt equal `accel`. */
    double u = c->tau / (c->n1 * c->ks)
               * (accel + c->n3 * y->force_rate_n_per_s + c->n2 * y->piston_accel_m_s2 + c->n1 * y->spool_m / c->tau);
    cmd->valve_command = u;
    if (c->limit > 0.0 && fabs(u) > c->limit) {
        snprintf(cmd->message, sizeof cmd->message, "command %.3g clipped at the valve limit", u);
        return EXOLEG_WARNING;
    }
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) { free(instance); }
