"""Type stubs of exoleg (units: SI, in the names)."""

import os
from typing import Callable, Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import distributed as distributed

__version__: str

ScenarioLike = Union[None, str, os.PathLike[str], Mapping[str, Any]]

class ExoError(Exception): ...
class ScenarioError(ValueError): ...
class DivergedError(RuntimeError): ...
class ControllerError(RuntimeError): ...

class Obs:
    """The readings of one sample (SI units, in the names); reused between samples."""

    fields: List[str]
    device_channels: List[str]
    t_s: float
    period_s: float
    force_n: float
    def array(self) -> np.ndarray: ...
    def copy(self) -> "Obs": ...
    def __getattr__(self, name: str) -> float: ...

class Simulation:
    """A run whose loop you own (sampled: controller.sample_period_s > 0)."""

    def __init__(
        self,
        scenario: ScenarioLike = ...,
        overrides: Optional[Mapping[str, Any]] = ...,
        *,
        out: Optional[Union[str, os.PathLike[str]]] = ...,
    ) -> None: ...
    def reset(self, seed: Optional[int] = ...) -> Obs: ...
    def step(self, command: Union[float, Mapping[str, float]]) -> Obs: ...
    @property
    def done(self) -> bool: ...
    @property
    def t_s(self) -> float: ...
    @property
    def obs(self) -> Obs: ...
    @property
    def force_error_n(self) -> float: ...
    @property
    def gross_metabolic_w_per_kg(self) -> float: ...
    @property
    def info(self) -> Dict[str, Any]: ...
    def finish(self) -> "Run": ...

class Plan(Sequence[Dict[str, Any]]):
    """A study's runs, lazily: (index, overrides) dicts."""

class Run:
    summary: Dict[str, Any]
    """The keys of summary.json: errors in N, times in s, angles in deg."""
    timeseries: Dict[str, np.ndarray]
    """Column name -> float64 array, the columns of timeseries.csv (units in the names)."""
    scenario: str
    """The resolved scenario as TOML."""

class Study:
    title: str
    aggregate: str
    out: str
    def runs(self) -> List[Dict[str, Any]]: ...

def run(
    scenario: ScenarioLike = ...,
    overrides: Optional[Mapping[str, Any]] = ...,
    *,
    controller: Optional[Callable[..., Any]] = ...,
    out: Optional[Union[str, os.PathLike[str]]] = ...,
    baseline: bool = ...,
) -> Run: ...
def sweep(
    scenario: ScenarioLike,
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = ...,
    monte_carlo: Optional[int] = ...,
    vary: Optional[Mapping[str, str]] = ...,
    overrides: Optional[Mapping[str, Any]] = ...,
    out: Union[str, os.PathLike[str]] = ...,
    jobs: int = ...,
    shard: Optional[Tuple[int, int]] = ...,
    controller: Optional[Callable[[Any], Any]] = ...,
    resume: bool = ...,
) -> Study: ...
def robustness(
    scenario: ScenarioLike,
    *,
    percent: float = ...,
    samples: int = ...,
    overrides: Optional[Mapping[str, Any]] = ...,
    out: Union[str, os.PathLike[str]] = ...,
    jobs: int = ...,
    shard: Optional[Tuple[int, int]] = ...,
    controller: Optional[Callable[[Any], Any]] = ...,
    resume: bool = ...,
) -> Study: ...
def plan(
    scenario: ScenarioLike,
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = ...,
    monte_carlo: Optional[int] = ...,
    vary: Optional[Mapping[str, str]] = ...,
    overrides: Optional[Mapping[str, Any]] = ...,
) -> Plan: ...
def faults(
    scenario: ScenarioLike,
    *,
    matrix: Union[str, os.PathLike[str], None] = ...,
    observe_strides: float = ...,
    overrides: Optional[Mapping[str, Any]] = ...,
    out: Union[str, os.PathLike[str]] = ...,
    jobs: int = ...,
    shard: Optional[Tuple[int, int]] = ...,
    controller: Optional[Callable[[Any], Any]] = ...,
    resume: bool = ...,
) -> Study: ...
def controller_info(scenario: ScenarioLike = ..., overrides: Optional[Mapping[str, Any]] = ...) -> Dict[str, Any]: ...
def merge(shards: Sequence[Union[str, os.PathLike[str]]], out: Union[str, os.PathLike[str]]) -> Study: ...
def compare(scenario: ScenarioLike = ..., overrides: Optional[Mapping[str, Any]] = ...) -> List[Dict[str, Any]]: ...
