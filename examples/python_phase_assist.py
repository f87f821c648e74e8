"""phase_assist in Python: the whole knee-exoskeleton controller of
examples/c_controller/phase_assist.c (heel strike from the foot sensors or the shank gyroscope,
gait phase from the recent stride times, knee extension support in the loading response, its
own force loop on the load cell, a safety monitor), with the same arithmetic in the same
order, so the two give byte-identical time series. It reads only the device's sensors (no
reference channels): the scenario sets reference.force = "none".

    pip install ./python
    python examples/python_phase_assist.py [SCENARIO] [OUT] [DURATION_S]

Default scenario: examples/phase_assist.toml (its C plugin is replaced by this controller).
"""

import math
import os
import sys

import exoleg

HERE = os.path.dirname(os.path.abspath(__file__))
SCENARIO = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "phase_assist.toml")
OUT = sys.argv[2] if len(sys.argv) > 2 else None
# The caller's controller replaces the scenario's plugin (which then need not be built).
OVERRIDES = {"controller.kind": "open_loop"}
if len(sys.argv) > 3:
    OVERRIDES["sim.duration_s"] = float(sys.argv[3])
N_STRIDES = 3
DEFAULTS = {
    "peak_nm": 15.0,
    "hs_threshold_n": 20.0,
    "stride0_s": 1.1,
    "kf": 300.0,
    "arm0_m": -0.0523,
    "arm1_m_per_rad": -0.0706,
    "knee_min_rad": -0.35,
    "knee_max_rad": 1.4,
    "cuff_limit_n": 400.0,
    "swing_gyro_rad_s": 1.5,
    "use_gyro": 0.0,
    "stop_on_trip": 0.0,
    "fric_coulomb_n": 20.0,
    "fric_viscous_n_s_per_m": 300.0,
}


class SafetyStop(Exception):
    """The safety monitor stopped the run (the C plugin's EXOLEG_STOP)."""


class PhaseAssist:
    """See examples/c_controller/phase_assist.c: the same controller, line for line."""

    def __init__(self, info, **params):
        unknown = set(params) - set(DEFAULTS)
        if unknown:
            raise ValueError(f"unknown parameters {sorted(unknown)}")
        p = {**DEFAULTS, **params}
        self.peak_nm, self.hs_threshold_n, self.stride0_s, self.kf = p["peak_nm"], p["hs_threshold_n"], p["stride0_s"], p["kf"]
        self.arm0, self.arm1 = p["arm0_m"], p["arm1_m_per_rad"]
        self.knee_min, self.knee_max, self.cuff_limit = p["knee_min_rad"], p["knee_max_rad"], p["cuff_limit_n"]
        self.swing_gyro, self.use_gyro, self.stop_on_trip = p["swing_gyro_rad_s"], p["use_gyro"], p["stop_on_trip"]
        self.fric_c, self.fric_v = p["fric_coulomb_n"], p["fric_viscous_n_s_per_m"]
        n = info["nominal"]
        self.n1, self.n2, self.n3, self.tau, self.ks = n["n1"], n["n2"], n["n3"], n["tau_s"], n["k_s"]
        self.foot_off = False
        self.armed = False
        self.have_hs = False
        self.strides = []
        self.tripped = False
        self.t_hs = 0.0

    def heel_strike(self, y):
        g = y.shank_gyro_y_rad_s
        if self.use_gyro > 0.5 or math.isnan(y.heel_force_n):
            if math.isnan(g):
                return False
            if g < -self.swing_gyro:
                self.armed = True
            if self.armed and g > 0.0:
                self.armed = False
                return True
            return False
        strike = self.foot_off and y.heel_force_n > self.hs_threshold_n
        if strike:
            self.foot_off = False
        if y.foot_contact < 0.5:
            self.foot_off = True
        return strike

    def __call__(self, y):
        t = y.t_s
        if self.heel_strike(y):
            stride = t - self.t_hs
            if self.have_hs and stride > 0.4 * self.stride0_s and stride < 2.5 * self.stride0_s:
                self.strides = ([stride] + self.strides)[:N_STRIDES]
            self.t_hs = t
            self.have_hs = True
        stride_est = self.stride0_s
        if self.strides:
            total = 0.0
            for s in self.strides:
                total = total + s
            stride_est = total / len(self.strides)
        phase = 0.0
        if self.have_hs:
            phase = 100.0 * (t - self.t_hs) / stride_est
            if phase > 99.9:
                phase = 99.9
        moment = 0.0
        if phase >= 2.0 and phase <= 18.0:
            s = math.sin(math.pi * (phase - 2.0) / 16.0)
            moment = self.peak_nm * (s * s)
        arm = self.arm0 + self.arm1 * y.knee_rad
        f_des = -moment / arm
        out = (
            y.knee_rad < self.knee_min
            or y.knee_rad > self.knee_max
            or abs(y.thigh_cuff_force_n) > self.cuff_limit
            or abs(y.shank_cuff_force_n) > self.cuff_limit
        )
        if out and not self.tripped:
            self.tripped = True
            if self.stop_on_trip > 0.5:
                raise SafetyStop(f"safety monitor: knee {y.knee_rad:.3f} rad at t = {t:.4f} s")
        if self.tripped:
            f_des = 0.0
        v = y.piston_velocity_m_s
        f_des = f_des + self.fric_c * math.tanh(v / 0.005) + self.fric_v * v
        f = y.force_n
        df = y.force_rate_n_per_s
        xv = (self.kf * (f_des - f) + self.n3 * f + self.n2 * v) / self.n1
        dxv = ((self.n3 - self.kf) * df + self.n2 * y.piston_accel_m_s2) / self.n1
        u = (xv + self.tau * dxv) / self.ks
        return {
            "valve_command": u,
            "gait_phase_pct": phase if self.have_hs else math.nan,  # no estimate before the first heel strike
            "force_desired_n": f_des,
            "stride_s": stride_est,
            "safety_tripped": float(self.tripped),
        }


def main():
    info = exoleg.controller_info(SCENARIO, OVERRIDES)
    r = exoleg.run(SCENARIO, OVERRIDES, controller=PhaseAssist(info), out=OUT)
    w = r.summary["wearer"]
    p = w["phase_estimate"]
    print(f"stance device share {w['stance_device_share']:.3f}, heel strikes detected {p['detected']} of {p['heel_strikes']}, "
          f"median latency {1e3 * p['median_latency_s']:.1f} ms, phase RMSE {p['phase_rmse_pct']:.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
