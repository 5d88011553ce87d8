"""Type stubs of the native engine (the public API is ``ggs``, in ``ggs/_api.py``)."""

import os
from typing import Any, Callable, Dict, List, Optional, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "Aligner",
    "AlignmentResult",
    "BenchPlan",
    "RunDirectory",
    "PRESETS",
    "ROTATION_SETS",
    "Report",
    "__version__",
    "align",
    "bench_row_json",
    "estimate_normals",
    "evaluate",
    "place",
    "read_point_cloud",
    "refine",
    "register",
    "render_view",
    "rotation_set",
    "rre",
    "rte",
    "settings",
    "voxel_downsample",
    "write_point_cloud",
]
__version__: str
ROTATION_SETS: List[str]
PRESETS: List[str]

def register(
    source: npt.NDArray[Any],
    target: npt.NDArray[Any],
    options: Dict[str, Any],
    rotation_matrices: Optional[npt.NDArray[np.float64]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Tuple[str, Report]: ...
def refine(
    source: npt.NDArray[Any],
    target: npt.NDArray[Any],
    init: npt.NDArray[np.float64],
    changes: str,
    threads: int,
) -> str: ...
def settings(options: Dict[str, Any]) -> str: ...

_Outcome = Tuple[List[float], float, bool, List[str], bool, float]

@final
class AlignmentResult:
    def document(self) -> str: ...
    def write(self, dir: Union[str, os.PathLike[str]], command: Optional[str] = None) -> None: ...
    def report_html(self) -> str: ...

def align(
    scans: List[npt.NDArray[Any]],
    names: List[str],
    options: Dict[str, Any],
    anchor: Optional[int] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> AlignmentResult: ...
def place(
    scan: npt.NDArray[Any], model: npt.NDArray[Any], options: Dict[str, Any], quick: bool
) -> _Outcome: ...

@final
class Aligner:
    def __new__(
        cls,
        scans: List[npt.NDArray[Any]],
        names: List[str],
        options: Dict[str, Any],
        anchor: Optional[int] = None,
    ) -> Aligner: ...
    def next_jobs(self) -> List[Tuple[int, npt.NDArray[np.float64], bool]]: ...
    def record(self, outcomes: List[_Outcome]) -> None: ...
    def finish(self) -> AlignmentResult: ...
def read_point_cloud(
    path: str,
    format: Optional[str],
    scan: Optional[int],
    apply_pose: bool,
    array: Optional[str],
    sample_mesh: Optional[int],
) -> npt.NDArray[np.float64]: ...
def write_point_cloud(path: str, points: npt.NDArray[Any], format: Optional[str]) -> None: ...
def rotation_set(name: str) -> npt.NDArray[np.float64]: ...
def voxel_downsample(points: npt.NDArray[Any], voxel: float) -> npt.NDArray[np.float64]: ...
def estimate_normals(points: npt.NDArray[Any], neighbors: int) -> npt.NDArray[np.float64]: ...
def evaluate(
    source: npt.NDArray[Any],
    target: npt.NDArray[Any],
    transformation: npt.NDArray[np.float64],
    max_distance: float,
) -> Dict[str, Any]: ...
def rre(estimate: npt.NDArray[np.float64], truth: npt.NDArray[np.float64]) -> float: ...
def rte(estimate: npt.NDArray[np.float64], truth: npt.NDArray[np.float64]) -> float: ...
def render_view(
    layers: List[Tuple[npt.NDArray[Any], Tuple[int, int, int]]],
    view: str,
    width: int,
    height: int,
) -> npt.NDArray[np.uint8]: ...

@final
class Report:
    def html(self) -> str: ...
    def write(
        self,
        path: str,
        source_name: Optional[str] = None,
        target_name: Optional[str] = None,
        command: Optional[str] = None,
    ) -> None: ...

@final
class BenchPlan:
    def __new__(cls, selection: Dict[str, Any], options: Dict[str, Any]) -> BenchPlan: ...
    @property
    def name(self) -> str: ...
    @property
    def ids(self) -> List[str]: ...
    def default_out(self) -> str: ...
    def run_pair(self, k: int) -> Tuple[str, Optional[bytes]]: ...
    def error_row(self, k: int, message: str) -> str: ...

@final
class RunDirectory:
    def __new__(cls, plan: BenchPlan, out: Union[str, os.PathLike[str]]) -> RunDirectory: ...
    def recorded(self, ids: List[str]) -> Dict[str, Optional[str]]: ...
    def record(self, line: str, picture_png: Optional[bytes] = None) -> None: ...
    def finish(self) -> None: ...

def bench_row_json(line: str) -> str: ...
