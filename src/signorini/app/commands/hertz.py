"""``signorini hertz``: the frictionless plane-strain Hertz benchmark (paper 5.1),
solved with DDM sensitivities, checked against the analytical solution and
central differences, written as contact.csv, summary.json, figures and VTU."""

from __future__ import annotations

import numpy as np

from ...algorithms.newton import NewtonOptions
from ...algorithms.coarse_to_fine import warn_failed_levels
from ...design.finite_differences import finite_difference
from ...post import files as io, plots
from ...problems.hertz import (
    DEFAULTS, analytical, coarse_start_for, coarse_start_skipped, fine_cell_size, hertz_problem,
    pressure, pressure_dR)
from ..options import (
    UNITS, Formatter, coarse_start_option, common_options, finish, fmt_coarse, fmt_fd, nominal_a0,
    newton_options, parse_sets, with_defaults)
from ... import timing
from .. import validity
from ..runner import (
    Timer, max_rel_diff, newton_log, prepare_output, solve_or_report, solver_entries, summary_header,
    use_solver, write_series, write_summary)

NAME = "hertz"
#: Newton's default tolerance of this command (--rtol)
RTOL = 1e-11


#: what the --set parameters of the Hertz problems are (their defaults are the builders')
HERTZ_TEXTS = {
    "E": "Young's modulus [N/mm²]",
    "nu": "Poisson's ratio",
    "P": "load per unit thickness [N/mm]",
    "R": "cylinder radius [mm]",
    "eps": "augmentation/penalty parameter [N/mm³], default E0/h (nominal E0, contact cell h)",
    "bump": "shape parameter: amplitude of a crown on the top face [mm], default 0",
}
HERTZ_SET = with_defaults(HERTZ_TEXTS, DEFAULTS)

def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    h = sub.add_parser(
        "hertz", formatter_class=Formatter, help="frictionless plane-strain Hertz benchmark (paper 5.1)",
        description="Rigid cylinder (radius R) pressed with P per unit thickness onto an elastic "
                    "block; symmetric half model, held only by the contact. Writes contact.csv "
                    "(pressure and its DDM sensitivities to R, E, P), summary.json (p0 and a vs "
                    "the analytical solution, Newton log, DDM vs FD), pressure.png, "
                    "sensitivity.png and hertz.vtu. " + UNITS)
    common_options(h, HERTZ_SET, 1, "number of equal load increments", nominal_a0("hertz"))
    h.add_argument("--method", choices=["al", "penalty"], default="al",
                   help="contact method: augmented Lagrangian (exact) or penalty (comparator)")
    coarse_start_option(h)
    newton_options(h, RTOL)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    params = parse_sets(args.set, HERTZ_SET)
    s = run(args.out, params, refine=args.refine, method=args.method,
                  finite_strain=args.finite_strain, steps=args.steps, fd_check=not args.no_fd,
                  solver=args.solver, size=args.block, zone=args.zone_width,
                  force_size=args.force_size, coarse_start=not args.no_coarse_start,
                  options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter))
    print(f"Hertz ({args.method}, {s['mesh']['dofs']} DOFs): p0 = {s['p0']['computed']:.5g} "
          f"(analytical {s['p0']['analytical']:.5g}, error {100 * s['p0']['rel_error']:+.2f} %), "
          f"a = {s['a']['computed']:.4g} (analytical {s['a']['analytical']:.4g}){validity.note(s)}; "
          f"Newton iterations {s['newton_iterations']}{fmt_coarse(s['coarse_start'])}; "
          f"DDM vs FD (max rel. diff.): {fmt_fd(s['ddm_vs_fd_rel_diff'])}; "
          f"solver {s['solver']}")
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, method: str = "al",
        finite_strain: bool = False, steps: int = 1, fd_check: bool = True,
        sensitivities=("R", "E", "P"), options=None, fd_step: float = 1e-4, solver="auto",
        size: float = 20.0, zone: float = 1.5, force_size: bool = False,
        coarse_start: bool = True) -> dict:
    """Solve the Hertz benchmark with DDM sensitivities and write the results.

    Writes ``contact.csv``, ``summary.json``, ``pressure.png``,
    ``sensitivity.png`` and ``hertz.vtu`` (``hertz.pvd`` + one VTU per
    increment when ``steps > 1``) into ``out``. Returns the summary. On a
    Newton failure the converged increments and ``summary.json`` (status
    ``failed``, the reason) are written before the error is re-raised.

    ``coarse_start``: the first increment's Newton starts from the solution of
    the coarser meshes of :func:`coarse_levels`, interpolated; the
    finite-difference re-solves start from the converged base solution. Only
    the first iterate changes, not the result.
    """

    clock = Timer()
    out = prepare_output(out)
    options = options or NewtonOptions(rtol=RTOL)
    solver = use_solver(solver)  # one instance: its symbolic analysis serves the FD re-solves too
    sensitivities = list(sensitivities)
    pb = hertz_problem(params, refine=refine, method=method, finite_strain=finite_strain, size=size,
                       zone=zone, force_size=force_size, solver=solver)
    v = pb.params
    an = analytical(v["P"], v["R"], v["E"], v["nu"])
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "contact_cell_size": fine_cell_size(pb),
                 "block_over_a0": size, "zone_over_a0": zone, "refine": refine}
    t0 = clock()
    timing.mark("solve")
    guide, levels = None, []
    skipped = coarse_start_skipped(pb, coarse_start)
    if skipped is None:
        guide, levels = coarse_start_for(
            pb, lambda r, n: hertz_problem(params, refine=r, n_fine=n, method=method,
                                           finite_strain=finite_strain, size=size, zone=zone),
            refine, 24, steps=steps, options=options, solver=solver)
    sol = solve_or_report(out, "hertz", pb, {"params": v, "mesh": mesh_info}, series=steps > 1,
                          steps=steps, wrt=sensitivities, options=options, solver=solver,
                          start=guide)
    warn_failed_levels(sol, levels)
    t_solve = clock() - t0
    c = sol.contact()
    x = c["x_ref"][:, 0]
    closed = c["p_N"] > 0
    a_fe = float(x[closed].max()) if closed.any() else 0.0
    p0_fe = float(c["p_N"].max())
    invalid = contact_validity(sol, a_fe, v["R"], pb, zone * nominal_a0("hertz"))

    timing.mark("output")
    _figures(out, x, c, an, v, method, sensitivities)  # the output helper draws them meanwhile
    _write_fields(out, sol, sensitivities, steps)
    ddm_fd = {}
    if fd_check:
        timing.mark("sensitivities")
        ddm_fd = _ddm_vs_fd(pb, sol, x < 0.9 * an["a"], sensitivities, steps=steps, options=options,
                            rel_step=fd_step, solver=solver, start=sol if coarse_start else None)
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "method": method,
        "finite_strain": finite_strain,
        "steps": steps,
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "p0": {"computed": p0_fe, "analytical": an["p0"], "rel_error": p0_fe / an["p0"] - 1},
        "a": {"computed": a_fe, "analytical": an["a"], "rel_error": a_fe / an["a"] - 1,
              "error_in_cells": (a_fe - an["a"]) / fine_cell_size(pb)},
        "analytical_comparison": validity.comparison(invalid),
        **newton_log(sol),
        "coarse_start": levels if levels else (skipped or "no coarser mesh"),
        "ddm_vs_fd_rel_diff": ddm_fd if fd_check else "not computed (--no-fd)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


def _write_fields(out, sol, sensitivities, steps) -> None:
    """contact.csv (pressure and its sensitivities) and the VTU file(s)."""
    c = sol.contact()
    cols = {"x_ref": c["x_ref"][:, 0], "x": c["x"][:, 0], "p_N": c["p_N"]}
    for n in sensitivities:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
    io.write_csv(out / "contact.csv", cols)
    io.write_vtu(sol, out / "hertz.vtu")
    if steps > 1:
        write_series(sol, out / "hertz.pvd")


def _ddm_vs_fd(pb, sol, inner, sensitivities, **fd_kwargs) -> dict:
    """Max relative difference of the DDM pressure sensitivities from central
    differences, over the nodes ``inner`` (p_N is not differentiable at x = a)."""
    c = sol.contact()
    return {n: max_rel_diff(c[f"dp_N_d{n}"][inner],
                            finite_difference(pb, n, lambda s: s.contact()["p_N"][inner], **fd_kwargs))
            for n in sensitivities}


def _figures(out, x, c, an, v, method, sensitivities) -> None:
    """pressure.png (against Hertz) and sensitivity.png (DDM against the analytical dp/dR)."""
    xa = np.linspace(0, 1.5 * an["a"], 400)
    plots.curves(out / "pressure.png", [
        {"x": xa, "y": pressure(xa, v["P"], v["R"], v["E"], v["nu"]), "label": "Hertz (eq. 22)"},
        {"x": x, "y": c["p_N"], "label": f"FE, {method}", "style": "points"}],
        xlabel="x [mm]", ylabel="p_N [N/mm²]", title="Frictionless Hertz: contact pressure",
        xlim=(0, 1.5 * an["a"]))
    if "R" in sensitivities:
        xs = np.linspace(0, 0.995 * an["a"], 400)
        plots.curves(out / "sensitivity.png", [
            {"x": np.concatenate([xs, [an["a"], 1.5 * an["a"]]]),
             "y": np.concatenate([pressure_dR(xs, v["P"], v["R"], v["E"], v["nu"]), [0, 0]]),
             "label": "analytical"},
            {"x": x, "y": c["dp_N_dR"], "label": "FE, DDM", "style": "points"}],
            xlabel="x [mm]", ylabel="Dp_N/DR [N/mm³]",
            title="Sensitivity of the pressure to the cylinder radius", xlim=(0, 1.5 * an["a"]))


def contact_validity(sol, a: float, R: float, pb, zone_width: float) -> list[str]:
    """The validity warnings (:mod:`signorini.app.validity`) of a Hertz half model's
    contact half-width ``a``: against R, the block's width and the fine zone."""
    W = float(pb.mesh.nodes[:, 0].max())
    return validity.check(sol, a, [validity.half_space(W), validity.fine_zone(zone_width)],
                          radius=R)
