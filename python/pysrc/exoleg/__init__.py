"""exoleg: force control of hydraulic lower-limb exoskeletons, simulated.

Python bindings of the exoleg Rust simulator. Units are SI and stated in the names
(``force_n``, ``t_s``, ``knee_angle_deg``, ...), exactly as in ``timeseries.csv`` and
``summary.json`` (see the project's README). The simulations release the GIL, so Python
threads and process pools run them in parallel.

>>> import exoleg
>>> r = exoleg.run()                                   # the embedded default scenario
>>> r.summary["max_abs_force_error_n"]
>>> r.timeseries["load_force_n"]                       # numpy array, N
>>> exoleg.run("gait.toml", {"controller.gamma": 200})
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import DivergedError, ExoError, ScenarioError

__all__ = [
    "run",
    "sweep",
    "robustness",
    "merge",
    "compare",
    "plan",
    "Run",
    "Study",
    "ExoError",
    "ScenarioError",
    "DivergedError",
]
__version__ = _native.__version__

ScenarioLike = Union[None, str, os.PathLike, Mapping[str, Any]]


def _toml_value(v: Any) -> str:
    """A Python value as a TOML value (for ``--set``-style overrides)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        r = repr(v)
        if r in ("inf", "-inf", "nan"):
            return r
        return r if ("." in r or "e" in r or "n" in r) else r + ".0"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise ScenarioError(f"cannot write {v!r} ({type(v).__name__}) as a scenario value")


def _flatten(d: Mapping[str, Any], prefix: str = "") -> List[str]:
    """A nested dict of sections as dotted ``key=value`` overrides."""
    out: List[str] = []
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.extend(_flatten(v, f"{prefix}{k}."))
        else:
            out.append(f"{prefix}{k}={_toml_value(v)}")
    return out


def _sets(overrides: Optional[Mapping[str, Any]]) -> List[str]:
    """``{"controller.gamma": 200}`` -> ``["controller.gamma=200"]``."""
    if overrides is None:
        return []
    if not isinstance(overrides, Mapping):
        raise ScenarioError("overrides: expected a dict of dotted keys, e.g. {'controller.gamma': 200}")
    return [f"{k}={_toml_value(v)}" for k, v in overrides.items()]


def _scenario(scenario: ScenarioLike) -> Tuple[Optional[str], Optional[str], List[str]]:
    """(path, toml text, extra sets) for the native layer."""
    if scenario is None:
        return None, None, []
    if isinstance(scenario, Mapping):
        return None, "", _flatten(scenario)
    if isinstance(scenario, os.PathLike):
        return os.fspath(scenario), None, []
    if isinstance(scenario, str):
        # TOML text has a newline or an `=`; anything else is a path.
        if "\n" in scenario or "=" in scenario:
            return None, scenario, []
        return scenario, None, []
    raise ScenarioError(f"scenario: expected a path, TOML text or a dict, got {type(scenario).__name__}")


@dataclass(frozen=True)
class Run:
    """One finished run.

    ``summary``: dict with the keys of ``summary.json`` (errors in N, times in s, angles in deg).
    ``timeseries``: column name -> numpy float64 array, the columns of ``timeseries.csv``.
    ``scenario``: the resolved scenario as TOML text (files by absolute path, with hashes).
    """

    summary: Dict[str, Any]
    timeseries: Dict[str, np.ndarray]
    scenario: str


def run(scenario: ScenarioLike = None, overrides: Optional[Mapping[str, Any]] = None) -> Run:
    """Run one scenario headless and return its figures and time series.

    ``scenario``: ``None`` (the embedded default, the paper's Figure 5 case), a path to a
    scenario TOML (or a ``summary.json`` to reproduce a run), TOML text, or a dict of sections.
    ``overrides``: dotted keys, ``{"controller.gamma": 200, "sim.duration_s": 2.0}``.

    Raises ``ScenarioError`` (a ``ValueError``) for bad input, with the CLI's one-line message,
    and ``DivergedError`` when the run diverges.
    """
    path, text, extra = _scenario(scenario)
    summary, columns, data, rows, resolved = _native.run(path, text, extra + _sets(overrides))
    values = np.frombuffer(data, dtype="<f8").reshape(rows, len(columns))
    series = {c: values[:, i].copy() for i, c in enumerate(columns)}
    return Run(json.loads(summary), series, resolved)


@dataclass(frozen=True)
class Study:
    """A finished sweep or robustness study written to ``out``.

    ``title``: the report line; ``aggregate``: ``aggregate.csv`` as text (min/median/max per
    figure); ``out``: the folder (``runs.jsonl``, ``aggregate.csv``, plots; or for a shard,
    ``runs.jsonl`` and ``shard.json``).
    """

    title: str
    aggregate: str
    out: str

    def runs(self) -> List[Dict[str, Any]]:
        """The lines of ``runs.jsonl``, parsed."""
        with open(os.path.join(self.out, "runs.jsonl"), encoding="utf-8") as f:
            return [json.loads(line) for line in f if line.strip()]


def _study(kind: str, scenario: ScenarioLike, out: str, overrides, shard, jobs, plan_only=False, **kw) -> Tuple[str, str]:
    path, text, extra = _scenario(scenario)
    if shard is not None:
        if not (isinstance(shard, (tuple, list)) and len(shard) == 2):
            raise ScenarioError(f"shard: expected (K, N), got {shard!r}")
        shard = (int(shard[0]), int(shard[1]))
    return _native.study(
        kind,
        os.fspath(out),
        path,
        text,
        extra + _sets(overrides),
        jobs=int(jobs),
        shard_k_n=shard,
        plan_only=plan_only,
        **kw,
    )


def sweep(
    scenario: ScenarioLike,
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = None,
    monte_carlo: Optional[int] = None,
    vary: Optional[Mapping[str, str]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Union[str, os.PathLike] = "out/sweep",
    jobs: int = 0,
    shard: Optional[Tuple[int, int]] = None,
) -> Study:
    """Run many variations of a scenario in parallel, like ``exoleg sweep``.

    ``grid``: ``{"controller.gamma": [100, 200]}`` (full factorial), or ``monte_carlo=N`` with
    ``vary={"hydraulics.beta_pa": "pct(10)"}`` (``uniform(lo,hi)``, ``normal(mean,sd)``,
    ``pct(p)``). ``shard=(K, N)`` runs only the runs with index % N == K and writes a shard
    folder for :func:`merge`. ``jobs``: worker threads (0 = all cores).
    """
    grids = [f"{k}={','.join(_toml_value(v) for v in vs)}" for k, vs in (grid or {}).items()]
    varies = [f"{k}={d}" for k, d in (vary or {}).items()]
    title, agg = _study("sweep", scenario, out, overrides, shard, jobs, grids=grids, monte_carlo=monte_carlo, vary=varies)
    return Study(title, agg, os.fspath(out))


def robustness(
    scenario: ScenarioLike,
    *,
    percent: float = 20.0,
    samples: int = 64,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Union[str, os.PathLike] = "out/robustness",
    jobs: int = 0,
    shard: Optional[Tuple[int, int]] = None,
) -> Study:
    """The robustness report, like ``exoleg robustness`` (the plant's parameters +-``percent``
    %, the controller keeping its nominal model, the paper's Table 2 disturbances)."""
    title, agg = _study("robustness", scenario, out, overrides, shard, jobs, percent=float(percent), samples=int(samples))
    return Study(title, agg, os.fspath(out))


def plan(
    scenario: ScenarioLike,
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = None,
    monte_carlo: Optional[int] = None,
    vary: Optional[Mapping[str, str]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
) -> List[Dict[str, Any]]:
    """The expanded runs of a sweep (index and overrides of each), without running them."""
    grids = [f"{k}={','.join(_toml_value(v) for v in vs)}" for k, vs in (grid or {}).items()]
    varies = [f"{k}={d}" for k, d in (vary or {}).items()]
    _, text = _study("sweep", scenario, "", overrides, None, 0, True, grids=grids, monte_carlo=monte_carlo, vary=varies)
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def merge(shards: Sequence[Union[str, os.PathLike]], out: Union[str, os.PathLike]) -> Study:
    """Merge shard folders into what the unsharded study writes (``exoleg merge``)."""
    title, agg = _native.merge([os.fspath(s) for s in shards], os.fspath(out))
    return Study(title, agg, os.fspath(out))


def compare(scenario: ScenarioLike = None, overrides: Optional[Mapping[str, Any]] = None) -> List[Dict[str, Any]]:
    """The paper's eight cases (Tables 3 and 4) on a base scenario, like ``exoleg compare``.
    Each result: case, controller, max errors (N), convergence times (s), the paper's figures."""
    path, text, extra = _scenario(scenario)
    return json.loads(_native.compare_cases(path, text, extra + _sets(overrides)))
from . import distributed  # noqa: E402,F401  (needs dask only when used)
