"""Direct differentiation (DDM) sensitivities, paper eqs. 3-6 (docs/theory.md §1).

After each converged increment, for all design parameters phi_k at once::

    P_k  = dR/dphi_k + dR/dw_p . dw_p/dphi_k + dR/d(state_n) . d(state_n)/dphi_k   (one batched JVP)
    K dw_k/dphi = -P_k                                                              (one back-substitution each)

with K the exact tangent at the converged state, already factorised. No
iterations: the multipliers' sensitivities come out of the same solve.
:func:`signorini.sensitivity.fd.finite_difference` computes the same
derivatives by central differences, for checking.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from .._jax import jax, jnp
from ..params import unit_tangents


class DDM:
    """Batched DDM pseudo-loads and sensitivity solves for one model.

    Args:
        model: the :class:`~signorini.model.Model`.
        names: design parameters (must be keys of the parameter dict).
    """

    def __init__(self, model, names: Sequence[str]):
        self.model = model
        self.names = list(names)

        def wp_dot(params, t, e):
            return jax.jvp(lambda p: model.prescribed_values(p, t), (params,), (e,))[1]

        def pseudo(w, params, t, state_n, cases, w_dot, e, state_dot_n):
            f = lambda w_, p_, s_: model.residual(w_, p_, t, s_, cases)
            return jax.jvp(f, (w, params, state_n), (w_dot, e, state_dot_n))[1]

        self._wp_dot = jax.jit(jax.vmap(wp_dot, (None, None, 0)))
        self._pseudo = jax.jit(jax.vmap(pseudo, (None, None, None, None, None, 0, 0, 0)))

    def solve(self, factor, w, params, t, state_n=None, state_dot_n=None):
        """Sensitivities dw/dphi (n_names, n_dof) at a converged increment.

        Args:
            factor: factorisation of the free-free tangent at ``w``.
            state_dot_n: sensitivities of the previous state (batched over names).

        Returns:
            (w_dot, timings) with w_dot (n_names, n_dof) including the prescribed DOFs.
        """
        m = self.model
        t0 = time.perf_counter()
        e = unit_tangents(params, self.names)
        w_dot = np.zeros((len(self.names), m.n_dof))
        if m.prescribed.size:
            w_dot[:, m.prescribed] = np.asarray(self._wp_dot(params, t, e))
        # friction: the branch of every node fixed as in the converged tangent
        cases = m._cases(w, params, t, state_n) if m.has_contact_history else None
        P = np.asarray(self._pseudo(w, params, t, state_n, cases, jnp.asarray(w_dot), e, state_dot_n))
        t1 = time.perf_counter()
        w_dot[:, m.free] = -factor.solve(np.ascontiguousarray(P[:, m.free].T)).reshape(m.free.size, -1).T
        t2 = time.perf_counter()
        return w_dot, {"pseudo_load": t1 - t0, "back_substitution": t2 - t1}
