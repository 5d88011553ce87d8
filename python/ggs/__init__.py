"""ggs: correspondence-free global registration of 3-D point clouds.

Greedy Grid Search (Bojanić et al., BMVC 2022 workshop) — voxelize both clouds, try every
rotation of a grid covering SO(3), find the best translation of each by FFT
cross-correlation — then verification of the distinct hypotheses and generalized ICP. No
features, no training, no initial guess.

    >>> import numpy as np, ggs
    >>> source = ggs.read_point_cloud("tests/data/bun045.ply")   # (N, 3) float64
    >>> target = ggs.read_point_cloud("tests/data/bun000.ply")
    >>> result = ggs.register(source, target, voxel=0.005)
    >>> result.transformation                                     # 4×4, p_target = T · p_source

Points are (N, 3) arrays (float32 or float64 used in place; lists, array-likes and objects
with ``.points`` such as Open3D's PointCloud are converted); transforms are 4×4 float64
arrays with ``p_target = T · p_source``. The GIL is released while registering, and Ctrl-C
stops a long search.
"""

try:
    from ._ggs import PRESETS, ROTATION_SETS, __version__
except ImportError as e:  # the source folder python/ggs imported instead of the installed package
    raise ImportError(
        f"ggs's native module is missing ({e}): this is the source folder {__path__[0]}, not an "
        "installed ggs. Install it (pip install ./python) and run Python from another directory."
    ) from e
from ._api import (
    Evaluation,
    GgsWarning,
    Result,
    as_points,
    estimate_normals,
    evaluate,
    read_point_cloud,
    refine,
    register,
    render,
    register_many,
    rotation_set,
    settings,
    transform_points,
    voxel_downsample,
    write_point_cloud,
)
from ._align import Alignment, align
from . import bench, metrics

__all__ = [
    "Alignment",
    "Evaluation",
    "GgsWarning",
    "PRESETS",
    "ROTATION_SETS",
    "Result",
    "__version__",
    "align",
    "as_points",
    "bench",
    "estimate_normals",
    "evaluate",
    "metrics",
    "read_point_cloud",
    "refine",
    "register",
    "render",
    "register_many",
    "rotation_set",
    "settings",
    "transform_points",
    "voxel_downsample",
    "write_point_cloud",
]
