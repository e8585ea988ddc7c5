"""Running a problem file: the solve, the responses and their sensitivities, and
the files (summary.json, contact tables, VTU, a .pvd series)."""


from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from ... import timing
from ..._jax import jnp
from ...algorithms.stepping import solve
from ...contact.friction3d import disc
from ...design.gradient import gradient
from ...errors import InputError, SolverError
from ...linsolve import check_size
from ...linsolve.memory import history_extra
from ...model.problem import Problem
from ...post import files as io
from .. import validity
from ..runner import (
    keep_for_interrupt,
    prepare_output,
    series_as_converged,
    use_solver,
    write_series,
    write_summary_json,
)
from .schema import Response, RunConfig, load

__all__ = ["run"]


def _finite(x: float):
    """A float for JSON (None for NaN: no residual evaluated)."""
    return float(x) if x == x else None


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if o is None or isinstance(o, (str, int, float, bool)):
        return o
    return str(o)


def _response_values(sol, problem: Problem, r: Response) -> dict:
    """Value and DDM sensitivities of one response at the last increment."""
    names = list(sol.names)
    if r.type not in ("max_pressure", "normal_force", "displacement", "reaction") or \
            problem.mesh.nodes.shape[1] == 3 and r.type != "normal_force":
        val, d = r.public().of(sol, -1)
        return {"value": val, "sensitivities": {n: float(d[n]) for n in names}}
    if r.type == "max_pressure":
        c = sol.contact(-1, r.surface)
        j = int(np.argmax(c["p_N"]))
        return {"value": float(c["p_N"][j]), "node": int(c["node"][j]),
                "x_ref": [float(v) for v in c["x_ref"][j]],
                "sensitivities": {n: float(c[f"dp_N_d{n}"][j]) for n in names}}
    if r.type == "normal_force":

        m, k = sol.model, r.surface

        def force(w, p, t):
            f = m.contact_fields(w, p, t, k)
            return jnp.sum(f["p_N"] * f["area"])

        val, d = sol.response(force, -1, key=("problemfile.normal_force", k))
        return {"value": float(val), "sensitivities": {n: float(d[n]) for n in names}}
    nodes = problem.mesh.node_set(r.node_set)
    if r.type == "displacement":
        val = float(sol.displacement()[nodes, r.component].mean())
        sens = {n: float(sol.displacement_sensitivity(n)[nodes, r.component].mean()) for n in names}
    else:
        # force of the supports on the body (Solution.reactions)
        val = float(sol.reactions()[nodes, r.component].sum())
        sens = {n: float(sol.reaction_sensitivity(n)[nodes, r.component].sum()) for n in names}
    return {"value": val, "sensitivities": sens}


def _contact_csv(sol, k: int, path: Path):

    c = sol.contact(-1, k)
    dim = c["x_ref"].shape[1]
    cols = {"node": c["node"]}
    cols.update({f"{a}_ref": c["x_ref"][:, i] for i, a in enumerate("xyz"[:dim])})
    cols.update({a: c["x"][:, i] for i, a in enumerate("xyz"[:dim])})
    cols.update({"p_N": c["p_N"], "p_T": c["p_T"], "gap": c["gap"]})
    for n in sol.names:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
    if "status" in c:
        for n in sol.names:
            cols[f"dp_T_d{n}"] = c[f"dp_T_d{n}"]
        cols["status"] = c["status"]
        cols["slip"] = c["slip"]
    flat = {}
    for key, v in cols.items():  # 3-D friction: tangential vectors, one column per component
        v = np.asarray(v)
        if v.ndim == 2:
            flat.update({f"{key}_{i}": v[:, i] for i in range(v.shape[1])})
        else:
            flat[key] = v
    io.write_csv(path, flat)
    return c


def _write_results(sol, problem: Problem, cfg: RunConfig, out: Path, summary: dict) -> None:
    """Files of the last converged increment (and the series); fills ``summary``."""
    files = summary["outputs"]
    if not sol.increments:
        return
    surfaces = []
    for k, s in enumerate(sol.model.surfaces):
        name = "contact.csv" if k == 0 else f"contact_{k}.csv"
        if cfg.csv:
            c = _contact_csv(sol, k, out / name)
            files.append(name)
        else:
            c = sol.contact(-1, k)
        surfaces.append({"edges": s.contact.edges, "method": type(s.contact.method).__name__,
                         "nodes": int(len(s.nodes)), "closed_nodes": int(np.sum(c["p_N"] > 0)),
                         "max_p_N": float(np.max(c["p_N"])) + 0.0 if len(c["p_N"]) else 0.0})
    summary["contact"] = surfaces
    summary["responses"] = {r.name: {"type": r.type, **_response_values(sol, problem, r)}
                            for r in cfg.responses}
    for r in cfg.responses:
        if r.adjoint and sol.status == "converged":  # one backward pass for every parameter
            g = gradient(problem, r.public(), list(problem.params), solution=sol, options=cfg.options)
            summary["responses"][r.name]["adjoint"] = {n: float(v) for n, v in g.grad.items()}
    if cfg.vtu:
        io.write_vtu(sol, out / f"{cfg.stem}.vtu")
        files.append(f"{cfg.stem}.vtu")
    if cfg.pvd and (cfg.steps > 1 or len(sol.increments) > 1):
        write_series(sol, out / f"{cfg.stem}.pvd")
        files.append(f"{cfg.stem}.pvd")
        files.extend(f"{cfg.stem}_{i + 1:04d}.vtu" for i in range(len(sol.increments)))


def check_file_size(problem, cfg, *, force: bool = False, solver="auto") -> float:
    """The size guard of a loaded file's run (:func:`signorini.linsolve.check_size`):
    its unknowns in its dimension, and the history a material with history keeps
    (2^dim Gauss points a cell at most) for every increment and, as its sensitivity,
    once per parameter. Returns the estimate in bytes."""
    dim = int(problem.mesh.nodes.shape[1])
    sets = problem.mesh.face_sets if dim == 3 else problem.mesh.edge_sets
    # in 3-D a Coulomb law is the Coulomb disc, three multipliers a node (as the model makes it)
    n_contact = sum(len(np.unique(sets[c.edges]))
                    * (disc(c.method) if dim == 3 else c.method).n_multipliers
                    for c in problem.contact)
    n_state = int(getattr(problem.material, "n_state", 0))
    n_dof = dim * problem.mesh.n_nodes + n_contact
    history = history_extra(problem.mesh.n_cells, n_dof, history_per_cell=8.0 * 2**dim * n_state,
                            steps=cfg.steps, sensitivities=len(cfg.sensitivities))
    return check_size(n_dof, force=force, what=str(cfg.path), solver=solver, dim=dim, extra=history,
                      hint="a coarser mesh" + (" or fewer steps" if n_state else ""))


@timing.recorded
def run(path, out, *, solver="auto", progress=None, force_size: bool = False,
        rtol: float | None = None, max_iter: int | None = None) -> dict:
    """Load a problem file, solve it with DDM sensitivities and write the results.

    Args:
        path: the TOML problem file (schema: module docstring).
        out: output directory (created if needed).
        solver: linear solver name for :func:`signorini.solve`.
        progress: reserved for progress reporting (accepted, not used yet).
        force_size: run even if the estimated memory exceeds what is available.
        rtol, max_iter: Newton's tolerance and iterations per increment in place of
            the file's ``[solve]`` values (None: the file's).

    Returns:
        The summary (also written to ``out/summary.json``).

    Raises:
        InputError: an invalid file (nothing is written).
        ConvergenceError: the solve failed; the converged increments' results
            and ``summary.json`` with ``"status": "failed"`` and the reason are
            written first.
    """


    t_start = time.perf_counter()
    problem, cfg = load(path, force_size=force_size, solver=solver)
    given = {k: v for k, v in (("rtol", rtol), ("max_iter", max_iter)) if v is not None}
    if given:
        cfg = dataclasses.replace(cfg, options=dataclasses.replace(cfg.options, **given))
    out = prepare_output(out)
    check_file_size(problem, cfg, force=force_size, solver=solver)
    summary = {
        "file": str(cfg.path), "title": cfg.title, "status": "running",
        "params": dict(problem.params),
        "mesh": {"nodes": problem.mesh.n_nodes, "cells": problem.mesh.n_cells},
        "steps": cfg.steps, "sensitivities": list(cfg.sensitivities),
        "options": {"rtol": cfg.options.rtol, "atol": cfg.options.atol,
                    "max_iter": cfg.options.max_iter, "max_cuts": cfg.options.max_cuts,
                    "predictor": cfg.options.predictor, "start": cfg.options.start,
                    "reuse_factor": cfg.options.reuse_factor},
    }

    solver = use_solver(solver)
    summary["solver"] = solver.name
    t0 = time.perf_counter()
    error = None
    timing.mark("solve")
    keep_for_interrupt(stem=cfg.stem, extra=dict(summary, status="interrupted"))
    try:
        with series_as_converged(out / f"{cfg.stem}.pvd", on=cfg.pvd and cfg.steps > 1):
            sol = solve(problem, steps=cfg.steps, wrt=list(cfg.sensitivities),
                        options=cfg.options, solver=solver, label="base")
    except KeyboardInterrupt as e:
        keep_for_interrupt(solution=getattr(e, "partial", None))
        raise
    except SolverError as e:  # ConvergenceError keeps the converged increments in .partial
        error, sol = e, getattr(e, "partial", None)
    except InputError as e:
        if type(e) is InputError:  # found when the model is built (e.g. surfaces that share nodes)
            raise InputError(f"{cfg.path}: {e}") from None
        raise
    summary["time_solve_s"] = time.perf_counter() - t0
    timing.mark("output")
    summary["status"] = "failed" if error is not None else "converged"
    if error is not None:
        summary["reason"] = str(error)
    if sol is not None:
        if error is None:
            validity.surface_ends(sol)
        summary["mesh"]["dofs"] = int(sol.model.n_dof)
        summary["increments"] = len(sol.increments)
        summary["load_factors"] = [float(inc.t) for inc in sol.increments]
        summary["newton_iterations"] = list(sol.newton_iterations)
        summary["newton_log"] = [  # every attempted increment, including cut and failed ones
            {"t": float(s.t), "dt": float(s.dt), "iterations": s.iterations,
             "converged": bool(s.converged), "relative_residual": _finite(s.relative_residual),
             "factorizations": s.factorizations, "kept_factor_krylov_iterations": s.krylov_iterations,
             **({"refactorizations": s.refactorizations} if s.refactorizations else {}),
             **({"stop": s.stop} if s.stop else {}), **({"reason": s.reason} if s.reason else {})}
            for s in getattr(sol, "log", [])]
        summary["factorizations"] = [inc.newton.factorizations for inc in sol.increments]
        summary["kept_factor_krylov_iterations"] = [inc.newton.krylov_iterations
                                                    for inc in sol.increments]
        if getattr(sol, "coarse_start", None) is not None:
            summary["algebraic_start"] = sol.coarse_start
        summary["warnings"] = _jsonable(list(cfg.warnings) + list(getattr(sol, "warnings", [])))
    else:
        summary.update(increments=0, load_factors=[], newton_iterations=[], newton_log=[],
                       warnings=list(cfg.warnings))
    summary["contact"], summary["responses"], summary["outputs"] = [], {}, []
    if sol is not None:
        try:
            _write_results(sol, problem, cfg, out, summary)
        except Exception as e:  # noqa: BLE001  (keep the solver's error; record this one)
            if error is None:
                raise
            summary["output_error"] = f"{type(e).__name__}: {e}"
    summary["outputs"].insert(0, "summary.json")
    summary["time_wall_s"] = time.perf_counter() - t_start
    summary = write_summary_json(out, _jsonable(summary))
    if error is not None:
        raise error
    return summary
