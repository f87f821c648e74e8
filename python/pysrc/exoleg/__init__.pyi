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
) -> List[Dict[str, Any]]: ...
def merge(shards: Sequence[Union[str, os.PathLike[str]]], out: Union[str, os.PathLike[str]]) -> Study: ...
def compare(scenario: ScenarioLike = ..., overrides: Optional[Mapping[str, Any]] = ...) -> List[Dict[str, Any]]: ...
