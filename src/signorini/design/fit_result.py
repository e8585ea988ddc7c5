"""The measured curves (:class:`Curve`) and the result of :func:`signorini.design.fit.fit`
with its statistics: Gauss-Newton
standard errors and correlations of the fitted parameters (docs/fitting.md),

    s^2 = r^T r / (m - n),    C = s^2 (J^T J)^-1,    SE_i = sqrt(C_ii),
    rho_ij = C_ij / (SE_i SE_j),

and the warnings that say when they are not to be trusted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..responses import Response

__all__ = ["Curve", "FitResult", "statistics"]

#: a measured time within this of an increment's load factor is that increment
TIME_TOL = 1e-9

#: above this |correlation| of two parameters the fit warns
MAX_CORRELATION = 0.99
#: above this condition number of J^T J (columns scaled to unit norm) the fit warns;
#: above SINGULAR it takes J^T J as singular (no covariance)
MAX_CONDITION = 1e10
SINGULAR = 1e14


# ---------------------------------------------------------------------- curves
def _numbers(x, what: str) -> np.ndarray:
    """x as a 1-D float array of finite numbers, else an InputError naming ``what``."""
    try:
        a = np.asarray(x)
    except (TypeError, ValueError) as e:
        raise InputError(f"{what} must be a list of numbers: {e}") from None
    if a.dtype.kind not in "iuf":
        bad = next((v for v in a.ravel() if not isinstance(v, (int, float, np.number))
                    or isinstance(v, bool)), a.ravel()[0] if a.size else None)
        bad = bad.item() if isinstance(bad, np.generic) else bad
        raise InputError(f"{what} must be numbers, got {bad!r} ({a.dtype} values)")
    if a.ndim > 1:
        raise InputError(f"{what} must be a flat list of numbers, got shape {a.shape}")
    a = a.astype(float).ravel()
    if not np.all(np.isfinite(a)):
        raise InputError(f"{what} must be finite numbers, got {float(a[~np.isfinite(a)][0])}")
    return a


@dataclass(frozen=True, eq=False)
class Curve:
    """A measured curve: a response at load factors (pseudo-times) with its values,
    or against another response (a force against a measured displacement).

    Attributes:
        response: the :class:`~signorini.responses.Response` measured.
        times: (k,) load factors, increasing, in (0, 1]; with ``abscissa``, the
            measured values of that response instead (increasing).
        values: (k,) the measured values.
        weights: (k,) weights w >= 0 of the squared differences (default 1;
            1 / variance of the measurement for statistical standard errors,
            or any relative weights: the fit estimates the common scale).
        abscissa: None (``times`` are load factors) or a Response whose value along
            the path increases: the model's curve is then ``response`` against it,
            interpolated linearly between increments at the measured abscissae
            (the interpolation differentiated exactly, abscissae included).
    """

    response: Response
    times: np.ndarray
    values: np.ndarray
    weights: np.ndarray | None = None
    abscissa: Response | None = None

    def __post_init__(self):
        if not isinstance(self.response, Response):
            raise InputError("a curve's response must be a signorini.responses Response (e.g. "
                             f"sg.responses.contact_force(component=2)), got {self.response!r}")
        name = f"curve {self.response.name}"
        t = _numbers(self.times, f"{name}: times")
        v = _numbers(self.values, f"{name}: values")
        w = np.ones_like(t) if self.weights is None else _numbers(self.weights, f"{name}: weights")
        if not (t.size == v.size == w.size) or t.size == 0:
            raise InputError(f"{name}: times, values (and weights) need one entry per measured "
                             f"point, got {t.size}, {v.size}, {w.size}")
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise InputError(f"{name}: the times must increase; time {float(t[k + 1])!r} (entry {k + 1}) "
                             f"follows {float(t[k])!r}")
        if self.abscissa is not None and not isinstance(self.abscissa, Response):
            raise InputError(f"{name}: the abscissa must be a signorini.responses Response (e.g. "
                             f"sg.responses.displacement(...)), got {self.abscissa!r}")
        if self.abscissa is None and (t[0] <= 0 or t[-1] > 1 + TIME_TOL):
            raise InputError(f"{name}: the times are load factors of the path, in (0, 1]; got "
                             f"{float(t[0])!r} .. {float(t[-1])!r}")
        if np.any(w < 0):
            raise InputError(f"{name}: weights must be >= 0")
        for k, a in (("times", t), ("values", v), ("weights", w)):
            object.__setattr__(self, k, a)

    @property
    def name(self) -> str:
        return self.response.name

    @classmethod
    def of(cls, spec) -> Curve:
        """A curve from a :class:`Curve` or a tuple (response, times, values[, weights])."""
        if isinstance(spec, Curve):
            return spec
        if isinstance(spec, (tuple, list)) and len(spec) in (3, 4, 5):
            return cls(*spec)
        raise InputError("a curve is a signorini.Curve or a tuple (response, times, values[, weights"
                         "[, abscissa]]), "
                         f"got {type(spec).__name__}")


def _curves(curves) -> list[Curve]:
    if isinstance(curves, Curve) or (isinstance(curves, tuple) and curves
                                     and isinstance(curves[0], Response)):
        curves = [curves]
    out = [Curve.of(c) for c in curves]
    if not out:
        raise InputError("fit needs at least one measured curve")
    return out


# ---------------------------------------------------------------------- result
@dataclass(eq=False)
class FitResult:
    """The result of :func:`fit`.

    Attributes:
        names: the parameters, in order.
        x: (n,) the fitted values; ``values``: the same as a dict.
        start: the start values (dict).
        stderr: name -> standard error sqrt(C_ii) (nan when J^T J is singular or m = n).
        covariance: (n, n) C = s^2 (J^T J)^-1.
        correlation: (n, n) C_ij / (SE_i SE_j) (from (J^T J)^-1, also when s = 0).
        sigma: s = sqrt(r^T r / (m - n)), the residuals' scale (1 when the weights are
            1 / variance and the model fits).
        misfit: F = r^T r at the optimum.
        residuals: (m,) the weighted residuals at the optimum; ``jacobian`` (m, n) their J.
        n_data: m, the measured points of positive weight.
        condition: the condition number of J^T J with columns scaled to unit norm.
        fitted: per curve, the model's values at its times at the optimum.
        history: one dict per iteration (0 = the start): ``iteration, F, grad_norm, x,
            solves, time``.
        n_solves, n_failed: solves of the fit, and how many failed (penalised).
        success, message: the optimiser's verdict.
        method, gradient: the optimiser and how it got the misfit's gradient (``"ddm"``
            or ``"adjoint"``).
        warnings: the fit's warnings (ill-conditioning, bounds) and the solves'.
        solution: the :class:`~signorini.Solution` at the optimum.
        evaluations: every solve's :class:`~signorini.design.history.Evaluation`.
    """

    names: list
    x: np.ndarray
    values: dict
    start: dict
    stderr: dict
    covariance: np.ndarray
    correlation: np.ndarray
    sigma: float
    misfit: float
    residuals: np.ndarray
    jacobian: np.ndarray
    n_data: int
    condition: float
    fitted: list
    curves: list
    bounds: list
    history: list
    n_solves: int
    n_failed: int
    success: bool
    message: str
    method: str
    gradient: str = "ddm"
    time: float = 0.0
    warnings: list = field(default_factory=list)
    solution: object = field(default=None, repr=False)
    evaluations: list = field(default_factory=list, repr=False)
    label: str = "fit"

    @property
    def iterations(self) -> int:
        return len(self.history) - 1

    def table(self) -> str:
        """The fitted values, standard errors and correlations, for a person."""
        w = max(9, *(len(n) for n in self.names))
        lines = [(f"fit of {', '.join(self.names)} to {len(self.curves)} curve(s), {self.n_data} data "
                  f"({self.method}{', adjoint gradient' if self.gradient == 'adjoint' else ''}): "
                  f"{'converged' if self.success else 'NOT converged'} in "
                  f"{self.iterations} iterations, {self.n_solves} solves ({self.message})"),
                 f"  {'parameter':<{w}} {'start':>13} {'fitted':>15} {'std error':>11} {'rel.':>9}"]
        for i, n in enumerate(self.names):
            se = self.stderr[n]
            rel = se / abs(self.x[i]) if self.x[i] != 0 else math.inf
            lines.append(f"  {n:<{w}} {self.start[n]:>13.6g} {self.x[i]:>15.9g} {se:>11.4g} "
                         f"{100 * rel:>8.3g}%")
        lines.append(f"misfit r^T r = {self.misfit:.6g}; sigma = {self.sigma:.4g} per weighted "
                     f"datum ({self.n_data - len(self.names)} degrees of freedom); "
                     f"cond(J^T J) = {self.condition:.3g}")
        lines.append("correlation:")
        lines.append("  " + " " * w + "".join(f" {n[:8]:>8}" for n in self.names))
        for i, n in enumerate(self.names):
            lines.append(f"  {n:<{w}}" + "".join(f" {v:>8.4f}" for v in self.correlation[i]))
        lines += [f"warning: {m}" for m in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def statistics(r: np.ndarray, J: np.ndarray, n_data: int, names: list) -> tuple:
    """(covariance, correlation, condition, sigma, warning messages) of the weighted
    residuals r (m,) and their Jacobian J (m, n) at the optimum."""
    n = len(names)
    dof = n_data - n
    F = float(r @ r)
    sigma = math.sqrt(F / dof) if dof > 0 else math.nan
    col = np.linalg.norm(J, axis=0)
    nan = np.full((n, n), math.nan)
    messages = []
    dead = [names[i] for i in range(n) if not col[i] > 0]
    if dead:
        messages.append(f"fit: the residuals do not depend on {dead}: these parameters cannot be "
                        "identified from these curves (J^T J singular; no standard errors)")
        return nan, nan, math.inf, sigma, messages
    s = np.linalg.svd(J / col, compute_uv=False)
    condition = float((s[0] / s[-1]) ** 2) if s[-1] > 0 else math.inf
    if condition > SINGULAR:
        messages.append(f"fit: J^T J is singular (condition number {condition:.3g}): the "
                        f"parameters {names} are not all identifiable from these curves; no "
                        "standard errors")
        return nan, nan, condition, sigma, messages
    inv = np.linalg.inv((J / col).T @ (J / col)) / np.outer(col, col)  # (J^T J)^-1
    d = np.sqrt(np.diag(inv))
    corr = inv / np.outer(d, d)
    cov = sigma ** 2 * inv if dof > 0 else nan
    if dof <= 0:
        messages.append(f"fit: as many data as parameters ({n_data}): no degrees of freedom are "
                        "left to estimate the standard errors")
    if condition > MAX_CONDITION:
        messages.append(f"fit: J^T J is ill-conditioned (condition number {condition:.3g}, "
                        "columns scaled): the standard errors are large and unreliable")
    for i in range(n):
        for j in range(i + 1, n):
            if abs(corr[i, j]) > MAX_CORRELATION:
                messages.append(f"fit: {names[i]} and {names[j]} are correlated (rho = "
                                f"{corr[i, j]:.4f}): these curves identify a combination of the "
                                "two rather than each; add a curve that separates them or fix one")
    return cov, corr, condition, sigma, messages
