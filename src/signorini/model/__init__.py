"""The model: a :class:`Problem` (what the user describes), its DOF layout and
the compiled residual, tangent and pseudo-load kernels (:class:`Model`), and
the checks of a problem before and during a solve."""

from .kernels import Model
from .problem import Problem

__all__ = ["Model", "Problem"]
