"""Registration errors between an estimated and a true 4×4 transform (SPEC §7)."""

from ._ggs import rre, rte

__all__ = ["rre", "rte"]
