"""Design optimisation with exact gradients (paper §5.3).

:class:`Objective` turns a :class:`~signorini.model.problem.Problem`, the names of
the design parameters and a scalar response into the ``fun``/``jac`` pair that
:func:`scipy.optimize.minimize` expects; :func:`minimize` runs it::

    import signorini as sg

    obj = sg.Objective(problem, wrt=["phi0", "phi1"], response=lambda model: my_response(model),
                       method=sg.DDM(), steps=20)
    res = sg.minimize(obj, x0, method="BFGS", gtol=1e-8)
    res.x, res.fun, res.iterations_log, obj.records, obj.write_csv("history.csv")

The problem may be plane-strain, axisymmetric or 3-D: the objective solves it as
:func:`signorini.solve` does and takes the response ``fn(w, params, t)`` of its
unknowns (see :meth:`~signorini.algorithms.solution.Solution.response`), the same
in every dimension.

* **One solve per design point.** ``fun(x)`` and ``jac(x)`` share one
  :func:`signorini.solve` of ``problem.with_params(**dict(zip(wrt, x)))``; the
  first call at a point solves, every later call at the bit-identical point
  (SciPy's usual fun-then-jac pattern, the callback) is served from a cache
  keyed by the bytes of x.
* **The gradient, by the objective's** ``method``: :class:`~signorini.DDM`
  (default: the solve carries the DDM sensitivities of the design parameters),
  :class:`~signorini.Adjoint` (the solve, then one backward pass for all of
  them) or :class:`~signorini.FiniteDifferences` (central differences of the
  value, two more solves per parameter with the method's step, one-sided where
  a perturbed solve fails: for comparing cost and accuracy).
* **Every evaluation is recorded** (:class:`Evaluation`: x, F, gradient,
  Newton iterations, converged increments, wall time, status) in
  :attr:`Objective.records`; :meth:`Objective.write_csv` writes them, and with
  ``history=path`` each one is appended to the CSV as soon as it is done, so
  an interrupted optimisation can be resumed (:func:`read_history`).
* **Failed trial points do not end the optimisation.** A Newton failure
  (:class:`~signorini.errors.ConvergenceError`) or an invalid design
  (:class:`~signorini.errors.InputError`: inverted elements, a ``validate``
  check such as a preform radius <= 0) at a trial point returns, with
  ``failure="penalty"`` (default), a large *finite* value

      F_fail = failure_value                     if given, else
      F_fail = F_max + 10 max(|F|)               over the successful evaluations so far

  (about 11 x the largest value seen for a non-negative objective) and a
  gradient ``s (x - x_good) / |x - x_good|^2`` along the step from the last
  good evaluation (x_good, F_good, gradient g_good), with the directional
  derivative ``s = max(6 (F_fail - F_good) - g_good.(x - x_good), 2 (F_fail - F_good))``
  > 0: the cubic through F_good, its slope, F_fail and s has its minimum
  halfway. BFGS's and L-BFGS-B's line searches (Moré-Thuente: cubic
  interpolation of values and slopes) then see the failed step as uphill
  with the minimum bracketed and back off towards the last good point
  (about half-way; the value alone already makes SLSQP's backtracking
  shorten the step). The value is never NaN; the record
  has ``status`` ``"failed"`` (Newton) or ``"invalid"`` (design) and the
  reason. With no successful evaluation yet (and no ``failure_value``) the
  error is raised: an optimisation cannot start from a design that cannot be
  solved. ``failure="raise"`` re-raises every failure.

:func:`minimize` wraps :func:`scipy.optimize.minimize` (BFGS, L-BFGS-B,
SLSQP; bounds and constraints passed through), refuses a start point that
fails, and logs F and |grad F| per iteration (``res.iterations_log``) for
convergence plots.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np


from .._deprecation import pop_old
from ..sensitivity.methods import DDM, Adjoint, FiniteDifferences, from_keywords
from ..errors import ConvergenceError, InputError
from .gradient import is_factory
from .evaluation import ObjectiveEvaluation
from .history import Evaluation, append_rows, read_history, write_header
from ..algorithms.newton import NewtonOptions
from ..params import check_names

log = logging.getLogger("signorini")

__all__ = ["Evaluation", "Objective", "minimize", "read_history", "METHODS"]

#: optimisers of :func:`minimize` (all gradient based)
METHODS = ("BFGS", "L-BFGS-B", "SLSQP")

_UID = itertools.count()


class Objective(ObjectiveEvaluation):
    """F(x) = response of the solved problem at the parameters ``names = x``, with its gradient.

    Args:
        problem: the :class:`~signorini.model.problem.Problem` at its nominal values;
            a design point x is solved as ``problem.with_params(**dict(zip(names, x)))``
            (same mesh and components, so the compiled model is reused).
        wrt: the design parameters (they must be parameters of ``problem``).
        response: either a factory ``G(model) -> fn`` (a callable of one argument,
            called once per compiled model, e.g. ``lambda m: forging.objective(m, nodes)``)
            or a ready ``fn(w, params, t)``; ``fn`` must return a scalar and be
            JAX-traceable (see :meth:`~signorini.algorithms.solution.Solution.response`).
        steps: load increments of every solve.
        options: :class:`~signorini.algorithms.newton.NewtonOptions` (default ``NewtonOptions()``).
        solver: linear solver name or object.
        response_key: key under which the compiled response is cached on the
            model (default: a key unique to this objective).
        increment: which converged increment the response is evaluated at (-1: the last).
        increments: instead, ``"all"`` or a list of increment indices: the response
            summed over them (a misfit to a measured history:
            :func:`signorini.responses.misfit` over ``"all"``), with the gradient of the
            sum (DDM or one adjoint pass).
        method: :class:`~signorini.DDM` (default: one solve with sensitivities per
            point), :class:`~signorini.Adjoint` (one solve and one backward pass per
            point, whatever the number of design parameters) or
            :class:`~signorini.FiniteDifferences` (central differences of the value:
            1 + 2 len(wrt) solves per gradient, step ``step_for(x_i)``).
        failure: ``"penalty"`` (return ``F_fail`` and a gradient pointing back to the
            last good point, see the module docstring) or ``"raise"``.
        failure_value: a fixed ``F_fail`` (default: F_max + 10 max |F| of the good points).
        validate: optional ``validate(params)`` raising :class:`~signorini.errors.InputError`
            for a design the problem builder would reject (e.g. ``forging.check_shape``);
            called with the full parameter dict before each solve.
        factory: force the interpretation of ``response`` (default: detected,
            one positional parameter = factory).
        history: path of a CSV file to which every evaluation is appended as it is done.
        append: with ``history``: continue an existing file (numbering continues)
            instead of overwriting it.
        label: name of the solves in log lines and progress bars.

    The keywords of version 0.1 still work, with a DeprecationWarning: ``names=``
    (now ``wrt=``), ``gradient_mode=`` and ``fd_step=`` (now ``method=``).

    Attributes:
        records: every :class:`Evaluation`, in order.
        warnings: distinct warnings of all solves (also logged once each).
    """

    def __init__(self, problem, wrt: Sequence[str] | None = None, response: Callable | None = None, *,
                 method=None, steps: int = 1, options: NewtonOptions | None = None, solver="auto",
                 response_key=None, increment: int = -1, increments=None, failure: str = "penalty",
                 failure_value: float | None = None, validate: Callable | None = None,
                 factory: bool | None = None, history=None, append: bool = False,
                 label: str = "opt", **deprecated):
        old = pop_old(deprecated, "Objective", {
            "names": "wrt=[...]", "gradient_mode": "method=signorini.DDM(), Adjoint() or "
            "FiniteDifferences()", "fd_step": "method=signorini.FiniteDifferences(rel_step=...)"})
        if "names" in old:
            if wrt is not None:
                raise InputError("give the design parameters once, as wrt= (names= is its old name)")
            wrt = old["names"]
        if wrt is None or response is None:
            raise InputError("an objective needs the design parameters (wrt) and a response")
        names = wrt
        method = from_keywords(method, old, "Objective", (DDM, Adjoint, FiniteDifferences),
                               "gradient_mode", "ddm")
        if isinstance(names, str):
            raise InputError(f"names must be a list of parameter names, got the string {names!r}")
        self.names = [str(n) for n in names]
        if not self.names:
            raise InputError("an objective needs at least one design parameter (names)")
        if len(set(self.names)) != len(self.names):
            raise InputError(f"names lists a parameter twice: {self.names}")
        check_names(self.names, problem.params, "the design parameters (names)")
        if failure not in ("penalty", "raise"):
            raise InputError(f"failure must be 'penalty' or 'raise', got {failure!r}")
        if failure_value is not None and not np.isfinite(failure_value):
            raise InputError(f"failure_value must be a finite number, got {failure_value!r}")
        if not callable(response):
            raise InputError("response must be a callable: fn(w, params, t) or a factory G(model) -> fn")
        self.problem = problem
        self.response = response
        self.factory = is_factory(response) if factory is None else bool(factory)
        self.steps = steps
        self.options = options if options is not None else NewtonOptions()
        self.solver = solver
        self.increment = increment
        self.increments = [increment] if increments is None else increments
        if isinstance(self.increments, str) and self.increments not in ("all", "last"):
            raise InputError(f"increments must be 'all', 'last' or a list of increment indices, got "
                             f"{increments!r}")
        self.method = method
        #: ``"ddm"``, ``"adjoint"`` or ``"fd"``: the name of ``method``
        self.gradient_mode = {DDM: "ddm", Adjoint: "adjoint", FiniteDifferences: "fd"}[type(method)]
        self.failure = failure
        self.failure_value = None if failure_value is None else float(failure_value)
        self.validate = validate
        self.label = label
        if response_key is None:  # a public response is named by what it computes
            response_key = (("response", response.name) if hasattr(response, "of")
                            else ("signorini.optimize", next(_UID)))
        self.key = response_key
        self.records: list[Evaluation] = []
        self.warnings: list[str] = []
        self._seen_logs: set = set()
        self._cache: dict[bytes, Evaluation] = {}
        self._grads: dict[bytes, np.ndarray] = {}  # fd mode: gradients by point
        self._fns: dict[int, tuple] = {}  # id(model) -> (model, fn)
        self._solutions: dict[bytes, object] = {}  # the last and the best solution
        self._offset = 0
        self.history = Path(history) if history is not None else None
        if self.history is not None:
            if append and self.history.exists():
                self._offset = len(read_history(self.history))
            else:
                write_header(self.history, self.names)

    # ------------------------------------------------------------ public API
    def fun(self, x) -> float:
        """F(x) (one solve at a new point, none at a point already evaluated)."""
        return self.evaluate(x).F

    def jac(self, x) -> np.ndarray:
        """DF/Dx: the gradient of the evaluation at x (DDM or adjoint; ``"fd"``: central
        differences)."""
        x = self.point(x)
        ev = self.evaluate(x)
        if self.gradient_mode != "fd" or not ev.ok:
            return ev.grad.copy() if ev.grad is not None else np.zeros(len(self.names))
        k = x.tobytes()
        if k not in self._grads:
            self._grads[k] = self._fd_gradient(x, ev)
        return self._grads[k].copy()

    def value_and_grad(self, x):
        """(F, DF/Dx) at x, sharing one solve (``scipy.optimize.minimize(..., jac=True)``)."""
        return self.fun(x), self.jac(x)

    __call__ = fun

    def params(self, x) -> dict:
        """The parameter dict of the design point x."""
        return {**self.problem.params, **dict(zip(self.names, (float(v) for v in self.point(x))))}

    def evaluate(self, x) -> Evaluation:
        """The (cached) evaluation at x: the value, and the gradient with a
        :class:`~signorini.DDM` or :class:`~signorini.Adjoint` method (with
        :class:`~signorini.FiniteDifferences`, :meth:`jac` adds the differences)."""
        x = self.point(x)
        k = x.tobytes()
        ev = self._cache.get(k)
        if ev is None:
            kind = "value+gradient" if self.gradient_mode != "fd" else "value"
            ev = self._solve(x, with_grad=self.gradient_mode != "fd", kind=kind)
        return ev

    def lookup(self, x, rtol: float = 1e-13) -> Evaluation | None:
        """The evaluation at x (bit-identical, else the nearest one within ``rtol``
        relative distance); None if x was not evaluated."""
        x = self.point(x)
        ev = self._cache.get(x.tobytes())
        if ev is not None:
            return ev
        best, dist = None, math.inf
        for e in self._cache.values():
            d = float(np.linalg.norm(e.x - x))
            if d < dist:
                best, dist = e, d
        if best is not None and dist <= rtol * max(float(np.linalg.norm(x)), 1.0):
            return best
        return None

    @property
    def best(self) -> Evaluation | None:
        """The successful evaluation of the lowest F among the design points (the
        perturbed points of finite differences left out); None before the first."""
        good = [r for r in self.records if r.ok and r.kind != "fd"]
        return min(good, key=lambda r: r.F) if good else None

    def solution(self, x=None):
        """The :class:`~signorini.algorithms.solution.Solution` at x (default: the best point).
        The last and the best solutions are kept; another point is solved again
        (with sensitivities in ``"ddm"`` mode; recorded as kind ``"final"``)."""
        if x is None:
            b = self.best
            if b is None:
                raise InputError("no successful evaluation yet")
            x = b.x
        x = self.point(x)
        sol = self._solutions.get(x.tobytes())
        if sol is None:
            self._solve(x, with_grad=self.gradient_mode != "fd", kind="final", keep=True)
            sol = self._solutions.get(x.tobytes())
            if sol is None:
                rec = self.records[-1]
                raise rec.error if rec.error is not None else InputError(rec.reason)
        return sol

    def write_csv(self, path) -> Path:
        """Write every evaluation of this objective (see :func:`read_history`)."""
        path = Path(path)
        write_header(path, self.names)
        append_rows(path, self.names, self.records)
        return path


def _projected(g, x, bounds):
    """The gradient with the components that push against an active bound removed."""
    if bounds is None or g is None:
        return g
    g = np.array(g, dtype=float)
    for i, (lo, hi) in enumerate(bounds):
        if lo is not None and x[i] <= lo and g[i] > 0:
            g[i] = 0.0
        if hi is not None and x[i] >= hi and g[i] < 0:
            g[i] = 0.0
    return g


def minimize(objective: Objective, x0, method: str = "BFGS", *, bounds=None, constraints=(),
             gtol: float = 1e-6, maxiter: int = 100, callback: Callable | None = None,
             options: dict | None = None):
    """Minimise an :class:`Objective` with :func:`scipy.optimize.minimize`.

    Args:
        objective: the :class:`Objective` (its ``fun`` and ``jac`` share one solve per point).
        x0: the start design; it must solve (else its error is raised).
        method: ``"BFGS"``, ``"L-BFGS-B"`` or ``"SLSQP"``.
        bounds: sequence of (low, high) per parameter (None for no bound);
            L-BFGS-B and SLSQP only.
        constraints: SLSQP constraints (passed through).
        gtol: BFGS: max |grad F_i| at convergence; L-BFGS-B: the same on the
            projected gradient; SLSQP: its ``ftol`` (precision goal on F).
        maxiter: iteration limit.
        callback: ``callback(record)`` after every iteration, with the
            :attr:`iterations_log` entry (dict).
        options: further SciPy options (override the above).

    Returns:
        SciPy's ``OptimizeResult`` (``x``, ``fun``, ``jac``, ``nit``, ``nfev``,
        ``njev``, ``success``, ``message``) with ``iterations_log`` (one dict per
        iteration, 0 = start: ``iteration, F, grad_norm, grad_inf, x, evaluations,
        solves, failed, time``), ``evaluations`` (the records of this call),
        ``n_solves``, ``n_failed``, ``time`` [s] and ``names``.
    """
    import scipy.optimize as so  # lazy: heavy, and only a minimisation needs it

    bounds = _checked_bounds(objective, method, bounds, constraints)
    t_start = time.perf_counter()
    n0 = len(objective.records)
    x0 = _start(objective, x0, bounds)
    history = _IterationLog(objective, bounds, n0, t_start, callback)
    history.entry(x0)
    opts = {"maxiter": int(maxiter), ("ftol" if method == "SLSQP" else "gtol"): float(gtol)}
    opts.update(options or {})
    kw = {"bounds": bounds} if bounds is not None else {}
    if method == "SLSQP" and constraints:
        kw["constraints"] = constraints
    res = so.minimize(objective.fun, x0, jac=objective.jac, method=method, callback=history,
                      options=opts, **kw)
    final = objective.lookup(res.x)
    if final is None or not final.ok:  # never hand back a failed point
        good = [r for r in objective.records[n0:] if r.ok and r.kind != "fd"]
        best = min(good, key=lambda r: r.F)
        res.x, res.fun = best.x.copy(), best.F
        res.message = f"{res.message} (the returned point failed; the best good point is returned)"
        res.success = False
        final = best
    res.jac = objective.jac(final.x)
    recs = objective.records[n0:]
    res.iterations_log = history.rows
    res.evaluations = recs
    res.n_solves = len(recs)
    res.n_failed = sum(not r.ok for r in recs)
    res.time = time.perf_counter() - t_start
    res.names = list(objective.names)
    res.method = method
    return res


def _checked_bounds(objective, method, bounds, constraints):
    """The bounds as (low or None, high or None) pairs, after checking that the
    method takes them (and the constraints)."""
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if bounds is not None and method == "BFGS":
        raise InputError("BFGS takes no bounds: use method='L-BFGS-B' or 'SLSQP' (or leave the "
                         "design unbounded and let the failure handling reject invalid points)")
    if constraints and method != "SLSQP":
        raise InputError("constraints need method='SLSQP'")
    if bounds is not None:
        bounds = [(None if lo is None or not np.isfinite(lo) else float(lo),
                   None if hi is None or not np.isfinite(hi) else float(hi)) for lo, hi in bounds]
        if len(bounds) != len(objective.names):
            raise InputError(f"bounds has {len(bounds)} entries, expected {len(objective.names)}")
    return bounds


def _start(objective, x0, bounds) -> np.ndarray:
    """The start design (clipped into the bounds), which must solve: else its error."""
    x0 = objective.point(x0)
    if bounds is not None:
        lo = np.array([-np.inf if b[0] is None else b[0] for b in bounds])
        hi = np.array([np.inf if b[1] is None else b[1] for b in bounds])
        x0 = np.clip(x0, lo, hi) + 0.0
    try:
        ev0 = objective.evaluate(x0)
        err = None if ev0.ok else (ev0.error or InputError(ev0.reason))
    except (ConvergenceError, InputError) as e:
        err = e
    if err is not None:
        where = dict(zip(objective.names, x0.tolist()))
        if isinstance(err, ConvergenceError):
            raise ConvergenceError(f"the optimisation cannot start: the solve at the start design "
                                   f"{where} failed: {err}", partial=err.partial) from err
        raise InputError(f"the optimisation cannot start: the start design {where} is invalid: "
                         f"{err}") from err
    return x0


class _IterationLog:
    """SciPy's per-iteration callback: one row per iteration (0 = the start)."""

    def __init__(self, objective, bounds, n0: int, t_start: float, callback):
        self.objective, self.bounds, self.n0, self.t_start = objective, bounds, n0, t_start
        self.callback = callback
        self.rows: list[dict] = []

    def entry(self, x) -> dict:
        objective = self.objective
        ev = objective.lookup(x)
        if ev is None or (objective.gradient_mode == "fd" and ev.kind == "fd"):
            ev = objective.evaluate(x)
        gp = _projected(objective.jac(ev.x), ev.x, self.bounds)
        recs = objective.records[self.n0:]
        row = {"iteration": len(self.rows), "F": ev.F, "grad_norm": float(np.linalg.norm(gp)),
               "grad_inf": float(np.max(np.abs(gp))), "x": ev.x.tolist(),
               "evaluations": len(recs), "solves": len(recs),
               "failed": sum(not r.ok for r in recs), "time": time.perf_counter() - self.t_start}
        self.rows.append(row)
        return row

    def __call__(self, xk, *args):
        row = self.entry(xk)
        log.info("%s iteration %d: F = %.10g, |grad| = %.4g, %d solves", self.objective.label,
                 row["iteration"], row["F"], row["grad_norm"], row["solves"])
        if self.callback is not None:
            self.callback(row)
