"""Load stepping, step cutting and the DDM solve after each converged increment.

:func:`solve` is the entry point: it builds (or reuses) the compiled
:class:`~signorini.model.Model`, walks the load factor t from 0 to 1, runs
Newton in each increment (halving it on failure), and after each converged
increment solves the sensitivity problem for all requested parameters with
the factorised exact tangent.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Sequence

import numpy as np

from .. import timing
from .._jax import jax, to_device
from .. import _programs as programs
from .._deprecation import pop_old
from ..errors import ConvergenceError, InputError, NonDifferentiableError, SingularTangentError
from ..linsolve import Pardiso, TangentSolver, for_model, get_solver, openblas_single_thread
from ..model.identity import structure_key
from ..model.kernels import Model
from ..model import checks
from .newton import NewtonOptions, StepFailure, StepLog, newton
from ..params import as_jax, check_names
from . import coarse_algebraic
from ..progress import SolveProgress
from ..model.problem import Problem
from ..sensitivity import nonsmooth
from ..sensitivity.ddm import DDM as DDMEngine
from ..sensitivity.methods import DDM, Adjoint, check_method
from .solution import Increment, Solution
from .start import Start, _Guide

log = logging.getLogger("signorini")

_MODELS: OrderedDict = OrderedDict()
#: per label, the solution of the last solve started with it (weakly held): what
#: an interrupted command keeps when the signal came just after its solve returned
_STARTED: weakref.WeakValueDictionary = weakref.WeakValueDictionary()


def last_started(label: str):
    """The solution of the last solve started with ``label`` (None if gone)."""
    return _STARTED.get(label)


def model_for(problem: Problem) -> Model:
    """The compiled model of a problem, reused for problems that differ only in
    parameter values (finite differences, optimisation loops), also when the
    problem is built again from scratch for new values (:func:`~signorini.model.identity.structure_key`:
    mesh, definitions and shape fields compared by content: the second build
    neither retraces nor recompiles; docs/theory.md §10.5)."""
    try:
        key = structure_key(problem)
    except TypeError:  # unhashable user component: no caching
        return Model(problem)
    m = _MODELS.get(key)
    if m is not None:
        _MODELS.move_to_end(key)
        m.check_values(problem.params)  # expressions of this problem's values (built once per model)
        return m
    m = _MODELS[key] = Model(problem, structure=key)
    _let_go()
    return m


#: the most models kept for reuse
MAX_MODELS = 8


def _let_go(maps=None) -> None:
    """Drop the models used least recently (never the one used last) while more
    than :data:`MAX_MODELS` are kept or the process holds more than
    :data:`~signorini._programs.MAP_SHARE` of the memory mappings the system allows
    (each executable's code is mapped: :func:`~signorini._programs.code_maps`; a
    process past the limit dies in XLA, a segmentation fault). A dropped model's
    executables are freed at once (they sit in reference cycles) and are loaded
    from the disk cache if it is built again."""
    while len(_MODELS) > MAX_MODELS:
        _MODELS.popitem(last=False)
    maps = programs.code_maps() if maps is None else maps
    while maps is not None and maps[0] > programs.MAP_SHARE * maps[1] and len(_MODELS) > 1:
        log.debug("a kept model is let go: %d memory mappings of %d allowed", *maps)
        _MODELS.popitem(last=False)
        gc.collect()
        maps = programs.code_maps()


programs.RELEASERS.append(_let_go)


def ddm_for(model: Model, names: Sequence[str]) -> DDMEngine | None:
    """The model's compiled DDM for these parameter names (None if there are none)."""
    if not names:
        return None
    key = ("ddm", tuple(names))
    if key not in model.cache:
        model.cache[key] = DDMEngine(model, names)
    return model.cache[key]


def solve(problem: Problem, *, steps: int = 1, wrt: Sequence[str] = (), method=None,
          options: NewtonOptions = NewtonOptions(), solver="auto", start=None,
          until: float = 1.0, switch_tol: float = nonsmooth.SWITCH_TOL,
          label: str | None = None, **deprecated) -> Solution:
    """Solve a contact problem by incremental Newton, with DDM sensitivities.

    Args:
        problem: the :class:`~signorini.model.problem.Problem`.
        steps: number of equal load increments from t = 0 to 1 (cut on failure).
        wrt: the design parameters to differentiate with respect to (names);
            their DDM sensitivities are computed after every converged increment.
        method: :class:`~signorini.DDM` (default; ``DDM(factorization="reuse")``
            solves with the last Newton factorisation, refined) or
            :class:`~signorini.Adjoint` (no forward sensitivities: the solve keeps
            what a later backward pass needs, every ``checkpoint``-th history
            state and, with ``factors="store"``, every factorisation).
        options: :class:`~signorini.algorithms.newton.NewtonOptions` (tolerances, iteration
            and step-cutting budgets).
        solver: linear solver: ``"auto"`` (the fastest installed: PARDISO, else
            SuperLU), a name (``pardiso``, ``superlu``, ``umfpack``), a
            :class:`~signorini.linsolve.LinearSolver` instance (reuses its
            symbolic analysis across solves) or an object with ``factorize(K)``.
        start: where Newton starts (:class:`Start`; only the start changes, not
            the converged result): ``Start(initial=w0)`` or the array ``w0`` itself,
            ``Start(guide=coarse)`` or the coarse :class:`Solution` itself.
        until: stop the load path at this load factor (the increments keep the
            nominal size 1/steps); a coarse-to-fine start solves the coarse meshes
            only to the end of the first increment.
        switch_tol: relative distance from a switch of the contact or plasticity
            law below which a point is reported on it (``Increment.switches``,
            :mod:`signorini.sensitivity.nonsmooth`); None: no report (the coarse
            levels of a coarse-to-fine start).
        label: name of this solve in log lines and progress bars (e.g. ``"FD R+"``).

    Returns:
        A :class:`~signorini.algorithms.solution.Solution` with every converged increment;
        ``solution.warnings`` lists anything suspicious found on the way.

    Raises:
        ConvergenceError: Newton failed even after cutting the increment (or the
            step-cutting floor/budget was reached), the converged tangent is
            singular, or the sensitivities are not finite (an expression not
            differentiable at the parameter values); its ``partial`` attribute
            holds the increments already converged.
        InputError: invalid parameters, names or meshes.

    The keywords of version 0.1 still work, with a DeprecationWarning:
    ``sensitivities=`` (now ``wrt=``), ``ddm_factorization=`` (``method=DDM(...)``),
    ``checkpoint=`` and ``keep_factors=`` (``method=Adjoint(...)``), ``initial=`` and
    ``guide=`` (``start=Start(...)``).
    """
    old = pop_old(deprecated, "signorini.solve", {
        "initial": "start=signorini.Start(initial=...)",
        "guide": "start=signorini.Start(guide=...)",
        "sensitivities": "wrt=[...]", "ddm_factorization": "method=signorini.DDM(factorization=...)",
        "checkpoint": "method=signorini.Adjoint(checkpoint=...)",
        "keep_factors": 'method=signorini.Adjoint(factors="store")'})
    if "sensitivities" in old:
        if wrt:
            raise InputError("give the parameters once, as wrt= (sensitivities= is its old name)")
        wrt = old["sensitivities"]
    keyword = "sensitivities" if "sensitivities" in old else "wrt"  # the one the user wrote
    wrt = _sensitivity_names(wrt, keyword)
    check_names(wrt, problem.params, keyword)
    method = DDM() if method is None else check_method(method, (DDM, Adjoint), "signorini.solve")
    if isinstance(method, Adjoint) and wrt:
        raise InputError("solve(method=Adjoint()) computes no forward sensitivities, so wrt= has no "
                         "use there: for DDM sensitivities use method=DDM(); for an adjoint "
                         "gradient, signorini.gradient(problem, response, wrt, method=Adjoint())")
    ddm_factorization = old.get("ddm_factorization",
                                method.factorization if isinstance(method, DDM) else "exact")
    checkpoint = old.get("checkpoint", method.checkpoint if isinstance(method, Adjoint) else 1)
    keep_factors = old.get("keep_factors", isinstance(method, Adjoint) and method.factors == "store")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"steps must be a positive integer (number of load increments), got {steps!r}")
    if isinstance(checkpoint, bool) or not isinstance(checkpoint, (int, np.integer)) or checkpoint < 1:
        raise InputError(f"checkpoint must be a positive integer (keep every k-th state), got "
                         f"{checkpoint!r}")
    if switch_tol is not None and not (isinstance(switch_tol, (int, float)) and 0 <= switch_tol < 1):
        raise InputError(f"switch_tol must be a number in [0, 1) or None (no report), got "
                         f"{switch_tol!r}")
    start = Start.of(start, old.get("initial"), old.get("guide"))
    with openblas_single_thread(), contextlib.ExitStack() as stack:
        return _solve(problem, steps, wrt, options, solver, label, start.initial,
                      ddm_factorization, until, int(checkpoint), bool(keep_factors), switch_tol,
                      start.guide, stack)


def kept_solver(model: Model, solver, stack: contextlib.ExitStack):
    """The linear solver of a solve. A solver given by name is the model's own
    instance, so the symbolic analyses it keeps serve every later solve of the
    model (finite differences, optimisation, a parameter loop), which then pays
    for numeric factorisations only. While one solve uses it (a solve within a
    solve, another thread), others get a fresh instance. A solver object is used
    as given."""
    if not isinstance(solver, str):
        return for_model(get_solver(solver), model)
    key = ("solver", solver)
    kept = model.cache.get(key)
    if kept is None:
        kept = model.cache[key] = (get_solver(solver), threading.Lock())
    instance, lock = kept
    if not lock.acquire(blocking=False):
        return for_model(get_solver(solver), model)
    stack.callback(lock.release)
    return for_model(instance, model)


def _solve(problem, steps, sensitivities, options, solver, label, initial, ddm_factorization,
           until, checkpoint, keep_factors, switch_tol, guide, stack):
    if not (isinstance(until, (int, float)) and 0.0 < until <= 1.0):
        raise InputError(f"until must be a load factor in (0, 1], got {until!r}")
    if ddm_factorization not in ("exact", "reuse"):
        raise InputError(f"ddm_factorization must be 'exact' or 'reuse', got {ddm_factorization!r}")
    names = list(sensitivities)  # checked by solve() under the keyword the user wrote
    check_finite(problem.params)
    if not isinstance(options, NewtonOptions):
        raise InputError(f"options must be a signorini.NewtonOptions, got {type(options).__name__}")
    model = model_for(problem)
    for c in problem.contact:
        driver = c.method.driver  # a law that needs its own solution algorithm
        if driver is not None:
            raise InputError(f"{type(c.method).__name__} is solved by {driver}, not by "
                             "signorini.solve (use AugmentedLagrangian for the single-Newton method)")
    if initial is not None:
        initial = np.asarray(initial, dtype=float)
        if initial.shape != (model.n_dof,) or not np.all(np.isfinite(initial)):
            raise InputError(f"initial must be a finite array of shape ({model.n_dof},) (one value "
                             f"per unknown), got shape {initial.shape}")
    path = _LoadPath(problem, model, names, steps, options, solver, label, initial,
                     ddm_factorization, checkpoint, keep_factors, switch_tol, guide, stack)
    return path.run(until)


class _LoadPath:
    """One solve: the load path t: 0 -> until in increments, each started from a
    prediction, solved by Newton, cut on failure, and followed by the converged
    tangent's sensitivities and the history update."""

    def __init__(self, problem, model, names, steps, options, solver, label, initial,
                 ddm_factorization, checkpoint, keep_factors, switch_tol, guide, stack):
        self.model, self.names, self.steps, self.options = model, names, steps, options
        self.initial, self.ddm_factorization = initial, ddm_factorization
        self.checkpoint, self.keep_factors = checkpoint, keep_factors
        self.params = params = as_jax(problem.params)
        model.check(problem.params)
        # a pattern seen for the first time is analysed with every contact node closed
        self.lin = TangentSolver(kept_solver(model, solver, stack),
                                 symmetric_candidate=not model.has_history,
                                 analysis=lambda: model.analysis_tangent(params),
                                 reuse=options.reuse_factor)
        # under mpiexec: each rank evaluates the element kernels of its own cells
        stack.enter_context(model.sharing(getattr(self.lin.solver, "communicator", None)))
        self.ddm = ddm_for(model, names)
        self.weights = model.convergence_weights(params)
        self.sol = sol = Solution(model, dict(problem.params), names)
        if label is not None:
            _STARTED[label] = sol
        sol.label = label
        sol.solver = self.lin.solver.name
        sol.linear_solver = self.lin.solver  # the object (kept analyses, user solvers) for an adjoint
        checks.before_solve(model, params, sol)
        self.inc_checks = checks.IncrementChecks(model, params, sol)
        self.switches = None if switch_tol is None else nonsmooth.SwitchDetector(model, params, switch_tol)
        self.progress = SolveProgress(label, steps)
        self.w = np.zeros(model.n_dof)
        self.state_n = model.initial_state(self.w, params)
        self.state_dot = model.initial_state_sensitivity(params, names) if self.ddm is not None else None
        self.inc_checks.start(self.w)
        self.t, self.dt_nominal = 0.0, 1.0 / steps
        self.t_prev, self.w_prev = None, None  # the converged state before (t, w), for the predictor
        self.loads = {}  # t -> the load state at t (_load_state): the predictor's kink test
        self.guides = None if guide is None else _Guide(guide, model)
        self.dt, self.cuts, self.total_cuts = self.dt_nominal, 0, 0

    def fail(self, message):
        """The error that ends the solve, with the converged increments kept in it and
        what they warn of (a load path too coarse for friction among them)."""
        self.inc_checks.final()
        self.sol.status = "failed"
        self.sol.reason = message
        self.progress.close("failed")
        return ConvergenceError(message, partial=self.sol)

    def run(self, until: float) -> Solution:
        try:
            return self._run(until)
        except KeyboardInterrupt as e:  # SIGINT, or SIGTERM in the command (errors.Interrupted)
            # the innermost solve's converged increments ride on the interrupt
            if getattr(e, "partial", None) is None:
                e.partial = self.sol
                self.sol.status, self.sol.reason = "interrupted", "interrupted"
                self.progress.close("interrupted")
            raise

    def _run(self, until: float) -> Solution:
        sol = self.sol
        while self.t < until - 1e-12:
            self.dt = min(self.dt, until - self.t)
            t_new = self.t + self.dt if until - (self.t + self.dt) > 1e-12 else until
            steplog = StepLog(t_new, self.dt)
            sol.log.append(steplog)
            w_trial, ref = self._start(t_new)
            try:
                w_trial, R, blocks, last_fac = newton(
                    self.model, self.model.pattern, self.lin, w_trial, self.params, t_new,
                    self.state_n, self.options, self.weights, ref, steplog)
            except StepFailure as e:
                steplog.reason = e.reason
                self._cut(e, t_new, w_trial)
                continue
            self._accept(t_new, w_trial, R, blocks, last_fac, steplog)
        self.inc_checks.final()
        message = nonsmooth.warning(sol)
        if message:
            checks.warn(sol, message)
        sol.symmetric = self.lin.symmetric
        sol.status = "converged"
        self.progress.close("converged")
        return sol

    def _start(self, t_new):
        """The first Newton iterate of the increment to t_new and the reference norm
        of its convergence test."""
        model, params, t, w = self.model, self.params, self.t, self.w
        w_trial = w.copy()
        if model.prescribed.size:
            w_trial[model.prescribed] = np.asarray(model.prescribed_at(params, t_new))
        ref = float(np.linalg.norm(np.asarray(model.external_force_vector(params, t_new))[model.free]))
        first = not self.sol.increments and t == 0.0
        started = first and self.initial is not None
        # a coarser solve of the same path: w_n + P(w^c_{n+1} - w^c_n)
        guided = self.guides is not None and not started and self.guides.covers(t_new)
        # else linear extrapolation of the last two converged states (a quadratic through
        # three needs more Newton iterations on the frictional Hertz path: zones growing
        # like sqrt(t) are not smooth in t; docs/theory.md §10.3)
        predicted = (not started and not guided and self.options.predictor == "extrapolate"
                     and self.w_prev is not None and self._smooth_path(t_new))
        coarse = None
        if first and not started and not guided and coarse_algebraic.wanted(model, self.options):
            coarse, self.sol.coarse_start = coarse_algebraic.AlgebraicStart(model)(
                w_trial, params, t_new, self.state_n)
        if started or guided or predicted or coarse is not None:
            # the reference norm of the convergence test is that of the unpredicted start
            # (the last state under the new load), so that a better start does not make
            # the test stricter than the round-off floor, where Newton would stagnate
            # (docs/theory.md §10.3)
            R0 = _residual(model, w_trial, params, t_new, self.state_n)[model.free]
            ref = max(ref, float(np.linalg.norm(R0 * self.weights[model.free])))
            if started:
                start = self.initial
            elif guided:
                start = self.guides.start(t, t_new, w, first)
            elif coarse is not None:
                start = coarse
            else:
                start = w + (t_new - t) / (t - self.t_prev) * (w - self.w_prev)
            w_trial[model.free] = start[model.free]
        return w_trial, ref

    #: a load path whose rate changes by more than this fraction from one increment
    #: to the next has a kink there (a load phase ending, another starting)
    KINK = 0.5

    def _load_state(self, t) -> list:
        """What the path prescribes at t: the external forces on the free DOFs, the
        prescribed displacements and each obstacle's geometry."""
        loads = self.loads.get(t)
        if loads is None:
            model, params = self.model, self.params
            f, geometry = model.contact_geometry(params, t)[:2]
            loads = [np.asarray(f)[model.free]]
            if model.prescribed.size:
                loads.append(np.asarray(model.prescribed_at(params, t), float).ravel())
            for g in geometry:
                leaves = [np.ravel(np.asarray(v, float)) for v in jax.tree_util.tree_leaves(g[3])]
                loads.append(np.concatenate(leaves) if leaves else np.zeros(0))
            self.loads[t] = loads
        return loads

    def _smooth_path(self, t_new) -> bool:
        """Whether the load path keeps its rate from the last increment into the
        next, each of forces, prescribed displacements and obstacle positions to
        :attr:`KINK`: where one load phase ends and another begins (a die pressed
        in, then slid), extrapolating the last increment continues the old phase,
        and Newton starts better from the last state (docs/theory.md §10.3)."""
        t, t0 = self.t, self.t_prev
        for a, b, c in zip(self._load_state(t0), self._load_state(t), self._load_state(t_new)):
            old, new = (b - a) / (t - t0), (c - b) / (t_new - t)
            scale = max(float(np.linalg.norm(old)), float(np.linalg.norm(new)))
            if scale > 0 and float(np.linalg.norm(new - old)) > self.KINK * scale:
                return False
        return True

    def _cut(self, e: StepFailure, t_new, w_trial) -> None:
        """Halve the increment after a Newton failure, or end the solve when the
        failure is final or a floor or budget of the step cutting is reached."""
        options, t, dt = self.options, self.t, self.dt
        n_done = len(self.sol.increments)
        reached = (f"{n_done} increments converged (kept in the error's .partial); "
                   f"the load factor reached is t = {t:.6g}")
        if e.stagnated:
            raise self.fail(f"at t={t_new:.6g}: {e.reason}. {reached}.") from None
        if e.fatal:
            raise self.fail(_diagnose(self.model, w_trial, self.params, t_new, e.reason, n_done)) from None
        advice = ("Try more load steps (steps=...), a different eps, or check the loads, "
                  "supports and material.")
        if self.cuts >= options.max_cuts:
            raise self.fail(f"Newton failed at t={t_new:.6g} after {self.cuts} step cuts ({e.reason}). "
                            f"{reached}. {advice}") from None
        if self.total_cuts >= options.max_total_cuts:
            raise self.fail(f"Newton failed at t={t_new:.6g} ({e.reason}) and the budget of "
                            f"{options.max_total_cuts} step cuts for the whole load path is spent "
                            f"(NewtonOptions.max_total_cuts). {reached}. {advice}") from None
        if 0.5 * dt < options.min_step * (1 - 1e-9):
            raise self.fail(f"Newton failed at t={t_new:.6g} ({e.reason}) with a step of {dt:.3g}; "
                            f"halving it would go below the smallest step {options.min_step:.3g} "
                            f"(NewtonOptions.min_step). {reached}. {advice}") from None
        self.dt *= 0.5
        self.cuts += 1
        self.total_cuts += 1
        self.progress.cut(t_new, e.reason, self.dt)

    def _accept(self, t_new, w_trial, R, blocks, last_fac, steplog) -> None:
        """Record the converged increment: switch points, the kept factor, the
        sensitivities, the history update; then move on."""
        model, params, sol = self.model, self.params, self.sol
        inc = Increment(t_new, w_trial.copy(), steplog, R[model.prescribed].copy())
        if self.switches is not None:
            inc.switches = self.switches(to_device(w_trial), params, t_new, self.state_n)
        if self.keep_factors or self.ddm is not None:
            with timing.phase("sensitivities"):
                self._derivatives(inc, w_trial, blocks, last_fac, t_new)
        self.state_n, self.state_dot = model.update_state(inc, params, t_new, self.state_n,
                                                          self.state_dot, self.names)
        if self.checkpoint > 1 and sol.increments and len(sol.increments) % self.checkpoint:
            sol.increments[-1].state = None  # not a checkpoint: recomputed when needed
        sol.increments.append(inc)
        self.progress.increment(t_new, steplog)
        self.inc_checks.after(w_trial, t_new, len(sol.increments))
        self.t_prev, self.w_prev = self.t, self.w
        self.w, self.t = w_trial, t_new
        self.loads = {k: v for k, v in self.loads.items() if k in (self.t_prev, self.t)}
        self.cuts = 0  # max_cuts counts the halvings of one increment
        if self.dt < self.dt_nominal:
            self.dt = min(2.0 * self.dt, self.dt_nominal)  # grow back after a successful cut increment

    def _derivatives(self, inc, w_trial, blocks, last_fac, t_new) -> None:
        """What the derivatives need of a converged increment: its factorisation
        kept for an adjoint, or the DDM sensitivities."""
        params = self.params
        t_k = time.perf_counter()
        K = self.model.pattern.assemble(blocks)
        t_k = time.perf_counter() - t_k  # booked with the DDM's factorisation, which it serves
        # the pseudo-loads need no factorisation: computed first, so that each solve
        # follows its factorisation while MKL's threads are awake (DDM.pseudo_loads)
        try:
            loads = None if self.ddm is None else self.ddm.pseudo_loads(
                to_device(w_trial), params, t_new, self.state_n, self.state_dot,
                reuse_stiffness=self.steps >= 3)
        except NonDifferentiableError as e:  # keep what converged
            raise self.fail(str(e)) from None
        if self.keep_factors:
            try:
                inc.factor = _own_factor(self.lin, K)
            except SingularTangentError as e:
                raise self.fail(f"the converged tangent at t={t_new:.6g} is singular, so no adjoint "
                                f"can be computed: {e}") from None
        if self.ddm is not None:
            kept = self.lin.kept
            before = (kept.factorizations, kept.krylov_iterations, len(kept.reasons))
            self._sensitivities(inc, K, loads, last_fac, t_new, t_k)
            # the increment's count includes its sensitivities' factorisation, if any
            inc.newton.factorizations += kept.factorizations - before[0]
            inc.newton.krylov_iterations += kept.krylov_iterations - before[1]
            inc.newton.refactorizations += [f"sensitivities: {r}"
                                            for r in kept.reasons[before[2]:]]

    def _sensitivities(self, inc, K, loads, last_fac, t_new, t_k) -> None:
        """The DDM of the converged increment: one back-substitution per parameter
        with the converged tangent (or the last Newton factor, refined, if asked)."""
        t0 = time.perf_counter() - t_k
        fac = inc.factor  # kept for an adjoint (keep_factors): the DDM uses it as well
        reused = fac is None and self.ddm_factorization == "reuse" and last_fac is not None
        if reused:
            # the last Newton factor preconditions refinement against the exact K;
            # kept only if the sensitivities reach the backward error of a fresh solve
            fac = last_fac.refined_for(K)
        w_dot = None

        def back_substitute(fac, or_none=False):
            guess = self._sensitivity_guess(t_new) if getattr(fac, "takes_guess", False) else None
            try:
                return self.ddm.back_substitute(fac, loads, guess)
            except SingularTangentError as e:
                if or_none:  # a reused factor: factorise instead
                    return None, None
                raise self.fail(f"the sensitivity solve at t={t_new:.6g} failed: {e}") from None

        if fac is not None:
            t1 = time.perf_counter()
            w_dot, timing = back_substitute(fac, or_none=reused)
            if reused and (w_dot is None or fac.backward_error > fac.refine_tol):
                w_dot, reused = None, False  # failed or short of a fresh solve: factorise
        if w_dot is None:
            try:
                # the converged tangent, or GMRES on the factorisation Newton kept while
                # that pays (linsolve.kept): checked and refined as a fresh solve is
                fac = self.lin.factor(K)
            except SingularTangentError as e:
                raise self.fail(f"the converged tangent at t={t_new:.6g} is singular, so the "
                                f"sensitivities are undefined: {e}") from None
            t1 = time.perf_counter()
            w_dot, timing = back_substitute(fac)
        timing["factorization"] = t1 - t0
        timing["reused_factorization"] = reused
        timing["refinements"] = fac.refinements
        # finite: the pseudo-loads were checked, every solve is (linsolve.Factor)
        inc.sens = {n: w_dot[k] for k, n in enumerate(self.names)}
        inc.timing = timing

    def _sensitivity_guess(self, t_new):
        """(n_names, n_dof) the sensitivities at ``t_new`` extrapolated linearly from
        the last two increments of this solve (the last one's where there is only
        one), for an iterative solver to start from (it decides the cost, not the
        result); None before the first increment."""
        incs = [inc for inc in self.sol.increments[-2:]
                if inc.sens and all(n in inc.sens for n in self.names)]
        if not incs:
            return None
        last = np.stack([incs[-1].sens[n] for n in self.names])
        if len(incs) == 1 or incs[-1].t <= incs[0].t:
            return last
        before = np.stack([incs[0].sens[n] for n in self.names])
        return last + (t_new - incs[-1].t) / (incs[-1].t - incs[0].t) * (last - before)


def _residual(model, w, params, t, state_n) -> np.ndarray:
    """R(w) as NumPy. A linear body takes it from the Newton kernel (elements by
    K_e u_e, tangents of the contact nodes only), which is compiled anyway: one
    kernel less to compile on a first run."""
    if model.linear_elements:
        return model.local_tangents(w, params, t, state_n)[0]
    return np.asarray(model.compiled.residual(to_device(w), params, t, state_n))


def _own_factor(lin: TangentSolver, K):
    """A factorisation of K that stays valid after later ones (PARDISO keeps one
    numeric factorisation per handle: a stored one gets a solver of its own)."""
    if isinstance(lin.solver, Pardiso):
        return Pardiso().factorize(K, symmetric=bool(lin.symmetric))
    return lin.factorize(K)


def _sensitivity_names(sensitivities, what: str = "wrt") -> list[str]:
    if isinstance(sensitivities, str):
        raise InputError(f"{what} must be a list of parameter names, got the string "
                         f"{sensitivities!r}; write {what}=[{sensitivities!r}]")
    try:
        names = list(sensitivities or ())
    except TypeError:
        raise InputError(f"{what} must be a list of parameter names, got "
                         f"{sensitivities!r}") from None
    for n in names:
        if not isinstance(n, str):
            raise InputError(f"{what} must be parameter names (strings), got {n!r}")
    if len(set(names)) != len(names):
        raise InputError(f"{what} lists a parameter twice: {names}")
    return names


def check_finite(params) -> None:
    """Every parameter value must be a finite number."""
    for k, v in params.items():
        if not np.isfinite(v):
            raise InputError(f"parameter {k!r} is {v}; every parameter must be a finite number")


def _diagnose(model: Model, w, params, t, reason: str, n_inc: int) -> str:
    """Explain a failure in the first iteration of an increment."""
    msg = f"Newton cannot start at t={t:.6g}: {reason}."
    if not model.surfaces or n_inc > 0:
        return msg + (" The body has an unrestrained rigid-body motion: add supports "
                      "(Fixed) or contact.")
    parts = []
    for i, s in enumerate(model.surfaces):
        f = model.contact_fields(to_device(w), params, t, i)
        g = np.asarray(f["gap"])
        k = int(np.argmin(g))
        parts.append(f"surface {s.contact.edges!r}: smallest gap {g[k]:.4g} at node {int(s.nodes[k])}")
    return (msg + " The tangent is singular, so the body is not held: " + "; ".join(parts) +
            ". Under force control a body supported only by contact must touch the obstacle "
            "at the start (zero gap at some contact node); move the obstacle onto the body, "
            "prescribe a displacement instead of a force, or add supports.")
