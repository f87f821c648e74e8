"""Hostile and careless input through the Python package (issue 22): numpy values, paths that
look like TOML, keys that look like assignments, strings where lists belong, integers beyond
64 bits, Ctrl-C, memory, lazy plans, and no Rust panic ever reaching Python."""

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import exoleg

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHORT = {"plant.kind": "bench", "sim.duration_s": 0.01}


def test_numpy_values_are_numbers():
    a = exoleg.run(None, dict(SHORT, **{"controller.gamma": np.float64(200.0), "seed": np.int64(3)}))
    b = exoleg.run(None, dict(SHORT, **{"controller.gamma": 200.0, "seed": 3}))
    assert np.array_equal(a.timeseries["load_force_n"], b.timeseries["load_force_n"])
    c = exoleg.run(None, dict(SHORT, **{"controller.gamma": np.float32(150.0)}))
    assert c.summary["scenario"]["controller"]["gamma"] == 150.0
    d = exoleg.run({"sim": {"duration_s": np.float64(0.01)}, "plant": {"kind": "bench"}})
    assert len(d.timeseries["t_s"]) == 11
    p = exoleg.plan(None, grid={"controller.gamma": np.linspace(100.0, 200.0, 3)}, overrides=SHORT)
    assert [r["sets"] for r in p] == [["controller.gamma=100.0"], ["controller.gamma=150.0"], ["controller.gamma=200.0"]]


def test_paths_keys_lists_and_integers_are_not_guessed(tmp_path):
    # A path holding `=` (sweep folders are often named so) is a path.
    folder = tmp_path / "gamma=200"
    folder.mkdir()
    sc = folder / "s.toml"
    sc.write_text('[plant]\nkind = "bench"\n[sim]\nduration_s = 0.01\n')
    assert len(exoleg.run(str(sc)).timeseries["t_s"]) == 11
    # A key holding `=` is a key that does not exist, not an assignment.
    with pytest.raises(exoleg.ScenarioError, match="gamma=5"):
        exoleg.run(None, dict(SHORT, **{"controller.gamma=5": 1.0}))
    # A string where a list of grid values belongs.
    with pytest.raises(exoleg.ScenarioError, match="expected a list"):
        exoleg.plan(None, grid={"controller.gamma": "100"})
    # Integers beyond 64 bits: a ScenarioError, not OverflowError.
    for v in (2**70, -(2**70)):
        with pytest.raises(exoleg.ScenarioError, match="out of range"):
            exoleg.run(None, dict(SHORT, **{"sensors.delay_samples": v}))
    assert exoleg.run(None, dict(SHORT, seed=2**64 - 1)).summary["scenario"]["seed"] == str(2**64 - 1)
    with pytest.raises(exoleg.ScenarioError):
        exoleg.run(None, dict(SHORT, **{"controller.gamma": float("nan")}))
    with pytest.raises(exoleg.ScenarioError):
        exoleg.run(None, {"sim": {"duration_s": object()}})


def test_a_plan_of_a_million_runs_is_lazy():
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    p = exoleg.plan(None, monte_carlo=1_000_000, vary={"hydraulics.beta_pa": "pct(10)"})
    assert len(p) == 1_000_000
    assert p[999_999]["index"] == 999_999 and p[-1]["sets"][0].startswith("hydraulics.beta_pa=")
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    # Measured: under 1 MB (the expanded list took 710 MB).
    assert grown_mb < 50, grown_mb


def _child(code):
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("with_callback", [False, True])
def test_ctrl_c_stops_a_long_run_promptly(with_callback):
    ctl = ", controller=lambda obs: 0.0" if with_callback else ""
    period = 0.001 if with_callback else 0.0
    p = _child(f"""
        import sys, time, exoleg
        print("ready", flush=True)
        t = time.time()
        try:
            exoleg.run(None, {{"sim.duration_s": 600.0, "controller.sample_period_s": {period}}}{ctl})
        except KeyboardInterrupt:
            print("interrupted after", time.time() - t, flush=True)
            sys.exit(0)
        sys.exit(1)
    """)
    assert p.stdout.readline().strip() == "ready"
    import time

    time.sleep(1.5)
    sent = time.time()
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 0, (out, err)
    # Measured: within 0.1 s of the signal (it used to wait for the whole run).
    assert time.time() - sent < 3.0, out


def test_memory_of_a_long_run_is_the_columns_once():
    steps = 5_000_000
    p = _child(f"""
        import resource, exoleg
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        r = exoleg.run(None, {{"plant.kind": "bench", "controller.kind": "znn", "sim.dt_s": 1e-3, "sim.duration_s": {steps} * 1e-3}})
        cols = sum(a.nbytes for a in r.timeseries.values())
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(cols, (peak - base) * 1024)
    """)
    out, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    cols, grown = map(int, out.split())
    print(f"columns {cols / 1e6:.0f} MB, peak growth {grown / 1e6:.0f} MB ({grown / cols:.2f}x)")
    # Measured: 1.00x of the 720 MB of columns (it used to hold them about three times).
    assert grown <= 1.3 * cols, (cols, grown)
