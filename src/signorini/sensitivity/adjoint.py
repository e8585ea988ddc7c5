"""Adjoint gradients of a scalar response along a path-dependent solution
(docs/theory.md §11).

Increment n solves R_n(w_n, phi, s_{n-1}) = 0 on the free rows, with the
prescribed unknowns w_n,p = w_p(phi, t_n), and updates the history
s_n = U(w_n, phi, s_{n-1}) (the state pytree of :class:`~signorini.model.Model`).
For G = sum_n G_n(w_n, phi, t_n, s_{n-1}) the backward pass runs n = N..1 with
the cotangent s^_n of the state after increment n (zero after the last one)::

    w^    = dG_n/dw + (dU/dw)^T s^_n                       (response + history, two VJPs)
    K_ff^T mu = w^_f                                        (transposed exact tangent)
    (w^_R, phi^_R, s^_R) = (dR/d(w, phi, s_{n-1}))^T c,     c_f = -mu, c_p = 0  (one VJP)
    phi^ += dG_n/dphi + (dU/dphi)^T s^_n + phi^_R + (dw_p/dphi)^T (w^_p + w^_R,p)
    s^_{n-1} = dG_n/ds + (dU/ds)^T s^_n + s^_R

and at the end phi^ += (ds_0/dphi)^T s^_0. Every transpose is a JAX VJP of the
same pure functions the DDM differentiates forward (never written by hand), and
the friction branch of each node is held as in the converged tangent, so the
adjoint gradient equals the DDM one to round-off, for any number of parameters:
``params["nodes"]`` (n_nodes, 2) gives the gradient with respect to every nodal
coordinate at the cost of the same single backward pass.
"""

from __future__ import annotations

import logging
from functools import partial
import time

import numpy as np

from .._jax import jax, jnp, to_device
from ..errors import SingularTangentError, SolverError
from ..linsolve import TangentSolver, for_model, get_solver, openblas_single_thread
from ..model.kernels import NODES

log = logging.getLogger("signorini")

#: backward error above which a transposed solve is an error, not a gradient
ACCURACY = 1e-10


class _Replay:
    """States before each increment for a backward pass: kept ones read, dropped
    ones (``solve(method=Adjoint(checkpoint=k))``) replayed once per segment and held until the
    pass leaves it (at most k states at a time)."""

    def __init__(self, sol):
        self.sol = sol
        self.held: dict = {}

    def before(self, n: int):
        if n == 0:
            return self.sol.state_before(0)[0]
        incs = self.sol.increments
        if incs[n - 1].state is not None:
            return incs[n - 1].state
        if n - 1 not in self.held:
            self.held = self.sol.replay(n - 1)
        return self.held[n - 1]


def _add(a, b):
    """Sum of two cotangent pytrees, either of which may be None."""
    if a is None:
        return b
    if b is None:
        return a
    return jax.tree_util.tree_map(lambda x, y: x + y, a, b)


class Adjoint:
    """Compiled VJPs of one model for a response ``fn(w, params, t, state_n)``."""

    def __init__(self, model, fn):
        self.model = m = model
        self._fn = jax.jit(jax.value_and_grad(fn, argnums=(0, 1, 3)))

        # on a mesh evaluated by the element kind's programs (Model.by_kind), these
        # programs take the contact and external forces and the contact history only,
        # the element part comes from the kind's programs (Model.element_vjp)
        def res_vjp(w, p, t, s, cases, c, part="all"):
            return jax.vjp(lambda w_, p_, s_: m.residual(w_, p_, t, s_, cases, part),
                           w, p, s)[1](c)

        def upd_vjp(w, p, t, s, c, part="all"):
            return jax.vjp(lambda w_, p_, s_: m.update(w_, p_, t, s_, part), w, p, s)[1](c)

        def wp_vjp(p, t, c):
            return jax.vjp(lambda p_: m.prescribed_values(p_, t), p)[1](c)[0]

        def init_vjp(p, c):
            return jax.vjp(lambda p_: m.initial_state(jnp.zeros(m.n_dof), p_), p)[1](c)[0]

        self._res_vjp_whole = m.program(res_vjp, "adjoint_residual_vjp")
        self._upd_vjp_whole = m.program(upd_vjp, "adjoint_update_vjp")
        self._res_vjp_rest = m.program(partial(res_vjp, part="rest"), "adjoint_residual_vjp_rest")
        self._upd_vjp_rest = m.program(partial(upd_vjp, part="contact"), "adjoint_update_vjp_contact")
        self._wp_vjp = m.program(wp_vjp, "adjoint_prescribed_vjp")
        self._init_vjp = m.program(init_vjp, "adjoint_initial_vjp")
        self._cases = m.compiled.cases

    def _res_vjp(self, w, pe, t, s, cases, c):
        """(dR/d(w, phi, s))^T c: a whole-mesh program, or the rest's program plus
        the elements' programs."""
        m = self.model
        if not m.by_kind:
            return self._res_vjp_whole(w, pe, t, s, cases, c)
        rw, rp, rs = self._res_vjp_rest(w, pe, t, m.without_material(s), cases, c)
        ew, ep, eh = m.element_vjp("update", (0,), w, pe, s, (np.asarray(c)[m.edofs],))
        return np.asarray(rw) + ew, _add(rp, ep), self._with_material(rs, eh)

    def _upd_vjp(self, w, pe, t, s, c):
        """(dU/d(w, phi, s))^T c: the contact history's program plus, with a
        material history, the elements' programs (or a whole-mesh program)."""
        m = self.model
        if not m.by_kind:
            return self._upd_vjp_whole(w, pe, t, s, c)
        uw, up, us = self._upd_vjp_rest(w, pe, t, m.without_material(s), (c[0], c[1], None))
        if not m.n_state:
            return uw, up, us
        ew, ep, eh = m.element_vjp("update", (1,), w, pe, s, (np.asarray(c[2]),))
        return np.asarray(uw) + ew, _add(up, ep), self._with_material(us, eh)

    def _with_material(self, s_bar, h_bar):
        """A state cotangent (w_n, contact, None) completed with the Gauss-point history's."""
        if s_bar is None or not self.model.n_state:
            return s_bar
        return (s_bar[0], s_bar[1], h_bar)

    def backward(self, solution, params_ext: dict, selected, *, solver="auto"):
        """d(sum over ``selected`` increments of G_n)/d(params_ext) by one backward pass.

        Args:
            solution: a converged :class:`~signorini.algorithms.solution.Solution` of the model
                (its increments' unknowns and states; factors if kept).
            params_ext: the parameter dict (JAX), possibly with ``"nodes"``.
            selected: increment indices whose G_n enter the sum.

        Returns:
            (G, gradient pytree like params_ext, timings dict).
        """
        with openblas_single_thread():
            return self._backward(solution, params_ext, sorted(set(selected)), solver)

    def _backward(self, sol, pe, selected, solver):
        m = self.model
        params = {k: v for k, v in pe.items() if k != NODES}
        lin = TangentSolver(for_model(get_solver(solver), m), symmetric_candidate=not m.has_history,
                            analysis=lambda: m.analysis_tangent(params))
        # under mpiexec: each rank evaluates the element kernels of its own cells
        with m.sharing(getattr(lin.solver, "communicator", None)):
            return self._sweep(sol, pe, selected, lin, params)

    def _sweep(self, sol, pe, selected, lin, params):
        m = self.model
        grad = jax.tree_util.tree_map(jnp.zeros_like, pe)
        G = 0.0
        s_bar = None  # cotangent of the state after increment n
        timing = {"tangent_factorization": 0.0, "solve": 0.0, "vjp": 0.0, "increments": 0,
                  "factorizations": 0}
        N = len(sol.increments)
        first = selected[0] if selected else N
        states = _Replay(sol)
        for n in range(N - 1, -1, -1):
            if not m.has_history and n < first:
                break  # without history nothing flows to earlier increments
            inc = sol.increments[n]
            t = inc.t
            w = to_device(inc.w)
            s_prev = states.before(n) if m.has_history else None
            t0 = time.perf_counter()
            w_bar = jnp.zeros(m.n_dof)
            s_prev_bar = None
            if n in selected:
                g, (gw, gp, gs) = self._fn(w, pe, t, s_prev)
                G += float(g)
                w_bar, grad, s_prev_bar = w_bar + gw, _add(grad, gp), gs
            if s_bar is not None:
                uw, up, us = self._upd_vjp(w, pe, t, s_prev, s_bar)
                w_bar, grad, s_prev_bar = w_bar + uw, _add(grad, up), _add(s_prev_bar, us)
            w_bar = np.asarray(w_bar)
            t1 = time.perf_counter()
            timing["vjp"] += t1 - t0
            if np.any(w_bar[m.free] != 0.0):
                c = self._multiplier(inc, w, params, s_prev, w_bar, lin, timing)
                t3 = time.perf_counter()
                # the branch flags of the converged tangent (evaluated as in local_tangents)
                cases = self._cases(w, params, t, s_prev) if m.has_contact_history else None
                rw, rp, rs = self._res_vjp(w, pe, t, s_prev, cases, to_device(c))
                w_p_bar = w_bar[m.prescribed] + np.asarray(rw)[m.prescribed]
                grad, s_prev_bar = _add(grad, rp), _add(s_prev_bar, rs)
            else:
                t3 = t1
                w_p_bar = w_bar[m.prescribed]
            if m.prescribed.size and np.any(w_p_bar != 0.0):
                grad = _add(grad, self._wp_vjp(pe, t, to_device(w_p_bar)))
            s_bar = s_prev_bar if m.has_history else None
            timing["vjp"] += time.perf_counter() - t3
            timing["increments"] += 1
            log.debug("adjoint: increment %d (t = %.4g) done", n + 1, t)
        if m.has_history and s_bar is not None:
            grad = _add(grad, self._init_vjp(pe, s_bar))
        log.info("adjoint: backward pass over %d increment(s), %d factorisation(s)",
                 timing["increments"], timing["factorizations"])
        return G, grad, timing

    def _multiplier(self, inc, w, params, s_prev, w_bar, lin, timing):
        """The adjoint multiplier of increment ``inc``: ``-K^-T w_bar`` on the free DOFs.

        Reuses the increment's kept factorisation when there is one, else factorises
        the converged tangent again (counted in ``timing``)."""
        m, t = self.model, inc.t
        t1 = time.perf_counter()
        fac = inc.factor
        if fac is None:
            _, blocks = m.local_tangents(w, params, t, s_prev)
            try:
                fac = lin.factorize(m.pattern.assemble(blocks))
            except SingularTangentError as e:
                raise SingularTangentError(
                    f"the converged tangent at t={t:.6g} is singular, so the adjoint "
                    f"gradient is undefined: {e}") from None
            timing["factorizations"] += 1
        t2 = time.perf_counter()
        mu = fac.solve(np.ascontiguousarray(w_bar[m.free]), transpose=True)
        if not np.all(np.isfinite(mu)) or fac.backward_error > ACCURACY:
            raise SolverError(
                f"the transposed solve at t={t:.6g} is not accurate (backward error "
                f"{fac.backward_error:.1e} > {ACCURACY:g}), so the adjoint gradient would be "
                "wrong; try another solver (solver='superlu')")
        timing["tangent_factorization"] += t2 - t1
        timing["solve"] += time.perf_counter() - t2
        c = np.zeros(m.n_dof)
        c[m.free] = -mu
        return c
