"""Derivatives for users and what they are for: :func:`gradient` (adjoint, DDM
or finite differences of a scalar response), :func:`finite_difference`
(central differences of any output), and optimisation (:mod:`.optimize`)."""

from .finite_differences import finite_difference
from .gradient import Gradient, gradient

__all__ = ["Gradient", "finite_difference", "gradient"]
