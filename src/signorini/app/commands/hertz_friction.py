"""``signorini hertz-friction``: the frictional Hertz benchmark (paper 5.2): stick
zone c/a at three loads, path-dependent DDM sensitivities, optional adjoint."""

from __future__ import annotations

import numpy as np

from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...algorithms.coarse_to_fine import warn_failed_levels
from ...errors import InputError
from ...post import files as io, plots
from ...problems import hertz
from ...problems.hertz_friction import (
    BLOCK, DEFAULTS, hertz_friction_problem, load_increments, stick_zone)
from ..options import (
    UNITS, Formatter, adjoint_option, coarse_start_option, common_options, finish, fmt_fd,
    newton_options, nominal_a0, parse_sets, print_adjoint, with_defaults)
from .hertz import HERTZ_TEXTS, contact_validity
from ... import timing
from .. import validity
from ..runner import (
    Timer, adjoint_report, max_rel_diff, newton_log, prepare_output, solve_or_report, solver_entries,
    summary_header, use_solver, write_series, write_summary)

NAME = "hertz-friction"


FRICTION_SET = with_defaults({
    **HERTZ_TEXTS, "P": "final load per unit thickness [N/mm]", "mu": "Coulomb friction coefficient",
    "eps": "normal augmentation parameter [N/mm³], default E0/h",
    "eps_t": "tangential augmentation parameter [N/mm³], default eps"}, DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    f = sub.add_parser(
        "hertz-friction", formatter_class=Formatter,
        help="frictional plane-strain Hertz benchmark with Coulomb friction (paper 5.2)",
        description="The Hertz half model with Coulomb friction (mu = 0.3, R = 10), the load "
                    "growing to P in --steps increments; path-dependent DDM sensitivities to R, "
                    "mu, E. Writes contact_P1..3.csv, summary.json (c/a with its bracket, Newton "
                    "log, DDM vs FD), Fig. 5/6-like figures, VTU files at P1..P3 and the series "
                    "hertz_friction.pvd. " + UNITS)
    common_options(f, FRICTION_SET, 30, "number of load increments, a multiple of 3 (P1 = P/3, P2 = 2P/3 "
            "and P3 = P must be increments)", nominal_a0("hertz_friction"), block=80.0)
    coarse_start_option(f)
    adjoint_option(f, "the contact work W = sum A p_N (g0 - g) at P")
    # 1e-10 leaves margin above the residual's round-off floor at the small early loads
    newton_options(f, 1e-10)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    params = parse_sets(args.set, FRICTION_SET)
    s = run(args.out, params, refine=args.refine, steps=args.steps,
                           fd_check=not args.no_fd, solver=args.solver, size=args.block,
                           zone=args.zone_width, finite_strain=args.finite_strain,
                           force_size=args.force_size, coarse_start=not args.no_coarse_start,
                           adjoint=args.adjoint,
                           options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter))
    ca = ", ".join(f"{lv['c_over_a']:.3f} [{lv['c_over_a_bracket'][0]:.3f}, "
                   f"{lv['c_over_a_bracket'][1]:.3f}]" for lv in s["loads"])
    print(f"frictional Hertz ({s['mesh']['dofs']} DOFs, {s['steps']} increments): "
          f"c/a at P1, P2, P3 = {ca}{validity.note(s)}; Newton iterations {sum(s['newton_iterations'])} "
          f"in total; DDM vs FD at P3 (max rel. diff.): {fmt_fd(s['ddm_vs_fd_rel_diff_P3'])}")
    print_adjoint(s)
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, steps: int = 30, fd_check: bool = True,
        sensitivities=("R", "mu", "E"), options=None, fd_step: float = 1e-5, solver="auto",
        size: float = BLOCK, zone: float = 1.5, finite_strain: bool = False,
        force_size: bool = False, coarse_start: bool = True, adjoint: bool = False) -> dict:
    """Solve the frictional Hertz benchmark with path-dependent DDM sensitivities.

    Writes ``contact_P{1,2,3}.csv`` (``x_ref, x, p_N, p_T, dp_N_d<name>,
    dp_T_d<name>, status``), ``pressure.png`` / ``friction.png`` (paper Fig. 5),
    ``normalised.png`` / ``normalised_sensitivity.png`` (Fig. 6),
    ``hertz_friction_P{1,2,3}.vtu``, the series ``hertz_friction.pvd`` (one VTU
    per increment) and ``summary.json`` into ``out``. Returns the summary.
    The FD check re-runs the whole load path at phi +- h,
    h = ``fd_step`` max(|phi|, 1): smaller steps are limited by the Newton
    tolerance (error ~ rtol / h), much larger ones change stick/slip states.
    On a Newton failure the converged increments and ``summary.json`` (status
    ``failed``) are written before the error is re-raised. ``adjoint``: also the
    adjoint gradient of the contact work W at P (:func:`hertz.contact_work`) with
    respect to the sensitivity parameters and every nodal coordinate, next to its
    DDM gradient (``summary.json`` ``adjoint``, ``shape_gradient.csv``, VTU field
    ``adjoint_shape_gradient`` in ``hertz_friction_P3.vtu``).
    """

    clock = Timer()
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 3 or steps % 3:
        raise InputError(f"--steps must be a positive multiple of 3 (P1, P2, P3 = P/3, 2P/3, P "
                         f"must be increments), got {steps!r}")
    sensitivities = list(dict.fromkeys(["R", *sensitivities]))
    out = prepare_output(out)
    # rtol 1e-10 leaves margin above the residual's round-off floor at the small early loads
    options = options or NewtonOptions(rtol=1e-10)
    solver = use_solver(solver)  # one instance: its symbolic analysis serves the FD re-solves too
    pb = hertz_friction_problem(params, refine=refine, size=size, zone=zone,
                                finite_strain=finite_strain, force_size=force_size, solver=solver)
    v = pb.params
    h = hertz.fine_cell_size(pb)
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "contact_cell_size": h,
                 "block_over_a0": size, "zone_over_a0": zone, "refine": refine}
    t0 = clock()
    timing.mark("solve")
    guide, coarse = None, []
    skipped = hertz.coarse_start_skipped(pb, coarse_start)
    if skipped is None:
        guide, coarse = hertz.coarse_start_for(
            pb, lambda r, n: hertz_friction_problem(params, refine=r, n_fine=n, size=size, zone=zone,
                                                    finite_strain=finite_strain),
            refine, 24, steps=steps, options=options, solver=solver)
    sol = solve_or_report(out, "hertz_friction", pb, {"params": v, "mesh": mesh_info}, steps=steps,
                          wrt=sensitivities, options=options, solver=solver,
                          start=guide)
    warn_failed_levels(sol, coarse)
    t_solve = clock() - t0

    adj = _adjoint(out, sol, sensitivities, solver) if adjoint else None
    timing.mark("output")
    levels = _levels(out, sol, v, sensitivities)
    invalid = contact_validity(sol, levels[-1]["a"], v["R"], pb, zone * nominal_a0("hertz_friction"))
    _figures(out, levels, v, plots)  # the output helper draws them and writes the VTU files
    write_series(sol, out / "hertz_friction.pvd")  # meanwhile, beside the check

    ddm_fd = {}
    if fd_check:
        timing.mark("sensitivities")
        ddm_fd = _ddm_vs_fd(pb, levels[-1], [n for n in ("R", "mu") if n in sensitivities], steps=steps,
                            options=options, rel_step=fd_step, solver=solver,
                            start=sol if coarse_start else None)
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "steps": steps,
        "coarse_start": coarse if coarse else (skipped or "no coarser mesh"),
        "finite_strain": finite_strain,
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "loads": [{k: val for k, val in lv.items() if k != "contact"} for lv in levels],
        "c_over_a": [lv["c_over_a"] for lv in levels],
        "c_over_a_bracket": [lv["c_over_a_bracket"] for lv in levels],
        "analytical_comparison": validity.comparison(invalid),
        **newton_log(sol),
        "ddm_vs_fd_rel_diff_P3": ddm_fd if fd_check else "not computed (--no-fd)",
        "adjoint": adj if adjoint else "not computed (use --adjoint)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


def _adjoint(out, sol, sensitivities, solver) -> dict:
    """The adjoint gradient of the contact work at P next to its DDM gradient
    (``summary.json`` ``adjoint``, ``shape_gradient.csv``)."""
    timing.mark("sensitivities")
    work = hertz.contact_work(sol.model)
    _, dW = sol.history_response(lambda w, p, t, s: work(w, p, t), key=("contact-work",))
    return adjoint_report(out, sol, hertz.contact_work, sensitivities,
                          "contact work W = sum A p_N (g0 - g) at P (hertz.contact_work)", solver,
                          {n: float(d) for n, d in dW.items()})


def _levels(out, sol, v, sensitivities) -> list[dict]:
    """At P1, P2, P3: contact_P<i>.csv, the VTU file, and the zone figures (a, c, c/a
    with brackets, Hertz's a and p0, stick and slip counts; the contact arrays kept)."""
    levels = []
    for i, k in enumerate(load_increments(sol), start=1):
        P = v["P"] * sol.increments[k].t
        an = hertz.analytical(P, v["R"], v["E"], v["nu"])
        c = sol.contact(k)
        z = stick_zone(c, v["mu"])
        cols = {"x_ref": c["x_ref"][:, 0], "x": c["x"][:, 0], "p_N": c["p_N"], "p_T": c["p_T"] + 0.0}
        for n in sensitivities:
            cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
            cols[f"dp_T_d{n}"] = c[f"dp_T_d{n}"] + 0.0
        cols["status"] = c["status"]
        io.write_csv(out / f"contact_P{i}.csv", cols)
        io.write_vtu(sol, out / f"hertz_friction_P{i}.vtu", k)
        levels.append({"P": P, "increment": k, "a": z["a"], "c": z["c"], "c_over_a": z["c_over_a"],
                       "a_bracket": z["a_bracket"], "c_bracket": z["c_bracket"],
                       "c_over_a_bracket": z["c_over_a_bracket"],
                       "a_nodes": z["a_nodes"], "c_nodes": z["c_nodes"],
                       "a_hertz": an["a"], "p0_hertz": an["p0"], "p0": float(c["p_N"].max()),
                       "n_stick": int((c["status"] == "stick").sum()),
                       "n_slip": int((c["status"] == "slip").sum()), "contact": c})
    return levels


def _ddm_vs_fd(pb, level: dict, names, **fd_kwargs) -> dict:
    """Max relative difference of the DDM (p_N, p_T) sensitivities at P3 from central
    differences of the whole path, inside 0.9 a (the tractions are not
    differentiable at the edge of the zone)."""
    k3, c3 = level["increment"], level["contact"]
    inner = c3["x_ref"][:, 0] < 0.9 * level["a_hertz"]

    def q(s):
        c = s.contact(k3)
        return np.concatenate([c["p_N"][inner], c["p_T"][inner]])

    return {n: max_rel_diff(np.concatenate([c3[f"dp_N_d{n}"][inner], c3[f"dp_T_d{n}"][inner]]),
                            finite_difference(pb, n, q, **fd_kwargs))
            for n in names}


def _figures(out, levels, v, plots):
    """Paper Fig. 5 (p_N, p_T at P1..P3) and Fig. 6 (normalised by p0_i, a_i, p0_i/R)."""
    def series(key, scale=None):
        res = []
        for i, lv in enumerate(levels, start=1):
            c = lv["contact"]
            m = c["x_ref"][:, 0] < 1.6 * lv["a_hertz"]
            x, y = c["x_ref"][m, 0], c[key][m]
            if scale is not None:
                x, y = x / lv["a_hertz"], y / scale(lv)
            res.append({"x": x, "y": y, "label": f"{key}, P{i} = {lv['P']:.2g}",
                        "style": "line" if scale is None else "points"})
        return res

    plots.curves(out / "pressure.png", series("p_N"), xlabel="x [mm]", ylabel="p_N [N/mm²]",
                 title="Frictional Hertz: contact pressure")
    plots.curves(out / "friction.png", series("p_T"), xlabel="x [mm]", ylabel="p_T [N/mm²]",
                 title="Frictional Hertz: friction stress")
    p0 = lambda lv: lv["p0_hertz"]
    plots.curves(out / "normalised.png", series("p_N", p0) + series("p_T", p0),
                 xlabel="x / a_i", ylabel="p / p0_i", title="Normalised tractions (self-similar)")
    p0R = lambda lv: lv["p0_hertz"] / v["R"]
    plots.curves(out / "normalised_sensitivity.png",
                 series("dp_N_dR", p0R) + series("dp_T_dR", p0R),
                 xlabel="x / a_i", ylabel="(R / p0_i) Dp/DR",
                 title="Normalised sensitivities to the cylinder radius")
