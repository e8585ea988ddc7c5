"""Forging preform optimisation (paper §5.3, Figs. 8-9).

For each friction coefficient mu, find the Bezier preform phi0..phi4 of
:mod:`signorini.problems.forging` whose upset billet comes closest to the
cylinder r = r_opt = h0: minimise F = sum_k (r_k - h0)^2 over the lateral
nodes (eq. 24) with BFGS (or L-BFGS-B / SLSQP) and exact DDM gradients, one
forging solve with five sensitivities per design point
(:class:`signorini.optimize.Objective`). The start is the cylinder
phi_k = 0.7 h0.

Invalid shapes: with L-BFGS-B and SLSQP the bounds phi_k >= ``phi_min``
keep r0(Z) >= phi_min > 0 (the Bernstein polynomials are non-negative and sum
to 1). BFGS is unbounded: a trial preform with r0 <= 0 somewhere
(:func:`~signorini.problems.forging._check_shape`), an inverted element or a
Newton failure is answered by the objective's penalty (a large finite value
and a gradient back towards the last good point), so the line search backs off.

:func:`run` writes, per mu, into ``out/mu_<mu>/``: ``history.csv`` (every
evaluation, appended as it is done), ``summary.json``, ``shape.png`` (optimal
preform and its deformed shape), ``convergence.png`` (F and |grad F| against
iteration), ``forging.pvd`` (+ one VTU per increment of the optimal process);
and into ``out/``: ``shapes.png`` (all mu: optimal preform radii r0(Z) and
final profiles) and ``summary.json`` (all mu).
"""

from __future__ import annotations

import functools
import logging
import math
import time
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..design.optimize import METHODS, Objective, minimize, read_history
from . import forging as fg

log = logging.getLogger("signorini")

#: start design: the cylinder of radius 0.7 h0
START = 0.7 * fg.H0
#: lower bound of phi_k for the bounded methods (keeps r0 >= PHI_MIN)
PHI_MIN = 0.05 * fg.H0


@functools.lru_cache(maxsize=4)
def base_problem(mesh: tuple[int, int] = (10, 20)):
    """The forging problem on ``mesh`` (cached: every mu and design point reuses
    its mesh and so its compiled model)."""
    return fg.forging_problem(mesh=tuple(mesh))


def validate(params: dict) -> None:
    """The preform radius must stay positive on [0, h0] (as forging_problem checks)."""
    fg._check_shape([params[k] for k in fg.SHAPE])


def objective_for(mu: float, *, mesh=(10, 20), steps: int = 50, rtol: float = 1e-11,
                  solver="auto", gradient: str = "ddm", history=None, append: bool = False,
                  label: str | None = None) -> Objective:
    """The :class:`~signorini.optimize.Objective` F(phi0..phi4) at friction ``mu``."""
    pb = base_problem(tuple(mesh)).with_params(mu=float(mu))
    lat = fg.lateral_nodes(pb)
    return Objective(pb, list(fg.SHAPE), lambda model: fg.objective(model, lat), steps=steps,
                     options=fg.options(rtol), solver=solver, gradient_mode=gradient,
                     validate=validate, response_key=("forging-opt-F", tuple(lat.tolist())),
                     history=history, append=append, label=label or f"opt mu={mu:g}")


def _mu_dir(out: Path, mu: float) -> Path:
    return out / f"mu_{mu:g}"


def _start(history: Path, resume: bool) -> tuple[np.ndarray, dict]:
    """The start design: the best good point of an existing history (resume) or the cylinder."""
    x0 = np.full(len(fg.SHAPE), START)
    if not resume:
        return x0, {}
    if not history.exists():
        return x0, {"resumed": False, "note": "no history.csv to resume from: started at the cylinder"}
    recs = read_history(history, list(fg.SHAPE))
    good = [r for r in recs if r.status == "ok" and r.kind != "fd" and math.isfinite(r.F)]
    if not good:
        return x0, {"resumed": False, "previous_evaluations": len(recs),
                    "note": "history.csv has no successful evaluation: started at the cylinder"}
    best = min(good, key=lambda r: r.F)
    return best.x.copy(), {"resumed": True, "previous_evaluations": len(recs),
                           "previous_solve_time_s": float(sum(r.time for r in recs)),
                           "restart_from_eval": best.index, "restart_F": best.F}


def _plot_convergence(path, rows, mu):
    from ..post import plots  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    it = [r["iteration"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.8), dpi=120)
    a.semilogy(it, [max(r["F"], 1e-300) for r in rows], "o-", ms=3)
    a.set_xlabel("iteration")
    a.set_ylabel("F")
    b.semilogy(it, [max(r["grad_norm"], 1e-300) for r in rows], "o-", ms=3, color="C1")
    b.set_xlabel("iteration")
    b.set_ylabel("|grad F|")
    for ax in (a, b):
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"Forging preform optimisation, mu = {mu:g}")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _plot_shapes(path, runs: list[dict]):
    from ..post import plots  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    Z = np.linspace(0.0, fg.H0, 201)
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 4.6), dpi=120, sharey=False)
    a.plot(np.full_like(Z, START), Z, "k:", lw=1, label="cylinder (start)")
    for k, s in enumerate(runs):
        if "phi_opt" not in s:
            continue
        phi = [s["phi_opt"][n] for n in fg.SHAPE]
        a.plot(fg.radius(phi, Z), Z, "-", color=f"C{k}", label=f"mu = {s['mu']:g}")
        r, z = np.asarray(s["final_profile"]["r"]), np.asarray(s["final_profile"]["z"])
        b.plot(r, z, "o-", ms=3, color=f"C{k}", label=f"mu = {s['mu']:g}")
    b.axvline(fg.H0, color="k", lw=0.8, ls="--", label="r_opt = h0")
    a.set_xlabel("r0(Z)")
    a.set_ylabel("Z")
    a.set_title("optimal preforms")
    b.set_xlabel("r")
    b.set_ylabel("z")
    b.set_title("final lateral profiles")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def optimise_mu(out: Path, mu: float, *, mesh=(10, 20), steps: int = 50, method: str = "BFGS",
                gtol: float = 1e-6, maxiter: int = 50, gradient: str = "ddm", resume: bool = False,
                solver="auto", rtol: float = 1e-11, phi_min: float = PHI_MIN) -> dict:
    """One mu: optimise, write ``out/mu_<mu>/`` and return its summary (see :func:`run`)."""
    from ..post import files as io, plots
    from ..app.runner import prepare_output

    t0 = time.perf_counter()
    d = prepare_output(_mu_dir(Path(out), mu))
    hist = d / "history.csv"
    x0, resumed = _start(hist, resume)
    obj = objective_for(mu, mesh=mesh, steps=steps, rtol=rtol, solver=solver, gradient=gradient,
                        history=hist, append=resume and hist.exists())
    bounds = None if method == "BFGS" else [(phi_min, None)] * len(fg.SHAPE)
    summary = {"mu": float(mu), "method": method, "gradient": gradient,
               "mesh": {"n_r": mesh[0], "n_z": mesh[1]}, "steps": steps, "gtol": gtol,
               "maxiter": maxiter, "start": dict(zip(fg.SHAPE, map(float, x0))),
               "bounds": None if bounds is None else f"phi_k >= {phi_min:g}", **resumed}
    try:
        res = minimize(obj, x0, method, bounds=bounds, gtol=gtol, maxiter=maxiter)
    except Exception as e:  # the start design cannot be solved: report, go on with the next mu
        summary.update({"status": "failed", "reason": str(e), "solves": obj.n_solves,
                        "time_wall_s": time.perf_counter() - t0, "warnings": list(obj.warnings)})
        io.write_json(d / "summary.json", summary)
        log.error("mu = %g: the optimisation could not start: %s", mu, e)
        return summary

    sol = obj.solution(res.x)  # kept from the evaluation (no new solve in DDM mode)
    pb = sol.model.problem
    lat = fg.lateral_nodes(pb)
    X, x = sol.reference(), sol.current()
    r = x[lat, 0]
    Z = np.linspace(0.0, fg.H0, 201)
    r0 = fg.radius(res.x, Z)
    rows = res.iterations_log
    F0 = rows[0]["F"]
    io.write_pvd(sol, d / "forging.pvd")
    alpha = np.asarray(sol.increments[-1].state[2])[..., 9].mean(axis=1)
    plots.meshes(d / "shape.png", [
        {"x": X, "cells": sol.model.conn, "title": "optimal preform"},
        {"x": x, "cells": sol.model.conn, "title": "after 50 % upsetting", "color": alpha,
         "color_label": "equivalent plastic strain"}],
        title=f"Optimal preform, mu = {mu:g}, F = {res.fun:.3g} (cylinder: {F0:.3g})")
    _plot_convergence(d / "convergence.png", rows, mu)
    warns = list(obj.warnings)
    if not res.success:
        warns.append(f"the optimiser stopped with: {res.message}")
    recs = res.evaluations
    summary.update({
        "status": "converged" if res.success else "stopped",
        "message": str(res.message),
        "phi_opt": dict(zip(fg.SHAPE, map(float, res.x))),
        "F_start": float(F0),
        "F_opt": float(res.fun),
        "reduction": float(F0 / res.fun) if res.fun > 0 else math.inf,
        "grad_opt": dict(zip(fg.SHAPE, map(float, res.jac))),
        "max_rel_deviation_from_r_opt": float(np.max(np.abs(r - fg.H0)) / fg.H0),
        "r0_range": {"min": float(r0.min()), "max": float(r0.max()), "max_minus_min": float(np.ptp(r0))},
        "final_profile": {"r": r.tolist(), "z": x[lat, 1].tolist()},
        "iterations": int(res.nit),
        "function_evaluations": int(res.nfev),
        "gradient_evaluations": int(getattr(res, "njev", 0)),
        "solves": res.n_solves,
        "failed_evaluations": res.n_failed,
        "failed_reasons": sorted({r_.reason.splitlines()[0][:200] for r_ in recs if not r_.ok}),
        "newton_iterations_total": int(sum(r_.newton_iterations for r_ in recs)),
        "solve_time_s": float(sum(r_.time for r_ in recs)),
        "iterations_log": [{k: v for k, v in row.items()} for row in rows],
        "time_wall_s": time.perf_counter() - t0,
        "warnings": warns,
    })
    io.write_json(d / "summary.json", summary)
    return summary


def run(out, mus=(0.1, 0.2, 0.3), *, mesh: tuple[int, int] = (10, 20), steps: int = 50,
        method: str = "BFGS", gtol: float = 1e-6, maxiter: int = 50, gradient: str = "ddm",
        resume: bool = False, solver="auto", rtol: float = 1e-11, phi_min: float = PHI_MIN,
        mapper=None, extra_summary: dict | None = None) -> dict:
    """Optimise the forging preform for each mu and write the results (module docstring).

    Args:
        out: output directory.
        mus: friction coefficients, one optimisation each.
        mesh: (n_r, n_z) cells; steps: load increments of every solve.
        method: ``"BFGS"`` (unbounded; failures are penalised), ``"L-BFGS-B"`` or
            ``"SLSQP"`` (bounds phi_k >= ``phi_min``).
        gtol: gradient tolerance (BFGS, L-BFGS-B; SLSQP: ftol); maxiter: iteration limit.
        gradient: ``"ddm"``, ``"adjoint"`` (one backward pass per design point) or ``"fd"``
            (central differences, 10 extra solves per gradient).
        resume: continue from ``out/mu_<mu>/history.csv`` (restart at its best point;
            the file is appended to).
        solver, rtol: linear solver and Newton tolerance of the forging solves.
        mapper: ``mapper(out, mus, kwargs) -> [summary per mu]`` running
            :func:`optimise_mu` for every mu (default: one after another here;
            :func:`signorini.sweep.optimise_mus_parallel` passes Dask tasks).
        extra_summary: entries added to the collected summary.

    Returns:
        The collected summary (also ``out/summary.json``): ``runs`` (one per mu:
        ``phi_opt``, ``F_start``, ``F_opt``, ``max_rel_deviation_from_r_opt``,
        ``r0_range``, ``iterations``, ``function_evaluations``, ``solves``,
        ``time_wall_s``, ``warnings``, ...).
    """
    from ..post import files as io
    from ..app.runner import prepare_output

    t0 = time.perf_counter()
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if gradient not in ("ddm", "adjoint", "fd"):
        raise InputError(f"gradient must be 'ddm', 'adjoint' or 'fd', got {gradient!r}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"steps must be a whole number >= 1, got {steps!r}")
    try:
        mus = [float(m) for m in mus]
    except (TypeError, ValueError):
        raise InputError(f"mus must be a list of friction coefficients, got {mus!r}") from None
    if not mus or any(not (np.isfinite(m) and m >= 0) for m in mus):
        raise InputError(f"mus must be non-negative finite numbers, got {mus}")
    out = prepare_output(out)
    base_problem(tuple(mesh))  # bad mesh input fails here, before any optimisation
    kwargs = dict(mesh=tuple(mesh), steps=steps, method=method, gtol=gtol, maxiter=maxiter,
                  gradient=gradient, resume=resume, solver=solver, rtol=rtol, phi_min=phi_min)
    if mapper is None:
        runs = [optimise_mu(out, mu, **kwargs) for mu in mus]
    else:
        runs = mapper(out, mus, kwargs)
    _plot_shapes(out / "shapes.png", runs)
    summary = {
        "status": "converged" if all(r["status"] == "converged" for r in runs) else
                  ("failed" if all(r["status"] == "failed" for r in runs) else "partial"),
        "settings": {"mus": mus, "mesh": list(mesh), "steps": steps, "method": method, "gtol": gtol,
                     "maxiter": maxiter, "gradient": gradient, "resume": resume, "r_opt": fg.H0,
                     "start": START},
        "runs": [{k: v for k, v in r.items() if k != "iterations_log"} for r in runs],
        "time_wall_s": time.perf_counter() - t0,
        "warnings": sorted({w for r in runs for w in r.get("warnings", [])}),
        **(extra_summary or {}),
    }
    io.write_json(out / "summary.json", summary)
    return summary
