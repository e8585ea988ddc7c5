"""How an :class:`~signorini.design.optimize.Objective` evaluates a design point: the
solve, the response and its gradient by the objective's method, the penalty of a
failed point, finite differences of the value, and the record of every evaluation."""

from __future__ import annotations

import contextlib
import logging
import math
import time
import warnings

import numpy as np

from ..model import checks
from ..sensitivity.methods import DDM, Adjoint
from ..errors import ConvergenceError, InputError, SignoriniWarning, SolverError
from .gradient import adjoint_gradient, selected_increments, with_state
from .history import Evaluation, append_rows
from ..sensitivity import nonsmooth
from ..algorithms.stepping import solve

log = logging.getLogger("signorini")


class _OncePerMessage(logging.Filter):
    """Drop log records whose message was already logged during this optimisation."""

    def __init__(self, seen: set):
        super().__init__()
        self.seen = seen

    def filter(self, record):
        msg = record.getMessage()
        if record.levelno < logging.WARNING and not msg.startswith("warning"):
            return True
        if msg in self.seen:
            return False
        self.seen.add(msg)
        return True


def _path_figures(sol) -> dict:
    """Newton iterations (cut attempts included), converged increments, cuts and
    warnings of a solve, converged or partial."""
    return {"its": sum(s.iterations for s in sol.log), "n_inc": len(sol.increments),
            "cuts": sum(not s.converged for s in sol.log), "warns": list(sol.warnings)}


class ObjectiveEvaluation:
    """The evaluation machinery of :class:`~signorini.design.optimize.Objective` (a part of it)."""

    def point(self, x) -> np.ndarray:
        """x as a design point: a float copy of the right length (InputError otherwise),
        without -0.0 (the bytes of x are the key of the evaluation cache)."""
        x = np.array(x, dtype=float).ravel()  # a copy
        if x.size != len(self.names):
            raise InputError(f"the design point has {x.size} value(s), expected {len(self.names)} "
                             f"({self.names})")
        return x + 0.0  # no -0.0: the cache key is the bytes of x

    @property
    def n_solves(self) -> int:
        """Solves done (= evaluations recorded)."""
        return len(self.records)

    @property
    def n_failed(self) -> int:
        """Solves that failed (penalised)."""
        return sum(not r.ok for r in self.records)

    # -------------------------------------------------------------- internals

    def _fn(self, model):
        entry = self._fns.get(id(model))
        if entry is None or entry[0] is not model:
            fn = self.response(model) if self.factory else self.response
            if not callable(fn):
                raise InputError("the response factory must return a callable fn(w, params, t)")
            entry = (model, fn)
            self._fns[id(model)] = entry
        return entry[1]

    @contextlib.contextmanager
    def _quiet(self):
        """Each distinct warning of the solves is logged and warned once per objective."""
        flt = _OncePerMessage(self._seen_logs)
        log.addFilter(flt)
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", SignoriniWarning)
                yield
        finally:
            log.removeFilter(flt)
        for w in caught:
            msg = str(w.message)
            if issubclass(w.category, SignoriniWarning) and msg in self.warnings:
                continue
            if issubclass(w.category, SignoriniWarning):
                self.warnings.append(msg)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)

    def _solve(self, x, *, with_grad: bool, kind: str, keep: bool = True) -> Evaluation:
        t0 = time.perf_counter()
        with self._quiet():
            out = self._attempt(x, with_grad)
        return self._record(x, kind, keep, t0, out)

    def _attempt(self, x, with_grad: bool) -> dict:
        """Solve at x (with the gradient of the method if asked): the outcome, a
        failure included, as a dict (status, reason, err, sol, F, g, its, n_inc, cuts, warns)."""
        names = self.names
        out = {"status": "ok", "reason": "", "err": None, "sol": None, "F": math.nan, "g": None,
               "its": 0, "n_inc": 0, "cuts": 0, "warns": []}
        ddm = with_grad and self.gradient_mode == "ddm"
        try:
            pvals = {n: float(v) for n, v in zip(names, x)}
            if not np.all(np.isfinite(x)):
                raise InputError(f"the design point is not finite: {pvals}")
            if self.validate is not None:
                self.validate({**self.problem.params, **pvals})
            pb = self.problem.with_params(**pvals)
            adjoint = with_grad and isinstance(self.method, Adjoint)
            out["sol"] = solve(pb, steps=self.steps, wrt=names if ddm else (),
                               method=self.method if ddm or adjoint else DDM(),
                               options=self.options, solver=self.solver, label=self.label)
        except ConvergenceError as e:
            out.update(status="failed", reason=str(e), err=e)
            if e.partial is not None:
                out.update(_path_figures(e.partial))
        except InputError as e:
            out.update(status="invalid", reason=str(e), err=e)
        sol = out["sol"]
        if sol is not None:
            out.update(_path_figures(sol))
            self._response(sol, with_grad, ddm, out)
        return out

    def _response(self, sol, with_grad: bool, ddm: bool, out: dict) -> None:
        """The response at a converged solve and its gradient (DDM: from the solve;
        adjoint: one backward pass for all names) into ``out``."""
        names = self.names
        fn = with_state(self._fn(sol.model))
        idx = selected_increments(self.increments, len(sol.increments))
        val, dv = 0.0, {n: 0.0 for n in names}
        for i in idx:  # the response summed over the increments (one: the usual case)
            v, d = sol.evaluate(fn, i, ddm, self.key, with_state=True)
            if np.size(v) != 1:
                raise InputError("the response must return a scalar, got an array of shape "
                                 f"{np.shape(v)}")
            val = val + v
            dv = {n: dv[n] + d[n] for n in d} if ddm else dv
        if with_grad and not ddm:  # adjoint: one backward pass for all names
            try:
                dv = adjoint_gradient(sol, self._fn(sol.model), names, increments=idx,
                                      solver=sol.linear_solver or self.solver)[1]
            except SolverError as e:
                out.update(status="failed", reason=f"adjoint: {e}",
                           err=ConvergenceError(str(e), partial=sol))
                dv = {n: math.nan for n in names}
            message = nonsmooth.warning(sol, names)
            if message:
                checks.warn(sol, message)
                out["warns"] = list(sol.warnings)
        F = out["F"] = float(np.asarray(val).reshape(()))
        g = None
        if with_grad:
            g = out["g"] = np.array([float(np.asarray(dv[n]).reshape(())) for n in names])
        if out["status"] == "ok" and (not np.isfinite(F) or (g is not None and not np.all(np.isfinite(g)))):
            reason = f"the response or its gradient is not finite (F = {F})"
            out.update(status="failed", reason=reason, err=ConvergenceError(reason, partial=sol))

    def _record(self, x, kind: str, keep: bool, t0: float, out: dict) -> Evaluation:
        """The evaluation of an attempt (a failed one penalised or raised), kept in the
        records, the cache, the kept solutions, the history file and the log."""
        k = x.tobytes()
        status, reason, err, sol, F, g = (out[n] for n in ("status", "reason", "err", "sol", "F", "g"))
        if status != "ok":
            if self.failure == "raise":
                raise err
            F, g = self._penalty(x, err)
            if kind == "fd":
                g = None  # a perturbed point of a difference quotient has no gradient of its own
        ev = Evaluation(self._offset + len(self.records) + 1, kind, x, float(F),
                        None if g is None else np.asarray(g, dtype=float), status, reason, out["its"],
                        out["n_inc"], out["cuts"], time.perf_counter() - t0, out["warns"], err)
        self.records.append(ev)
        if kind != "final" or k not in self._cache:
            self._cache[k] = ev
        if ev.ok and sol is not None and keep and kind != "fd":
            b = self.best
            keys = {k}
            if b is not None:
                keys.add(b.x.tobytes())
            self._solutions = {kk: s for kk, s in {**self._solutions, k: sol}.items() if kk in keys}
        if self.history is not None:
            append_rows(self.history, self.names, [ev])
        log.info("%s evaluation %d (%s): F = %.10g%s, %d Newton iterations, %.2f s%s", self.label,
                 ev.index, kind, ev.F, "" if ev.grad is None else f", |grad| = {ev.grad_norm:.4g}",
                 out["its"], ev.time, "" if ev.ok else f" [{status}: {reason.splitlines()[0][:200]}]")
        return ev

    def _penalty(self, x, err):
        """(F_fail, gradient) of a failed point (module docstring)."""
        good = [r for r in self.records if r.ok]
        if self.failure_value is not None:
            Ff = self.failure_value
        elif good:
            Fs = np.array([r.F for r in good])
            scale = float(np.abs(Fs).max()) or 1.0
            Ff = float(Fs.max()) + 10.0 * scale
        else:
            raise err  # nothing to compare with: the start point itself cannot be solved
        g = np.zeros(len(self.names))
        if good:
            last = good[-1]
            d = x - last.x
            dd = float(d @ d)
            if dd > 0 and np.isfinite(dd):
                a = float(last.grad @ d) if last.grad is not None else 0.0
                slope = max(6.0 * (Ff - last.F) - a, 2.0 * (Ff - last.F))
                g = slope * d / dd
                if not np.all(np.isfinite(g)):
                    g = np.zeros(len(self.names))
        return Ff, g

    def _fd_gradient(self, x, ev) -> np.ndarray:
        """Central differences of the value (one-sided where a perturbed solve fails)."""
        g = np.zeros(len(self.names))
        for i in range(len(self.names)):
            h = self.method.step_for(x[i])
            xp, xm = x.copy(), x.copy()
            xp[i] += h
            xm[i] -= h
            ep, em = (self._cache.get(y.tobytes()) or self._solve(y, with_grad=False, kind="fd")
                      for y in (xp, xm))
            if ep.ok and em.ok:
                g[i] = (ep.F - em.F) / (xp[i] - xm[i])
            elif ep.ok:
                g[i] = (ep.F - ev.F) / (xp[i] - x[i])
            elif em.ok:
                g[i] = (ev.F - em.F) / (x[i] - xm[i])
        return g
