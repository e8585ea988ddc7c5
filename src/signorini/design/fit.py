"""Identification of parameters from measured curves: :func:`fit` (docs/fitting.md).

Each measured curve is a response (:mod:`signorini.responses`) at load factors
t_j (the pseudo-time of the load path) with values m_j and weights w_j; the
fit minimises the misfit of the whole path over the parameters x,

    F(x) = sum_j r_j(x)^2,    r_j = sqrt(w_j) (y(t_j; x) - m_j),

with the residuals' Jacobian J = dr/dx exact: one :func:`signorini.solve` with
``wrt=`` the parameters gives every y(t_j) and its DDM sensitivities, so the
residuals and J at a point cost one solve (the last points are kept: SciPy's
value-then-Jacobian calls at the same x share it). At the optimum,
Gauss-Newton's covariance of the parameters

    s^2 = r^T r / (m - n),    C = s^2 (J^T J)^-1,    SE_i = sqrt(C_ii),
    rho_ij = C_ij / (SE_i SE_j)

(m data of positive weight, n parameters) gives their standard errors and
correlations; a :class:`~signorini.errors.SignoriniWarning` says when they are
not to be trusted (a correlation |rho| > 0.99, J^T J singular or its condition
number, columns scaled to unit norm, above 1e10, a parameter at its bound).

Where the responses are evaluated: at the converged increments. With
``steps=None`` the number of equal increments is the smallest n <= 1000 that
puts every measured time on an increment (t_j n an integer), so each datum is an
increment's value. With ``steps`` given, a time between two increments t_k <
t_j < t_k+1 takes the linear interpolation of their values and sensitivities
(the same weights in both, fixed by the times). Either way the increments come
from the times and ``steps`` alone, never from a parameter; a cut increment
adds increments but the data keep their times. The solve stops at the last
measured time (``until``).

With ``method="L-BFGS-B", gradient="adjoint"`` the gradient of F comes from one
backward pass instead (:meth:`Misfit.objective`: F as
:func:`~signorini.responses.misfit` summed over the increments at the measured
times), and one solve with DDM sensitivities at the optimum gives J for the
statistics.
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .._jax import jnp
from ..algorithms.newton import NewtonOptions
from ..algorithms.stepping import solve
from ..errors import ConvergenceError, InputError
from ..model import checks
from ..params import check_names
from ..responses import Response, misfit
from ..sensitivity.methods import Adjoint
from .evaluation import ObjectiveEvaluation
from .fit_result import TIME_TOL, Curve, FitResult, _curves, _numbers, statistics
from .history import Evaluation
from .optimize import Objective

log = logging.getLogger("signorini")

__all__ = ["GRADIENTS", "METHODS", "Misfit", "fit"]

#: optimisers of :func:`fit`
METHODS = ("least_squares", "L-BFGS-B")
#: how L-BFGS-B's gradient of the misfit is computed
GRADIENTS = ("ddm", "adjoint")
#: the largest number of increments derived from the measured times
MAX_STEPS = 1000
#: solves kept (value and Jacobian at the same point share one)
KEPT_POINTS = 4


def _derived_steps(times: np.ndarray) -> int:
    """The smallest n <= MAX_STEPS with every t n an integer (to TIME_TOL)."""
    for n in range(1, MAX_STEPS + 1):
        k = times * n
        if np.all(np.abs(k - np.round(k)) <= TIME_TOL * n):
            return n
    raise InputError(f"the measured times are not on a grid k/n of n <= {MAX_STEPS} equal "
                     "increments: give steps= (the responses are then interpolated linearly "
                     "between increments)")


def fit_steps(curves, steps: int | None = None) -> int:
    """The equal load increments of a fit's solves: ``steps``, checked, or with None
    derived from the measured load factors of ``curves`` (module docstring)."""
    curves = _curves(curves)
    timed = [c.times for c in curves if c.abscissa is None]
    times = np.concatenate(timed) if timed else np.array([1.0])
    if steps is None:
        if not timed:
            raise InputError("steps=None derives the increments from the measured load factors, "
                             "but every curve is measured against an abscissa response: give steps")
        steps = _derived_steps(times)
    elif isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"steps must be a positive integer or None (from the times), got {steps!r}")
    if times.min() < (1 - TIME_TOL) / steps:
        raise InputError(f"the measured time {float(times.min())!r} comes before the first increment "
                         f"(t = 1/{steps}): give more steps")
    return int(steps)


@dataclass
class Point:
    """The residuals of the curves at a parameter point x (one solve)."""

    x: np.ndarray
    status: str                      # "ok", "failed" (Newton), "invalid" (rejected parameters)
    r: np.ndarray | None = None      # (m,) weighted residuals sqrt(w) (y - m)
    J: np.ndarray | None = None      # (m, n) dr/dx
    fitted: list | None = None       # the model's values at each curve's times
    solution: object = None
    reason: str = ""
    error: BaseException | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def F(self) -> float:
        return float(self.r @ self.r) if self.ok else math.inf


class Misfit(ObjectiveEvaluation):
    """F(x) = sum_j r_j^2 of measured curves, its weighted residuals r and their Jacobian J.

    The residuals and J at x cost one :func:`~signorini.solve` with DDM
    sensitivities; the last :data:`KEPT_POINTS` points are kept. Every solve is
    recorded (:class:`~signorini.design.history.Evaluation`: F, gradient 2 J^T r;
    F = inf where the solve failed). From :class:`~signorini.Objective`'s
    machinery it takes the point checks, each distinct warning of the solves
    once, and the penalty of a failed point (:func:`fit` with L-BFGS-B).

    Args:
        problem: the problem at its nominal values; a point x is solved as
            ``problem.with_params(**dict(zip(wrt, x)))``.
        wrt: the parameters to identify.
        curves: :class:`Curve` objects or tuples (response, times, values[, weights]).
        steps: equal load increments (default: derived from the times, module docstring).
        options: :class:`~signorini.NewtonOptions` of the solves.
        solver: linear solver of the solves.
        label: the solves' name in log lines and progress bars.
    """

    def __init__(self, problem, wrt: Sequence[str], curves, *, steps: int | None = None,
                 options: NewtonOptions | None = None, solver="auto", label: str = "fit"):
        if isinstance(wrt, str):
            raise InputError(f"wrt must be a list of parameter names, got the string {wrt!r}")
        self.names = [str(n) for n in wrt]
        if not self.names:
            raise InputError("fit needs at least one parameter to identify (wrt)")
        if len(set(self.names)) != len(self.names):
            raise InputError(f"wrt lists a parameter twice: {self.names}")
        check_names(self.names, problem.params, "the parameters to fit (wrt)")
        self.curves = _curves(curves)
        steps = fit_steps(self.curves, steps)
        self.n_data = int(sum(np.count_nonzero(c.weights > 0) for c in self.curves))
        if self.n_data < len(self.names):
            raise InputError(f"fewer data ({self.n_data} measured points of positive weight) than "
                             f"parameters ({len(self.names)}: {self.names}): they cannot be identified")
        if options is not None and not isinstance(options, NewtonOptions):
            raise InputError(f"options must be a signorini.NewtonOptions, got {type(options).__name__}")
        self.problem, self.steps, self.solver, self.label = problem, int(steps), solver, label
        self.options = options if options is not None else NewtonOptions()
        timed = [c.times for c in self.curves if c.abscissa is None]
        # the solves run to the last measured load factor (to the end without one)
        self.until = float(min(np.concatenate(timed).max(), 1.0)) if timed else 1.0
        self.records: list[Evaluation] = []
        self.warnings: list[str] = []
        self.failure_value = None
        self._seen_logs: set = set()
        self._kept: OrderedDict[bytes, Point] = OrderedDict()
        self.best: Point | None = None
        self._objective = None

    # ------------------------------------------------------------ public API
    def evaluate(self, x) -> Point:
        """The residuals and Jacobian at x (a kept point, else one solve)."""
        x = self.point(x)
        key = x.tobytes()
        pt = self._kept.get(key)
        if pt is not None:
            self._kept.move_to_end(key)
            return pt
        t0 = time.perf_counter()
        with self._quiet():
            pt = self._solve_point(x)
        self._kept[key] = pt
        while len(self._kept) > KEPT_POINTS:
            self._kept.popitem(last=False)
        if pt.ok and (self.best is None or pt.F < self.best.F):
            self.best = pt
        g = 2.0 * pt.J.T @ pt.r if pt.ok else None
        sol = pt.solution
        its = sum(s.iterations for s in sol.log) if sol is not None else 0
        ev = Evaluation(len(self.records) + 1, "value+gradient", x, pt.F, g, pt.status, pt.reason,
                        its, len(sol.increments) if sol is not None else 0,
                        sum(not s.converged for s in sol.log) if sol is not None else 0,
                        time.perf_counter() - t0, list(sol.warnings) if sol is not None else [],
                        pt.error)
        self.records.append(ev)
        log.info("%s evaluation %d: F = %.10g%s, %d Newton iterations, %.2f s%s", self.label,
                 ev.index, ev.F, "" if g is None else f", |grad| = {ev.grad_norm:.4g}", its, ev.time,
                 "" if pt.ok else f" [{pt.status}: {pt.reason.splitlines()[0][:200]}]")
        return pt

    def residuals(self, x) -> np.ndarray:
        """(m,) the weighted residuals sqrt(w_j) (y(t_j; x) - m_j), all curves in order
        (+inf where the solve failed)."""
        pt = self.evaluate(x)
        return pt.r.copy() if pt.ok else np.full(self._m, math.inf)

    def jacobian(self, x) -> np.ndarray:
        """(m, n) dr/dx, exact (DDM)."""
        pt = self.evaluate(x)
        if not pt.ok:
            raise pt.error
        return pt.J.copy()

    def __call__(self, x) -> float:
        """F(x) = r^T r."""
        return self.evaluate(x).F

    def gradient(self, x) -> np.ndarray:
        """dF/dx = 2 J^T r."""
        pt = self.evaluate(x)
        if not pt.ok:
            raise pt.error
        return 2.0 * pt.J.T @ pt.r

    def response(self) -> Response:
        """F as one response summed over the increments: per curve,
        :func:`signorini.responses.misfit` at the increments at its measured times
        (zero at the others, cut increments included). Only for times on the
        increments (an interpolated datum is not a sum over increments)."""
        T = np.arange(1, self.steps + 1) / self.steps
        for c in self.curves:
            if c.abscissa is not None:
                raise InputError(f"curve {c.name}: the adjoint gradient needs curves measured at "
                                 "load factors; one against an abscissa response takes gradient='ddm'")
            off = [float(t) for t in c.times if np.abs(T - t).min() > TIME_TOL]
            if off:
                raise InputError(f"curve {c.name}: the adjoint gradient needs every measured time on "
                                 f"an increment (k / {self.steps}); {off[0]!r} is between two: leave "
                                 "steps=None or take gradient='ddm' (which interpolates)")
        parts = [(misfit(c.response, c.times, c.values, c.weights), c.times) for c in self.curves]

        def build(model):
            fns = [(m(model), tc) for m, tc in parts]

            def fn(w, p, t, s):
                return sum(jnp.where(jnp.any(jnp.abs(t - tc) <= TIME_TOL), f(w, p, t, s), 0.0)
                           for f, tc in fns)
            return fn
        return Response("fit[" + ",".join(m.name for m, _ in parts) + "]", build)

    def objective(self):
        """The :class:`~signorini.Objective` of F with the adjoint gradient (one solve
        and one backward pass per point, whatever the number of parameters): F =
        :meth:`response` summed over all increments of the path."""
        if self._objective is None:
            self._objective = Objective(self.problem, self.names, self.response(), method=Adjoint(),
                                        steps=self.steps, increments="all", options=self.options,
                                        solver=self.solver, label=self.label)
        return self._objective

    # -------------------------------------------------------------- internals
    @property
    def _m(self) -> int:
        return sum(c.times.size for c in self.curves)

    def _solve_point(self, x) -> Point:
        pvals = {n: float(v) for n, v in zip(self.names, x)}
        try:
            if not np.all(np.isfinite(x)):
                raise InputError(f"the parameter point is not finite: {pvals}")
            sol = solve(self.problem.with_params(**pvals), steps=self.steps, wrt=self.names,
                        options=self.options, solver=self.solver, until=self.until, label=self.label)
        except ConvergenceError as e:
            return Point(x, "failed", reason=str(e), error=e, solution=e.partial)
        except InputError as e:
            return Point(x, "invalid", reason=str(e), error=e)
        T = np.array([inc.t for inc in sol.increments])
        rows, jac, fitted = [], [], []
        for c in self.curves:
            y, dy = self._curve(sol, T, c)
            sw = np.sqrt(c.weights)
            fitted.append(y)
            rows.append(sw * (y - c.values))
            jac.append(sw[:, None] * dy)
        r, J = np.concatenate(rows), np.concatenate(jac)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
            reason = "the responses or their sensitivities are not finite"
            return Point(x, "failed", reason=reason, error=ConvergenceError(reason, partial=sol),
                         solution=sol)
        return Point(x, "ok", r, J, fitted, sol)

    def _reader(self, sol, response):
        """at(i) -> (value, (n,) DDM sensitivities) of ``response`` at increment i,
        each increment read once."""
        seen = {}

        def at(i):
            if i not in seen:
                v, s = response.of(sol, i)
                seen[i] = (v, np.array([s[n] for n in self.names]))
            return seen[i]
        return at

    def _curve(self, sol, T: np.ndarray, c: Curve):
        """(k,) the response at the curve's times and (k, n) its sensitivities:
        an increment's, or the linear interpolation between the two around t."""
        at = self._reader(sol, c.response)
        if c.abscissa is not None:
            return self._against(sol, c, at)
        y, dy = np.empty(c.times.size), np.empty((c.times.size, len(self.names)))
        for j, t in enumerate(c.times):
            k = int(np.searchsorted(T, t))
            near = [i for i in (k - 1, k) if 0 <= i < T.size and abs(T[i] - t) <= TIME_TOL]
            if near:
                y[j], dy[j] = at(near[0])
            elif 0 < k < T.size:
                a = (t - T[k - 1]) / (T[k] - T[k - 1])
                (v0, s0), (v1, s1) = at(k - 1), at(k)
                y[j], dy[j] = (1 - a) * v0 + a * v1, (1 - a) * s0 + a * s1
            else:
                raise InputError(f"curve {c.name}: the time {float(t)!r} is outside the solved path "
                                 f"({T[0] if T.size else 0:.6g} .. {T[-1] if T.size else 0:.6g})")
        return y, dy

    def _against(self, sol, c: Curve, at):
        """The response against the abscissa response at the measured abscissae:
        between the increments k, k+1 whose abscissae x_k <= x* <= x_k+1 (x
        increasing along the path), y = (1 - a) y_k + a y_k+1 with a = (x* - x_k) /
        (x_k+1 - x_k), and its sensitivities through a's too."""
        x_at = self._reader(sol, c.abscissa)
        n = len(sol.increments)
        X = np.array([x_at(i)[0] for i in range(n)])
        if np.any(np.diff(X) <= 0):
            raise InputError(f"curve {c.name}: its abscissa {c.abscissa.name} does not increase "
                             "along the path, so the model's curve is not a function of it")
        y, dy = np.empty(c.times.size), np.empty((c.times.size, len(self.names)))
        for j, xm in enumerate(c.times):
            k = int(np.searchsorted(X, xm))
            if k == n and abs(xm - X[-1]) <= TIME_TOL * max(abs(X[-1]), 1.0):
                k = n - 1
            elif k == 0 and n > 1 and xm == X[0]:
                k = 1  # the first increment's own abscissa: a = 0
            if not 0 < k < n:
                raise InputError(f"curve {c.name}: the measured abscissa {float(xm)!r} is outside "
                                 f"the model's path ({X[0]:.6g} .. {X[-1]:.6g} of "
                                 f"{c.abscissa.name}): give a longer path or fewer data")
            (x0, dx0), (x1, dx1) = x_at(k - 1), x_at(k)
            (v0, s0), (v1, s1) = at(k - 1), at(k)
            a = (xm - x0) / (x1 - x0)
            da = -((1 - a) * dx0 + a * dx1) / (x1 - x0)
            y[j] = (1 - a) * v0 + a * v1
            dy[j] = (1 - a) * s0 + a * s1 + (v1 - v0) * da
        return y, dy


# ------------------------------------------------------------------------- fit
def _per_name(value, names, what, default):
    """A dict or a sequence in the order of names, as a list (``default(name)`` where missing)."""
    if value is None:
        return [default(n) for n in names]
    if isinstance(value, Mapping):
        unknown = [k for k in value if k not in names]
        if unknown:
            raise InputError(f"{what} names {unknown}, which are not among the parameters to fit "
                             f"{names}")
        return [value[n] if n in value else default(n) for n in names]
    value = list(value)
    if len(value) != len(names):
        raise InputError(f"{what} has {len(value)} entries, expected {len(names)} ({names})")
    return value


def _bounds(bounds, names, start) -> tuple[np.ndarray, np.ndarray]:
    pairs = _per_name(bounds, names, "bounds", lambda n: (None, None))
    lo, hi = np.full(len(names), -math.inf), np.full(len(names), math.inf)
    for i, pair in enumerate(pairs):
        try:
            a, b = (None, None) if pair is None else pair
            lo[i] = -math.inf if a is None else float(a)
            hi[i] = math.inf if b is None else float(b)
        except (TypeError, ValueError):
            raise InputError(f"the bounds of {names[i]!r} must be a pair (low, high) of numbers or "
                             f"None, got {pair!r}") from None
        if not lo[i] < hi[i] or math.isnan(lo[i]) or math.isnan(hi[i]):
            raise InputError(f"the bounds of {names[i]!r} are empty: ({lo[i]}, {hi[i]})")
        if not lo[i] <= start[i] <= hi[i]:
            raise InputError(f"the start value {names[i]} = {float(start[i])!r} is outside its bounds "
                             f"({lo[i]}, {hi[i]})")
    return lo, hi


class _Stop(Exception):
    """The budget of solves is spent."""


def fit(problem, wrt: Sequence[str], curves, *, start=None, bounds=None, steps: int | None = None,
        method: str = "least_squares", gradient: str = "ddm", tol: float = 1e-10,
        max_solves: int = 100,
        options: NewtonOptions | None = None, solver="auto", optimizer_options: dict | None = None,
        callback: Callable | None = None, label: str = "fit") -> FitResult:
    """Identify parameters of a problem from measured curves, with standard errors.

    Args:
        problem: the :class:`~signorini.Problem`; its other parameters stay at their values.
        wrt: the names of the parameters to identify.
        curves: one or more :class:`Curve` or tuples (response, times, values[, weights]):
            a response of :mod:`signorini.responses` measured at load factors ``times``.
        start: the start values, a dict or a list in the order of ``wrt`` (default: the
            problem's values).
        bounds: (low, high) per parameter (None or +-inf: unbounded), a dict or a list.
        steps: equal load increments; default: the fewest that put every measured time on
            an increment (else the responses are interpolated linearly between increments).
        method: ``"least_squares"`` (:func:`scipy.optimize.least_squares`, trust-region
            reflective with the exact Jacobian) or ``"L-BFGS-B"`` (the misfit F and its
            gradient 2 J^T r, F divided by its start value and x by the start's scale).
        gradient: L-BFGS-B's gradient of F: ``"ddm"`` (2 J^T r, one solve with
            sensitivities of every parameter) or ``"adjoint"`` (F as
            :func:`signorini.responses.misfit` summed over the increments,
            :class:`~signorini.Objective` with :class:`~signorini.Adjoint`: one solve
            and one backward pass, whatever the number of parameters; the measured
            times must be on increments). The standard errors then come from one
            more solve, with DDM sensitivities, at the optimum.
        tol: the optimisers' tolerances (least_squares' ftol, xtol, gtol; L-BFGS-B's
            ftol and gtol).
        max_solves: the budget of solves (a failed one included).
        options: :class:`~signorini.NewtonOptions` of the solves.
        solver: linear solver of the solves.
        optimizer_options: further SciPy options (override the above).
        callback: ``callback(row)`` after every iteration with its :attr:`FitResult.history` row.
        label: the solves' name in log lines and progress bars.

    Returns:
        A :class:`FitResult` (its :meth:`~FitResult.table` for a person).

    Raises:
        InputError: a parameter, curve, bound or option that cannot be used (before any
            solve), or a start point the problem rejects.
        ConvergenceError: the solve at the start point fails.

    A failed solve at a trial point does not end the fit: least squares gets
    infinite residuals there and shrinks its trust region; L-BFGS-B gets the
    penalty of :class:`~signorini.Objective` (a large value, the gradient
    pointing back to the last good point). Every iteration is logged on the
    ``signorini`` logger (INFO) as :func:`~signorini.minimize` does.
    """
    import scipy.optimize as so  # lazy: heavy, and only a fit needs it

    t_start = time.perf_counter()
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if gradient not in GRADIENTS:
        raise InputError(f"gradient must be one of {GRADIENTS}, got {gradient!r}")
    if gradient == "adjoint" and method != "L-BFGS-B":
        raise InputError("gradient='adjoint' is for method='L-BFGS-B' (least squares needs the "
                         "residuals' Jacobian, which DDM gives)")
    if not (isinstance(max_solves, (int, np.integer)) and max_solves >= 1):
        raise InputError(f"max_solves must be a positive integer, got {max_solves!r}")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise InputError(f"tol must be a number in (0, 1), got {tol!r}")
    mis = Misfit(problem, wrt, curves, steps=steps, options=options, solver=solver, label=label)
    names = mis.names
    x0 = _numbers(_per_name(start, names, "start", lambda n: problem.params[n]), "start")
    lo, hi = _bounds(bounds, names, x0)
    scale = np.where(x0 != 0, np.abs(x0), 1.0)

    obj = mis.objective() if gradient == "adjoint" else None  # its times checked before a solve

    def solves() -> int:
        return mis.n_solves + (obj.n_solves if obj is not None else 0)

    def seen(x) -> bool:
        return mis.point(x).tobytes() in (obj._cache if obj is not None else mis._kept)

    def at(x):
        """(F, dF/dx) at x (a failed solve: the penalty of Objective)."""
        if obj is not None:
            ev = obj.evaluate(x)
            return ev.F, ev.grad
        pt = mis.evaluate(x)
        return (pt.F, 2.0 * pt.J.T @ pt.r) if pt.ok else mis._penalty(mis.point(x), pt.error)

    if obj is None:
        first = mis.evaluate(x0)
        status, reason, err, partial = first.status, first.reason, first.error, first.solution
    else:
        try:
            status, err, partial = obj.evaluate(x0).status, None, None
        except (ConvergenceError, InputError) as e:  # the start has no good point to fall back on
            status, reason, err = ("failed" if isinstance(e, ConvergenceError) else "invalid"), str(e), e
            partial = getattr(e, "partial", None)
    if status != "ok":
        where = dict(zip(names, x0.tolist()))
        if status == "failed":
            raise ConvergenceError(f"the fit cannot start: the solve at the start {where} failed: "
                                   f"{reason}", partial=partial) from err
        raise InputError(f"the fit cannot start: the start {where} is invalid: {reason}") from err
    history: list[dict] = []

    def iteration(x):
        x = mis.point(x)
        F, g = at(x)
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))  # projected on the bounds
        row = {"iteration": len(history), "F": F, "grad_norm": float(np.linalg.norm(g[free])),
               "x": x.tolist(), "solves": solves(), "time": time.perf_counter() - t_start}
        history.append(row)
        log.info("%s iteration %d: F = %.10g, |grad| = %.4g, %d solves", label, row["iteration"],
                 row["F"], row["grad_norm"], row["solves"])
        if callback is not None:
            callback(row)

    def budget():
        if solves() >= max_solves:
            raise _Stop

    success, message = False, ""
    try:
        if method == "least_squares":
            def residuals(x):
                if not seen(x):
                    budget()
                return mis.residuals(x)

            def jacobian(x, *_):
                iteration(x)  # least squares asks for J at each accepted point
                return mis.jacobian(x)

            opts = {"ftol": tol, "xtol": tol, "gtol": tol, "max_nfev": max_solves, "x_scale": scale}
            opts.update(optimizer_options or {})
            res = so.least_squares(residuals, x0, jac=jacobian, bounds=(lo, hi), method="trf", **opts)
        else:
            F0 = at(x0)[0] or 1.0

            def value_and_gradient(z):
                x = z * scale
                if not seen(x):
                    budget()
                F, g = at(x)
                return F / F0, g * scale / F0

            iteration(x0)
            opts = {"ftol": tol, "gtol": tol, "maxfun": max_solves, "maxiter": max_solves}
            opts.update(optimizer_options or {})
            res = so.minimize(value_and_gradient, x0 / scale, jac=True, method="L-BFGS-B",
                              bounds=list(zip(lo / scale, hi / scale)), options=opts,
                              callback=lambda zk, *a: iteration(zk * scale))
        success, message = bool(res.success), str(res.message)
    except _Stop:
        message = f"the budget of {max_solves} solves is spent (max_solves)"
    best = mis.best if obj is None else mis.evaluate(obj.best.x)  # adjoint: one DDM solve for J
    if not best.ok:
        raise ConvergenceError(f"fit: the solve with sensitivities at the optimum "
                               f"{dict(zip(names, best.x.tolist()))} failed: {best.reason}",
                               partial=best.solution) from best.error
    if history[-1]["x"] != best.x.tolist():
        iteration(best.x)
    cov, corr, condition, sigma, messages = statistics(best.r, best.J, mis.n_data, names)
    at = [n for i, n in enumerate(names) if best.x[i] - lo[i] <= 1e-9 * scale[i]
          or hi[i] - best.x[i] <= 1e-9 * scale[i]]
    if at:
        messages.append(f"fit: {at} ended at a bound: the standard errors assume an optimum inside "
                        "the bounds")
    if not success:
        messages.append(f"fit: the optimiser did not converge: {message}")
    se = np.sqrt(np.diag(cov))
    result = FitResult(
        names=names, x=best.x.copy(), values=dict(zip(names, best.x.tolist())),
        start=dict(zip(names, x0.tolist())), stderr=dict(zip(names, se.tolist())),
        covariance=cov, correlation=corr, sigma=sigma, misfit=best.F, residuals=best.r.copy(),
        jacobian=best.J.copy(), n_data=mis.n_data, condition=condition, fitted=best.fitted,
        curves=mis.curves, bounds=list(zip(lo.tolist(), hi.tolist())), history=history,
        n_solves=solves(), n_failed=mis.n_failed + (obj.n_failed if obj is not None else 0),
        success=success, message=message, method=method, gradient=gradient,
        time=time.perf_counter() - t_start,
        warnings=list(dict.fromkeys(mis.warnings + (obj.warnings if obj is not None else []))),
        solution=best.solution, evaluations=(obj.records if obj is not None else []) + mis.records,
        label=label)
    for m in messages:
        checks.warn(result, m)
    return result
