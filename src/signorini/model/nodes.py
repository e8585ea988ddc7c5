"""The contact node kernels of a contact kind, compiled once for every mesh
(:mod:`signorini.model.chunks`, docs/theory.md §10.6).

A kind is a contact method x an obstacle x its kinematics (linearised or
not). An item is a contact node: ``items = (x (2,), lam (m,), A (), X (2,),
N (2,), history[, case flags])`` (current position, multipliers, area,
reference position and outward normal, for friction the pair (s_n, tangential
mask), and the case flags when the caller holds them fixed: the DDM and the
adjoint take the converged tangent's); the obstacle geometry and the method's
values, ``(geo, cp)``, are shared by the nodes of a surface.
"""

from __future__ import annotations

from .._jax import jax, jnp
from ..contact.obstacles import Linearized
from .chunks import Chunked


class NodeKernels(Chunked):
    """The contact programs of one kind: ``NodeKernels.of(method, obstacle, linear)``.
    Kernels: ``"tangent"`` -> (K (k, k), r (k,)) with the friction case flags
    evaluated first at the node (one set of flags for both), ``"residual"`` -> (r,),
    ``"cases"`` -> (flags,), ``"fields"`` -> (gap, p_N, p_T)."""

    #: nodes per chunk: contact surfaces hold a few hundred to a few thousand
    #: nodes, whose kernels cost little next to the cells'
    SIZES = (1024, 64)

    def _kernel(self, name: str):
        method, obstacle, linear = self.parts

        def at(items, shared):
            x, lam, A, X0, N0, hs = items[:6]
            if len(items) > 6:  # case flags given
                hs = tuple(hs) + (items[6],)
            ob = Linearized(obstacle, X0, N0) if linear else obstacle
            return x, lam, A, ob, hs, shared[0], shared[1]

        if name == "tangent":
            def tangent(items, shared):
                x, lam, A, ob, hs, geo, cp = at(items, shared)
                if hs is not None and hasattr(method, "cases"):  # flags once, as data
                    hs = tuple(hs) + (method.cases(x, lam, geo, ob, cp, hs),)

                d = x.shape[-1]  # the node's coordinates (2 or 3)

                def r(v):
                    out = method.residual(v[:d], v[d:], A, geo, ob, cp, hs)
                    return out, out
                return jax.jacfwd(r, has_aux=True)(jnp.concatenate([x, lam]))
            return tangent
        if name == "residual":
            def residual(items, shared):
                x, lam, A, ob, hs, geo, cp = at(items, shared)
                return (method.residual(x, lam, A, geo, ob, cp, hs),)
            return residual
        if name == "cases":
            def cases(items, shared):
                x, lam, A, ob, hs, geo, cp = at(items, shared)
                return (method.cases(x, lam, geo, ob, cp, hs),)
            return cases
        if name == "fields":
            def fields(items, shared):
                x, lam, A, ob, hs, geo, cp = at(items, shared)
                return (ob.gap(x, geo),) + tuple(method.tractions(x, lam, A, geo, ob, cp))
            return fields
        raise KeyError(f"no contact node kernel {name!r}")
