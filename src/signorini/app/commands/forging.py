"""``signorini forging``: axisymmetric J2 forging of a Bezier preform (paper
5.3, Table 1): the objective, its DDM sensitivities, the FD check and the
optional adjoint, written as summary.json, table1.csv, figures and a .pvd series."""

from __future__ import annotations

import numpy as np

from ... import timing
from ...algorithms.newton import NewtonOptions
from ...errors import InputError
from ...post import plots
from ...problems import forging
from ...problems.forging import (
    DEFAULTS, H0, TABLE1, body_volume, die_force, forging_problem, lateral_nodes, objective, options)
from ..options import (
    Formatter, adjoint_option, command_options, finish, forging_mesh_options, newton_options,
    parse_sets, path_options, print_adjoint, print_ddm_fd, solver_options, with_defaults)
from ..runner import (
    Timer, adjoint_report, fd_table, newton_log, prepare_output, solve_or_report, solver_entries,
    summary_header, use_solver, write_series, write_summary)

NAME = "forging"


FORGING_SET = with_defaults({
    **{f"phi{k}": f"Bezier control radius {k} of the preform [h0] (all equal: a cylinder)"
       for k in range(5)},
    "mu": "Coulomb friction coefficient on the die",
    "sigma_y": "initial yield stress",
    "H": "linear isotropic hardening modulus",
    "E": "Young's modulus",
    "nu": "Poisson's ratio",
    "stroke": "die travel [h0] (0.5: 50 %% height reduction)",
    "eps": "normal augmentation parameter, default E0/h0",
    "eps_t": "tangential augmentation parameter, default eps",
}, DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    fg = sub.add_parser(
        "forging", formatter_class=Formatter,
        help="axisymmetric J2 forging of a Bezier preform with friction (paper 5.3, Table 1)",
        description="A billet (height 2 h0 = 2, half model) upset by a flat rigid die with Coulomb "
                    "friction to 50 % height reduction: axisymmetric finite-strain J2 plasticity "
                    "(F-bar Q4), preform radius r0(Z) = Bezier curve of phi0..phi4. Computes the "
                    "objective F = sum (r_k - h0)^2 over the free-surface nodes and its DDM "
                    "sensitivities to phi0..phi4, mu and sigma_y, checked by central differences. "
                    "Writes summary.json, table1.csv, shape.png, force.png and forging.pvd. "
                    "Units: lengths in h0, stresses in the units of E.")
    command_options(fg, FORGING_SET, refine=None)
    forging_mesh_options(fg)  # --mesh and --steps, shared with optimize-forging
    path_options(fg, fd="14 re-solves of the whole path")
    adjoint_option(fg, "F")
    newton_options(fg, 1e-11)
    solver_options(fg)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    params = parse_sets(args.set, FORGING_SET)
    s = run(args.out, params, mesh=forging.parse_mesh(args.mesh), steps=args.steps,
                    fd_check=not args.no_fd, solver=args.solver, force_size=args.force_size,
                    adjoint=args.adjoint, rtol=args.rtol, max_iter=args.max_iter)
    print(f"forging ({s['mesh']['dofs']} DOFs, {s['steps']} increments, mu = "
          f"{s['params']['mu']:g}): F = {s['F']:.6g}, max |r - h0| / h0 = "
          f"{s['max_rel_deviation_from_r_opt']:.4f}, die force {s['die_force_final']:.5g}, "
          f"volume ratio {s['volume']['ratio']:.4f}")
    print_ddm_fd(s)
    print_adjoint(s)
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, mesh: tuple[int, int] = (10, 20), steps: int = 50,
        fd_check: bool = True, solver="auto", force_size: bool = False, rtol: float = 1e-11,
        fd_step: float = 1e-6, adjoint: bool = False,
        max_iter: int = NewtonOptions.max_iter) -> dict:
    """Upset the billet with DDM sensitivities of the objective F (eq. 24) and write results.

    Writes into ``out``: ``summary.json`` (F, DF/Dphi_k, DF/Dmu, DF/Dsigma_y by DDM
    and, unless ``fd_check`` is False, by central differences with step
    ``fd_step`` max(|phi|, 1) (1e-6 h0 for the shape, the paper's), final lateral
    radii, die force, billet volume, Newton iterations, wall time, warnings);
    ``table1.csv`` (the paper's Table 1 analogue); ``shape.png`` (initial and
    deformed mesh, plastic strain); ``force.png`` (die force against stroke);
    ``forging.pvd`` with one VTU per increment. Returns the summary. On a Newton
    failure the converged increments and a ``failed`` summary are written first.
    ``adjoint``: also the adjoint gradient of F with respect to the same
    parameters and every nodal coordinate, next to the DDM one (``summary.json``
    ``adjoint``, ``shape_gradient.csv``, VTU field ``adjoint_shape_gradient`` on
    the last increment).
    """

    clock = Timer()
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"--steps must be a whole number >= 1, got {steps!r}")
    out = prepare_output(out)
    # the history kept: the run's and its sensitivities, and one more run for the FD check
    pb = forging_problem(params, mesh=mesh, force_size=force_size, solver=solver, steps=steps,
                         sensitivities=len(TABLE1) + int(bool(fd_check)))
    v = pb.params
    opts = options(rtol, max_iter)
    solver = use_solver(solver)  # one instance: its symbolic analysis serves the FD re-solves too
    names = list(TABLE1)
    info = {"n_r": mesh[0], "n_z": mesh[1], "nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells}
    t0 = clock()
    sol = solve_or_report(out, "forging", pb, {"params": v, "mesh": info}, steps=steps,
                          wrt=names, options=opts, solver=solver)
    t_solve = clock() - t0
    model = sol.model
    lat = lateral_nodes(pb)
    F_fn = objective(model, lat)
    F, dF = sol.response(F_fn, key=("forging-objective",))
    dF = {k: float(val) for k, val in dF.items()}
    adj = None
    if adjoint:
        timing.mark("sensitivities")
        adj = adjoint_report(out, sol, lambda m: objective(m, lat), names,
                             "F = sum (r_k - r_opt)^2 over the lateral nodes (forging.objective)",
                             solver, dF)
    timing.mark("output")
    force_fn = die_force(model)
    force = [float(sol.response(force_fn, k, with_sensitivities=False, key=("die-force",))[0])
             for k in range(len(sol.increments))]
    X = sol.reference()
    x = sol.current()
    vol0, vol1 = body_volume(model, X), body_volume(model, x)
    _figures(out, sol, X, x, v, F, force)  # the output helper draws them and writes the VTU
    write_series(sol, out / "forging.pvd")  # files meanwhile, beside the check

    timing.mark("sensitivities")
    fd, rel = fd_table(out / "table1.csv", pb, F_fn, ("forging-objective",), names, dF, fd_check,
                       steps=steps, options=opts, solver=solver, rel_step=fd_step)
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
        "lateral_radii_final": (x[lat, 0]).tolist(),
        "max_rel_deviation_from_r_opt": float(np.max(np.abs(x[lat, 0] - H0)) / H0),
        "die_force_final": force[-1],
        "volume": {"initial": vol0, "final": vol1, "ratio": vol1 / vol0},
        "max_equivalent_plastic_strain": float(np.asarray(sol.increments[-1].state[2])[..., 9].max()),
        **newton_log(sol),
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


def _figures(out, sol, X, x, v, F, force) -> None:
    """shape.png (preform and final shape with the plastic strain) and force.png."""
    model = sol.model
    alpha = np.asarray(sol.increments[-1].state[2])[..., 9].mean(axis=1)
    plots.meshes(out / "shape.png", [
        {"x": X, "cells": model.conn, "title": "initial (preform)"},
        {"x": x, "cells": model.conn, "title": f"after {v['stroke'] / H0:.0%} stroke",
         "color": alpha, "color_label": "equivalent plastic strain"}],
        title=f"Forging, mu = {v['mu']:g}, F = {float(F):.4g}")
    plots.curves(out / "force.png", [
        {"x": [inc.t * v["stroke"] for inc in sol.increments], "y": force, "label": "die force"}],
        xlabel="die stroke [h0]", ylabel="axial force (full 2 pi) [N]",
        title="Forging: die force against stroke")
