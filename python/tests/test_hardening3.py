"""Issue 34 through the Python package: outputs never replace a device, a FIFO or an input;
logged channel names are names; a failed run never looks like a good one; a Simulation from
another thread; KeyboardInterrupt and SystemExit stop a sweep; the gym environment's actions
and seeds; whole-number arguments; resuming a study."""

import gc
import json
import os
import stat
import subprocess
import threading

import numpy as np
import pytest

import exoleg

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHORT = {"plant.kind": "bench", "sim.duration_s": 0.01}
SAMPLED = dict(SHORT, **{"controller.sample_period_s": 0.001})
EXE = os.environ.get("EXOLEG_BIN", os.path.join(ROOT, "target", "release", "exoleg"))


def _temporaries(folder):
    return [n for n in os.listdir(folder) if "exoleg-tmp" in n]


def test_outputs_never_replace_a_device_a_fifo_or_an_input(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    sc = tmp_path / "s.toml"
    sc.write_text('[plant]\nkind = "bench"\n[sim]\nduration_s = 0.01\n')
    for target in ("/dev/null", str(fifo), str(sc)):
        before = os.lstat(target)
        with pytest.raises(exoleg.ScenarioError):
            exoleg.run(str(sc), out=target)
        with pytest.raises(exoleg.ScenarioError):
            exoleg.Simulation(str(sc), {"controller.sample_period_s": 0.001}, out=target)
        with pytest.raises(exoleg.ScenarioError):
            exoleg.sweep(str(sc), grid={"seed": [1, 2]}, out=target)
        after = os.lstat(target)
        assert (stat.S_IFMT(after.st_mode), after.st_ino, after.st_rdev) == (
            stat.S_IFMT(before.st_mode),
            before.st_ino,
            before.st_rdev,
        )
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert sc.read_text().startswith("[plant]")
    assert not _temporaries(tmp_path)


@pytest.mark.parametrize("key", ["a,b", 'say "hi"', "two\nlines", "", "x" * 65])
def test_logged_keys_are_names(key, tmp_path):
    with pytest.raises(exoleg.ControllerError, match="keys"):
        exoleg.run(None, SAMPLED, controller=lambda obs: {"valve_command": 0.0, key: 1.0}, out=tmp_path / "o")
    assert not (tmp_path / "o").exists()
    sim = exoleg.Simulation(None, SAMPLED, out=tmp_path / "p")
    with pytest.raises(exoleg.ControllerError, match="keys"):
        sim.step({"valve_command": 0.0, key: 1.0})
    sim.step({"valve_command": 0.0, "fine_name": 1.0})
    del sim
    gc.collect()
    assert not (tmp_path / "p").exists() and not _temporaries(tmp_path)


def test_a_failed_loop_writes_nothing_and_says_so(tmp_path):
    # A NaN command: step() raises, the run stops there; finish() raises, nothing written.
    sim = exoleg.Simulation(None, SAMPLED, out=tmp_path / "nan")
    sim.step(0.0)
    with pytest.raises(exoleg.ControllerError, match="(?i)nan"):
        sim.step(float("nan"))
    assert sim.done
    with pytest.raises(exoleg.ControllerError, match="the run failed at t = 0.001"):
        sim.step(0.0)
    with pytest.raises(exoleg.ControllerError, match="the run failed"):
        sim.finish()
    assert not (tmp_path / "nan").exists() and not _temporaries(tmp_path)
    # A diverged step: the same, with the divergence's message; no internal names.
    sim = exoleg.Simulation(None, dict(SAMPLED, **{"sim.duration_s": 1.0}), out=tmp_path / "div")
    with pytest.raises(exoleg.DivergedError):
        for _ in range(1000):
            sim.step(1e300)
    for call in (lambda: sim.step(0.0), sim.finish):
        with pytest.raises(exoleg.DivergedError, match="the run failed") as e:
            call()
        assert "hold()" not in str(e.value) and "sample()" not in str(e.value)
    assert not (tmp_path / "div").exists()
    # reset() starts a good run again.
    sim.reset()
    while not sim.done:
        sim.step(0.0)
    assert sim.finish().summary["max_abs_force_error_n"] < 1e6
    assert (tmp_path / "div" / "summary.json").exists()


def test_a_summary_of_an_outside_controller_is_not_replayed_with_another(tmp_path):
    exoleg.run(None, SAMPLED, controller=lambda obs: 0.0, out=tmp_path / "py")
    summary = tmp_path / "py" / "summary.json"
    assert json.loads(summary.read_text())["external_controller"] == "python"
    with pytest.raises(exoleg.ScenarioError, match="external_controller.*python"):
        exoleg.run(str(summary))
    with pytest.raises(exoleg.ScenarioError, match="external_controller"):
        exoleg.sweep(str(summary), grid={"seed": [1]}, out=tmp_path / "sw")
    o = subprocess.run([EXE, "run", str(summary), "--out", str(tmp_path / "cli")], capture_output=True, text=True)
    assert o.returncode == 2 and "external_controller" in o.stderr, o.stderr
    # Given the controller again, it replays.
    again = exoleg.run(str(summary), controller=lambda obs: 0.0)
    assert again.summary["max_abs_force_error_n"] == json.loads(summary.read_text())["max_abs_force_error_n"]
    # The scenario's own controller: no such field, replays as before.
    exoleg.run(None, SHORT, out=tmp_path / "own")
    assert "external_controller" not in json.loads((tmp_path / "own" / "summary.json").read_text())
    exoleg.run(str(tmp_path / "own" / "summary.json"))


def test_a_simulation_works_from_another_thread_and_is_dropped_anywhere(tmp_path):
    sim = exoleg.Simulation(None, SAMPLED, out=tmp_path / "o")
    errors = []

    def other():
        try:
            while not sim.done:
                sim.step(0.0)
        except BaseException as e:  # noqa: BLE001 (any exception is a failure of the test)
            errors.append(e)

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert not errors, errors
    assert sim.finish().summary["steps"] > 0
    # An environment used by another thread, and a half-run Simulation dropped there: no
    # PanicException, no temporary folder left.
    pytest.importorskip("gymnasium")
    import exoleg.gym as exogym

    env = exogym.ExolegEnv(None, SAMPLED)
    env.reset(seed=1)
    box = {"sim": exoleg.Simulation(None, SAMPLED, out=tmp_path / "dropped")}

    def use_and_drop():
        try:
            env.step(np.array([0.0]))
            box["sim"].step(0.0)
            box.clear()
            gc.collect()
        except BaseException as e:  # noqa: BLE001
            errors.append(e)

    t = threading.Thread(target=use_and_drop)
    t.start()
    t.join()
    assert not errors, errors
    assert not (tmp_path / "dropped").exists() and not _temporaries(tmp_path)


@pytest.mark.parametrize("exc", [KeyboardInterrupt, SystemExit])
def test_keyboard_interrupt_and_system_exit_stop_a_sweep(exc, tmp_path):
    calls = []

    def ctl(obs):
        calls.append(obs.t_s)
        if len(calls) == 25:
            raise exc(7) if exc is SystemExit else exc()
        return 0.0

    with pytest.raises(exc) as e:
        exoleg.sweep(None, grid={"seed": list(range(20))}, overrides=SAMPLED, out=tmp_path / "sw", controller=ctl)
    if exc is SystemExit:
        assert e.value.code == 7
    # Stopped there: the runs after it were not made, and the interrupted run has no line.
    assert len(calls) == 25
    assert not (tmp_path / "sw").exists()
    journal = tmp_path / ".sw.exoleg-partial" / "runs.jsonl"
    lines = journal.read_text().splitlines()
    assert len(lines) == 2 and all(not json.loads(l)["error"] for l in lines)
    # Resumed with a controller that behaves: the whole sweep.
    s = exoleg.sweep(None, grid={"seed": list(range(20))}, overrides=SAMPLED, out=tmp_path / "sw",
                     controller=lambda obs: 0.0, resume=True)
    assert len(s.runs()) == 20 and not journal.exists()


def test_gym_actions_and_seeds():
    pytest.importorskip("gymnasium")
    import exoleg.gym as exogym

    env = exogym.ExolegEnv(None, SAMPLED)
    env.reset(seed=3)
    for bad in (np.array([0.0, 1.0]), np.zeros((1, 1)), np.array([])):
        with pytest.raises(ValueError, match="shape"):
            env.step(bad)
    env.step(np.array([0.0]))
    env.step(0.0)
    # reset() without a seed: a new episode, not the last seed's again.
    noisy = dict(SAMPLED, **{"sensors.preset": "adc16", "sensors.force.noise_std": 5.0})
    env = exogym.ExolegEnv(None, noisy)
    first = env.reset(seed=11)[0]
    again = env.reset(seed=11)[0]
    assert np.array_equal(first, again)
    fresh = [env.reset()[0] for _ in range(3)]
    assert not all(np.array_equal(first, f) for f in fresh)


def test_whole_number_arguments_are_checked_here():
    for kwargs in ({"monte_carlo": -1}, {"monte_carlo": 0}, {"jobs": -2}, {"monte_carlo": 2.5}, {"shard": (-1, 2)}):
        args = dict({"monte_carlo": 2, "vary": {"hydraulics.beta_pa": "pct(10)"}}, **kwargs)
        with pytest.raises(exoleg.ScenarioError):
            exoleg.sweep(None, overrides=SHORT, out="never", **args)
    with pytest.raises(exoleg.ScenarioError, match="samples"):
        exoleg.robustness(None, samples=-5, out="never")
    with pytest.raises(exoleg.ScenarioError, match="seed"):
        exoleg.Simulation(None, SAMPLED).reset(seed=-1)
    assert not os.path.exists("never")


def test_a_huge_integer_from_a_callback_is_said_to_be_one():
    with pytest.raises(exoleg.ControllerError, match="too large for a float"):
        exoleg.run(None, SAMPLED, controller=lambda obs: 10**400)
    with pytest.raises(exoleg.ControllerError, match="too large for a float"):
        exoleg.run(None, SAMPLED, controller=lambda obs: {"valve_command": 0.0, "big": 10**400})


def test_a_huge_value_is_not_echoed_whole():
    with pytest.raises(exoleg.ScenarioError) as e:
        exoleg.run(None, {"controller.kind": "x" * 100_000_000})
    assert len(str(e.value)) < 10_000 and "bytes in all" in str(e.value)
