"""Type stubs of the native module (the public names are re-exported by ``ggs``)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

Points = Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]
Matrix4 = npt.NDArray[np.float64]
StrPath = Union[str, "PathLike[str]"]

__version__: str
ROTATION_SETS: List[str]
PRESETS: List[str]

class Result:
    """The outcome of :func:`register` or :func:`refine`."""

    @property
    def transformation(self) -> Matrix4:
        """Final 4×4 float64 transform, ``p_target = T · p_source``."""
    @property
    def coarse_transformation(self) -> Optional[Matrix4]:
        """The chosen hypothesis's grid transform, before ICP (None after :func:`refine`)."""
    @property
    def confidence(self) -> Optional[float]:
        """In [0, 1]: 1 − (verification score of the best distinct runner-up) / (the chosen
        one's); without a verified runner-up, 1 − the coarse ambiguity. None after refine()."""
    @property
    def ambiguous(self) -> Optional[bool]:
        """True when two distinct poses explain the data about equally well."""
    @property
    def warnings(self) -> List[str]:
        """Ambiguity and low-evidence warnings (also issued with ``warnings.warn``)."""
    @property
    def chosen_rank(self) -> Optional[int]:
        """Rank of the chosen coarse hypothesis (0: the coarse winner)."""
    @property
    def verified(self) -> List[Dict[str, Any]]:
        """The verified hypotheses in coarse rank order: rank, rotation_index, match_score,
        polished_match_score, score, fitness_source, fitness_target, iterations,
        rejected_early, chosen, runner_up, coarse_transformation, transformation."""
    @property
    def fitness(self) -> Optional[float]:
        """Share of source points matched within the correspondence distance after refinement."""
    @property
    def fitness_target(self) -> Optional[float]:
        """Share of target points matched after refinement."""
    @property
    def inlier_rmse(self) -> Optional[float]:
        """RMS distance of the inlier correspondences, in the clouds' units."""
    @property
    def score(self) -> Optional[int]:
        """The coarse search's exact integer score."""
    @property
    def ambiguity(self) -> Optional[float]:
        """Runner-up / best match score over distinct rotations; near 1 means ambiguous."""
    @property
    def rotation_index(self) -> Optional[int]:
        """Index of the best rotation in the rotation set."""
    @property
    def voxel(self) -> Optional[float]:
        """Voxel size used by the coarse search."""
    @property
    def converged(self) -> Optional[bool]:
        """Whether the refinement converged."""
    @property
    def timings(self) -> Dict[str, float]:
        """Milliseconds: coarse_ms, target_ms, extents_ms, search_ms, refine_ms, total_ms."""
    @property
    def hypotheses(self) -> List[Dict[str, Any]]:
        """The ``top_k`` best distinct coarse hypotheses, best first."""
    @property
    def report(self) -> Optional[Dict[str, Any]]:
        """The refinement's quality report (fitness both ways, RMSE, eigenvalues, ...)."""

def register(
    source: Points,
    target: Points,
    voxel: Optional[float] = None,
    *,
    preset: str = "default",
    rotations: Optional[str] = None,
    refine: Optional[str] = None,
    threads: Optional[int] = None,
    top_k: Optional[int] = None,
    search: Optional[str] = None,
    precision: str = "mixed",
    max_hypotheses: Optional[int] = None,
    verify: bool = True,
    polish: bool = False,
) -> Result:
    """Register ``source`` onto ``target`` with no initial guess.

    voxel: grid size in the clouds' units (default: the target's longest side / 32).
    preset: ``default`` (the full-SO(3) set ``hopf15-id``, coarse-to-fine search, the
    distinct hypotheses whose match score is at least half the winner's (at most 8) refined
    on thinned clouds and the best-verified one kept, then GICP) or ``paper`` (the GGS
    paper: ``limited15``, exhaustive, one hypothesis, GICP). The other arguments change the
    preset: rotations (a name of ``ROTATION_SETS``), refine (``gicp``, ``p2plane``, ``p2p``,
    ``none``), search (``exhaustive`` or ``coarse-to-fine``), precision (``mixed``: f32 with
    proven error bounds and f64 re-scoring where they matter, the picks of ``f64``; or
    ``f64``), max_hypotheses (verified at most), verify=False (take the coarse winner),
    polish=True (a finer rotation grid around each hypothesis), top_k (coarse hypotheses
    reported). threads: default all cores; the result does not depend on it.
    Warnings (ambiguous poses, low evidence) are issued with ``warnings.warn`` and kept in
    ``Result.warnings``.
    Raises ValueError for arrays that are not (N, 3) float32/float64 or hold NaN.
    """

def refine(
    source: Points,
    target: Points,
    init: Matrix4,
    method: str = "gicp",
    max_distance: Optional[float] = None,
    distance_quantile: Optional[float] = None,
    max_iterations: Optional[int] = None,
    neighbors: Optional[int] = None,
    threads: Optional[int] = None,
) -> Result:
    """Refine an initial 4×4 transform by ICP (``gicp``, ``p2plane`` or ``p2p``).

    max_distance: a fixed correspondence distance (default: the distance_quantile, 0.25, of
    the nearest-neighbour distances at the start); max_iterations: 500; neighbors (for normals
    and covariances): 20. The defaults are the library's (the reference GICP's)."""

def read_point_cloud(
    path: StrPath,
    format: Optional[str] = None,
    *,
    scan: Optional[int] = None,
    apply_pose: bool = True,
    array: Optional[str] = None,
    sample_mesh: Optional[int] = None,
) -> npt.NDArray[np.float64]:
    """Read any format ggs reads (PLY, PCD, XYZ/TXT/CSV/PTS, NPY/NPZ, KITTI .bin, LAS/LAZ,
    E57, OBJ, STL). E57: `scan` picks one scan (default all, posed unless apply_pose=False);
    NPZ: `array` names the array; meshes: `sample_mesh=N` samples N points on the faces."""

def write_point_cloud(path: StrPath, points: Points, format: Optional[str] = None) -> None:
    """Write an (N, 3) array atomically; the format follows the extension unless given."""

def rotation_set(name: str) -> npt.NDArray[np.float64]:
    """A built-in rotation set as an (N, 3, 3) float64 array."""

def rre(estimate: Matrix4, truth: Matrix4) -> float:
    """Relative rotation error, degrees."""

def rte(estimate: Matrix4, truth: Matrix4) -> float:
    """Relative translation error, in the clouds' units."""
