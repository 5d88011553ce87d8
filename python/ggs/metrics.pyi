from ._ggs import rre as rre, rte as rte

__all__ = ["rre", "rte"]
