"""What every command-line run shares: an output directory checked before any
work, a ``summary.json`` with the run's status, reason and warnings, and the
converged increments written even when a later one fails.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from pathlib import Path

import numpy as np

from .. import _programs, progress, timing
from ..contact.area import nodal_normals
from ..post import files as io
from ..post import helper
from ..sensitivity import nonsmooth
from ..errors import InputError
from ..algorithms.stepping import last_started, solve
from ..design.finite_differences import finite_difference
from ..design.gradient import adjoint_gradient
from ..errors import ConvergenceError
from ..linsolve import get_solver

log = logging.getLogger("signorini")

#: what this process's run has so far, for a report if it is interrupted
#: (:func:`report_interrupt`): its output directory, the stem and summary
#: entries of its base solve, and the base solution (or its converged part)
_RUN: dict = {}
#: whether a run's base solve writes its .pvd series as its increments converge
#: (:func:`stream_series`)
_STREAM = {"on": False}


def prepare_output(out) -> Path:
    """Create (if needed) and check the output directory before any solve.

    Raises:
        InputError: ``out`` is empty, names an existing file, or is not writable.
    """
    if out is None or str(out).strip() == "":
        raise InputError("the output directory is empty; give a directory name (--out DIR)")
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise InputError(f"--out {str(out)!r} is an existing file, not a directory; choose another "
                         "name or remove the file")
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".signorini-write-test-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise InputError(f"cannot write into the output directory {str(out)!r} ({e.strerror or e}); "
                         "choose a writable location") from None
    _RUN.clear()
    _RUN["out"] = path
    return path


def write_summary(out: Path, summary: dict, solution) -> dict:
    """``summary.json`` of a converged run, with the solve's final list of warnings."""
    summary["warnings"] = list(solution.warnings)
    return write_summary_json(out, summary)


def write_summary_json(out: Path, summary: dict) -> dict:
    """summary.json, with the run's time split (:mod:`signorini.timing`) if one is
    kept, and what was wrong with the caches of compiled programs (if anything).
    The files the run handed to the output helper are written first
    (:func:`signorini.post.helper.finish`)."""
    written = helper.finish()
    if _programs.WARNINGS:
        said = list(summary.get("warnings", []))
        summary["warnings"] = said + [w for w in _programs.WARNINGS if w not in said]
    t = timing.current()
    if t is not None:
        summary["timings"] = {**t.split(), "output_helper": written}
    io.write_json(out / "summary.json", summary)
    return summary


def solver_entries(solver, solution) -> dict:
    """The linear solver of a summary and whether its tangents were factorised as
    symmetric (also under the key's 0.1 spelling, kept for one release); for an
    iterative solver the Krylov iterations of every solve of the process (coarse
    levels, Newton corrections, sensitivities, in their order)."""
    out = {"solver": solver.name, "symmetric_factorization": solution.symmetric,
           "symmetric_factorisation": solution.symmetric}
    its = getattr(solver, "iterations", None)  # an iterative solver's, solve by solve
    if its is not None:
        out["krylov_iterations"] = [int(k) for k in its]
    mpi = getattr(solver, "mpi_report", None)  # the PETSc solvers: ranks, parallel work
    if callable(mpi):
        out["mpi"] = mpi()
    return out


def newton_log(solution) -> dict:
    """The Newton entries of a summary, per converged increment: iterations,
    residual norms, the relative residual reached and why Newton stopped
    ("rtol", or "round-off floor": the residual stopped falling above rtol while
    the corrections no longer changed the solution; NewtonOptions); and the time
    of its tangents' assembly (element and contact kernels included), their
    factorisation and the solves (an iterative solver builds its multigrid
    hierarchy in a tangent's first solve: counted there)."""
    incs = solution.increments
    extra = {}
    if getattr(solution, "coarse_start", None) is not None:
        # the algebraic coarse start of the first increment (algorithms.coarse_algebraic)
        extra["algebraic_start"] = solution.coarse_start
    return {**extra, "newton_iterations": solution.newton_iterations,
            "newton_residuals": [inc.newton.residuals for inc in incs],
            "newton_relative_residuals": [float(inc.newton.relative_residual) for inc in incs],
            "newton_stops": [inc.newton.stop for inc in incs],
            # the tangents factorised (Newton's and the sensitivities'), the Krylov
            # iterations on a kept factorisation, and why each factorisation was made
            # (linsolve.kept: "first", "cap", "budget", "small", "never", "direct")
            "factorizations": [inc.newton.factorizations for inc in incs],
            "kept_factor_krylov_iterations": [inc.newton.krylov_iterations for inc in incs],
            "refactorizations": [inc.newton.refactorizations for inc in incs],
            # where Newton's time went, summed over the increments (the fine mesh's)
            "newton_time_s": {k: round(sum(getattr(inc.newton, "time_" + k, 0.0) for inc in incs), 3)
                              for k in ("assembly", "factorization", "solve")}}


def summary_header(status: str, solution=None, reason: str = "") -> dict:
    """The keys every ``summary.json`` starts with."""
    head = {"status": status}
    if reason:
        head["reason"] = reason
    head["warnings"] = list(getattr(solution, "warnings", []) or [])
    if solution is not None and solution.increments:
        head["load_factor_reached"] = float(solution.increments[-1].t)
        head["converged_increments"] = len(solution.increments)
        # increments with points on a switch of a non-smooth law (docs/theory.md §11)
        head["derivative_switches"] = nonsmooth.summary(solution)
        if any(s.patches is not None for s in solution.model.surfaces):
            # contact pairs: increments whose closed slave nodes changed master partners
            head["partner_changes"] = nonsmooth.partner_changes(solution)
        bodies = io.bodies(solution)
        if len(bodies) > 1:
            head["bodies"] = body_summary(solution, bodies)
    return head


def body_summary(solution, bodies) -> dict:
    """Per body of a mesh of several: its nodes and cells, the resultant of its
    supports' reactions and its largest displacement, at the last increment."""
    u = solution.displacement()
    r = solution.reactions()
    return {name: {"nodes": int(nodes.size), "cells": int(cells.size),
                   "support_force": r[nodes].sum(axis=0).tolist(),
                   "max_displacement": float(np.linalg.norm(u[nodes], axis=1).max())}
            for name, nodes, cells in bodies}


def write_partial(out: Path, solution, stem: str, reason: str, extra: dict | None = None) -> dict:
    """After a failed solve: write what converged (VTU series, last contact table)
    and ``summary.json`` with ``"status": "failed"`` and the reason."""
    summary = summary_header("failed", solution, reason)
    written = []
    if solution is not None and solution.increments:
        try:
            written.append(str(io.write_vtu(solution, out / f"{stem}_partial.vtu").name))
            c = solution.contact() if solution.model.surfaces else None
            if c is not None:
                cols = {"x_ref": c["x_ref"][:, 0], "x": c["x"][:, 0], "p_N": c["p_N"],
                        "p_T": c["p_T"] + 0.0}
                if "status" in c:
                    cols["status"] = c["status"]
                written.append(str(io.write_csv(out / "contact_partial.csv", cols).name))
        except Exception as e:  # noqa: BLE001 - the failure report must still be written
            log.warning("warning: could not write the converged increments: %s", e)
    summary["files"] = written
    summary.update(extra or {})
    return write_summary_json(out, summary)


def use_solver(solver="auto"):
    """Resolve a solver name once per run (``auto``: the fastest installed) and say
    which one it is in the log."""
    lin = get_solver(solver)
    log.info("linear solver: %s%s", lin.describe(), " (auto)" if solver == "auto" else "")
    return lin


def solve_or_report(out: Path, stem: str, problem, extra: dict, series: bool = True,
                    **solve_kwargs):
    """``signorini.solve(problem, label="base", **solve_kwargs)``; on a Newton failure
    write the converged increments (``<stem>.pvd`` series, last contact table) and a
    ``failed`` summary.json with ``extra`` before re-raising. ``series``: whether
    the command writes the ``<stem>.pvd`` series of the solution (then written as
    the increments converge where :func:`stream_series` asks for it)."""
    solver = solve_kwargs.get("solver", "auto")
    extra = {**extra, "solver": getattr(solver, "name", solver)}
    keep_for_interrupt(stem=stem, extra=extra)
    timing.mark("solve")
    try:
        with series_as_converged(out / f"{stem}.pvd", on=series):
            solution = solve(problem, label="base", **solve_kwargs)
    except KeyboardInterrupt as e:
        # the load path's converged increments (also when the signal came as it returned)
        keep_for_interrupt(solution=getattr(e, "partial", None) or last_started("base"))
        raise
    except ConvergenceError as e:
        timing.mark("output")
        if e.partial is not None and e.partial.increments:
            write_series(e.partial, out / f"{stem}.pvd")
        write_partial(out, e.partial, stem, str(e), extra)
        raise
    keep_for_interrupt(solution=solution)
    return solution


def stream_series(on: bool = True) -> None:
    """From now on (``on``) a run's base solve writes its ``.pvd`` series as its
    increments converge (:func:`series_as_converged`): a run under ``mpiexec`` on
    several ranks, whose launcher kills an interrupted rank one second after its
    SIGTERM, too short to compute the series' fields then (docs/parallel.md)."""
    _STREAM["on"] = bool(on)


@contextlib.contextmanager
def series_as_converged(path: Path, label: str = "base", on: bool = True):
    """While in the block, if :func:`stream_series` asked for it and ``on``: each
    increment the solve ``label`` converges is written at once into the series
    ``path`` (its VTU files and the ``.pvd`` of the increments so far), so that an
    interrupt has nothing left to write but summary.json; :func:`write_series`
    (the end of the run, a failure, an interrupt's report) writes only the rest. A
    write that fails is logged and leaves the rest of the series to the end."""
    if not (on and _STREAM["on"]):
        yield
        return
    series = _RUN["series"] = io.Series(path)

    def converged(name, n, t):
        sol = last_started(label)
        if name != label or sol is None or len(sol.increments) != n or "series_error" in _RUN:
            return
        try:
            # rank 0 alone writes: its element kernels on every cell (the other ranks
            # are not in this call: model.sharing)
            with timing.phase("output"), sol.model.alone():
                series.add(sol)
        except Exception as e:  # noqa: BLE001 - the solve goes on; the end writes the series
            _RUN["series_error"] = str(e)
            log.warning("warning: the series %s is written at the end of the run: increment %d "
                        "could not be written as it converged (%s)", path.name, n, e)

    with progress.on_increment(converged):
        yield


def write_series(solution, path: Path) -> Path:
    """The ``.pvd`` series of ``solution`` (:func:`signorini.post.files.write_pvd`):
    only what its base solve has not written as it converged
    (:func:`series_as_converged`)."""
    series = _RUN.get("series")
    if series is not None and series.path == Path(path):
        return series.complete(solution)
    return io.write_pvd(solution, path)


SIGNALS = {2: "SIGINT", 15: "SIGTERM"}


def keep_for_interrupt(**entries) -> None:
    """What an interrupt report (:func:`report_interrupt`) of this run writes:
    ``stem`` (of the ``.pvd`` series), ``extra`` (summary entries), ``solution``
    (the base solution or its converged part)."""
    _RUN.update(entries)


def note_run(out: Path, kept: str) -> None:
    """A run without a base solve of its own (a sweep) keeps its work as ``kept``
    says, and writes no summary of its own when interrupted."""
    _RUN.clear()
    _RUN.update(out=Path(out), note=kept)


def report_interrupt(signum: int) -> str:
    """After SIGINT or SIGTERM: keep what this run has (``summary.json`` with status
    ``interrupted``, first, then the converged increments of its base solve as a
    ``.pvd`` series) and return the line that says so. A second signal while
    this is written ends the process at once (the summary is already there)."""
    name = SIGNALS.get(signum, f"signal {signum}")
    t = timing.current()
    during = (t.now() if t is not None else None) or "setup"
    out = _RUN.get("out")
    if out is None:
        return f"interrupted by {name} during {during}, before any output: nothing kept"
    if "note" in _RUN:
        return f"interrupted by {name} during {during}: {_RUN['note']} ({out}/)"
    sol = _RUN.get("solution")
    summary = summary_header("interrupted", sol, f"interrupted by {name} during {during}")
    summary.update(_RUN.get("extra", {}))
    summary["files"] = []
    write_summary_json(out, summary)
    kept = "nothing converged"
    if sol is not None and sol.increments:
        stem = _RUN.get("stem", "result")
        try:
            summary["files"] = [write_series(sol, out / f"{stem}.pvd").name]
            write_summary_json(out, summary)
            n = len(sol.increments)
            kept = f"{n} converged increment{'s' * (n != 1)} ({stem}.pvd)"
        except Exception as e:  # noqa: BLE001 - the summary is written; say what failed
            kept = f"the converged increments could not be written ({e})"
    return (f"interrupted by {name} during {during}: kept {kept} and summary.json (status "
            f"'interrupted') in {out}/")


def adjoint_report(out: Path, sol, response, names, description: str, solver, ddm: dict) -> dict:
    """Adjoint gradient of ``response`` on the converged ``sol`` (one backward pass)
    for ``names`` and every nodal coordinate, next to the DDM gradient ``ddm``;
    writes ``shape_gradient.csv`` and attaches the nodal gradient to ``sol`` (so the
    last VTU written holds it as ``adjoint_shape_gradient``). Returns the
    ``summary.json`` entry."""
    t0 = time.perf_counter()
    G, grad, timing = adjoint_gradient(sol, response, list(names) + ["nodes"], increments="last",
                                       solver=solver)
    t = time.perf_counter() - t0
    g = grad.pop("nodes")
    sol.shape_gradient = g
    X = sol.reference()
    axes = "XYZ"[: X.shape[1]]
    io.write_csv(out / "shape_gradient.csv", {"node": np.arange(len(X)),
                                              **{a: X[:, k] for k, a in enumerate(axes)},
                                              **{f"dG_d{a}": g[:, k] for k, a in enumerate(axes)}})
    rel = {n: abs(grad[n] - ddm[n]) / abs(ddm[n]) if ddm[n] else abs(grad[n]) for n in names}
    log.info("adjoint gradient of %s: one backward pass in %.2f s; max |adjoint - DDM| / |DDM| = %.2g",
             description, t, max(rel.values()))
    return {"response": description, "value": G, "adjoint": grad, "ddm": ddm,
            "adjoint_vs_ddm_rel_diff": rel, "time_backward_s": t,
            "backward": {k: v for k, v in timing.items()},
            "shape_gradient": "shape_gradient.csv; VTU point data adjoint_shape_gradient (last increment)"}


def fd_table(path: Path, pb, F_fn, key, names, dF: dict, fd_check: bool, **fd_kwargs):
    """(FD derivatives, relative differences) of the response ``F_fn`` (cached under
    ``key``) by central differences of the whole process for ``names`` (empty
    without ``fd_check``), next to its DDM derivatives ``dF``; writes them as the
    CSV ``path`` (parameter, DDM[, FD, rel_diff])."""
    fd, rel = {}, {}
    if fd_check:
        q = lambda s: float(s.response(F_fn, with_sensitivities=False, key=key)[0])  # noqa: E731
        for n in names:
            fd[n] = float(finite_difference(pb, n, q, **fd_kwargs))
            rel[n] = abs(dF[n] - fd[n]) / abs(dF[n]) if dF[n] else abs(fd[n])
    rows = {"parameter": list(names), "DDM": [dF[n] for n in names]}
    if fd_check:
        rows.update({"FD": [fd[n] for n in names], "rel_diff": [rel[n] for n in names]})
    io.write_csv(path, rows)
    return fd, rel


def max_rel_diff(ddm: np.ndarray, fd: np.ndarray) -> float:
    """max |DDM - FD| / max |DDM| (the comparison every command reports)."""
    scale = float(np.max(np.abs(ddm))) if np.size(ddm) else 0.0
    return float(np.max(np.abs(ddm - fd)) / scale) if scale > 0 else float(np.max(np.abs(fd), initial=0.0))


class Timer:
    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self) -> float:
        return time.perf_counter() - self.t0


def master_tractions(sol, surface: int = 0) -> dict:
    """The master surface of a contact pair at the last increment: its ``nodes``,
    their reference positions ``X``, areas ``A``, reference outward normals ``N``
    and the contact force on each node over its area ``t`` (n, dim): minus the
    node's contact rows of the residual (what the pair adds to it: R = f_int -
    f_ext + r_c). The rows come from one program per model, kept between
    processes (a run of a model of the same structure loads it)."""
    m = sol.model
    mesh = m.problem.mesh
    master = (mesh.face_set if m.dim == 3 else mesh.edge_set)(m.surfaces[surface].contact.obstacle.master)
    nodes = np.unique(master)
    X = np.asarray(sol.reference())
    A = np.asarray(m.kinematics.contact_areas(X, master, nodes))
    N = np.asarray(nodal_normals(X, master, nodes))
    key = ("pair", "contact_rows")
    if key not in m.cache:
        m.cache[key] = m.program(lambda w, p, state: m.residual(w, p, 1.0, state, None, "rest")
                                 + m.external_forces(m.reference(p), p, 1.0), "pair_contact_rows")
    state = sol.state_before(-1)[0] if m.has_history else None
    rows = m.cache[key](sol.increments[-1].w, sol.jax_params, state)
    t = -np.asarray(rows)[: m.dim * m.n_nodes].reshape(-1, m.dim)[nodes] / A[:, None]
    return {"nodes": nodes, "X": X[nodes], "A": A, "N": N, "t": t}
