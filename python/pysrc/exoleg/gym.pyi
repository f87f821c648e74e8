"""Type stubs of exoleg.gym (units: SI; rewards in N^2, or W/kg with reward="metabolic_rate")."""

from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import gymnasium
import numpy as np
from gymnasium.vector import VectorEnv

from . import ScenarioLike

REWARDS: Tuple[str, ...]
"""The rewards: "force_error" (-(F_L - F_d)^2, N^2; the default), "metabolic_rate" (minus the
wearer's gross metabolic rate over the last step, W/kg; needs the wearer's muscles)."""

class ExolegEnv(gymnasium.Env):
    """One sample period a step: action (1,) valve command, observation the readings
    (exoleg.Obs.fields, NaN -> 0), reward -(F_L - F_d)^2 in N^2, info["t_s"] (s) and
    info["failure"] when the run fails; reward="metabolic_rate": minus the wearer's gross
    metabolic rate (W/kg)."""

    def __init__(
        self, scenario: ScenarioLike = ..., overrides: Optional[Mapping[str, Any]] = ..., *, reward: str = ...
    ) -> None: ...
    def reset(
        self, *, seed: Optional[int] = ..., options: Optional[Dict[str, Any]] = ...
    ) -> Tuple[np.ndarray, Dict[str, Any]]: ...
    def step(self, action: Any) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]: ...

class ExolegVectorEnv(VectorEnv):
    """num_envs ExolegEnv stepped together in Rust threads (next-step autoreset), bit for bit
    those of SyncVectorEnv over ExolegEnv with the same seeds and actions."""

    num_envs: int
    info: Dict[str, Any]
    """What the controller is told (exoleg.controller_info): sample_period_s (s), valve_command_limit, ..."""
    def __init__(
        self,
        scenario: ScenarioLike = ...,
        overrides: Optional[Mapping[str, Any]] = ...,
        num_envs: int = ...,
        *,
        threads: Optional[int] = ...,
        reward: str = ...,
    ) -> None: ...
    @property
    def threads(self) -> int: ...
    @property
    def np_random(self) -> Tuple[np.random.Generator, ...]: ...  # type: ignore[override]
    @property
    def np_random_seed(self) -> Tuple[int, ...]: ...  # type: ignore[override]
    def reset(
        self,
        *,
        seed: Union[None, int, Sequence[Optional[int]]] = ...,
        options: Optional[Dict[str, Any]] = ...,
    ) -> Tuple[np.ndarray, Dict[str, Any]]: ...
    def step(self, actions: Any) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
        """Observations (num_envs, n), rewards (num_envs,) in N^2, terminated, truncated, infos
        (t_s in s; failure)."""
        ...
