"""Solution algorithms: Newton's method, load stepping with step cutting and
sensitivities (:func:`solve`), the :class:`Solution` it returns, the
coarse-to-fine start, and Uzawa's nested loops as a comparator."""

from .newton import NewtonOptions
from .solution import Solution
from .stepping import solve

__all__ = ["NewtonOptions", "Solution", "solve"]
