"""A Gymnasium environment over :class:`exoleg.Simulation` (needs ``gymnasium``).

>>> import exoleg.gym
>>> env = exoleg.gym.ExolegEnv("gait.toml", {"controller.sample_period_s": 0.001})
>>> obs, info = env.reset(seed=1)
>>> obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

- One step is one sample period: the action (the valve command, shape (1,)) is held for
  ``controller.sample_period_s``.
- The observation is the readings of the sample (:attr:`exoleg.Obs.fields`, float64, SI).
- The reward is minus the squared true force error, ``-(F_L - F_d)^2`` in N^2, at the new
  sample instant (the simulator's truth, not the noisy reading).
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
"""

from __future__ import annotations

from typing import Any, Dict, Mapping, Optional, Tuple

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as e:  # pragma: no cover
    raise ImportError("exoleg.gym needs gymnasium: pip install gymnasium") from e

import exoleg

__all__ = ["ExolegEnv"]


class ExolegEnv(gymnasium.Env):
    """Force control of the scenario's cylinder, one sample period per step (see the module)."""

    metadata = {"render_modes": []}

    def __init__(self, scenario: exoleg.ScenarioLike = None, overrides: Optional[Mapping[str, Any]] = None) -> None:
        super().__init__()
        self._sim = exoleg.Simulation(scenario, overrides)
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
        err = self._sim.force_error_n
        reward = -(err * err) if np.isfinite(err) else -1e12
        info["t_s"] = self._sim.t_s
        terminated = self._failed or self._sim.done
        return self._obs(obs), float(reward), bool(terminated), False, info
