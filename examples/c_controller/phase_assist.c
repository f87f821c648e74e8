/*
 * phase_assist: a whole knee-exoskeleton controller as a firmware plugin for exoleg (ABI 1.1).
 * It uses only the device's own sensors (no reference channels): run it with
 * reference.force = "none", exoleg computes no desired force and scores what the wearer gets.
 *
 *   1. Heel strike from the heel force sensor (its rising edge over `hs_threshold_n` after the
 *      foot switch was off), or from the shank gyroscope (`use_gyro` = 1, or when the run has
 *      no foot sensors): armed when the shank swings forward (gyro y under -`swing_gyro_rad_s`),
 *      a heel strike when it stops (gyro y back over 0).
 *   2. Gait phase: the time since the last heel strike over the mean of the last three stride
 *      times (`stride0_s` until it has one), 0..99.9 %.
 *   3. Assistance: knee extension support in the loading response, a sin^2 bump of
 *      `peak_nm` (N m, extensor) over 2-18 % of the stride, turned into a cylinder force with
 *      the device's own moment-arm table dL/dq = arm0_m + arm1_m_per_rad * knee (m/rad; the
 *      built-in leg's: -0.0523, -0.0706 over 0-30 deg).
 *   4. Its own force loop on the load cell, toward the desired net force plus its own model of
 *      the seal friction (`fric_coulomb_n` tanh(v / 5 mm/s) + `fric_viscous_n_s_per_m` v, v
 *      the piston velocity sensor; identified on the bench, here the scenario's figures): the
 *      spool opening x_w that makes the nominal
 *      model's dF/dt = kf (F_des - F) (its velocity and leakage terms cancelled), led by the
 *      spool's time constant: u = (x_w + tau d(x_w)/dt) / k_s, the rate from the load cell's
 *      and the piston velocity's firmware differences.
 *   5. A safety monitor: the knee outside [knee_min_rad, knee_max_rad] or a cuff force over
 *      `cuff_limit_n` trips it; then the command follows zero force (transparent) for the rest
 *      of the run, or (`stop_on_trip` = 1) the run stops with a message.
 *   6. A sensor fault monitor (`monitor` = 1; off by default): the knee encoder has failed when
 *      it reads NaN, or the same value for `freeze_s` while the IMUs say the knee turns (the
 *      shank and thigh gyros differ by over `knee_motion_rad_s` at some sample of that time);
 *      the load cell has failed when it reads NaN, or the same value for `freeze_s` while the
 *      load pressure moves by over `pressure_change_pa` (stuck, frozen, clipped at a level,
 *      a dropout to zero or held). An encoder fault makes the controller transparent for the
 *      rest of the run (zero force with its friction model: the force loop does not need the
 *      knee; the moment arm falls back to arm0_m); a load-cell fault stops the run (its force
 *      loop is blind), so the device's failsafe takes over (set actuator.failsafe = "free", a
 *      bypass valve, for a walking wearer). A bias, drift or gain error is not detected: the
 *      readings still move. Logged as the fifth channel, `fault_detected` (0, 1 encoder, 2 load
 *      cell): exoleg's safety outcomes take its detection time from it.
 *
 * Logged channels (controller.plugin.log, in this order): gait_phase_pct, force_desired_n,
 * stride_s, safety_tripped, and with the monitor fault_detected. examples/python_phase_assist.py is the same controller in
 * Python: the same arithmetic in the same order, so the two give byte-identical time series.
 *
 * Build:  cc -O2 -fPIC -shared -ffp-contract=off -I include \
 *            -o target/libexoleg_phase_assist.so examples/c_controller/phase_assist.c -lm
 * Run:    exoleg run examples/phase_assist.toml (the monitor: examples/phase_assist_monitor.toml)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exoleg_controller.h"

#define N_STRIDES 3

typedef struct {
    /* parameters */
    double peak_nm, hs_threshold_n, stride0_s, kf, arm0, arm1;
    double knee_min, knee_max, cuff_limit, swing_gyro, use_gyro, stop_on_trip, fric_c, fric_v;
    double monitor, freeze_s, knee_motion, pressure_change;
    /* from the host */
    double n1, n2, n3, tau, ks, period;
    /* state */
    int foot_off, armed, have_hs, n_strides, tripped;
    double t_hs, strides[N_STRIDES];
    /* the fault monitor's state: the last readings, how many samples they held, what moved */
    int fault, knee_same, force_same;
    double knee_last, knee_moved, force_last, p_start, p_moved;
} PhaseAssist;

static const char *NAMES[] = {"peak_nm",     "hs_threshold_n", "stride0_s",    "kf",
                              "arm0_m",      "arm1_m_per_rad", "knee_min_rad", "knee_max_rad",
                              "cuff_limit_n", "swing_gyro_rad_s", "use_gyro",  "stop_on_trip",
                              "fric_coulomb_n", "fric_viscous_n_s_per_m", "monitor", "freeze_s",
                              "knee_motion_rad_s", "pressure_change_pa"};

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }

void *exoleg_create(const ExolegInfo *info) {
    if (info == NULL || info->size < sizeof(ExolegInfo)) {
        return NULL;
    }
    PhaseAssist *c = calloc(1, sizeof *c);
    if (c == NULL) {
        return NULL;
    }
    double *p[] = {&c->peak_nm,    &c->hs_threshold_n, &c->stride0_s, &c->kf,         &c->arm0,     &c->arm1,
                   &c->knee_min,   &c->knee_max,       &c->cuff_limit, &c->swing_gyro, &c->use_gyro, &c->stop_on_trip,
                   &c->fric_c,     &c->fric_v,         &c->monitor,  &c->freeze_s, &c->knee_motion, &c->pressure_change};
    const double defaults[] = {15.0, 20.0, 1.1,   300.0, -0.0523, -0.0706, -0.35, 1.4, 400.0,
                               1.5,  0.0,  0.0,   20.0,  300.0,   0.0,     0.02,  0.5, 2e4};
    for (size_t k = 0; k < sizeof defaults / sizeof defaults[0]; k++) {
        *p[k] = defaults[k];
    }
    for (uint32_t i = 0; i < info->n_params; i++) {
        size_t k = 0;
        while (k < sizeof defaults / sizeof defaults[0] && strcmp(info->params[i].name, NAMES[k]) != 0) {
            k++;
        }
        if (k == sizeof defaults / sizeof defaults[0]) {
            free(c); /* an unknown parameter is a mistake: refuse it */
            return NULL;
        }
        *p[k] = info->params[i].value;
    }
    c->n1 = info->nominal_n1;
    c->n2 = info->nominal_n2;
    c->n3 = info->nominal_n3;
    c->tau = info->nominal_tau_s;
    c->ks = info->nominal_k_s;
    c->period = info->sample_period_s;
    return c;
}

int32_t exoleg_reset(void *instance) {
    PhaseAssist *c = instance;
    c->foot_off = 0;
    c->armed = 0;
    c->have_hs = 0;
    c->n_strides = 0;
    c->tripped = 0;
    c->t_hs = 0.0;
    c->fault = 0;
    c->knee_same = 0;
    c->force_same = 0;
    c->knee_last = NAN;
    c->force_last = NAN;
    c->knee_moved = 0.0;
    c->p_start = NAN;
    c->p_moved = 0.0;
    return EXOLEG_OK;
}

/* The fault monitor: 1 when the knee encoder has failed, 2 when the load cell has, else 0. */
static int sensor_fault(PhaseAssist *c, const ExolegReadings *y) {
    int freeze_n = (int)ceil(c->freeze_s / c->period - 1e-9);
    double q = y->knee_rad;
    double turn = fabs(y->shank_gyro_rad_s[1] - y->thigh_gyro_rad_s[1]);
    if (!isfinite(q)) {
        return 1;
    }
    if (q == c->knee_last) {
        c->knee_same++;
        if (isfinite(turn) && turn > c->knee_moved) {
            c->knee_moved = turn;
        }
    } else {
        c->knee_same = 0;
        c->knee_moved = 0.0;
    }
    c->knee_last = q;
    if (c->knee_same >= freeze_n && c->knee_moved > c->knee_motion) {
        return 1;
    }
    double f = y->force_n, p = y->load_pressure_pa;
    if (!isfinite(f)) {
        return 2;
    }
    c->force_same = f == c->force_last ? c->force_same + 1 : 0;
    if (c->force_same == 0 || !isfinite(c->p_start)) {
        c->p_start = p;
        c->p_moved = 0.0;
    } else if (isfinite(p) && fabs(p - c->p_start) > c->p_moved) {
        c->p_moved = fabs(p - c->p_start);
    }
    c->force_last = f;
    if (c->force_same >= freeze_n && c->p_moved > c->pressure_change) {
        return 2;
    }
    return 0;
}

/* 1: a heel strike at this sample. */
static int heel_strike(PhaseAssist *c, const ExolegReadings *y) {
    double g = y->shank_gyro_rad_s[1];
    if (c->use_gyro > 0.5 || isnan(y->heel_force_n)) {
        if (isnan(g)) {
            return 0;
        }
        if (g < -c->swing_gyro) {
            c->armed = 1;
        }
        if (c->armed && g > 0.0) {
            c->armed = 0;
            return 1;
        }
        return 0;
    }
    int strike = c->foot_off && y->heel_force_n > c->hs_threshold_n;
    if (strike) {
        c->foot_off = 0;
    }
    if (y->foot_contact < 0.5) {
        c->foot_off = 1;
    }
    return strike;
}

int32_t exoleg_step(void *instance, const ExolegReadings *y, ExolegCommand *cmd) {
    PhaseAssist *c = instance;
    if (!EXOLEG_READINGS_HAS_DEVICE(y)) {
        snprintf(cmd->message, EXOLEG_MESSAGE_LEN, "phase_assist needs the device's sensors (exoleg with ABI 1.1)");
        return EXOLEG_STOP;
    }
    double t = y->t_s;
    if (c->monitor > 0.5 && c->fault == 0) {
        c->fault = sensor_fault(c, y);
        if (c->fault == 2) {
            cmd->log[4] = 2.0;
            snprintf(cmd->message, EXOLEG_MESSAGE_LEN,
                     "fault monitor: load cell failed (%.6g N; pressure moved %.3g Pa) at t = %.4f s", y->force_n,
                     c->p_moved, t);
            return EXOLEG_STOP;
        }
    }
    if (heel_strike(c, y)) {
        double stride = t - c->t_hs;
        if (c->have_hs && stride > 0.4 * c->stride0_s && stride < 2.5 * c->stride0_s) {
            for (int k = N_STRIDES - 1; k > 0; k--) {
                c->strides[k] = c->strides[k - 1];
            }
            c->strides[0] = stride;
            c->n_strides = c->n_strides < N_STRIDES ? c->n_strides + 1 : N_STRIDES;
        }
        c->t_hs = t;
        c->have_hs = 1;
    }
    double stride_est = c->stride0_s;
    if (c->n_strides > 0) {
        double sum = 0.0;
        for (int k = 0; k < c->n_strides; k++) {
            sum = sum + c->strides[k];
        }
        stride_est = sum / c->n_strides;
    }
    double phase = 0.0;
    if (c->have_hs) {
        phase = 100.0 * (t - c->t_hs) / stride_est;
        if (phase > 99.9) {
            phase = 99.9;
        }
    }
    double moment = 0.0;
    if (phase >= 2.0 && phase <= 18.0) {
        double s = sin(M_PI * (phase - 2.0) / 16.0);
        moment = c->peak_nm * (s * s);
    }
    double arm = c->fault == 1 ? c->arm0 : c->arm0 + c->arm1 * y->knee_rad;
    double f_des = -moment / arm;
    int out = (c->fault != 1 && (y->knee_rad < c->knee_min || y->knee_rad > c->knee_max)) || fabs(y->thigh_cuff_force_n) > c->cuff_limit
              || fabs(y->shank_cuff_force_n) > c->cuff_limit;
    if (out && !c->tripped) {
        c->tripped = 1;
        if (c->stop_on_trip > 0.5) {
            snprintf(cmd->message, EXOLEG_MESSAGE_LEN,
                     "safety monitor: knee %.3f rad, cuffs %.1f / %.1f N at t = %.4f s", y->knee_rad,
                     y->thigh_cuff_force_n, y->shank_cuff_force_n, t);
            return EXOLEG_STOP;
        }
    }
    if (c->tripped || c->fault != 0) {
        f_des = 0.0;
    }
    double v = y->piston_velocity_m_s;
    f_des = f_des + c->fric_c * tanh(v / 0.005) + c->fric_v * v;
    double f = y->force_n;
    double df = y->force_rate_n_per_s;
    double xv = (c->kf * (f_des - f) + c->n3 * f + c->n2 * v) / c->n1;
    double dxv = ((c->n3 - c->kf) * df + c->n2 * y->piston_accel_m_s2) / c->n1;
    cmd->valve_command = (xv + c->tau * dxv) / c->ks;
    cmd->log[0] = c->have_hs ? phase : NAN; /* no estimate before the first heel strike */
    cmd->log[1] = f_des;
    cmd->log[2] = stride_est;
    cmd->log[3] = c->tripped;
    cmd->log[4] = c->fault;
    return EXOLEG_OK;
}

void exoleg_destroy(void *instance) { free(instance); }
