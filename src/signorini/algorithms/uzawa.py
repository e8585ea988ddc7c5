"""Uzawa's nested-loop augmented Lagrangian and its (iterative) DDM sensitivity.

A comparator for the paper's claim (section 3.3): with Uzawa, the exact
sensitivity is not one linear solve but an iteration that follows the outer
multiplier loop (docs/theory.md §4)::

    K_UU^k  dU^{k+1} = -(dR_U/dLam . dLam^k + dR_U/dphi)          (one solve per outer iteration)
    dlam^{k+1} = chi (dlam^k + eps (grad g . dU^{k+1} + dg/dphi))    (chi = 1 on closed nodes)

Both the inner residual and the pseudo-load come from the same model kernels
as the single-Newton method (:class:`~signorini.contact.uzawa.UzawaPenalty`
keeps lam^k in the per-node history slot). Frictionless contact only.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._jax import jax, jnp
from ..contact.uzawa import UzawaPenalty
from .._deprecation import pop_old
from ..errors import ConvergenceError, InputError, NonDifferentiableError
from ..linsolve import TangentSolver, for_model, get_solver
from .newton import NewtonOptions, StepFailure, StepLog, newton
from ..params import as_jax, check_names, unit_tangents
from .stepping import ddm_for, model_for

log = logging.getLogger("signorini")


@dataclass
class UzawaSolution:
    """Result of :func:`solve_uzawa` (last increment).

    Attributes:
        w: (n_dof,) displacements. lam: (nc,) multipliers of the contact surface.
        outer_iterations: per increment. newton_iterations: total inner iterations
            per increment. linear_solves: factorisations + back-substitutions in total.
        sens: name -> dw/dphi; lam_sens: name -> dlam/dphi.
        sens_history: name -> list of dlam/dphi after each outer iteration of the last
            increment (to measure what truncating the iteration costs).
    """

    model: object
    w: np.ndarray = None
    lam: np.ndarray = None
    outer_iterations: list = field(default_factory=list)
    newton_iterations: list = field(default_factory=list)
    linear_solves: int = 0
    sens: dict = field(default_factory=dict)
    lam_sens: dict = field(default_factory=dict)
    sens_history: dict = field(default_factory=dict)
    time_s: float = 0.0

    @property
    def pressure(self) -> np.ndarray:
        """p_N = -lam per contact node (positive in compression)."""
        return -self.lam

    def displacement(self) -> np.ndarray:
        d = self.model.dim
        return self.w[: d * self.model.n_nodes].reshape(-1, d)


def _check(model):
    if len(model.surfaces) != 1 or not isinstance(model.surfaces[0].contact.method, UzawaPenalty):
        raise InputError("solve_uzawa needs exactly one contact surface with method UzawaPenalty()")


def solve_uzawa(problem, *, steps: int = 1, wrt: Sequence[str] = (),
                options: NewtonOptions = NewtonOptions(), solver="auto", tol: float = 1e-10,
                max_outer: int = 500, **deprecated) -> UzawaSolution:
    """Uzawa algorithm: Newton on U with frozen multipliers, then lam <- min(lam + eps g, 0).

    Args:
        problem: a problem whose contact surface uses :class:`UzawaPenalty`.
        wrt: the parameters to differentiate with respect to (Uzawa's iterative
            sensitivity: one back-substitution per parameter and outer iteration).
        tol: outer loop stops when max |lam^{k+1} - lam^k| <= tol * max |lam^{k+1}|.
        max_outer: outer iterations per increment before giving up.

    The other arguments are those of :func:`signorini.solve`; ``sensitivities=``
    is the 0.1 name of ``wrt=`` (a DeprecationWarning).
    """
    old = pop_old(deprecated, "solve_uzawa", {"sensitivities": "wrt=[...]"})
    wrt = old.get("sensitivities", wrt)
    t_start = time.perf_counter()
    model = model_for(problem)
    _check(model)
    names = list(wrt)
    check_names(names, problem.params, "wrt")
    params = as_jax(problem.params)
    model.check(problem.params)
    loop = _OuterLoop(model, names, params, TangentSolver(for_model(get_solver(solver), model), symmetric_candidate=False),
                      options, tol, max_outer)  # the general LU
    out = loop.out
    for n_inc in range(1, steps + 1):
        k, newton_its = loop.increment(n_inc / steps, 1.0 / steps)
        out.outer_iterations.append(k)
        out.newton_iterations.append(newton_its)
        log.info("Uzawa increment %d: %d outer iterations, %d Newton iterations", n_inc, k, newton_its)
    out.w, out.lam = loop.w, np.asarray(loop.lam)
    if loop.ddm is not None:
        out.sens = {n: loop.w_dot[j] for j, n in enumerate(names)}
        out.lam_sens = {n: np.asarray(loop.lam_dot[j]) for j, n in enumerate(names)}
        out.sens_history = loop.hist
    out.time_s = time.perf_counter() - t_start
    return out


def _compiled_update(model, s, method):
    """(update, its JVP batched over parameters), compiled once per model: the
    multiplier update lam <- min(lam + eps g, 0) of surface s."""
    if ("uzawa",) not in model.cache:  # compiled once per model, like solve()'s DDM
        def update(w, p, t, lam_k):
            X = model.reference(p)
            u, lams = model.split(w)
            x, _, _, geo, cp, Xs = model.contact_inputs(s, X, u, lams[0], p, t)
            return jax.vmap(lambda xs, lk, X0, N0: method.update(
                xs, geo, model.obstacle_at(s, (X0, N0)), cp, lk))(x, lam_k, *Xs)

        model.cache[("uzawa",)] = (model.program(update, "uzawa_update"), model.program(jax.vmap(
            lambda w, p, t, lk, wd, e, lkd: jax.jvp(
                lambda w_, p_, l_: update(w_, p_, t, l_), (w, p, lk), (wd, e, lkd))[1],
            (None, None, None, None, 0, 0, 0)), "uzawa_update_jvp"))
    return model.cache[("uzawa",)]


class _OuterLoop:
    """Uzawa's outer iterations of one increment after another, with the state they carry."""

    def __init__(self, model, names, params, lin, options, tol, max_outer):
        self.model, self.names, self.params, self.lin = model, names, params, lin
        self.options, self.tol, self.max_outer = options, tol, max_outer
        s = model.surfaces[0]
        self.upd, self.upd_jvp = _compiled_update(model, s, s.contact.method)
        self.ddm = ddm_for(model, names)
        self.weights = model.convergence_weights(params)
        self.out = UzawaSolution(model)
        nc = s.nodes.size
        self.w = np.zeros(model.n_dof)
        self.lam = jnp.zeros(nc)
        self.lam_dot = jnp.zeros((len(names), nc))
        self.zeros_w = jnp.zeros(model.n_dof)
        self.w_dot, self.hist = None, {n: [] for n in names}

    def increment(self, t, dt):
        """Outer iterations to the multipliers' convergence at t: (iterations, Newton iterations)."""
        model, params, out = self.model, self.params, self.out
        if model.prescribed.size:
            self.w[model.prescribed] = np.asarray(model.prescribed_at(params, t))
        ref = float(np.linalg.norm(np.asarray(model.external_force_vector(params, t))[model.free]))
        newton_its, self.hist = 0, {n: [] for n in self.names}
        for k in range(1, self.max_outer + 1):
            state = (self.zeros_w, (self.lam,))
            steplog = StepLog(t, dt)
            try:
                self.w, R, blocks, _ = newton(model, model.pattern, self.lin, self.w, params, t, state,
                                              self.options, self.weights, ref, steplog)
            except StepFailure as e:
                raise ConvergenceError(f"Uzawa inner Newton failed at t={t:.6g}, outer iteration {k}: "
                                       f"{e.reason}", partial=out) from None
            newton_its += steplog.iterations
            out.linear_solves += steplog.iterations
            wj = jnp.asarray(self.w)
            lam_new = self.upd(wj, params, t, self.lam)
            if self.ddm is not None:
                self._sensitivity(wj, blocks, state, t, k)
            change = float(jnp.max(jnp.abs(lam_new - self.lam)))
            self.lam = lam_new
            if change <= self.tol * max(float(jnp.max(jnp.abs(self.lam))), 1e-300):
                return k, newton_its
        raise ConvergenceError(f"Uzawa outer loop did not converge in {self.max_outer} iterations at "
                               f"t={t:.6g} (last multiplier change {change:.2e}); a larger eps "
                               "converges faster", partial=out)

    def _sensitivity(self, wj, blocks, state, t, k) -> None:
        """One iterative sensitivity step: the DDM at frozen multipliers, then the
        multiplier update's JVP."""
        model, names, params = self.model, self.names, self.params
        fac = self.lin.factorize(model.pattern.assemble(blocks))
        sdot = (jnp.zeros((len(names), model.n_dof)), (self.lam_dot,))
        try:
            self.w_dot, _ = self.ddm.solve(fac, wj, params, t, state, sdot)
        except NonDifferentiableError as e:
            raise ConvergenceError(f"Uzawa at t={t:.6g}, outer iteration {k}: {e}",
                                   partial=self.out) from None
        self.out.linear_solves += 1 + len(names)
        self.lam_dot = self.upd_jvp(wj, params, t, self.lam, jnp.asarray(self.w_dot),
                                    unit_tangents(params, names), self.lam_dot)
        for j, n in enumerate(names):
            self.hist[n].append(np.asarray(self.lam_dot[j]))
