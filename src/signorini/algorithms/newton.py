"""Newton's method for one load increment (paper eq. 2 / 21).

Displacements and contact multipliers are updated together from
K dw = -R, with K the exact Jacobian of the residual (assembled from the
JAX block Jacobians). The iteration log records the residual norm of every
iterate so quadratic convergence can be seen and tested.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, SingularTangentError

log = logging.getLogger("signorini")


@dataclass(frozen=True)
class NewtonOptions:
    """Tolerances and limits of the Newton solver and load stepping.

    Attributes:
        rtol: converged when ||R|| <= rtol * ref, ref = max(||R_0||, ||f_ext||)
            (multiplier rows weighted to force units). An iterate whose residual
            has stopped falling at the round-off floor of the problem is
            accepted too when that floor lies above rtol (see ``step_tol``).
        atol: absolute floor of the same test.
        max_iter: iterations per increment before the increment is cut.
        max_cuts: how many times one increment may be halved.
        max_total_cuts: budget of step halvings over the whole load path; with
            ``min_step`` it guarantees that the load stepping ends.
        min_step: smallest load-factor increment (the floor of the cutting).
        divergence: ||R|| > divergence * ref stops the increment early.
        singular_check: relative linear residual above which a solve is taken
            as singular.
        line_search: halve a Newton correction until the residual norm falls
            (helps when stick/slip or contact states cycle; off by default:
            Newton's own path is then exactly the textbook one).
        step_tol: the round-off floor: an iterate is also converged when its
            residual is at most ``floor_max * ref``, did not fall below half the
            residual before it (Newton's quadratic phase is over) and the
            correction that led to it changed the displacements by at most
            ``step_tol`` relative (||du|| <= step_tol ||u||, free DOFs): the
            arithmetic resolves the solution no better. The step's log says so
            (``stop = "round-off floor"``) with the relative residual reached.
        floor_max: the largest relative residual accepted at a floor; above it a
            residual that stops falling is a failure.
        predictor: first iterate of an increment after the first:
            ``"extrapolate"`` (default) continues the last two converged
            increments linearly (free DOFs, multipliers included), except
            after a turn of the load path (a load phase ending, another
            starting), where it starts from the last state; ``"none"``
            starts from the last converged state. Only the start changes, not
            the converged point (docs/theory.md §10).
        start: the first iterate of the first increment where no other is given
            (no ``start=`` and no coarser mesh): ``"auto"`` (default) starts 3-D
            problems of at least :data:`signorini.algorithms.coarse_algebraic.AUTO_NODES`
            nodes with contact (rigid obstacles, pairs, with or without friction)
            from an algebraic coarse problem
            (docs/theory.md §10.3), ``"coarse"`` does so for every problem with
            contact, ``"rest"`` starts from the undeformed state. Only the start
            changes, not the converged point.
        reuse_factor: how a direct solver's factorisations serve later tangents
            (:mod:`signorini.linsolve.kept`): ``"auto"`` (default) solves a
            tangent by GMRES preconditioned by the last factorisation while that
            costs less than factorising it (3-D tangents; none in 2-D, where a
            factorisation costs a few back-substitutions), ``"always"`` does so
            for every factor, ``"never"`` factorises every tangent. Only the cost
            changes: the corrections are solved to the same tolerances.
    """

    rtol: float = 1e-10
    atol: float = 0.0
    max_iter: int = 25
    max_cuts: int = 8
    max_total_cuts: int = 40
    min_step: float = 1e-6
    divergence: float = 1e12
    singular_check: float = 1e-6
    line_search: bool = False
    step_tol: float = 1e-9
    floor_max: float = 1e-7
    predictor: str = "extrapolate"
    start: str = "auto"
    reuse_factor: str = "auto"

    def __post_init__(self):
        if not (self.rtol > 0 or self.atol > 0):
            raise InputError("NewtonOptions: rtol or atol must be positive")
        if not self.rtol < 1:
            raise InputError(f"NewtonOptions: rtol must be below 1 (a fraction of the reference "
                             f"residual; default 1e-10), got {self.rtol!r}")
        for name in ("max_iter", "max_cuts", "max_total_cuts"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool):
                raise InputError(f"NewtonOptions: {name} must be an integer, got {v!r}")
        if self.max_iter < 1 or self.max_cuts < 0 or self.max_total_cuts < 0:
            raise InputError("NewtonOptions: max_iter >= 1, max_cuts >= 0 and max_total_cuts >= 0 "
                             "are required")
        for name in ("rtol", "atol", "min_step", "divergence", "singular_check", "step_tol",
                     "floor_max"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v == v and abs(v) != float("inf")):
                raise InputError(f"NewtonOptions: {name} must be a finite number, got {v!r}")
        if self.start not in ("auto", "coarse", "rest"):
            raise InputError(f"NewtonOptions: start must be 'auto', 'coarse' or 'rest', got "
                             f"{self.start!r}")
        if self.reuse_factor not in ("auto", "always", "never"):
            raise InputError(f"NewtonOptions: reuse_factor must be 'auto', 'always' or 'never', "
                             f"got {self.reuse_factor!r}")
        if self.predictor not in ("extrapolate", "none"):
            raise InputError(f"NewtonOptions: predictor must be 'extrapolate' or 'none', got "
                             f"{self.predictor!r}")
        if not (0 <= self.step_tol < 1 and 0 <= self.floor_max < 1):
            raise InputError(f"NewtonOptions: step_tol and floor_max must lie in [0, 1), got "
                             f"{self.step_tol!r} and {self.floor_max!r}")
        if not 0 < self.min_step < 1:
            raise InputError(f"NewtonOptions: min_step must lie in (0, 1), got {self.min_step}")


@dataclass
class StepLog:
    """What Newton did in one (attempted) increment."""

    t: float
    dt: float
    residuals: list[float] = field(default_factory=list)
    converged: bool = False
    reason: str = ""
    #: why Newton stopped: "rtol", "atol" or "round-off floor" (converged), else ""
    stop: str = ""
    #: ||R|| / ref of the last iterate
    relative_residual: float = float("nan")
    time_assembly: float = 0.0
    time_factorization: float = 0.0
    time_solve: float = 0.0
    #: tangents factorised in this increment, by Newton and for its sensitivities (the
    #: others were solved by Krylov on a kept factorisation: linsolve.kept)
    factorizations: int = 0
    #: Krylov iterations on a kept factorisation in this increment
    krylov_iterations: int = 0
    #: why each factorisation was made (linsolve.kept.KeptFactor.reasons)
    refactorizations: list[str] = field(default_factory=list)

    @property
    def iterations(self) -> int:
        """Number of linear solves (iterates after the first)."""
        return max(len(self.residuals) - 1, 0)

    def summary(self) -> str:
        res = " ".join(f"{r:.1e}" for r in self.residuals)
        state = "converged" if self.converged else f"FAILED ({self.reason})"
        if self.stop == "round-off floor":
            state += f" at the round-off floor ({self.relative_residual:.1e} of the reference)"
        return (f"t={self.t:.6g} dt={self.dt:.3g}: {state} in {self.iterations} it"
                f"{self.linear_summary()}, |R|: {res}")

    def linear_summary(self) -> str:
        """', F factorisations, K Krylov iterations' where a kept factor served."""
        if not self.krylov_iterations:
            return ""
        return f", {self.factorizations} factorisations, {self.krylov_iterations} Krylov it"


class StepFailure(Exception):
    """An increment failed; ``fatal`` means cutting the step cannot help."""

    def __init__(self, reason: str, fatal: bool = False, stagnated: bool = False):
        super().__init__(reason)
        self.reason = reason
        self.fatal = fatal or stagnated
        self.stagnated = stagnated  # at the round-off floor: the tolerance is unreachable


#: halvings of a Newton correction whose iterate has a non-finite residual
BACKTRACK = 8

#: iterations without progress near round-off before Newton is declared stagnated
STAGNATION = 4

#: the loosest tolerance of an inexact Newton correction (an iterative solver's)
FORCING_MAX = 1e-3
#: an inexact correction aims at a residual this far below Newton's own tolerance,
#: so that converged states (and finite differences of them) are as exact as a
#: direct solver's
FORCING_FLOOR = 1e-3


def _stagnated(res: list[float], ref: float) -> bool:
    """The last STAGNATION+1 residuals are all tiny (< 1e-9 ref) and none is less
    than half the smallest before them: Newton only stirs round-off."""
    if len(res) <= STAGNATION + 1:
        return False
    last = res[-(STAGNATION + 1):]
    if max(last) > 1e-9 * ref:
        return False
    return min(last[1:]) > 0.5 * last[0]


def _relative(dw, w, disp) -> float | None:
    """||dw|| / ||w|| over the displacements (``disp``: their mask among the free
    DOFs; the multipliers, in other units, are held by the residual test): inf
    for zero displacements with a nonzero correction, None without a correction."""
    if dw is None:
        return None
    n, d = float(np.linalg.norm(dw[disp])), float(np.linalg.norm(w[disp]))
    return n / d if d > 0 else (0.0 if n == 0 else float("inf"))


def _converged(norm: float, norm_prev: float, ref: float, step, options) -> str:
    """Why the iterate is converged ("rtol", "atol", "round-off floor"), or "".

    The floor: the residual is small (<= floor_max ref), stopped falling (not
    below half the one before: the quadratic phase, where each residual is a
    small fraction of the last, is never cut short) and the last correction
    moved the displacements by no more than step_tol relative (``step``; None
    before the first correction)."""
    if norm <= options.rtol * ref:
        return "rtol"
    if norm <= options.atol:
        return "atol"
    if (step is not None and norm <= options.floor_max * ref and norm > 0.5 * norm_prev
            and step <= options.step_tol):
        return "round-off floor"
    return ""


def _reject(Rf, weights, norm_prev, alpha, options) -> bool:
    """Backtrack from this iterate? Always if its residual is not finite; with a
    line search also if the norm did not fall (Armijo, c = 1e-4)."""
    if not np.all(np.isfinite(Rf)):
        return True
    if not options.line_search:
        return False
    return float(np.linalg.norm(Rf * weights)) > (1.0 - 1e-4 * alpha) * norm_prev


def newton(model, pattern, solver, w, params, t, state_n, options: NewtonOptions,
           weights: np.ndarray, ref_floor: float, steplog: StepLog):
    """Iterate to convergence from ``w`` (modified in place on the free DOFs).

    Returns:
        (w, R, blocks, factor): converged unknowns, residual and block Jacobians
        at w (so the caller can factorise the exact converged tangent for DDM),
        and the factorisation of the last iteration's tangent (None if no
        iteration was needed).

    Raises:
        StepFailure: no convergence, divergence, non-finite residual or singular tangent.
    """
    free = model.free
    disp = free < model.dim * model.n_nodes  # the displacements among the free DOFs
    ref = None
    dw = None
    norm_prev = np.inf
    fac = None
    forcing = None  # the last inexact solve's tolerance (an iterative solver's)
    polished = False  # a converged inexact state taken one correction further
    at_floor = False  # the last correction was solved to the floor's tolerance
    for k in range(options.max_iter + 1):
        t0 = time.perf_counter()
        R, blocks = _evaluate_with_backtracking(model, w, params, t, state_n, dw, weights, norm_prev,
                                                options, k)
        Rf = R[free]
        steplog.time_assembly += time.perf_counter() - t0
        if not np.all(np.isfinite(Rf)):
            raise StepFailure(
                "non-finite residual: an element is inverted (J <= 0) or a contact node reached "
                "the centre of the obstacle; a smaller load increment may help")
        norm = float(np.linalg.norm(Rf * weights[free]))
        if ref is None:
            ref = max(norm, ref_floor)
        steplog.residuals.append(norm)
        steplog.relative_residual = norm / ref if ref > 0 else 0.0
        log.debug("  t=%.6g it %d |R|=%.3e", t, k, norm)
        step = _relative(dw, w[free], disp)
        stop = _converged(norm, norm_prev, ref, step, options)
        if (stop == "rtol" and not polished and k < options.max_iter and fac is not None
                and forcing is not None and fac.inexact and not at_floor
                and norm > FORCING_FLOOR * options.rtol * ref):
            # converged on an inexact correction, just below the tolerance: one more,
            # solved to the floor, so that the state is as exact as a direct solver's
            # (and finite differences of converged states as smooth); not where the
            # correction that led here was already solved to the floor
            polished = True
            forcing = _floor(norm, ref, options)
            fac, dw = _correction(pattern, solver, blocks, Rf, options, steplog, first=False,
                                  forcing=forcing)
            w[free] += dw
            norm_prev = norm
            continue
        if stop:
            steplog.converged, steplog.stop = True, stop
            if stop == "round-off floor":
                log.debug("  t=%.6g: converged at the round-off floor, |R| = %.1e of the reference "
                          "(rtol %g), last correction %.1e of the displacements", t,
                          steplog.relative_residual, options.rtol, step)
            return w, R, blocks, fac
        norm_prev = norm
        if _stagnated(steplog.residuals, ref):
            floor = norm / ref
            raise StepFailure(
                f"Newton stagnated at |R| = {norm:.2e} ({floor:.1e} of the reference norm) for "
                f"{STAGNATION} iterations while its corrections still changed the displacements by "
                f"{step:.1e} (more than step_tol = {options.step_tol:g}): the "
                "tangent is inaccurate or the problem is ill-conditioned; check the contact "
                "penalties eps (too large ones make the tangent ill-conditioned) and the mesh",
                stagnated=True)
        if k == options.max_iter:
            raise StepFailure(f"no convergence in {options.max_iter} iterations (last |R| = "
                              f"{steplog.relative_residual:.1e} of the reference, rtol "
                              f"{options.rtol:g}; raise max_iter or use smaller load steps)")
        if norm > options.divergence * ref:
            raise StepFailure("residual diverging")
        forcing = _forcing(norm, steplog.residuals, ref, forcing, options)
        floor = _floor(norm, ref, options)
        res = steplog.residuals
        if len(res) >= 2 and res[-2] > 0 and norm * (norm / res[-2]) ** 2 <= options.rtol * ref:
            # the correction expected to be the last (the residuals falling as fast as
            # they did, squared): solved to the floor at once, not polished after
            forcing = min(forcing, floor)
        at_floor = forcing <= floor * (1.0 + 1e-12)
        fac, dw = _correction(pattern, solver, blocks, Rf, options, steplog, first=(k == 0),
                              forcing=forcing)
        # a Krylov correction that went further than asked reached the floor as well
        at_floor = at_floor or fac.relative_residual <= floor
        w[free] += dw
    raise AssertionError("unreachable")


def _evaluate_with_backtracking(model, w, params, t, state_n, dw, weights, norm_prev, options, k):
    """(R, blocks) at w. A Newton correction whose iterate inverts an element
    (non-finite residual) or, with options.line_search, does not decrease the residual
    norm is halved (up to BACKTRACK times, w changed in place) instead of cutting the
    load step: the converged point and the load path stay the same, which keeps finite
    differences consistent with the DDM."""
    free = model.free
    R, blocks = model.local_tangents(w, params, t, state_n)
    halvings = 0
    while dw is not None and halvings < BACKTRACK and _reject(R[free], weights[free], norm_prev,
                                                              0.5**halvings, options):
        dw *= 0.5
        w[free] -= dw
        halvings += 1
        R, blocks = model.local_tangents(w, params, t, state_n)
    if halvings:
        log.debug("  t=%.6g it %d: Newton correction halved %d times", t, k, halvings)
    return R, blocks


def _forcing(norm: float, residuals: list[float], ref: float, last: float | None,
             options) -> float:
    """The tolerance of an inexact Newton correction, ||K dw + R|| <= eta ||R||
    (an iterative solver's; a direct one solves to round-off whatever it is):
    Eisenstat and Walker's choice eta = 0.9 (||R_k|| / ||R_k-1||)^2, kept from
    falling faster than 0.9 eta_k-1^2 while that is above 0.1, at most
    :data:`FORCING_MAX`, and never tighter than needed for the final residual to
    lie FORCING_FLOOR times below ``rtol * ref`` (docs/theory.md §12.7)."""
    if len(residuals) < 2 or last is None:
        eta = FORCING_MAX
    else:
        eta = 0.9 * (norm / residuals[-2]) ** 2
        if 0.9 * last**2 > 0.1:
            eta = max(eta, 0.9 * last**2)
    return float(min(FORCING_MAX, max(eta, _floor(norm, ref, options))))


def _floor(norm: float, ref: float, options) -> float:
    """The tightest forcing term a correction of the residual ``norm`` needs: its
    linear error FORCING_FLOOR times below ``rtol * ref`` (at most FORCING_MAX)."""
    return min(FORCING_MAX, FORCING_FLOOR * options.rtol * ref / norm) if norm > 0 else FORCING_MAX


def _correction(pattern, solver, blocks, Rf, options, steplog, first: bool,
                forcing: float | None = None):
    """(factor, dw): the tangent assembled and factorised, K dw = -R solved and checked
    (an iterative solver's only to the relative residual ``forcing``: :func:`_forcing`);
    a singular tangent fails the step (fatally at the first iteration)."""
    t0 = time.perf_counter()
    K = pattern.assemble(blocks)
    steplog.time_assembly += time.perf_counter() - t0
    kept = getattr(solver, "kept", None)  # a TangentSolver's factorisations (linsolve.kept)
    counts = None if kept is None else (kept.factorizations, kept.krylov_iterations,
                                        len(kept.reasons))
    t0 = time.perf_counter()
    try:
        fac = solver.factor(K, blocks) if kept is not None else solver.factorize(K, blocks)
    except SingularTangentError as e:
        raise StepFailure(str(e), fatal=first) from None
    steplog.time_factorization += time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        inexact = forcing is not None and fac.inexact
        dw = fac.solve_to(-Rf, forcing) if inexact else fac.solve(-Rf)
    except SingularTangentError as e:
        raise StepFailure(str(e), fatal=first) from None
    lin = fac.relative_residual  # linsolve.Factor: every solver's factors are one
    steplog.time_solve += time.perf_counter() - t0
    if counts is not None:
        steplog.factorizations += kept.factorizations - counts[0]
        steplog.krylov_iterations += kept.krylov_iterations - counts[1]
        steplog.refactorizations += kept.reasons[counts[2]:]
    if lin > (max(options.singular_check, 2 * forcing) if inexact else options.singular_check):
        raise StepFailure(f"singular tangent (linear residual {lin:.1e})", fatal=first)
    return fac, dw
