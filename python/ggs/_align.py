"""``ggs.align``: many scans into one frame with no initial guess."""

from __future__ import annotations

import json
import os
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _ggs
from ._api import PointsLike, Preset, StrPath, as_points, native_options, read_point_cloud

ScanLike = Union[PointsLike, StrPath]


class Alignment:
    """The result of :func:`align`: each scan's pose in the common frame (``p_model = pose ·
    p_scan``) or ``None``, its confidence, the scans not placed, the pose graph."""

    def __init__(self, native: Any) -> None:
        self._native = native
        self.document: Dict[str, Any] = json.loads(native.document())
        """Everything, as ``poses.json`` holds it (format ``ggs-alignment/1``)."""
        scans = self.document["scans"]
        self.names: List[str] = [s["name"] for s in scans]
        """The scans' names, in the order given."""
        self.poses: List[Optional[npt.NDArray[np.float64]]] = [
            None if s["pose"] is None else np.array(s["pose"], dtype=np.float64) for s in scans
        ]
        """4×4 float64 pose of each scan, ``None`` for a scan not placed."""
        self.confidences: List[float] = [float(s["confidence"]) for s in scans]
        """The confidence of the registration that placed each scan (1 for the frame's scan,
        0 when not placed)."""
        self.reasons: List[Optional[str]] = [s["reason"] for s in scans]
        """Why each scan is not placed (``None`` when placed)."""
        self.anchor: str = self.document["anchor"]
        """The scan whose frame is the common frame."""
        self.warnings: List[str] = list(self.document["warnings"])
        self.graph: List[Dict[str, Any]] = list(self.document["edges"])
        """The pose graph's edges: ``from``, ``to`` (scan indices), ``relative`` (4×4,
        ``p_from = relative · p_to``), ``overlap``, ``accepted``, ``reason``."""
        self.registrations: int = int(self.document["registrations"])
        """Global registrations run."""
        self.settings: Dict[str, Any] = self.document["settings"]

    @property
    def unplaced(self) -> List[str]:
        """Names of the scans not placed, in the order given."""
        return [n for n, p in zip(self.names, self.poses) if p is None]

    def pose(self, name: str) -> Optional[npt.NDArray[np.float64]]:
        """The pose of the scan named ``name`` (``None`` when not placed)."""
        try:
            return self.poses[self.names.index(name)]
        except ValueError:
            raise KeyError(f"no scan named {name!r} (scans: {', '.join(self.names)})") from None

    def write(self, out_dir: StrPath) -> None:
        """Write poses.json, poses.txt, the moved scans (scans/), the merged model
        (model.ply) and report.html into ``out_dir``, as ``ggs align --out`` does."""
        self._native.write(os.fspath(out_dir))

    def report_html(self) -> str:
        """The report page (the scans in three views, the pose graph, every registration)."""
        result: str = self._native.report_html()
        return result

    def __repr__(self) -> str:
        placed = len(self.names) - len(self.unplaced)
        return f"<ggs.Alignment: {placed} of {len(self.names)} scans placed in the frame of {self.anchor}>"


def _scans(scans: Sequence[ScanLike], names: Optional[Sequence[str]]) -> Tuple[List[Any], List[str]]:
    """The scans as arrays (paths read) and their names (the paths as given, else
    ``scan 1``, ``scan 2``, …)."""
    arrays: List[Any] = []
    default: List[str] = []
    for k, s in enumerate(scans):
        if isinstance(s, (str, os.PathLike)):
            arrays.append(read_point_cloud(s))
            default.append(os.fspath(s))
        else:
            arrays.append(as_points(s, f"scans[{k}]"))
            default.append(f"scan {k + 1}")
    given = list(names) if names is not None else default
    if len(given) != len(arrays):
        raise ValueError(f"names: {len(given)} names for {len(arrays)} scans")
    return arrays, given


def align(
    scans: Sequence[ScanLike],
    *,
    names: Optional[Sequence[str]] = None,
    anchor: Optional[str] = None,
    voxel: Optional[float] = None,
    preset: Optional[Preset] = None,
    settings: Union[Dict[str, Any], StrPath, None] = None,
    threads: Optional[int] = None,
    executor: Literal["local", "ray"] = "local",
    progress: Optional[Callable[[int, int], None]] = None,
    **keywords: Any,
) -> Alignment:
    """Align ``scans`` (arrays, point-like objects or file paths) into one frame with no
    initial guess, as ``ggs align`` does.

    names: one per scan (default: the paths as given, else ``scan 1``, ``scan 2``, …).
    anchor: the name of the scan whose frame is the common frame (default: the first; when
      it cannot be placed, the frame is another scan's and ``warnings`` says so).
    voxel, preset, settings, threads and any settings key as a keyword (the ``align_*``
      keys among them): as for :func:`register`.
    executor: ``"local"`` runs every registration here; ``"ray"`` runs each registration
      of a batch as a Ray task (``align_batch`` registrations at once; the result is the
      same as with ``"local"`` for the same settings).
    progress: called as ``progress(scans_placed, total)`` (local executor).

    Returns an :class:`Alignment`. Raises ValueError for bad scans or settings.
    """
    arrays, given = _scans(scans, names)
    index = None
    if anchor is not None:
        if anchor not in given:
            raise ValueError(f"anchor: no scan named {anchor!r} (scans: {', '.join(given)})")
        index = given.index(anchor)
    options, _ = native_options(preset, settings, threads=threads, voxel=voxel, **keywords)
    if executor == "local":
        return Alignment(_ggs.align(arrays, given, options, index, progress))
    if executor != "ray":
        raise ValueError(f"executor must be 'local' or 'ray', not {executor!r}")
    return Alignment(_align_on_ray(arrays, given, options, index))


def _place_task(scan: Any, model: Any, options: Dict[str, Any], quick: bool) -> Any:
    """One placement's registration (a Ray task)."""
    return _ggs.place(scan, model, options, quick)


def _align_on_ray(arrays: List[Any], names: List[str], options: Dict[str, Any], anchor: Optional[int]) -> Any:
    """The placement loop with each batch's registrations as Ray tasks (the engine decides
    every step; the tasks only register)."""
    from ._ray import require_ray

    ray = require_ray()
    task_options = dict(options, threads=max(1, int(options["threads"] or 1)))
    place = ray.remote(num_cpus=task_options["threads"])(_place_task)
    aligner = _ggs.Aligner(arrays, names, options, anchor)
    refs = [ray.put(a) for a in arrays]
    while True:
        jobs = aligner.next_jobs()
        if not jobs:
            return aligner.finish()
        pending = [place.remote(refs[scan], model, task_options, quick) for scan, model, quick in jobs]
        aligner.record(ray.get(pending))
