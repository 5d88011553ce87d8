"""A typed use of the ggs API, checked by ``mypy --strict`` in CI (run from the repository root).

    python python/examples/typed_example.py
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import List, Optional

import numpy as np
import numpy.typing as npt

import ggs

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"


def register_bundled_pair() -> ggs.Result:
    source: npt.NDArray[np.float64] = ggs.read_point_cloud(DATA / "bun0.pcd")
    target = ggs.read_point_cloud(DATA / "bun4.pcd")
    steps: List[int] = []
    result = ggs.register(
        source, target, voxel=0.006, preset="default", progress=lambda done, total: steps.append(done)
    )
    confidence: Optional[float] = result.confidence
    print(f"confidence {confidence}, {len(result.verified)} verified, {len(steps)} progress calls")
    moved = ggs.transform_points(source, result.transformation)
    e: ggs.Evaluation = ggs.evaluate(source, target, result.transformation, max_distance=0.002)
    print(f"fitness {e.fitness:.3f}, RMSE {e.inlier_rmse:.5f}, moved {moved.shape}")
    return result


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", ggs.GgsWarning)
        r = register_bundled_pair()
    truth = np.loadtxt(DATA / "bun0_to_bun4_groundtruth.txt")
    print(f"RRE {ggs.metrics.rre(r.transformation, truth):.3f}°")


if __name__ == "__main__":
    main()
