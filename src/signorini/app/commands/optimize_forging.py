"""``signorini optimize-forging``: the preform optimisation of paper Figs. 8-9,
one BFGS run per friction coefficient (one Dask task each).

:func:`run` writes, per mu, into ``out/mu_<mu>/``: ``history.csv`` (every
evaluation, appended as it is done), ``summary.json``, ``shape.png`` (optimal
preform and its deformed shape), ``convergence.png`` (F and |grad F| against
iteration), ``forging.pvd`` (+ one VTU per increment of the optimal process);
and into ``out/``: ``shapes.png`` (all mu: optimal preform radii r0(Z) and
final profiles) and ``summary.json`` (all mu). :func:`optimize_mus_parallel`
does the same with one Dask task per mu."""

from __future__ import annotations

import logging
import math
import os
import time
from pathlib import Path

import numpy as np

from ... import timing
from ...design.optimize import METHODS, minimize, read_history
from ...errors import InputError
from ...post import files as io, plots
from ...problems import forging
from ...problems.forging_opt import PHI_MIN, START, base_problem, objective_for
from ..options import (
    Formatter, dask_options, finish, forging_mesh_options, newton_options, positive_float,
    positive_int, solver_options)
from ..runner import note_run, prepare_output, write_summary_json
from ..sweep import map_tasks, single_threaded_env

log = logging.getLogger("signorini")

NAME = "optimize-forging"


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    o = sub.add_parser(
        "optimize-forging", formatter_class=Formatter,
        help="find the forging preform whose free surface ends as a cylinder (paper Figs. 8-9)",
        description="For each friction coefficient, minimise the forging objective F = sum "
                    "(r_k - h0)^2 over phi0..phi4 from the cylinder phi = 0.7 h0, with gradients "
                    "by DDM (one solve per design point) or by central differences (for "
                    "comparison). Writes per mu (mu_<value>/): history.csv of every evaluation, "
                    "summary.json, shape.png, convergence.png, forging.pvd of the optimal "
                    "process; and shapes.png and summary.json for all mu in --out. A design where "
                    "Newton fails or the shape is invalid is penalised, never fatal.")
    o.add_argument("--out", required=True, metavar="DIR", help="output directory")
    o.add_argument("--mu", default="0.1,0.2,0.3", metavar="MU[,MU...]",
                   help="friction coefficients, one optimisation each")
    forging_mesh_options(o)
    o.add_argument("--method", default="BFGS", choices=["BFGS", "L-BFGS-B", "SLSQP"],
                   help="scipy.optimize method (L-BFGS-B, SLSQP: bounds phi >= 0.05)")
    o.add_argument("--gtol", type=positive_float, default=1e-6, help="gradient tolerance")
    o.add_argument("--maxiter", type=positive_int, default=50, help="iterations per mu")
    o.add_argument("--gradient", default="ddm", choices=["ddm", "adjoint", "fd"],
                   help="DDM (exact, one solve with 5 sensitivities per design), adjoint (exact, "
                        "one solve and one backward pass per design) or central differences "
                        "(11 solves)")
    o.add_argument("--resume", action="store_true",
                   help="continue from the best point of each mu's history.csv in --out")
    dask_options(o)
    # --maxiter is BFGS's: the forging solves keep Newton's default iterations
    newton_options(o, 1e-11, max_iter=False)
    solver_options(o)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    try:
        mus = [float(m) for m in args.mu.split(",") if m.strip()]
    except ValueError:
        raise InputError(f"--mu expects comma-separated numbers, e.g. 0.1,0.2; got {args.mu!r}") from None
    if not mus or any(not 0 <= m < float("inf") for m in mus):
        raise InputError(f"--mu needs friction coefficients >= 0, got {args.mu!r}")
    kwargs = dict(mesh=forging.parse_mesh(args.mesh), steps=args.steps, method=args.method,
                  gtol=args.gtol, maxiter=args.maxiter, gradient=args.gradient,
                  resume=args.resume, solver=args.solver, rtol=args.rtol,
                  force_size=args.force_size)
    if len(mus) > 1 and not args.sequential:  # one Dask task per mu

        s = optimize_mus_parallel(args.out, mus, scheduler=args.scheduler,
                                        n_workers=args.workers, **kwargs)
    else:
        s = run(args.out, mus, **kwargs)
    print(f"{'mu':>5} {'F(cylinder)':>12} {'F*':>10} {'max|r-h0|/h0':>13} {'r0 range':>9} "
          f"{'iters':>6} {'solves':>6} {'time [s]':>8}")
    for r in s.get("runs", []):
        if r.get("status") == "failed" or "F_opt" not in r:
            print(f"{r.get('mu', float('nan')):5g} failed: {r.get('message', r.get('reason', ''))}")
            continue
        print(f"{r['mu']:5g} {r['F_start']:12.4e} {r['F_opt']:10.3e} "
              f"{r['max_rel_deviation_from_r_opt']:13.2e} {r['r0_range']['max_minus_min']:9.4f} "
              f"{r['iterations']:6d} {r['solves']:6d} {r['time_wall_s']:8.1f}")
    return finish(args, s)


def _mu_dir(out: Path, mu: float) -> Path:
    return out / f"mu_{mu:g}"


def _start(history: Path, resume: bool) -> tuple[np.ndarray, dict]:
    """The start design: the best good point of an existing history (resume) or the cylinder."""
    x0 = np.full(len(forging.SHAPE), START)
    if not resume:
        return x0, {}
    if not history.exists():
        return x0, {"resumed": False, "note": "no history.csv to resume from: started at the cylinder"}
    recs = read_history(history, list(forging.SHAPE))
    good = [r for r in recs if r.status == "ok" and r.kind != "fd" and math.isfinite(r.F)]
    if not good:
        return x0, {"resumed": False, "previous_evaluations": len(recs),
                    "note": "history.csv has no successful evaluation: started at the cylinder"}
    best = min(good, key=lambda r: r.F)
    return best.x.copy(), {"resumed": True, "previous_evaluations": len(recs),
                           "previous_solve_time_s": float(sum(r.time for r in recs)),
                           "restart_from_eval": best.index, "restart_F": best.F}


def _plot_convergence(path, rows, mu):

    it = [r["iteration"] for r in rows]
    fig, (a, b) = plots.subplots(1, 2, figsize=(9, 3.8), dpi=120)
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
    plots.save(fig, path)


def _plot_shapes(path, runs: list[dict]):

    Z = np.linspace(0.0, forging.H0, 201)
    fig, (a, b) = plots.subplots(1, 2, figsize=(9, 4.6), dpi=120, sharey=False)
    a.plot(np.full_like(Z, START), Z, "k:", lw=1, label="cylinder (start)")
    for k, s in enumerate(runs):
        if "phi_opt" not in s:
            continue
        phi = [s["phi_opt"][n] for n in forging.SHAPE]
        a.plot(forging.radius(phi, Z), Z, "-", color=f"C{k}", label=f"mu = {s['mu']:g}")
        r, z = np.asarray(s["final_profile"]["r"]), np.asarray(s["final_profile"]["z"])
        b.plot(r, z, "o-", ms=3, color=f"C{k}", label=f"mu = {s['mu']:g}")
    b.axvline(forging.H0, color="k", lw=0.8, ls="--", label="r_opt = h0")
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
    plots.save(fig, path)


def optimize_mu(out: Path, mu: float, *, mesh=(10, 20), steps: int = 50, method: str = "BFGS",
                gtol: float = 1e-6, maxiter: int = 50, gradient: str = "ddm", resume: bool = False,
                solver="auto", rtol: float = 1e-11, phi_min: float = PHI_MIN) -> dict:
    """One mu: optimise, write ``out/mu_<mu>/`` and return its summary (see :func:`run`)."""

    t0 = time.perf_counter()
    d = _mu_dir(Path(out), mu)
    d.mkdir(parents=True, exist_ok=True)  # out is checked (prepare_output) by the caller
    hist = d / "history.csv"
    x0, resumed = _start(hist, resume)
    obj = objective_for(mu, mesh=mesh, steps=steps, rtol=rtol, solver=solver, gradient=gradient,
                        history=hist, append=resume and hist.exists())
    bounds = None if method == "BFGS" else [(phi_min, None)] * len(forging.SHAPE)
    summary = {"mu": float(mu), "method": method, "gradient": gradient,
               "mesh": {"n_r": mesh[0], "n_z": mesh[1]}, "steps": steps, "gtol": gtol,
               "maxiter": maxiter, "start": dict(zip(forging.SHAPE, map(float, x0))),
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
    summary.update(_optimum(d, sol, res, obj, mu, t0))
    io.write_json(d / "summary.json", summary)
    return summary


def _optimum(d: Path, sol, res, obj, mu: float, t0: float) -> dict:
    """The optimum's files (forging.pvd, shape.png, convergence.png) and its summary entries."""
    pb = sol.model.problem
    lat = forging.lateral_nodes(pb)
    X, x = sol.reference(), sol.current()
    r = x[lat, 0]
    Z = np.linspace(0.0, forging.H0, 201)
    r0 = forging.radius(res.x, Z)
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
    return {
        "status": "converged" if res.success else "stopped",
        "message": str(res.message),
        "phi_opt": dict(zip(forging.SHAPE, map(float, res.x))),
        "F_start": float(F0),
        "F_opt": float(res.fun),
        "reduction": float(F0 / res.fun) if res.fun > 0 else math.inf,
        "grad_opt": dict(zip(forging.SHAPE, map(float, res.jac))),
        "max_rel_deviation_from_r_opt": float(np.max(np.abs(r - forging.H0)) / forging.H0),
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
    }


@timing.recorded
def run(out, mus=(0.1, 0.2, 0.3), *, mesh: tuple[int, int] = (10, 20), steps: int = 50,
        method: str = "BFGS", gtol: float = 1e-6, maxiter: int = 50, gradient: str = "ddm",
        resume: bool = False, solver="auto", rtol: float = 1e-11, phi_min: float = PHI_MIN,
        mapper=None, extra_summary: dict | None = None, force_size: bool = False) -> dict:
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
            :func:`optimize_mu` for every mu (default: one after another here;
            :func:`signorini.app.commands.optimize_forging.optimize_mus_parallel` passes Dask tasks).
        extra_summary: entries added to the collected summary.
        force_size: run even if the mesh is estimated not to fit in memory.

    Returns:
        The collected summary (also ``out/summary.json``): ``runs`` (one per mu:
        ``phi_opt``, ``F_start``, ``F_opt``, ``max_rel_deviation_from_r_opt``,
        ``r0_range``, ``iterations``, ``function_evaluations``, ``solves``,
        ``time_wall_s``, ``warnings``, ...).
    """

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
    note_run(out, "every evaluation is recorded in mu_<value>/history.csv: the same command with "
                  "--resume continues from the best point of each")
    forging.check_mesh_size(tuple(mesh), force=force_size, solver=solver, steps=steps,
                            sensitivities=len(forging.SHAPE))
    base_problem(tuple(mesh))  # bad mesh input fails here, before any optimisation
    kwargs = dict(mesh=tuple(mesh), steps=steps, method=method, gtol=gtol, maxiter=maxiter,
                  gradient=gradient, resume=resume, solver=solver, rtol=rtol, phi_min=phi_min)
    timing.mark("solve")  # the optimisations (their solves, sensitivities and history files)
    if mapper is None:
        runs = [optimize_mu(out, mu, **kwargs) for mu in mus]
    else:
        runs = mapper(out, mus, kwargs)
    timing.mark("output")
    _plot_shapes(out / "shapes.png", runs)
    summary = {
        "status": "converged" if all(r["status"] == "converged" for r in runs) else
                  ("failed" if all(r["status"] == "failed" for r in runs) else "partial"),
        "settings": {"mus": mus, "mesh": list(mesh), "steps": steps, "method": method, "gtol": gtol,
                     "maxiter": maxiter, "gradient": gradient, "resume": resume, "r_opt": forging.H0,
                     "start": START},
        "runs": [{k: v for k, v in r.items() if k != "iterations_log"} for r in runs],
        "time_wall_s": time.perf_counter() - t0,
        "warnings": sorted({w for r in runs for w in r.get("warnings", [])}),
        **(extra_summary or {}),
    }
    return write_summary_json(out, summary)


# --------------------------------------------------------------------------- forging optimisation

def _optimize_one(out: str, mu: float, kwargs: dict) -> dict:
    """One task: :func:`optimize_mu` (never raises)."""
    single_threaded_env()

    t0 = time.perf_counter()
    try:
        return optimize_mu(Path(out), mu, **kwargs)
    except Exception as e:  # noqa: BLE001  (one mu failing must not stop the others)
        return {"mu": float(mu), "status": "failed", "reason": f"{type(e).__name__}: {e}",
                "time_wall_s": time.perf_counter() - t0, "warnings": []}


def optimize_mus_parallel(out, mus=(0.1, 0.2, 0.3), *, mesh=(10, 20), steps: int = 50,
                          method: str = "BFGS", gtol: float = 1e-6, maxiter: int = 50,
                          gradient: str = "ddm", resume: bool = False, solver="auto",
                          rtol: float = 1e-11, phi_min=None, scheduler=None, n_workers=None,
                          sequential: bool = False, client=None, force_size: bool = False) -> dict:
    """:func:`run` with one Dask task per mu.

    Same arguments, files and returned summary as ``run`` (plus
    ``"parallel"`` in the summary): each task calls
    :func:`optimize_mu`, which writes only
    ``out/mu_<mu>/`` and returns its summary; ``shapes.png`` and
    ``summary.json`` for all mu are written here. A mu whose task raises is
    recorded as failed. Dask options as in :func:`run_sweep`.
    """

    def mapper(out_, mus_, kwargs):
        return map_tasks(_optimize_one, [(str(out_), mu, kwargs) for mu in mus_],
                         scheduler=scheduler, n_workers=n_workers, sequential=sequential,
                         client=client)

    where = "sequential" if sequential else ("client" if client is not None else
                                             (scheduler or f"local cluster, "
                                              f"{n_workers or os.cpu_count()} workers"))
    return run(out, mus, mesh=mesh, steps=steps, method=method, gtol=gtol, maxiter=maxiter,
               gradient=gradient, resume=resume, solver=solver, rtol=rtol,
               phi_min=PHI_MIN if phi_min is None else phi_min, mapper=mapper,
               extra_summary={"parallel": where}, force_size=force_size)
