"""Sweeps on a Dask cluster (``dask.distributed``): the same sweep as :func:`exoleg.sweep`,
split into shards (one task per shard), each run on a worker, merged into the identical result.

>>> from dask.distributed import Client, LocalCluster
>>> client = Client(LocalCluster(n_workers=2, threads_per_worker=1))
>>> exoleg.distributed.sweep(client, "gait.toml", monte_carlo=64,
...                          vary={"hydraulics.beta_pa": "pct(10)"}, out="out/mc")

Each task writes its shard folder on the worker's file system and returns it as data (its
``shard.json`` and ``runs.jsonl``), so workers on other machines need no shared disk; the
client writes the shards locally and merges them (``exoleg merge``). A scenario given as a
path must be readable on the workers (or pass its TOML text).
"""

from __future__ import annotations

import os
import tempfile
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import exoleg


def _run_shard(scenario, k: int, n: int, kwargs: Mapping[str, Any], kind: str = "sweep") -> Tuple[bytes, bytes]:
    """Run shard k of n of a sweep (or a fault campaign, ``kind="faults"``) on a worker;
    return its ``shard.json`` and ``runs.jsonl`` bytes."""
    study = exoleg.faults if kind == "faults" else exoleg.sweep
    with tempfile.TemporaryDirectory(prefix="exoleg-shard-") as tmp:
        out = os.path.join(tmp, f"shard_{k}")
        study(scenario, out=out, shard=(k, n), jobs=1, **kwargs)
        with open(os.path.join(out, "shard.json"), "rb") as f:
            meta = f.read()
        with open(os.path.join(out, "runs.jsonl"), "rb") as f:
            runs = f.read()
    return meta, runs


def sweep(
    client: Any,
    scenario: Union[str, os.PathLike, Mapping[str, Any], None],
    *,
    grid: Optional[Mapping[str, Sequence[Any]]] = None,
    monte_carlo: Optional[int] = None,
    vary: Optional[Mapping[str, str]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Union[str, os.PathLike] = "out/sweep",
    shards: Optional[int] = None,
) -> "exoleg.Study":
    """Run the sweep on ``client`` (a ``dask.distributed.Client``) in ``shards`` tasks (default:
    twice the cluster's worker threads, at most the number of runs) and merge the shards into
    ``out``: the same ``runs.jsonl`` and ``aggregate.csv`` as ``exoleg.sweep`` on one machine."""
    if isinstance(scenario, os.PathLike):
        scenario = os.fspath(scenario)
    kwargs = dict(grid=grid, monte_carlo=monte_carlo, vary=vary, overrides=overrides)
    runs = len(exoleg.plan(scenario, grid=grid, monte_carlo=monte_carlo, vary=vary, overrides=overrides))
    return _sharded(client, scenario, kwargs, "sweep", runs, shards, out)


def faults(
    client: Any,
    scenario: Union[str, os.PathLike, Mapping[str, Any], None],
    *,
    matrix: Union[str, os.PathLike, None] = None,
    observe_strides: float = 2.0,
    overrides: Optional[Mapping[str, Any]] = None,
    out: Union[str, os.PathLike] = "out/faults",
    shards: Optional[int] = None,
) -> "exoleg.Study":
    """The fault campaign (:func:`exoleg.faults`) on ``client`` in ``shards`` tasks, merged into
    ``out``: the same ``faults.csv``, ``fmea.md`` and heat map as on one machine. A matrix file
    must be readable on the workers."""
    if isinstance(scenario, os.PathLike):
        scenario = os.fspath(scenario)
    if matrix is not None:
        matrix = os.path.abspath(os.fspath(matrix))
    kwargs = dict(matrix=matrix, observe_strides=observe_strides, overrides=overrides)
    runs = len(exoleg._native.plan("faults", **exoleg._args(scenario, overrides), matrix=matrix,
                                   observe_strides=float(observe_strides)))
    return _sharded(client, scenario, kwargs, "faults", runs, shards, out)


def _sharded(client, scenario, kwargs, kind, runs, shards, out) -> "exoleg.Study":
    """Submit ``shards`` tasks of a study of ``runs`` runs, gather them and merge into ``out``."""
    if shards is None:
        threads = sum(client.nthreads().values()) or 1
        shards = 2 * threads
    shards = min(exoleg._count("shards", shards, 1), runs)
    futures = [client.submit(_run_shard, scenario, k, shards, kwargs, kind, pure=False) for k in range(shards)]
    results = client.gather(futures)
    with tempfile.TemporaryDirectory(prefix="exoleg-merge-") as tmp:
        dirs = []
        for k, (meta, lines) in enumerate(results):
            d = os.path.join(tmp, f"shard_{k}")
            os.makedirs(d)
            with open(os.path.join(d, "shard.json"), "wb") as f:
                f.write(meta)
            with open(os.path.join(d, "runs.jsonl"), "wb") as f:
                f.write(lines)
            dirs.append(d)
        return exoleg.merge(dirs, out)
