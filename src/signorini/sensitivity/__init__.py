"""Sensitivity kernels: the direct differentiation method (:mod:`.ddm`, run by
:func:`signorini.solve` after every converged increment), the adjoint backward
pass (:mod:`.adjoint`) and the detection of switch points where a derivative
is one-sided (:mod:`.nonsmooth`). They work on a model and a factorised
tangent and never solve the nonlinear problem themselves; the user-facing
entry points (:func:`signorini.gradient`, :func:`signorini.finite_difference`)
live in :mod:`signorini.design`."""

from .ddm import DDM

__all__ = ["DDM"]
