"""Registration errors between an estimated and a true 4×4 transform.

RRE = arccos(clip((trace(R_estᵀ·R_gt) − 1) / 2, −1, 1)) in degrees; RTE = ‖t_gt − t_est‖ in
the clouds' units. A registration succeeds when both are below a benchmark's thresholds.
"""

from ._ggs import rre, rte

__all__ = ["rre", "rte"]
