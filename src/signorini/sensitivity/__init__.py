"""Sensitivity kernels: the direct differentiation method (:mod:`.ddm`, run by
:func:`signorini.solve` after every converged increment), the adjoint backward
pass (:mod:`.adjoint`) and the detection of switch points where a derivative
is one-sided (:mod:`.nonsmooth`). They work on a model and a factorised
tangent and never solve the nonlinear problem themselves. :mod:`.methods`
holds the objects a user names a method with (``DDM()``, ``Adjoint()``,
``FiniteDifferences()``); the user-facing
entry points (:func:`signorini.gradient`, :func:`signorini.finite_difference`)
live in :mod:`signorini.design`."""

from .methods import DDM, Adjoint, FiniteDifferences

__all__ = ["DDM", "Adjoint", "FiniteDifferences"]
