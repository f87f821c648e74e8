"""Issue 41 (3): exoleg.gym.ExolegVectorEnv, N environments stepped in Rust threads in one call,
against gymnasium.vector.SyncVectorEnv over N exoleg.gym.ExolegEnv: the same arrays step for
step (observations, rewards, terminations, truncations, infos) with the same seeds and actions,
through autoresets, failures and partial resets; seeds; wrong action shapes; num_envs."""

import gc
import os

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import exoleg  # noqa: E402
import exoleg.gym as exogym  # noqa: E402
from gymnasium.vector import AutoresetMode, SyncVectorEnv  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TREADMILL = os.path.join(ROOT, "assets", "scenarios", "gait_treadmill.toml")
# 50-step episodes on the reduced treadmill, with a noisy load cell: the seed shows.
SHORT = {
    "leg.engine": "reduced",
    "sim.dt_s": 0.001,
    "sim.duration_s": 0.05,
    "controller.sample_period_s": 0.001,
    "metrics.settle_s": 0.01,
    "sensors.preset": "adc16",
    "sensors.force.noise_std": 5.0,
}


def _pair(n, **kw):
    vec = exogym.ExolegVectorEnv(TREADMILL, SHORT, n, **kw)
    sync = SyncVectorEnv([lambda: exogym.ExolegEnv(TREADMILL, SHORT)] * n)
    return vec, sync


def _same(a, b, where=""):
    """Equal arrays (values, dtype and shape) or dicts of them, bit for bit."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{where}: {sorted(a)} != {sorted(b)}"
        for k in a:
            _same(a[k], b[k], f"{where}[{k}]")
    elif isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b)
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    else:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape} != {b.dtype}{b.shape}"
        if a.dtype == object:
            assert list(a) == list(b), f"{where}: {a} != {b}"
        else:
            # Bit for bit: the same bytes (NaN included), not just numerically equal.
            assert a.tobytes() == b.tobytes(), f"{where}: {a} != {b}"


def test_vector_env_equals_sync_vector_env_step_for_step():
    n = 3
    vec, sync = _pair(n)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP == sync.metadata["autoreset_mode"]
    assert vec.observation_space == sync.observation_space and vec.action_space == sync.action_space
    assert vec.single_observation_space == sync.single_observation_space
    assert vec.single_action_space == sync.single_action_space
    _same(vec.reset(seed=7), sync.reset(seed=7), "reset")
    rng = np.random.default_rng(3)
    ends = np.zeros(n, dtype=int)
    failures = 0
    for k in range(170):  # more than three 50-step episodes each
        a = rng.uniform(-1e-3, 1e-3, size=(n, 1))
        if k in (20, 75):
            a[1, 0] = np.nan  # env 1 fails (twice); the others go on
        if k == 130:
            a[2, 0] = np.inf
        got, want = vec.step(a), sync.step(a)
        _same(got, want, f"step {k}")
        ends += got[2]
        failures += int("failure" in got[4])
    assert (ends >= 3).all() and failures == 3
    # Actions of shape (n,), a reset with a list of seeds (None: drawn), then without a seed.
    _same(vec.step(np.zeros(n)), sync.step(np.zeros(n)), "flat actions")
    _same(vec.reset(seed=[5, None, 2**64 - 1]), sync.reset(seed=[5, None, 2**64 - 1]), "list of seeds")
    for k in range(60):
        a = rng.uniform(-1e-3, 1e-3, size=(n, 1))
        _same(vec.step(a), sync.step(a), f"after the list, step {k}")
    _same(vec.reset(), sync.reset(), "reset()")
    for k in range(60):
        a = rng.uniform(-1e-3, 1e-3, size=(n, 1))
        _same(vec.step(a), sync.step(a), f"after reset(), step {k}")
    assert [g.bit_generator.state for g in vec.np_random] == [g.bit_generator.state for g in sync.np_random]
    assert vec.np_random_seed == sync.np_random_seed


def test_partial_reset_and_stepping_before_reset_match_sync_vector_env():
    n = 4
    vec, sync = _pair(n, threads=2)
    # Before any reset: each runs the scenario's own seed, as a new ExolegEnv does.
    a = np.full((n, 1), 1e-4)
    _same(vec.step(a), sync.step(a), "before reset")
    _same(vec.reset(seed=1), sync.reset(seed=1), "reset")
    for k in range(30):
        _same(vec.step(a * k), sync.step(a * k), f"step {k}")
    mask = np.array([False, True, False, True])
    _same(vec.reset(seed=11, options={"reset_mask": mask}), sync.reset(seed=11, options={"reset_mask": mask}), "mask")
    for k in range(60):
        _same(vec.step(a), sync.step(a), f"after the mask, step {k}")
    for bad in (np.array([True]), np.zeros(n, dtype=bool), np.ones(n, dtype=int), [True] * n):
        with pytest.raises((TypeError, ValueError)):
            vec.reset(options={"reset_mask": bad})


def test_seeds_give_the_episodes_of_single_environments():
    n = 3
    vec = exogym.ExolegVectorEnv(TREADMILL, SHORT, n)
    obs, _ = vec.reset(seed=40)
    single = [exogym.ExolegEnv(TREADMILL, SHORT) for _ in range(n)]
    for i, env in enumerate(single):
        assert np.array_equal(env.reset(seed=40 + i)[0], obs[i])
    for k in range(20):
        a = np.full((n, 1), 2e-4 * k)
        obs, rew, term, trunc, infos = vec.step(a)
        for i, env in enumerate(single):
            o, r, t, tr, info = env.step(a[i])
            assert np.array_equal(o, obs[i]) and r == rew[i] and t == term[i] and not trunc[i]
            assert info["t_s"] == infos["t_s"][i]
    # The same seed, the same episode; another seed, another (noisy load cell).
    again, _ = vec.reset(seed=40)
    other, _ = vec.reset(seed=41)
    assert np.array_equal(again[1], other[0]) and not np.array_equal(again[0], other[0])
    with pytest.raises(ValueError, match="num_envs=3"):
        vec.reset(seed=[1, 2])
    with pytest.raises(gymnasium.error.Error):
        vec.reset(seed=-1)
    with pytest.raises(exoleg.ScenarioError, match="seed"):
        vec.reset(seed=2**64)


def test_wrong_action_shapes_raise_value_error():
    n = 2
    vec, sync = _pair(n)
    _same(vec.reset(seed=3), sync.reset(seed=3))
    for bad in (np.zeros((n, 2)), np.zeros((n + 1, 1)), np.zeros((1,)), 0.0, np.zeros((n, 1, 1)), np.zeros((1, n))):
        with pytest.raises(ValueError, match="shape"):
            vec.step(bad)
    with pytest.raises(ValueError, match="shape"):
        vec._native.step(np.zeros((n, 2)))
    # Nothing was stepped: still the same as the environments that never saw them.
    for k in range(5):
        a = np.full((n, 1), 1e-4)
        _same(vec.step(a), sync.step(a), f"step {k}")
    _same(vec.step([[0.0], [1e-4]]), sync.step([[0.0], [1e-4]]), "a list")


@pytest.mark.parametrize("num_envs", [0, -1, 1025, 2.5, "4"])
def test_num_envs_out_of_range_is_a_scenario_error(num_envs):
    with pytest.raises(exoleg.ScenarioError, match="num_envs"):
        exogym.ExolegVectorEnv(TREADMILL, SHORT, num_envs)


def test_a_failing_sub_environment_ends_alone():
    n = 3
    vec = exogym.ExolegVectorEnv(TREADMILL, SHORT, n)
    first, _ = vec.reset(seed=9)
    vec.step(np.zeros((n, 1)))
    a = np.array([[0.0], [np.nan], [0.0]])
    obs, rew, term, trunc, infos = vec.step(a)
    assert term.tolist() == [False, True, False] and not trunc.any()
    assert infos["_failure"].tolist() == [False, True, False]
    assert infos["failure"][0] is None and "valve command is NaN" in infos["failure"][1]
    assert rew[1] == -1e12 and np.isfinite(rew).all()
    assert infos["t_s"].tolist() == pytest.approx([0.002, 0.001, 0.002])
    # The next step resets it (its action ignored: NaN again) and the others go on.
    obs, rew, term, trunc, infos = vec.step(a * np.array([[0.0], [1.0], [0.0]]))
    assert not term.any() and "failure" not in infos
    assert rew[1] == 0.0 and infos["t_s"][1] == 0.0 and infos["t_s"][0] == pytest.approx(0.003)
    assert obs.shape == (n, len(exoleg.Obs.fields)) and obs.dtype == np.float64
    # A command that makes a run diverge fails that one with the simulator's message.
    vec.reset(seed=9)
    big = np.array([[0.0], [0.0], [1.0]])
    for _ in range(60):
        obs, rew, term, trunc, infos = vec.step(big)
        if "failure" in infos:
            break
    assert "diverged" in infos["failure"][2] and term[2] and not term[:2].any()


def test_help_and_threads():
    vec = exogym.ExolegVectorEnv(TREADMILL, SHORT, 2, threads=1)
    assert vec.threads == 1 and vec.num_envs == 2
    assert exogym.ExolegVectorEnv(TREADMILL, SHORT, 1).threads == 1
    assert "autoreset" in exogym.ExolegVectorEnv.__doc__ and exogym.ExolegVectorEnv.step.__doc__
    assert exoleg._native.VecSimulation.__doc__ and exoleg._native.VecSimulation.step.__doc__
    with pytest.raises(exoleg.ScenarioError, match="sample_period_s"):
        exogym.ExolegVectorEnv(TREADMILL, dict(SHORT, **{"controller.sample_period_s": 0.0}), 2)
    assert repr(vec) == "ExolegVectorEnv(num_envs=2)"


def test_close_and_a_forked_child():
    n = 4
    vec = exogym.ExolegVectorEnv(TREADMILL, SHORT, n, threads=2)
    vec.reset(seed=2)
    a = np.full((n, 1), 1e-4)
    if hasattr(os, "fork"):
        # A child forked after the worker threads started has none: it steps every run itself.
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover (the child)
            code = 1
            try:
                os.write(w, vec.step(a)[0].tobytes())
                del vec  # dropped in the child: its parent's threads are not joined
                gc.collect()
                code = 0
            finally:
                os._exit(code)
        os.close(w)
        got = b""
        while chunk := os.read(r, 1 << 16):
            got += chunk
        os.close(r)
        assert os.waitpid(pid, 0)[1] == 0
        assert got == vec.step(a)[0].tobytes()
    vec.close()
    with pytest.raises(exoleg.ExoError, match="closed"):
        vec.step(a)


def test_the_threads_change_nothing():
    n = 5
    envs = [exogym.ExolegVectorEnv(TREADMILL, SHORT, n, threads=t) for t in (1, 2, 5)]
    assert [e.threads for e in envs] == [1, 2, 5]
    first = [e.reset(seed=21) for e in envs]
    for got in first[1:]:
        _same(got, first[0], "reset")
    rng = np.random.default_rng(5)
    for k in range(130):
        a = rng.uniform(-0.05, 0.05, size=(n, 1))
        got = [e.step(a) for e in envs]
        for g in got[1:]:
            _same(g, got[0], f"step {k}")
