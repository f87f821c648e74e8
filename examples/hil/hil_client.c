/*
 * hil_client.c: the firmware linked with exoleg_hil.c, a controller peer of `exoleg hil`.
 * Link it with any plugin source (it calls the plugin's exoleg_* functions):
 *
 *   cc -O2 -ffp-contract=off -I include -o hil_erl_smc examples/hil/hil_client.c \
 *      examples/hil/exoleg_hil.c examples/c_controller/erl_smc.c -lm
 *   exoleg hil assets/scenarios/paper_2hz_gamma100.toml --listen 127.0.0.1:9300 \
 *      --set controller.sample_period_s=0.001 --set 'controller.plugin.params={k=100.0}' &
 *   ./hil_erl_smc 127.0.0.1 9300
 *
 * Test knobs: --sleep P MAX_S (sleep a uniform 0..MAX_S before a reply, with probability P),
 * --drop P (drop a reply with probability P), --seed N. Prints its counts on stdout at the end:
 * "samples N repeats N dropped N slept N malformed N".
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exoleg_hil.h"

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s HOST PORT [--sleep P MAX_S] [--drop P] [--seed N] [--timeout S]\n", argv[0]);
        return 2;
    }
    ExolegHilOptions o = {0};
    for (int i = 3; i < argc; i++) {
        if (strcmp(argv[i], "--sleep") == 0 && i + 2 < argc) {
            o.sleep_probability = atof(argv[++i]);
            o.sleep_max_s = atof(argv[++i]);
        } else if (strcmp(argv[i], "--drop") == 0 && i + 1 < argc) {
            o.drop_probability = atof(argv[++i]);
        } else if (strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
            o.seed = strtoull(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc) {
            o.timeout_s = atof(argv[++i]);
        } else {
            fprintf(stderr, "unknown option %s\n", argv[i]);
            return 2;
        }
    }
    ExolegHilPlugin plugin = {exoleg_create, exoleg_reset, exoleg_step, exoleg_destroy};
    ExolegHilStats st;
    char err[256] = "";
    int r = exoleg_hil_run(argv[1], argv[2], &plugin, &o, &st, err, sizeof err);
    printf("samples %llu repeats %llu dropped %llu slept %llu malformed %llu\n", (unsigned long long)st.samples,
           (unsigned long long)st.repeats, (unsigned long long)st.dropped, (unsigned long long)st.slept,
           (unsigned long long)st.malformed);
    if (r != 0) {
        fprintf(stderr, "hil_client: %s\n", err);
        return 1;
    }
    return 0;
}
