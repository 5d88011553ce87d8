"""ggs: correspondence-free global registration of 3-D point clouds.

Greedy Grid Search (Bojanić et al., BMVC 2022 workshop) — voxelize both clouds, try every
rotation of a grid, find the best translation of each by FFT cross-correlation — then
verification of the distinct hypotheses and generalized ICP. No features, no training, no
initial guess.

    >>> import numpy as np, ggs
    >>> source = ggs.read_point_cloud("bun045.ply")          # (N, 3) float64
    >>> target = ggs.read_point_cloud("bun000.ply")
    >>> result = ggs.register(source, target, voxel=0.005)
    >>> result.transformation                                 # 4×4, p_target = T · p_source

Arrays are (N, 3) float32 or float64 numpy arrays; the transforms are 4×4 float64 arrays
with ``p_target = T · p_source``. The GIL is released while registering, and Ctrl-C stops a
long search.
"""

from ._ggs import (
    PRESETS,
    ROTATION_SETS,
    Result,
    __version__,
    read_point_cloud,
    refine,
    register,
    rotation_set,
    write_point_cloud,
)
from . import metrics

__all__ = [
    "PRESETS",
    "ROTATION_SETS",
    "Result",
    "__version__",
    "metrics",
    "read_point_cloud",
    "refine",
    "register",
    "rotation_set",
    "write_point_cloud",
]
