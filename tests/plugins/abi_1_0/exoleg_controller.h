/* The ABI 1.0 header as exoleg shipped it before 1.1 (git 36f8bac, include/exoleg_controller.h):
   tests build plugins against it to check that a 1.0 plugin keeps working under the new host. */
/*
 * exoleg_controller.h: the C ABI of an exoleg controller plugin (ABI 1.0).
 *
 * A plugin is a shared library that exports the five functions below. exoleg loads it for
 * `controller.kind = "plugin"`, `controller.plugin.library = "PATH"`, and calls it once per
 * sample period (`controller.sample_period_s`) with the readings of that sample; the command
 * it returns is held until the next sample (zero-order hold) and clipped to the valve limit.
 *
 *   exoleg_abi_version()   checked before anything else: EXOLEG_ABI_VERSION. The major
 *                          version must equal exoleg's; structs only grow at their end, and
 *                          every struct starts with its size in bytes.
 *   exoleg_create(info)    one instance per run, with the run's parameters
 *                          (`controller.plugin.params`, numbers by name) and the host's
 *                          figures; NULL refuses the parameters (exit 2).
 *   exoleg_reset(inst)     before the first sample of a run.
 *   exoleg_step(inst, readings, command)
 *                          one sample: read `readings`, write `command->valve_command`.
 *   exoleg_destroy(inst)   when the run ends, completed or not.
 *
 * Status codes: EXOLEG_OK; EXOLEG_WARNING (the sample is used; counted and reported in
 * summary.json with the last `command->message`); EXOLEG_STOP (the run stops with exit 3,
 * naming the plugin, its message and the simulated time). A non-finite valve command stops
 * the run too.
 *
 * Rules: no global or static mutable state. A parallel sweep creates one instance per run
 * and calls instances from several threads at once; one instance is called by one thread at a
 * time (not always the same thread). Pointers passed in are valid during the call only.
 * Units are SI; see the README's "Your controller" for the table of readings (when each is
 * sampled, its quantisation under each sensor preset).
 *
 * Build (Linux):  cc -O2 -fPIC -shared -ffp-contract=off -I include -o libmyctl.so myctl.c
 * (-ffp-contract=off keeps a*b+c as two roundings, as exoleg's Rust code computes it.)
 */
#ifndef EXOLEG_CONTROLLER_H
#define EXOLEG_CONTROLLER_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define EXOLEG_ABI_MAJOR 1
#define EXOLEG_ABI_MINOR 0
#define EXOLEG_ABI_VERSION ((uint32_t)((EXOLEG_ABI_MAJOR << 16) | EXOLEG_ABI_MINOR))

#define EXOLEG_OK 0
#define EXOLEG_WARNING 1
#define EXOLEG_STOP 2

/* Channels, in the order of ExolegReadings.counts. */
#define EXOLEG_CH_FORCE 0
#define EXOLEG_CH_SPOOL 1
#define EXOLEG_CH_PISTON 2
#define EXOLEG_CH_KNEE 3
#define EXOLEG_CH_PISTON_VELOCITY 4

#define EXOLEG_LOG_LEN 8
#define EXOLEG_MESSAGE_LEN 160

/* One parameter: `controller.plugin.params.<name> = value`. */
typedef struct ExolegParam {
    const char *name; /* NUL-terminated */
    double value;
} ExolegParam;

/* What an instance is told at creation. */
typedef struct ExolegInfo {
    uint32_t size;              /* sizeof(ExolegInfo) as exoleg built it */
    uint32_t abi_version;       /* exoleg's EXOLEG_ABI_VERSION */
    double sample_period_s;     /* s */
    double valve_command_limit; /* |u| <= limit; 0 = none */
    /* The controller's nominal force model (controller.nominal over [hydraulics]):
       dF/dt = n1 x_v - n2 v - n3 F (+ disturbances), dx_v/dt = (k_s u - x_v) / tau. */
    double nominal_n1;    /* N/m */
    double nominal_n2;    /* N/m */
    double nominal_n3;    /* 1/s */
    double nominal_tau_s; /* s */
    double nominal_k_s;   /* m per unit command */
    uint64_t seed;        /* the run's seed */
    uint32_t n_params;
    uint32_t reserved;
    const ExolegParam *params; /* n_params entries */
} ExolegInfo;

/* The readings of one sample (after noise, A/D, delay and the firmware differences). */
typedef struct ExolegReadings {
    uint32_t size;         /* sizeof(ExolegReadings) as exoleg built it */
    uint32_t counts_valid; /* bit i: counts[i] holds channel i's raw A/D counts */
    double t_s;            /* sample instant, s */
    double period_s;       /* s */
    double force_n;             /* load cell, N */
    double force_rate_n_per_s;  /* its filtered difference, N/s */
    double spool_m;             /* spool LVDT, m (NaN without the sensor) */
    double piston_m;            /* piston position from t = 0, m */
    double piston_velocity_m_s; /* m/s */
    double piston_accel_m_s2;   /* filtered difference of the velocity, m/s^2 */
    double knee_rad;            /* knee flexion, rad */
    double knee_rate_rad_s;     /* its filtered difference, rad/s */
    double ref_force_n;                   /* desired force at t_s, N */
    double ref_force_rate_n_per_s;        /* N/s */
    double ref_force_accel_n_per_s2;      /* N/s^2 */
    double next_ref_force_n;              /* desired force at t_s + period_s, N */
    double next_ref_force_rate_n_per_s;   /* N/s */
    double next_ref_force_accel_n_per_s2; /* N/s^2 */
    double valve_command_limit;           /* 0 = none */
    int64_t counts[5]; /* raw A/D counts: reading = counts * lsb, lsb = 2 range / 2^bits */
} ExolegReadings;

/* What the plugin returns for one sample (exoleg zeroes it before each call). */
typedef struct ExolegCommand {
    uint32_t size; /* sizeof(ExolegCommand) as exoleg built it */
    uint32_t reserved;
    double valve_command;                 /* u (k_s u is the commanded spool position, m) */
    double disturbance_estimate_n_per_s2; /* logged; 0 if none */
    double log[EXOLEG_LOG_LEN];           /* logged channels, named by controller.plugin.log */
    char message[EXOLEG_MESSAGE_LEN];     /* NUL-terminated text for a warning or a stop */
} ExolegCommand;

uint32_t exoleg_abi_version(void);
void *exoleg_create(const ExolegInfo *info);
int32_t exoleg_reset(void *instance);
int32_t exoleg_step(void *instance, const ExolegReadings *readings, ExolegCommand *command);
void exoleg_destroy(void *instance);

#ifdef __cplusplus
}
#endif

#endif /* EXOLEG_CONTROLLER_H */
