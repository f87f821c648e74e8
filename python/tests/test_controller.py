"""Your own controller from Python (issue 21): a callback, a loop you own and a Gymnasium
environment give the built-in controller's numbers, bit for bit, and fail cleanly."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import exoleg

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("EXOLEG_BIN", os.path.join(ROOT, "target", "release", "exoleg"))
SC = {name: os.path.join(ROOT, "assets", "scenarios", f"{name}.toml") for name in ("paper_2hz_gamma100", "gait_walk")}
FIRMWARE = {"controller.sample_period_s": 0.001, "sensors.preset": "adc16", "sensors.delay_samples": 1}
GAINS = {"paper_2hz_gamma100": 100.0, "gait_walk": 200.0}


def erl_smc(info, k, delta=15.0, zeta=10.0):
    """ERL-SMC as a user writes it in Python, in the order of exoleg's built-in."""
    n = info["nominal"]

    def law(obs):
        e = obs.ref_force_n - obs.force_n
        e_dot = obs.ref_force_rate_n_per_s - obs.force_rate_n_per_s
        s = e_dot + delta * e
        accel = obs.ref_force_accel_n_per_s2 + delta * e_dot + k * s + zeta * math.tanh(s)
        return n["tau_s"] / (n["n1"] * n["k_s"]) * (
            accel + n["n3"] * obs.force_rate_n_per_s + n["n2"] * obs.piston_accel_m_s2 + n["n1"] * obs.spool_m / n["tau_s"]
        )

    return law


@pytest.mark.parametrize("name", ["paper_2hz_gamma100", "gait_walk"])
def test_callback_and_your_loop_equal_the_builtin_csv(name, tmp_path):
    builtin = tmp_path / "builtin"
    args = [BIN, "run", "--quiet", "--out", str(builtin), SC[name], "--set", 'controller.kind="erl_smc"']
    for k, v in FIRMWARE.items():
        args += ["--set", f"{k}={v!r}" if not isinstance(v, str) else f'{k}="{v}"']
    p = subprocess.run(args, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    law = erl_smc(exoleg.controller_info(SC[name], FIRMWARE), GAINS[name])
    exoleg.run(SC[name], FIRMWARE, controller=law, out=tmp_path / "callback")
    sim = exoleg.Simulation(SC[name], FIRMWARE, out=tmp_path / "loop")
    obs = sim.reset()
    while not sim.done:
        obs = sim.step(law(obs))
    sim.finish()
    want = (builtin / "timeseries.csv").read_bytes()
    assert (tmp_path / "callback" / "timeseries.csv").read_bytes() == want
    assert (tmp_path / "loop" / "timeseries.csv").read_bytes() == want


def test_callback_failures_stop_the_run_and_leave_nothing(tmp_path):
    ov = {"sim.duration_s": 0.1, "controller.sample_period_s": 0.001}
    out = tmp_path / "out"

    def boom(obs):
        if obs.t_s >= 0.05:
            raise ZeroDivisionError("the firmware divided by zero")
        return 0.0

    with pytest.raises(exoleg.ControllerError, match=r"ZeroDivisionError.*t = 0\.050000 s") as e:
        exoleg.run(None, ov, controller=boom, out=out)
    assert isinstance(e.value.__cause__, ZeroDivisionError)
    with pytest.raises(exoleg.ControllerError, match=r"returned 'u' \(str\)"):
        exoleg.run(None, ov, controller=lambda obs: "u", out=out)
    with pytest.raises(exoleg.ControllerError, match="NaN"):
        exoleg.run(None, ov, controller=lambda obs: float("nan"), out=out)
    with pytest.raises(exoleg.ControllerError, match="no `valve_command`"):
        exoleg.run(None, ov, controller=lambda obs: {"u": 0.0}, out=out)
    with pytest.raises(exoleg.ControllerError, match="same keys"):
        exoleg.run(None, ov, controller=lambda obs: {"valve_command": 0.0, ("a" if obs.t_s < 0.01 else "b"): 1.0})
    with pytest.raises(exoleg.ScenarioError, match="sample_period_s"):
        exoleg.run(None, {"sim.duration_s": 0.1}, controller=lambda obs: 0.0)
    assert not out.exists() and not [p for p in os.listdir(tmp_path) if p.startswith(".out")]


def test_obs_is_one_object_with_the_readings_by_name():
    seen = []

    def ctl(obs):
        seen.append((id(obs), obs.t_s, obs.force_n, obs.counts[0]))
        return {"valve_command": 1e-5 * (obs.ref_force_n - obs.force_n), "err_n": obs.ref_force_n - obs.force_n}

    r = exoleg.run(None, {"sim.duration_s": 0.01, "controller.sample_period_s": 0.001, "sensors.preset": "adc16"}, controller=ctl)
    assert len({s[0] for s in seen}) == 1 and len(seen) == 10
    assert [s[1] for s in seen] == pytest.approx([i * 1e-3 for i in range(10)])
    assert all(isinstance(s[3], int) for s in seen)
    assert "log_err_n" in r.timeseries and len(r.timeseries["log_err_n"]) == 11
    assert exoleg.Obs.fields[2] == "force_n"


def test_a_sweep_takes_a_callable(tmp_path):
    # The controller keeps its nominal model while the plant's bulk modulus varies.
    ov = dict(FIRMWARE, **{"plant.kind": "bench", "sim.duration_s": 0.1, "controller.nominal.beta_pa": 1.517e9})
    law = erl_smc(exoleg.controller_info(None, ov), 100.0)
    kw = dict(monte_carlo=4, vary={"hydraulics.beta_pa": "pct(10)"})
    mine = exoleg.sweep(None, overrides=ov, out=tmp_path / "mine", controller=law, **kw)
    builtin = exoleg.sweep(None, overrides=dict(ov, **{"controller.kind": "erl_smc", "controller.k": 100.0}), out=tmp_path / "b", **kw)
    assert [r["summary"] for r in mine.runs()] == [r["summary"] for r in builtin.runs()]


def test_gymnasium_environment_passes_the_checker():
    gym = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    import exoleg.gym

    env = exoleg.gym.ExolegEnv(None, {"plant.kind": "bench", "sim.duration_s": 0.05, "controller.sample_period_s": 0.001})
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    total, done = 0.0, False
    while not done:
        obs, reward, done, truncated, info = env.step(np.array([1e-5 * (obs[10] - obs[2])]))
        total += reward
    assert info["t_s"] == pytest.approx(0.05) and total < 0.0


def test_the_python_example_runs():
    p = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python_controller.py")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "the same time series: True" in p.stdout


def test_the_device_readings_by_name(tmp_path):
    """ABI 1.1's readings reach Python: 40 fields, the device's by name, their raw counts."""
    assert len(exoleg.Obs.fields) == 40 and exoleg.Obs.fields[17] == "hip_rad"
    assert exoleg.Obs.device_channels[0] == "hip_rad" and len(exoleg.Obs.device_channels) == 21
    seen = []

    def law(obs):
        with pytest.raises(AttributeError, match="Obs.fields"):
            obs.no_such_reading
        seen.append((obs.thigh_accel_z_m_s2, obs.supply_pressure_pa, obs.heel_force_n, obs.device_counts[19], obs.array()[38]))
        return 0.0

    ov = {"sim.duration_s": 0.01, "metrics.settle_s": 0.0, "controller.sample_period_s": 0.001, "sensors.preset": "adc16",
          "reference.force": "none",
          "controller.kind": "open_loop"}
    exoleg.run(os.path.join(ROOT, "assets", "scenarios", "stand.toml"), ov)
    exoleg.run(os.path.join(ROOT, "assets", "scenarios", "stand.toml"), ov, controller=law)
    az, ps, heel, counts, ps_array = seen[0]
    # Standing: the thigh IMU reads about +g up; the supply transducer 8 MPa in 16-bit counts.
    assert 9.0 < az < 9.82 and ps == ps_array and abs(ps - 8e6) < 1e3 and heel == 0.0  # 2 mm above the ground at t = 0
    assert counts == round(ps / (2 * 25e6 / 65536))


def test_phase_assist_in_c_and_python_give_the_same_csv(tmp_path):
    """examples/phase_assist.toml: the C plugin and the Python controller, byte for byte."""
    lib = os.path.join(ROOT, "target", "libexoleg_phase_assist.so")
    src = os.path.join(ROOT, "examples", "c_controller", "phase_assist.c")
    cc = ["cc", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-I", os.path.join(ROOT, "include"), "-o", lib, src, "-lm"]
    assert subprocess.run(cc, capture_output=True).returncode == 0
    scenario = os.path.join(ROOT, "examples", "phase_assist.toml")
    short = ["--set", "sim.duration_s=3.0"]
    p = subprocess.run([BIN, "run", "--quiet", "--out", str(tmp_path / "c"), scenario] + short, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    py = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python_phase_assist.py"), scenario, str(tmp_path / "py"), "3.0"],
                        capture_output=True, text=True)
    assert py.returncode == 0, py.stderr
    assert "heel strikes detected" in py.stdout
    assert (tmp_path / "c" / "timeseries.csv").read_bytes() == (tmp_path / "py" / "timeseries.csv").read_bytes()
