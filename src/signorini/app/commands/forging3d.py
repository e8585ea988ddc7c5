"""``signorini forging3d``: upsetting of a billet with a rounded-square cross-section
between flat dies with friction (one eighth, F-bar hexahedra, finite-strain J2),
with DDM sensitivities of its out-of-roundness checked by central differences."""

from __future__ import annotations

import numpy as np

from ... import timing
from ...errors import InputError
from ...post import files as io, plots
from ...problems.forging import parse_mesh
from ...problems.forging3d import (
    DEFAULTS, REPORTED, die_force, elastic_volume_ratio, forging3d_problem, options,
    out_of_round, volume)
from ..options import (
    Formatter, adjoint_option, command_options, finish, newton_options, parse_sets, path_options,
    print_adjoint, print_ddm_fd, solver_options, with_defaults)
from ..runner import (
    Timer, adjoint_report, fd_table, newton_log, prepare_output, solve_or_report, solver_entries,
    summary_header, use_solver, write_series, write_summary)

NAME = "forging3d"

FORGING3D_SET = with_defaults({
    "square": "shape: the square part of the section's half-width [h0]",
    "round": "shape: the circular part of the section's half-width [h0]",
    "bulge": "shape: amplitude of a barrel on the lateral surface [h0]",
    "mu": "Coulomb friction coefficient on the die", "sigma_y": "initial yield stress",
    "H": "linear isotropic hardening modulus", "E": "Young's modulus", "nu": "Poisson's ratio",
    "stroke": "die travel [h0]", "eps": "normal augmentation parameter, default E0/h0",
    "eps_t": "tangential augmentation parameter, default eps"}, DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    p = sub.add_parser(
        NAME, formatter_class=Formatter,
        help="3-D upsetting of a rounded-square billet between flat dies with friction",
        description="One eighth of a billet of height 2 h0 whose cross-section is a square with "
                    "rounded corners (shape parameters square, round, bulge), upset by flat rigid "
                    "dies with Coulomb friction: finite-strain J2 plasticity on F-bar hexahedra. "
                    "Objective: the final lateral surface's deviation from a circular cylinder, "
                    "F = mean (r_k - mean r)^2; DDM sensitivities to the shape parameters, mu and "
                    "sigma_y checked by central differences of the whole process. Writes "
                    "summary.json, sensitivities.csv, force.csv, force.png, lateral.csv and the "
                    "VTU series forging3d.pvd. Lengths in h0, stresses in the units of E.")
    command_options(p, FORGING3D_SET, refine=None)
    p.add_argument("--mesh", default="6x6", metavar="NSxNZ",
                   help="cells across the half-section (each way) and along the half-height")
    path_options(p, steps=20, steps_help="equal increments of the die stroke",
                 fd="10 re-solves of the whole path")
    adjoint_option(p, "F")
    newton_options(p, 1e-10)
    solver_options(p)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    params = parse_sets(args.set, FORGING3D_SET)
    s = run(args.out, params, mesh=parse_mesh(args.mesh), steps=args.steps,
            fd_check=not args.no_fd, solver=args.solver, force_size=args.force_size,
            adjoint=args.adjoint, rtol=args.rtol, max_iter=args.max_iter)
    print(f"forging3d ({s['mesh']['dofs']} DOFs, {s['steps']} increments, mu = "
          f"{s['params']['mu']:g}): F = {s['F']:.6g}, die force {s['die_force_final']:.5g}, "
          f"volume ratio {s['volume']['ratio']:.5f} (elastic estimate "
          f"{s['volume']['elastic_estimate']:.5f})")
    print_ddm_fd(s)
    print_adjoint(s)
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, mesh: tuple[int, int] = (6, 6), steps: int = 20,
        fd_check: bool = True, solver="auto", force_size: bool = False, rtol: float = 1e-10,
        fd_step: float = 1e-6, adjoint: bool = False, max_iter: int | None = None) -> dict:
    """Upset the billet with DDM sensitivities of the out-of-roundness F and write results.

    Writes into ``out``: ``summary.json`` (F, DF/D<name> by DDM and, unless
    ``fd_check`` is False, by central differences of the whole process with step
    ``fd_step`` max(|phi|, 1); the die force, the billet volume before and after
    with the elastic estimate of its change, Newton iterations, warnings),
    ``sensitivities.csv``, ``force.csv`` and ``force.png`` (die force against
    stroke), ``lateral.csv`` (the final lateral surface) and ``forging3d.pvd``
    with one VTU per increment. Returns the summary.
    """
    clock = Timer()
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"--steps must be a whole number >= 1, got {steps!r}")
    out = prepare_output(out)
    # the history kept: the run's and its sensitivities, and one more run for the FD check
    pb = forging3d_problem(params, mesh=mesh, force_size=force_size, solver=solver, steps=steps,
                           sensitivities=len(REPORTED) + int(bool(fd_check)))
    v = pb.params
    opts = options(rtol) if max_iter is None else options(rtol, max_iter)
    solver = use_solver(solver)
    names = list(REPORTED)
    info = {"n_section": mesh[0], "n_z": mesh[1], "nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells}
    t0 = clock()
    sol = solve_or_report(out, NAME, pb, {"params": v, "mesh": info}, steps=steps, wrt=names,
                          options=opts, solver=solver)
    t_solve = clock() - t0
    model = sol.model
    lat = pb.mesh.node_set("lateral")
    F_fn = out_of_round(model, lat)
    F, dF = sol.response(F_fn, key=("forging3d-objective",))
    dF = {k: float(val) for k, val in dF.items()}
    adj = None
    if adjoint:
        timing.mark("sensitivities")
        adj = adjoint_report(out, sol, lambda m: out_of_round(m, lat), names,
                             "F = mean (r_k - mean r)^2 over the lateral nodes (forging3d.out_of_round)",
                             solver, dF)
    timing.mark("output")
    force_fn = die_force(model)
    force = [0.0] + [float(sol.response(force_fn, k, with_sensitivities=False, key=("die-force",))[0])
                     for k in range(len(sol.increments))]
    stroke = [0.0] + [inc.t * v["stroke"] for inc in sol.increments]  # from the undeformed start
    X, x = sol.reference(), sol.current()
    vol0, vol1 = volume(model, X), volume(model, x)
    elastic = elastic_volume_ratio(model, x, sol.stress()[0], v)
    io.write_csv(out / "force.csv", {"stroke": stroke, "die_force": force})
    r = np.hypot(x[lat, 0], x[lat, 1])
    io.write_csv(out / "lateral.csv", {"node": lat, "x": x[lat, 0], "y": x[lat, 1], "z": x[lat, 2],
                                       "r": r})
    plots.curves(out / "force.png", [{"x": stroke, "y": force, "label": "die force (one eighth)"}],
                 xlabel="die stroke [h0]", ylabel="axial force [E h0²]",
                 title="3-D forging: die force against stroke")
    write_series(sol, out / "forging3d.pvd")

    if fd_check:
        timing.mark("sensitivities")
    fd, rel = fd_table(out / "sensitivities.csv", pb, F_fn, ("forging3d-objective",), names, dF,
                       fd_check, steps=steps, options=opts, solver=solver, rel_step=fd_step)
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "mesh": {**info, "dofs": int(model.n_dof)},
        "steps": steps,
        **solver_entries(solver, sol),
        "F": float(F),
        "dF_ddm": dF,
        "dF_fd": fd if fd_check else "not computed (--no-fd)",
        "ddm_vs_fd_rel_diff": rel if fd_check else "not computed (--no-fd)",
        "adjoint": adj if adjoint else "not computed (use --adjoint)",
        "fd_step": {n: fd_step * max(abs(v[n]), 1.0) for n in names},
        "lateral_radius": {"min": float(r.min()), "max": float(r.max()), "mean": float(r.mean())},
        "die_force_final": force[-1],
        "volume": {"initial": vol0, "final": vol1, "ratio": vol1 / vol0,
                   "elastic_estimate": elastic},
        "max_equivalent_plastic_strain": float(np.asarray(sol.increments[-1].state[2])[..., 9].max()),
        **newton_log(sol),
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)
