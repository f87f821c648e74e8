"""exoleg: force control of hydraulic lower-limb exoskeletons, simulated.

Python bindings of the exoleg Rust simulator. Units are SI and stated in the names
(``force_n``, ``t_s``, ``knee_angle_deg``, ...), exactly as in ``timeseries.csv`` and
``summary.json`` (see the project's README). Simulations without a Python controller release
the GIL (Python threads run them in parallel) and stop on Ctrl-C.

>>> import exoleg
>>> r = exoleg.run()                                   # the embedded default scenario
>>> r.summary["max_abs_force_error_n"]
>>> r.timeseries["load_force_n"]                       # numpy array, N
>>> exoleg.run("gait.toml", {"controller.gamma": 200})

Your own controller in the loop (``controller.sample_period_s`` > 0):

>>> def pi(obs):                                       # called once per sample period
...     return 1e-4 * (obs.ref_force_n - obs.force_n)   # the valve command
>>> exoleg.run(None, {"controller.sample_period_s": 0.001}, controller=pi)
>>> sim = exoleg.Simulation(None, {"controller.sample_period_s": 0.001})
>>> obs = sim.reset(seed=1)
>>> while not sim.done:
...     obs = sim.step(1e-4 * (obs.ref_force_n - obs.force_n))
>>> result = sim.finish()
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import ControllerError, DivergedError, ExoError, Obs, ScenarioError

__all__ = [
    "run",
    "faults",
    "sweep",
    "robustness",
    "merge",
    "compare",
    "plan",
    "controller_info",
    "Simulation",
    "Obs",
    "Run",
    "Study",
    "Plan",
    "ExoError",
    "ScenarioError",
    "DivergedError",
    "ControllerError",
]
__version__ = _native.__version__

ScenarioLike = Union[None, str, os.PathLike, Mapping[str, Any]]
Controller = Callable[[Obs], Union[float, Mapping[str, float]]]


def _plain(v: Any, key: str) -> Any:
    """A Python value as plain JSON data (numpy scalars and arrays included); errors name the key."""
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return v
    if isinstance(v, int):
        if key == "seed" and 2**63 <= v < 2**64:
            return str(v)  # a seed is unsigned; TOML integers are signed (the CLI takes text)
        if not -(2**63) <= v < 2**63:
            raise ScenarioError(f"overrides: {key}: integer {v} is out of range (a scenario integer fits in 64 bits)")
        return v
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ScenarioError(f"overrides: {key}: must be a finite number, got {v}")
        return v
    if isinstance(v, np.ndarray):
        return [_plain(x, key) for x in v.tolist()]
    if isinstance(v, (list, tuple)):
        return [_plain(x, f"{key}.{i}") for i, x in enumerate(v)]
    if isinstance(v, Mapping):
        out = {}
        for k, x in v.items():
            if not isinstance(k, str):
                raise ScenarioError(f"overrides: {key}: a key must be a string, got {k!r}")
            out[k] = _plain(x, f"{key}.{k}" if key else k)
        return out
    raise ScenarioError(f"overrides: {key}: cannot use {v!r} ({type(v).__name__}) as a scenario value")


def _count(name: str, v: Any, low: int = 0, high: int = 2**63 - 1) -> int:
    """A whole number argument (``jobs``, ``monte_carlo``, ``samples``, a seed, a shard) checked
    here: a negative, fractional or huge one is a ``ScenarioError`` naming it, never an
    ``OverflowError`` from the native layer."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool) or not isinstance(v, int):
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        else:
            raise ScenarioError(f"{name}: expected a whole number, got {v!r}")
    if not low <= v <= high:
        raise ScenarioError(f"{name}: {v} is out of range ({low}..={high})")
    return v


def _out(out: Union[str, os.PathLike]) -> str:
    """An output path made absolute now (nothing a run loads later, such as a plugin changing
    the working directory, moves where its outputs go)."""
    return os.path.abspath(os.fspath(out))


def _scenario(scenario: ScenarioLike) -> Dict[str, Any]:
    """The scenario arguments of the native layer: a path, TOML text, or a dict as JSON data.

    A ``str`` is a path (a path may hold ``=``), unless it holds a newline and names no file:
    then it is scenario text (TOML). A dict is a scenario file's sections.
    """
    if scenario is None:
        return {}
    if isinstance(scenario, Mapping):
        return {"scenario_json": json.dumps(_plain(scenario, ""))}
    if isinstance(scenario, os.PathLike):
        return {"path": os.fspath(scenario)}
    if isinstance(scenario, str):
        if "\n" in scenario and not os.path.exists(scenario):
            return {"toml_text": scenario}
        return {"path": scenario}
    raise ScenarioError(f"scenario: expected a path, TOML text or a dict, got {type(scenario).__name__}")


def _overrides(overrides: Optional[Mapping[str, Any]]) -> Optional[str]:
    """``{"controller.gamma": 200}`` as JSON data: [[key, value], ...] (keys are keys: a key
    holding ``=`` is a key that does not exist)."""
    if overrides is None:
        return None
    if not isinstance(overrides, Mapping):
        raise ScenarioError("overrides: expected a dict of dotted keys, e.g. {'controller.gamma': 200}")
    pairs = []
    for k, v in overrides.items():
        if not isinstance(k, str):
            raise ScenarioError(f"overrides: a key must be a string, got {k!r}")
        pairs.append([k, _plain(v, k)])
    return json.dumps(pairs)


def _args(scenario: ScenarioLike, overrides: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
    a = _scenario(scenario)
    a["overrides_json"] = _overrides(overrides)
    return a


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


def _run(result: Tuple[str, Dict[str, np.ndarray], str]) -> Run:
    summary, columns, resolved = result
    return Run(json.loads(summary), dict(columns), resolved)


def run(
    scenario: ScenarioLike = None,
    overrides: Optional[Mapping[str, Any]] = None,
    *,
    controller: Optional[Controller] = None,
    out: Optional[Union[str, os.PathLike]] = None,
    baseline: bool = False,
) -> Run:
    """Run one scenario headless and return its figures and time series.

    ``scenario``: ``None`` (the embedded default, the paper's Figure 5 case), a path to a
    scenario TOML (or a ``summary.json`` to reproduce a run), TOML text, or a dict of sections.
    ``overrides``: dotted keys, ``{"controller.gamma": 200, "sim.duration_s": 2.0}``.
    ``controller``: your controller, a callable ``controller(obs)`` called once per sample
    period (``controller.sample_period_s`` > 0) with the readings (an :class:`Obs`, reused:
    keep its numbers, not the object); it returns the valve command, or a dict with
    ``valve_command`` and logged channels (columns ``log_<name>``). ``out``: also write the
    outputs of ``exoleg run`` there (whole, or not at all). ``baseline``: also run the scenario
    without the device's help (its cylinder disconnected; an ideal device gives no moment) and
    compare what the wearer's muscles cost (``summary["wearer"]["metabolics"]["change_pct"]``;
    needs ``wearer.muscles = true``), as ``exoleg run --baseline``.

    Raises ``ScenarioError`` (a ``ValueError``) for bad input, with the CLI's one-line message;
    ``DivergedError`` when the run diverges or its controller stops it; ``ControllerError``
    when the controller raises (its exception is the cause) or returns no usable command.
    """
    o = None if out is None else _out(out)
    return _run(_native.run(**_args(scenario, overrides), controller=controller, out=o, baseline=bool(baseline)))


def controller_info(scenario: ScenarioLike = None, overrides: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
    """What a controller of the scenario is told: ``sample_period_s``, ``valve_command_limit``,
    the nominal force model (``nominal``: n1, n2 in N/m, n3 in 1/s, tau_s in s, k_s), ``seed``,
    ``steps``, ``dt_s`` (the C plugin's ``ExolegInfo``)."""
    return json.loads(_native.controller_info(**_args(scenario, overrides)))


class Simulation:
    """A run whose loop you own (sampled: ``controller.sample_period_s`` > 0).

    >>> sim = exoleg.Simulation("gait.toml", {"controller.sample_period_s": 0.001})
    >>> obs = sim.reset(seed=1)            # the readings at t = 0
    >>> while not sim.done:
    ...     obs = sim.step(my_command(obs))  # held for one sample period; the next readings
    >>> result = sim.finish()               # an exoleg.Run; with out=..., the files too

    ``step`` takes the valve command or a dict with ``valve_command`` and logged channels.
    ``obs`` is one object updated in place at every sample. ``force_error_n`` is the true
    F_L - F_d now (not a reading). ``info``: what the controller is told (see
    :func:`controller_info`).
    """

    def __init__(
        self,
        scenario: ScenarioLike = None,
        overrides: Optional[Mapping[str, Any]] = None,
        *,
        out: Optional[Union[str, os.PathLike]] = None,
    ) -> None:
        o = None if out is None else _out(out)
        self._sim = _native.Simulation(**_args(scenario, overrides), out=o)
        self.info: Dict[str, Any] = json.loads(self._sim.info_json)

    def reset(self, seed: Optional[int] = None) -> Obs:
        """Start again from t = 0 (with ``seed`` in place of the scenario's); the first readings."""
        return self._sim.reset(None if seed is None else _count("seed", seed, 0, 2**64 - 1))

    def step(self, command: Union[float, Mapping[str, float]]) -> Obs:
        """Hold ``command`` for one sample period; the readings of the next sample."""
        return self._sim.step(command)

    @property
    def done(self) -> bool:
        """True once the run has taken all its steps."""
        return self._sim.done

    @property
    def t_s(self) -> float:
        """Simulated time (s)."""
        return self._sim.t_s

    @property
    def obs(self) -> Obs:
        """The readings of the last sample."""
        return self._sim.obs

    @property
    def force_error_n(self) -> float:
        """The true force error F_L - F_d (N) now."""
        return self._sim.force_error_n

    @property
    def gross_metabolic_w_per_kg(self) -> float:
        """The wearer's gross metabolic rate over the last step (W/kg: both legs' muscles over
        the body mass, plus 1.2 W/kg basal); NaN without the wearer's muscles
        (``wearer.model = "muscles"`` or ``wearer.muscles = true``) or before the first step."""
        return self._sim.gross_metabolic_w_per_kg

    def finish(self) -> Run:
        """Record the end (or now, if you stop early) and return the run, as :func:`run` does;
        the files are written if the simulation was given ``out``."""
        return _run(self._sim.finish())


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


def _grid_value(key: str, v: Any) -> str:
    """One grid value as the text of a ``--grid`` entry (numbers, booleans, strings)."""
    v = _plain(v, key)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str) and "," not in v:
        return json.dumps(v)
    raise ScenarioError(f"grid: {key}: a grid value is a number, a boolean or a string without commas, got {v!r}")


def _study_args(grid, vary) -> Dict[str, Any]:
    grids = []
    for k, vs in (grid or {}).items():
        if isinstance(vs, (str, bytes)) or not hasattr(vs, "__iter__"):
            raise ScenarioError(f"grid: {k}: expected a list of values, got {vs!r}")
        vals = list(vs.tolist() if isinstance(vs, np.ndarray) else vs)
        grids.append(f"{k}={','.join(_grid_value(k, v) for v in vals)}")
    if vary is not None and not isinstance(vary, Mapping):
        raise ScenarioError("vary: expected a dict, e.g. {'hydraulics.beta_pa': 'pct(10)'}")
    varies = []
    for k, d in (vary or {}).items():
        if not isinstance(d, str):
            raise ScenarioError(f"vary: {k}: expected a distribution text such as 'pct(10)', got {d!r}")
        varies.append(f"{k}={d}")
    return {"grids": grids, "vary": varies}


def _shard(shard) -> Optional[Tuple[int, int]]:
    if shard is None:
        return None
    if not (isinstance(shard, (tuple, list)) and len(shard) == 2):
        raise ScenarioError(f"shard: expected (K, N), got {shard!r}")
    n = _count("shard N", shard[1], 1, 10**6)
    return (_count("shard K", shard[0], 0, n - 1), n)


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
    controller: Optional[Controller] = None,
    resume: bool = False,
) -> Study:
    """Run many variations of a scenario in parallel, like ``exoleg sweep``.

    ``grid``: ``{"controller.gamma": [100, 200]}`` (full factorial), or ``monte_carlo=N`` with
    ``vary={"hydraulics.beta_pa": "pct(10)"}`` (``uniform(lo,hi)``, ``normal(mean,sd)``,
    ``pct(p)``). ``shard=(K, N)`` runs only the runs with index % N == K and writes a shard
    folder for :func:`merge`. ``jobs``: worker threads (0 = all cores). ``controller``: your
    Python controller for every run (as in :func:`run`); the runs then go one after the other
    in this process (``jobs`` is 1), and a run whose controller fails is a failed line.
    Every run's line is kept as it finishes; ``resume=True`` keeps the runs an interrupted
    study of the same plan into the same ``out`` finished and makes only the others (as the
    CLI's ``--resume``).
    """
    title, agg = _native.study(
        "sweep",
        _out(out),
        **_args(scenario, overrides),
        **_study_args(grid, vary),
        monte_carlo=None if monte_carlo is None else _count("monte_carlo", monte_carlo, 1, 10**6),
        jobs=_count("jobs", jobs, 0, 2**32),
        shard_k_n=_shard(shard),
        controller=controller,
        resume=bool(resume),
    )
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
    controller: Optional[Controller] = None,
    resume: bool = False,
) -> Study:
    """The robustness report, like ``exoleg robustness`` (the plant's parameters +-``percent``
    %, the controller keeping its nominal model, the paper's Table 2 disturbances).
    ``controller``, ``resume``: as in :func:`sweep`."""
    title, agg = _native.study(
        "robustness",
        _out(out),
        **_args(scenario, overrides),
        percent=float(percent),
        samples=_count("samples", samples, 1, 10**6),
        jobs=_count("jobs", jobs, 0, 2**32),
        shard_k_n=_shard(shard),
        controller=controller,
        resume=bool(resume),
    )
    return Study(title, agg, os.fspath(out))


def faults(
    scenario: ScenarioLike,
    *,
    matrix: Union[str, os.PathLike, None] = None,
    observe_strides: float = 2.0,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Union[str, os.PathLike] = "out/faults",
    jobs: int = 0,
    shard: Optional[Tuple[int, int]] = None,
    controller: Optional[Controller] = None,
    resume: bool = False,
) -> Study:
    """The fault campaign, like ``exoleg faults``: every failure mode of ``matrix`` (a TOML
    file; default: the modes that apply to the scenario, see ``exoleg faults --print-matrix``)
    at every onset and severity, each run scored by the scenario's ``[safety]`` limits; writes
    ``faults.csv``, ``fmea.csv``, ``fmea.md`` and ``faults.png`` into ``out`` (or a shard
    folder with ``shard``). ``controller``: your Python controller for every run (it may read
    the device's channels; a campaign then also faults ``heel_force_n`` and
    ``shank_gyro_y_rad_s``). ``jobs``, ``resume``: as in :func:`sweep`. Unlike the CLI, a run
    that breaks a safety criterion raises nothing: read ``fmea.md`` or ``faults.csv``."""
    title, agg = _native.study(
        "faults",
        _out(out),
        **_args(scenario, overrides),
        matrix=None if matrix is None else os.path.abspath(os.fspath(matrix)),
        observe_strides=float(observe_strides),
        jobs=_count("jobs", jobs, 0, 2**32),
        shard_k_n=_shard(shard),
        controller=controller,
        resume=bool(resume),
    )
    return Study(title, agg, os.fspath(out))


class Plan(Sequence):
    """The runs of a study, expanded lazily: ``len(plan)``, ``plan[i]`` (``{"index": i,
    "sets": [...]}``), iteration. A plan of 10^6 runs costs nothing until its runs are read."""

    def __init__(self, native: Any) -> None:
        self._p = native

    def __len__(self) -> int:
        return len(self._p)

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        n = len(self)
        if i < 0:
            i += n
        return {"index": i, "sets": self._p.sets(i)}

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]


def plan(
    scenario: ScenarioLike,
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = None,
    monte_carlo: Optional[int] = None,
    vary: Optional[Mapping[str, str]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
) -> Plan:
    """The expanded runs of a sweep (index and overrides of each), without running them."""
    n = None if monte_carlo is None else _count("monte_carlo", monte_carlo, 1, 10**6)
    return Plan(_native.plan("sweep", **_args(scenario, overrides), **_study_args(grid, vary), monte_carlo=n))


def merge(shards: Sequence[Union[str, os.PathLike]], out: Union[str, os.PathLike]) -> Study:
    """Merge shard folders into what the unsharded study writes (``exoleg merge``)."""
    if isinstance(shards, (str, bytes, os.PathLike)):
        raise ScenarioError("merge: expected a list of shard folders")
    title, agg = _native.merge([os.fspath(s) for s in shards], _out(out))
    return Study(title, agg, os.fspath(out))


def compare(scenario: ScenarioLike = None, overrides: Optional[Mapping[str, Any]] = None) -> List[Dict[str, Any]]:
    """The paper's eight cases (Tables 3 and 4) on a base scenario, like ``exoleg compare``.
    Each result: case, controller, max errors (N), convergence times (s), the paper's figures."""
    return json.loads(_native.compare_cases(**_args(scenario, overrides)))


from . import distributed  # noqa: E402,F401  (needs dask only when used)
