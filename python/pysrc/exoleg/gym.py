"""A Gymnasium environment over :class:`exoleg.Simulation` (needs ``gymnasium``).

>>> import exoleg.gym
>>> env = exoleg.gym.ExolegEnv("gait.toml", {"controller.sample_period_s": 0.001})
>>> obs, info = env.reset(seed=1)
>>> obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

- One step is one sample period: the action (the valve command, shape (1,)) is held for
  ``controller.sample_period_s``.
- The observation is the readings of the sample (:attr:`exoleg.Obs.fields`, float64, SI).
- The reward is minus the squared true force error, ``-(F_L - F_d)^2`` in N^2, at the new
  sample instant (the simulator's truth, not the noisy reading). With
  ``reward="metabolic_rate"`` it is minus the wearer's gross metabolic rate (W/kg) over the
  last simulation step before the new sample instant: the cost a controller saves or adds the
  wearer (needs the wearer's muscles: ``wearer.model = "muscles"``, or ``wearer.muscles =
  true`` for the analysis of the impedance wearer; otherwise ``ValueError``).
- ``terminated`` when the run reaches ``sim.duration_s``, or when the simulation fails
  (diverges, or the command is not finite): then ``info["failure"]`` holds the message and the
  reward is that of the last state. ``truncated`` is never set (add a TimeLimit wrapper).
- ``reset(seed=...)`` starts again with that seed for the run's random elements (sensor
  noise, random disturbances); the same seed gives the same episode. ``reset()`` without a
  seed draws the episode's seed from the environment's generator (``np_random``, seeded by
  the last ``reset(seed=...)``), so successive episodes differ, as Gymnasium expects.
- An action of any other shape than the action space's (one number: shape ``(1,)``, or a
  scalar) raises ``ValueError``; it is never cut to its first element.
- The action space is ``[-limit, limit]`` with ``actuator.valve_command_limit``, or [-1, 1]
  when the scenario sets none (k_s * 1 m of spool: far beyond any useful command).

:class:`ExolegVectorEnv` steps N such environments in one call, on worker threads with the GIL
released (a Gymnasium ``VectorEnv`` with next-step autoreset): its episodes are those of N
:class:`ExolegEnv` in a ``gymnasium.vector.SyncVectorEnv`` with the same seeds and actions,
bit for bit.

>>> envs = exoleg.gym.ExolegVectorEnv("gait.toml", {"controller.sample_period_s": 0.001}, num_envs=8)
>>> obs, infos = envs.reset(seed=1)                  # obs: (8, n)
>>> obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())  # (8, 1)
"""

from __future__ import annotations

import json
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
    from gymnasium.utils import seeding
    from gymnasium.vector import AutoresetMode, VectorEnv
    from gymnasium.vector.utils import batch_space
except ImportError as e:  # pragma: no cover
    raise ImportError("exoleg.gym needs gymnasium: pip install gymnasium") from e

import exoleg
from exoleg import _native

__all__ = ["ExolegEnv", "ExolegVectorEnv", "REWARDS"]

#: The rewards an environment can give: minus the squared force error (N^2, the default) or
#: minus the wearer's gross metabolic rate (W/kg).
REWARDS = ("force_error", "metabolic_rate")


class ExolegEnv(gymnasium.Env):
    """Force control of the scenario's cylinder, one sample period per step (see the module)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: exoleg.ScenarioLike = None,
        overrides: Optional[Mapping[str, Any]] = None,
        *,
        reward: str = "force_error",
    ) -> None:
        super().__init__()
        if reward not in REWARDS:
            raise ValueError(f"reward: {reward!r} is not a reward: one of {REWARDS}")
        self._sim = exoleg.Simulation(scenario, overrides)
        if reward == "metabolic_rate" and not self._sim.info.get("wearer_muscles"):
            raise ValueError(
                'reward: "metabolic_rate" needs the wearer\'s muscles: the scenario has none '
                '(set wearer.model = "muscles" or wearer.muscles = true)'
            )
        self._reward = reward
        limit = float(self._sim.info["valve_command_limit"]) or 1.0
        n = len(exoleg.Obs.fields)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float64)
        self.action_space = spaces.Box(-limit, limit, shape=(1,), dtype=np.float64)
        self._failed = False

    def _obs(self, obs: exoleg.Obs) -> np.ndarray:
        a = obs.array()
        # A switched-off sensor reads NaN; the observation says 0 for it instead.
        return np.nan_to_num(a, nan=0.0, posinf=0.0, neginf=0.0)

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None) -> Tuple[np.ndarray, Dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**63 - 1))
        obs = self._sim.reset(seed)
        self._failed = False
        return self._obs(obs), {"t_s": self._sim.t_s}

    def step(self, action: Any) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        a = np.asarray(action, dtype=np.float64)
        if a.size != 1 or a.ndim > 1:
            raise ValueError(f"action: expected one valve command (shape (1,) or a scalar), got shape {a.shape}")
        u = float(a.reshape(-1)[0])
        info: Dict[str, Any] = {}
        try:
            obs = self._sim.step(u)
        except (exoleg.DivergedError, exoleg.ControllerError) as e:
            self._failed = True
            obs = self._sim.obs
            info["failure"] = str(e)
        if self._reward == "metabolic_rate":
            reward = -self._sim.gross_metabolic_w_per_kg
        else:
            err = self._sim.force_error_n
            reward = -(err * err)
        if not np.isfinite(reward):
            reward = -1e12
        info["t_s"] = self._sim.t_s
        terminated = self._failed or self._sim.done
        return self._obs(obs), float(reward), bool(terminated), False, info


class ExolegVectorEnv(VectorEnv):
    """``num_envs`` :class:`ExolegEnv` stepped together in Rust (a Gymnasium ``VectorEnv``).

    >>> envs = exoleg.gym.ExolegVectorEnv("gait.toml", {"controller.sample_period_s": 0.001}, num_envs=8)
    >>> obs, infos = envs.reset(seed=1)              # sub-environment i gets seed 1 + i
    >>> obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())

    - ``step(actions)`` steps every sub-environment in one call, on ``threads`` threads, the
      calling one included (default: one per core; at most one per sub-environment), with the
      GIL released; each is
      exactly an :class:`ExolegEnv` (the same observation, reward in N^2, ``terminated``, and
      ``info["failure"]`` when its run fails: the others go on).
    - ``actions``: float64 valve commands, shape ``(num_envs, 1)`` (the action space's) or
      ``(num_envs,)``; any other shape raises ``ValueError``.
    - Autoreset as ``gymnasium.vector.SyncVectorEnv`` does it by default
      (``metadata["autoreset_mode"]`` is ``AutoresetMode.NEXT_STEP``): the step after the one
      that ended an episode resets that sub-environment (with a seed drawn from its own
      ``np_random``, as ``ExolegEnv.reset()`` does), ignores its action, and returns its first
      observation with reward 0 and ``terminated`` False.
    - ``reset(seed=s)`` seeds sub-environment i with ``s + i`` (a list: one seed each; None:
      seeds drawn from the sub-environments' generators); ``options={"reset_mask": mask}``
      resets only where ``mask`` (bool, shape ``(num_envs,)``) is True.
    - ``infos``: ``t_s`` (simulated time, s) with its mask ``_t_s``, and ``failure`` (object
      array: the message, or None) with ``_failure`` when a sub-environment failed.
    - ``num_envs``: 1 to 1024 (else ``exoleg.ScenarioError``).

    With the same seeds and actions, its arrays (observations, rewards, terminations,
    truncations, infos) are those of ``SyncVectorEnv([lambda: ExolegEnv(scenario, overrides)] * num_envs)``,
    step for step, bit for bit.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        scenario: exoleg.ScenarioLike = None,
        overrides: Optional[Mapping[str, Any]] = None,
        num_envs: int = 1,
        *,
        threads: Optional[int] = None,
        reward: str = "force_error",
    ) -> None:
        super().__init__()
        n = exoleg._count("num_envs", num_envs, 1, 1024)
        t = 0 if threads is None else exoleg._count("threads", threads, 1, 1024)
        if reward not in REWARDS:
            raise ValueError(f"reward: {reward!r} is not a reward: one of {REWARDS}")
        self._native = _native.VecSimulation(n, t, reward=reward, **exoleg._args(scenario, overrides))
        self.info: Dict[str, Any] = json.loads(self._native.info_json)
        limit = float(self.info["valve_command_limit"]) or 1.0
        self.num_envs = n
        self.metadata = dict(type(self).metadata)
        self.render_mode = None
        nobs = len(exoleg.Obs.fields)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, shape=(nobs,), dtype=np.float64)
        self.single_action_space = spaces.Box(-limit, limit, shape=(1,), dtype=np.float64)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        # Each sub-environment's generator and its seed (as ExolegEnv's np_random: made when
        # first needed).
        self._rngs: List[Optional[np.random.Generator]] = [None] * n
        self._rng_seeds: List[Optional[int]] = [None] * n
        # An episode ended at the last step: the next one resets it.
        self._pending = False

    @property
    def threads(self) -> int:
        """Worker threads stepping the sub-environments (1: the calling thread, GIL released)."""
        return self._native.threads

    def _rng(self, i: int) -> np.random.Generator:
        """Sub-environment ``i``'s generator (``gymnasium.Env.np_random``)."""
        if self._rngs[i] is None:
            self._rngs[i], self._rng_seeds[i] = seeding.np_random()
        return self._rngs[i]

    def _episode_seed(self, i: int, seed: Optional[int]) -> int:
        """The seed of sub-environment ``i``'s next episode, as ``ExolegEnv.reset(seed)`` takes it."""
        if seed is not None:
            self._rngs[i], self._rng_seeds[i] = seeding.np_random(seed)
        else:
            seed = int(self._rng(i).integers(0, 2**63 - 1))
        return exoleg._count("seed", seed, 0, 2**64 - 1)

    @property
    def np_random(self) -> Tuple[np.random.Generator, ...]:
        """The sub-environments' generators (as ``SyncVectorEnv.np_random``)."""
        return tuple(self._rng(i) for i in range(self.num_envs))

    @property
    def np_random_seed(self) -> Tuple[int, ...]:
        """The seeds of the sub-environments' generators (as ``SyncVectorEnv.np_random_seed``)."""
        for i in range(self.num_envs):
            if self._rng_seeds[i] is None:
                self._rngs[i], self._rng_seeds[i] = seeding.np_random()
        return tuple(self._rng_seeds)  # type: ignore[arg-type]

    def reset(
        self,
        *,
        seed: Union[None, int, Sequence[Optional[int]]] = None,
        options: Optional[Dict[str, Any]] = None,
    ) -> Tuple[np.ndarray, Dict[str, Any]]:
        """Reset every sub-environment (or those of ``options["reset_mask"]``): observations
        ``(num_envs, n)`` and infos (``t_s``). ``seed``: None, an int (``seed + i`` for
        sub-environment i) or one seed (or None) each."""
        n = self.num_envs
        if seed is None:
            seeds: Sequence[Optional[int]] = [None] * n
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(n)]
        else:
            seeds = seed
        if len(seeds) != n:
            raise ValueError(
                f"If seeds are passed as a list the length must match num_envs={n} but got length={len(seeds)}."
            )
        mask = self._reset_mask(options)
        chosen = np.ones(n, dtype=np.bool_) if mask is None else mask.copy()
        episode = np.zeros(n, dtype=np.uint64)
        for i in np.flatnonzero(chosen):
            episode[i] = self._episode_seed(int(i), seeds[i])
        obs, t_s = self._native.reset(episode, mask)
        self._pending = bool(self._native.ended())
        t_s[~chosen] = 0.0
        return obs, {"t_s": t_s, "_t_s": chosen}

    def _reset_mask(self, options: Optional[Dict[str, Any]]) -> Optional[np.ndarray]:
        """``options["reset_mask"]``, checked as ``SyncVectorEnv`` does (None: every one)."""
        if options is None or "reset_mask" not in options:
            return None
        m = options["reset_mask"]
        if not isinstance(m, np.ndarray):
            raise TypeError(f"`options['reset_mask']` must be a numpy array, got {type(m)}")
        if m.shape != (self.num_envs,):
            raise ValueError(f"`options['reset_mask']` must have shape `({self.num_envs},)`, got {m.shape}")
        if m.dtype != np.bool_:
            raise TypeError(f"`options['reset_mask']` must have `dtype=np.bool_`, got {m.dtype}")
        if not np.any(m):
            raise ValueError(
                f"`options['reset_mask']` must contain a boolean array with at least one True value, got reset_mask={m}"
            )
        return m

    def step(self, actions: Any) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
        """Step every sub-environment (autoresetting those whose episode ended at the last
        step): observations ``(num_envs, n)``, rewards (N^2), terminated, truncated (never
        set), infos."""
        a = np.asarray(actions, dtype=np.float64)
        n = self.num_envs
        if a.shape != (n, 1) and a.shape != (n,):
            raise ValueError(
                f"actions: expected one valve command per environment (shape ({n}, 1) or ({n},)), got shape {a.shape}"
            )
        seeds = None
        if self._pending:
            seeds = np.zeros(self.num_envs, dtype=np.uint64)
            for i in self._native.ended():
                seeds[i] = self._episode_seed(i, None)
        obs, rewards, terminated, t_s, failures, ended = self._native.step(a, seeds)
        self._pending = ended > 0
        infos: Dict[str, Any] = {"t_s": t_s, "_t_s": np.ones(self.num_envs, dtype=np.bool_)}
        if failures:
            why = np.full(self.num_envs, None, dtype=object)
            has = np.zeros(self.num_envs, dtype=np.bool_)
            for i, message in failures:
                why[i], has[i] = message, True
            infos["failure"], infos["_failure"] = why, has
        return obs, rewards, terminated, np.zeros(self.num_envs, dtype=np.bool_), infos

    def close_extras(self, **kwargs: Any) -> None:
        """Let the runs and their worker threads go (``close()``); later calls raise."""
        self._native = _Closed()

    def __repr__(self) -> str:
        """``ExolegVectorEnv(num_envs=N)``."""
        return f"ExolegVectorEnv(num_envs={self.num_envs})"


class _Closed:
    """What a closed :class:`ExolegVectorEnv` steps: every call raises."""

    def __getattr__(self, name: str) -> Any:
        raise exoleg.ExoError("the environment is closed")
