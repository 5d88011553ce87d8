"""Benchmarks from Python: the protocols and manifests of ``ggs bench``, run here or on a Ray
cluster, into the same run directory and files.

    >>> import ggs.bench
    >>> run = ggs.bench.run("tests/data/pairs.tsv", out="runs/bundled")       # doctest: +SKIP
    >>> run.recall, run.summary["pairs"]                                      # doctest: +SKIP

``executor="ray"`` sends every pair to a Ray worker (``ray.init()`` is called unless Ray is
already initialized: a local cluster, or the one of ``RAY_ADDRESS``). Paths travel, not
arrays: each worker reads the clouds of its pair, so the clouds must be where the workers
can read them (a shared file system on a multi-node cluster). The driver writes the run
directory as pairs finish — ``pairs.csv`` line by line, so an interrupted run started again
skips what is done — and at the end the files ``ggs bench`` writes (``pairs.csv`` in the
protocol's order, ``results.json``, ``summary.md``, ``recall.svg``, ``report.html``):
identical, whichever executor ran the pairs, apart from the ``*_ms`` timing columns.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, List, Literal, Optional, Tuple, Union

from . import _ggs
from ._api import StrPath, native_options

#: The published protocols (each needs ``data``); anything else is a manifest file.
PROTOCOLS = ("3dmatch", "kitti", "eth", "fpv1")
Executor = Literal["local", "ray"]
#: ``progress(done, total, row)`` after each pair; ``row`` as in ``results.json``'s pairs.
BenchProgress = Callable[[int, int, Dict[str, Any]], None]
#: The error of a pair whose task was lost (its worker died more often than Ray retries):
#: such a pair is run again when the run is resumed.
LOST = "executor: "


@dataclass(frozen=True)
class BenchRun:
    """A finished run: its directory and what ``results.json`` holds."""

    out: Path
    #: Pairs, successes, recall (fraction), mean errors, times: ``results.json``'s summary.
    summary: Dict[str, Any]
    #: One dict per pair (the columns of ``pairs.csv``), in the protocol's order.
    pairs: List[Dict[str, Any]]
    #: Pairs taken from an earlier, interrupted run of the same directory.
    resumed: int

    @property
    def recall(self) -> float:
        """Successful pairs over all pairs, in percent."""
        return float(self.summary["recall"]) * 100.0

    @property
    def markdown(self) -> str:
        """The summary table (``summary.md``)."""
        return (self.out / "summary.md").read_text()


def _selection(protocol: StrPath, data: Optional[StrPath], **given: Any) -> Dict[str, Any]:
    """The native selection: paths made absolute, so that workers elsewhere find them."""
    name = os.fspath(protocol)
    is_protocol = name in PROTOCOLS
    return {
        "protocol": name if is_protocol else "manifest",
        "manifest": None if is_protocol else os.path.abspath(name),
        "data": None if data is None else os.path.abspath(os.fspath(data)),
        **given,
    }


_PLANS: Dict[str, Any] = {}


def _plan(spec: str) -> Any:
    """The plan of a spec (JSON of selection and options), built once per process."""
    plan = _PLANS.get(spec)
    if plan is None:
        d = json.loads(spec)
        plan = _PLANS[spec] = _ggs.BenchPlan(d["selection"], d["options"])
    return plan


def _run_pair(spec: str, k: int) -> Tuple[str, Optional[bytes]]:
    """Run pair ``k`` of the spec's plan where this is called (a Ray task)."""
    result: Tuple[str, Optional[bytes]] = _plan(spec).run_pair(k)
    return result


def _tty_progress(done: int, total: int, row: Dict[str, Any]) -> None:
    end = "\n" if done == total else ""
    sys.stderr.write(f"\r{done}/{total} pairs, last {row['id']}\x1b[K{end}")
    sys.stderr.flush()


def run(
    protocol: StrPath,
    *,
    data: Optional[StrPath] = None,
    out: Optional[StrPath] = None,
    pairs: Optional[str] = None,
    limit: Optional[int] = None,
    shard: Optional[str] = None,
    voxel: Union[float, str, None] = None,
    move_seed: Optional[int] = None,
    max_rre: Optional[float] = None,
    max_rte: Optional[float] = None,
    executor: Executor = "local",
    threads: Optional[int] = None,
    retries: int = 3,
    progress: Union[BenchProgress, bool, None] = None,
    **options: Any,
) -> BenchRun:
    """Run a benchmark as ``ggs bench`` does, pair by pair, into the run directory ``out``
    (default ``ggs-bench-<protocol>``; resumed if it holds an interrupted run of the same
    configuration, refused if it holds another).

    protocol: ``"3dmatch"``, ``"kitti"``, ``"eth"``, ``"fpv1"`` (with ``data``, the clouds'
      directory), or the path of a manifest (``pairs.tsv`` format).
    pairs, limit, shard, voxel, move_seed, max_rre, max_rte: as ``ggs bench``'s ``--pairs``,
      ``--limit``, ``--shard I/N``, ``--voxel`` (a size or ``"auto"``, the voxel
      :func:`ggs.register` picks with no ``voxel``), ``--move-seed``, ``--max-rre``,
      ``--max-rte``.
    executor: ``"local"`` (this process, one pair after another) or ``"ray"`` (one Ray task
      per pair). threads: per pair; for Ray each task reserves this many CPUs (default 1),
      locally None means all cores. retries: Ray's retries of a task whose worker died; a
      pair still lost is recorded as failed with an error starting ``"executor: "`` and is
      run again when the run is resumed.
    progress: ``progress(done, total, row)`` as each pair finishes (in the order they
      finish); True prints a line on stderr; None prints it when stderr is a terminal.
    options: the pipeline options of :func:`ggs.register` (``preset``, ``rotations`` by name,
      ``refine``, ``search``, ``verify``, ...).

    Returns a :class:`BenchRun`. A pair that cannot be read or registered is a failed row
    with its error, never an exception; bad arguments raise ValueError.
    """
    if executor not in ("local", "ray"):
        raise ValueError(f"executor must be 'local' or 'ray', not {executor!r}")
    if not isinstance(options.get("rotations", ""), (str, type(None))):
        raise ValueError("a benchmark takes rotations by name (see ggs.ROTATION_SETS)")
    if threads is None and executor == "ray":
        threads = 1
    native, _ = native_options(threads=threads, **options)
    selection = _selection(
        protocol, data, pairs=pairs, limit=limit, shard=shard, voxel=voxel,
        move_seed=move_seed, max_rre=max_rre, max_rte=max_rte,
    )  # fmt: skip
    spec = json.dumps({"selection": selection, "options": native}, sort_keys=True)
    plan = _plan(spec)
    out_dir = Path(out) if out is not None else Path(plan.default_out())
    report = _tty_progress if progress is True or (
        progress is None and sys.stderr.isatty()
    ) else (progress or None)
    directory = _ggs.RunDirectory(plan, out_dir)
    ids: List[str] = plan.ids
    recorded = directory.recorded(ids)
    todo = [k for k, i in enumerate(ids) if not (i in recorded and not _lost(recorded[i]))]
    done = resumed = len(ids) - len(todo)

    def record(line: str, png: Optional[bytes]) -> None:
        nonlocal done
        directory.record(line, png)
        done += 1
        if report is not None:
            report(done, len(ids), json.loads(_ggs.bench_row_json(line)))

    if executor == "local":
        for k in todo:
            record(*plan.run_pair(k))
    else:
        from ._ray import run_tasks

        run_tasks(
            _run_pair,
            ((k, (spec, k)) for k in todo),
            cpus=max(1, native["threads"] or 1),
            retries=retries,
            on_result=lambda k, v: record(*v),
            on_error=lambda k, e: record(plan.error_row(k, f"{LOST}{_one_line(e)}"), None),
        )
    directory.finish()
    results = json.loads((out_dir / "results.json").read_text())
    return BenchRun(out_dir, results["summary"], results["pairs"], resumed)


def _lost(error: Optional[str]) -> bool:
    return error is not None and error.startswith(LOST)


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text[:300]}"
