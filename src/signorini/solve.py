"""Load stepping, step cutting and the DDM solve after each converged increment.

:func:`solve` is the entry point: it builds (or reuses) the compiled
:class:`~signorini.model.Model`, walks the load factor t from 0 to 1, runs
Newton in each increment (halving it on failure), and after each converged
increment solves the sensitivity problem for all requested parameters with
the factorised exact tangent.
"""

from __future__ import annotations

import logging
import time
from collections import OrderedDict
from collections.abc import Sequence

import numpy as np

from ._jax import jax, jnp
from .assembly import SparsityPattern
from .errors import ConvergenceError, InputError, SingularTangentError
from .linsolve import get_solver
from .model import Model
from .newton import NewtonOptions, StepFailure, StepLog, newton
from .params import as_jax, check_names
from .problem import Problem
from .sensitivity import DDM
from .solution import Increment, Solution

log = logging.getLogger("signorini")

_MODELS: OrderedDict = OrderedDict()


def model_for(problem: Problem) -> Model:
    """The compiled model of a problem, reused for problems that differ only in
    parameter values (finite differences, optimisation loops)."""
    key = (id(problem.mesh), id(problem.material), problem.fixed, problem.loads, problem.contact,
           tuple((k, id(v)) for k, v in problem.shape.items()), tuple(sorted(problem.params)))
    try:
        m = _MODELS[key]
        _MODELS.move_to_end(key)
        return m
    except (KeyError, TypeError):
        pass
    m = Model(problem)
    m.pattern = SparsityPattern(m.block_dofs(), m.n_dof, m.free)
    m.fext = jax.jit(m.external_forces)
    m.cache = {}  # compiled DDM / response functions, reused across solves
    try:
        _MODELS[key] = m
        if len(_MODELS) > 8:
            _MODELS.popitem(last=False)
    except TypeError:  # unhashable user component: no caching
        pass
    return m


def ddm_for(model: Model, names: Sequence[str]) -> DDM | None:
    """The model's compiled DDM for these parameter names (None if there are none)."""
    if not names:
        return None
    key = ("ddm", tuple(names))
    if key not in model.cache:
        model.cache[key] = DDM(model, names)
    return model.cache[key]


def solve(problem: Problem, *, steps: int = 1, sensitivities: Sequence[str] = (),
          options: NewtonOptions = NewtonOptions(), solver="superlu") -> Solution:
    """Solve a contact problem by incremental Newton, with DDM sensitivities.

    Args:
        problem: the :class:`~signorini.problem.Problem`.
        steps: number of equal load increments from t = 0 to 1 (cut on failure).
        sensitivities: design-parameter names; their DDM sensitivities are
            computed after every converged increment.
        options: :class:`~signorini.newton.NewtonOptions`.
        solver: linear solver name (``superlu``, ``umfpack``, ``pardiso``) or object.

    Returns:
        A :class:`~signorini.solution.Solution` with every converged increment.

    Raises:
        ConvergenceError: Newton failed even after cutting the increment; its
            ``partial`` attribute holds the increments already converged.
        InputError: invalid parameters, names or meshes.
    """
    if steps < 1:
        raise InputError(f"steps must be >= 1, got {steps}")
    names = list(sensitivities)
    check_names(names, problem.params, "sensitivities")
    model = model_for(problem)
    for c in problem.contact:
        driver = getattr(c.method, "driver", None)  # a law that needs its own solution algorithm
        if driver is not None:
            raise InputError(f"{type(c.method).__name__} is solved by {driver}, not by "
                             "signorini.solve (use AugmentedLagrangian for the single-Newton method)")
    params = as_jax(problem.params)
    model.check(problem.params)
    lin = get_solver(solver)
    ddm = ddm_for(model, names)
    weights = model.convergence_weights(params)

    sol = Solution(model, dict(problem.params), names)
    w = np.zeros(model.n_dof)
    state_n = model.initial_state(w, params) if hasattr(model, "initial_state") else None
    state_dot = None
    if ddm is not None:
        state_dot = model.initial_state_sensitivity(params, names) if hasattr(model, "initial_state") else None

    t, dt_nominal = 0.0, 1.0 / steps
    dt, cuts = dt_nominal, 0
    n_inc = 0
    while t < 1.0 - 1e-12:
        dt = min(dt, 1.0 - t)
        t_new = t + dt if 1.0 - (t + dt) > 1e-12 else 1.0
        steplog = StepLog(t_new, dt)
        sol.log.append(steplog)
        w_trial = w.copy()
        if model.prescribed.size:
            w_trial[model.prescribed] = np.asarray(model.prescribed_values(params, t_new))
        ref = float(np.linalg.norm(np.asarray(model.fext(model.reference(params), params, t_new))[model.free]))
        try:
            w_trial, R, blocks = newton(model, model.pattern, lin, w_trial, params, t_new,
                                        state_n, options, weights, ref, steplog)
        except StepFailure as e:
            steplog.reason = e.reason
            log.info("increment t=%.6g: %s", t_new, steplog.summary())
            if e.fatal:
                sol.status = "failed"
                raise ConvergenceError(_diagnose(model, w_trial, params, t_new, e.reason, n_inc),
                                       partial=sol) from None
            if cuts >= options.max_cuts:
                sol.status = "failed"
                raise ConvergenceError(
                    f"Newton failed at t={t_new:.6g} after {cuts} step cuts ({e.reason}). "
                    f"{len(sol.increments)} increments converged (kept in the error's .partial). "
                    "Try more load steps, a different eps, or check the loads and supports.",
                    partial=sol) from None
            dt *= 0.5
            cuts += 1
            continue
        n_inc += 1
        log.info("increment %d: %s", n_inc, steplog.summary())
        inc = Increment(t_new, w_trial.copy(), steplog, R[model.prescribed].copy())
        if ddm is not None:
            t0 = time.perf_counter()
            K = model.pattern.assemble(blocks)
            try:
                fac = lin.factorize(K)
            except SingularTangentError as e:
                raise ConvergenceError(f"the converged tangent at t={t_new:.6g} is singular, so the "
                                       f"sensitivities are undefined: {e}", partial=sol) from None
            t1 = time.perf_counter()
            w_dot, timing = ddm.solve(fac, jnp.asarray(w_trial), params, t_new, state_n, state_dot)
            timing["factorization"] = t1 - t0
            inc.sens = {n: w_dot[k] for k, n in enumerate(names)}
            inc.timing = timing
        if hasattr(model, "update_state"):
            state_n, state_dot = model.update_state(inc, params, t_new, state_n, state_dot, names)
        sol.increments.append(inc)
        w, t = w_trial, t_new
        cuts = 0  # max_cuts counts the halvings of one increment
        if dt < dt_nominal:
            dt = min(2.0 * dt, dt_nominal)  # grow back after a successful cut increment
    sol.status = "converged"
    return sol


def _diagnose(model: Model, w, params, t, reason: str, n_inc: int) -> str:
    """Explain a failure in the first iteration of an increment."""
    msg = f"Newton cannot start at t={t:.6g}: {reason}."
    if not model.surfaces or n_inc > 0:
        return msg + (" The body has an unrestrained rigid-body motion: add supports "
                      "(Fixed) or contact.")
    parts = []
    for i, s in enumerate(model.surfaces):
        f = model.contact_fields(jnp.asarray(w), params, t, i)
        g = np.asarray(f["gap"])
        k = int(np.argmin(g))
        parts.append(f"surface {s.contact.edges!r}: smallest gap {g[k]:.4g} at node {int(s.nodes[k])}")
    return (msg + " The tangent is singular, so the body is not held: " + "; ".join(parts) +
            ". Under force control a body supported only by contact must touch the obstacle "
            "at the start (zero gap at some contact node); move the obstacle onto the body, "
            "prescribe a displacement instead of a force, or add supports.")
