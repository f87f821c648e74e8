"""Your own controller in the loop from Python: the PI force controller of
examples/pi_controller.rs, first as a callback, then in a loop you own (the same numbers).

    pip install ./python
    python examples/python_controller.py [SCENARIO]

The controller is called once per sample period (here 1 kHz) with the readings of that
sample (an exoleg.Obs, one object updated in place); it returns the valve command, or a dict
with the command and channels to log (columns log_<name> of the time series).
"""

import math
import sys

import numpy as np

import exoleg

SCENARIO = sys.argv[1] if len(sys.argv) > 1 else None
OVERRIDES = {"controller.sample_period_s": 0.001}


class Pi:
    """u = u_ff + kp e + ki integral(e), e = F_d - F, gains from the nominal model (40 Hz)."""

    def __init__(self, info):
        n = info["nominal"]
        self.n = n
        gain = n["n1"] * n["k_s"]  # N/s of force rate per unit command
        self.kp = 2 * math.pi * 40.0 / gain
        self.ki = self.kp * 2 * math.pi * 5.0
        self.integral = 0.0

    def __call__(self, obs):
        n = self.n
        e = obs.ref_force_n - obs.force_n
        u_ff = (obs.ref_force_rate_n_per_s + n["n3"] * obs.ref_force_n + n["n2"] * obs.piston_velocity_m_s) / (
            n["n1"] * n["k_s"]
        )
        u = u_ff + self.kp * e + self.ki * self.integral
        limit = obs.valve_command_limit
        if limit == 0.0 or abs(u) < limit:
            self.integral += e * obs.period_s
        return {"valve_command": u, "integral_n_s": self.integral}


def main():
    info = exoleg.controller_info(SCENARIO, OVERRIDES)
    # 1. A callback: exoleg owns the loop.
    a = exoleg.run(SCENARIO, OVERRIDES, controller=Pi(info))
    print(f"callback:  max |F_L - F_d| {a.summary['max_abs_force_error_n']:.4f} N, RMS {a.summary['rms_force_error_n']:.4f} N")
    # 2. Your loop: step(command) holds the command for one sample period.
    sim = exoleg.Simulation(SCENARIO, OVERRIDES)
    pi = Pi(sim.info)
    obs = sim.reset()
    while not sim.done:
        obs = sim.step(pi(obs))
    b = sim.finish()
    print(f"your loop: max |F_L - F_d| {b.summary['max_abs_force_error_n']:.4f} N, RMS {b.summary['rms_force_error_n']:.4f} N")
    same = list(a.timeseries) == list(b.timeseries) and all(np.array_equal(a.timeseries[k], b.timeseries[k], equal_nan=True) for k in a.timeseries)
    print("the same time series:", same)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
