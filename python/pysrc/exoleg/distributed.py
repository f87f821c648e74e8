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


def _run_shard(scenario, k: int, n: int, kwargs: Mapping[str, Any]) -> Tuple[bytes, bytes]:
    """Run shard k of n on a worker; return its ``shard.json`` and ``runs.jsonl`` bytes."""
    with tempfile.TemporaryDirectory(prefix="exoleg-shard-") as tmp:
        out = os.path.join(tmp, f"shard_{k}")
        exoleg.sweep(scenario, out=out, shard=(k, n), jobs=1, **kwargs)
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
    if shards is None:
        threads = sum(client.nthreads().values()) or 1
        shards = 2 * threads
    shards = max(1, min(int(shards), runs))
    futures = [client.submit(_run_shard, scenario, k, shards, kwargs, pure=False) for k in range(shards)]
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
