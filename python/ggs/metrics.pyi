from ._ggs import rre as rre, rte as rte
