"""Sensitivities: the direct differentiation method (:mod:`.ddm`, used by
:func:`signorini.solve` after every converged increment) and central finite
differences (:mod:`.fd`) to check it. Import order: ``ddm`` depends on the
model only; ``fd`` calls :func:`signorini.solve` when it runs."""

from .ddm import DDM
from .fd import finite_difference

__all__ = ["DDM", "finite_difference"]
