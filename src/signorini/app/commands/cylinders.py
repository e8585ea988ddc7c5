"""``signorini cylinders``: two elastic cylinders pressed together (Hertz) and,
with friction, sheared by a tangential force (Mindlin): the two-body contact
example (a mortar pair between non-matching meshes); DDM sensitivities to the
shape and the modulus of either body, the loads and mu, checked by central
differences."""

from __future__ import annotations

import numpy as np

from ... import timing
from .. import validity
from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...post import files as io, plots
from ...algorithms.coarse_to_fine import warn_failed_levels
from ...problems import hertz
from ...problems.cylinders import DEFAULTS, analytical, cylinders_problem, extents, pressure, shear
from ...problems.hertz_friction import stick_zone
from ..options import (
    UNITS, Formatter, coarse_start_option, command_options, finish, fmt_coarse, fmt_fd,
    newton_options, parse_sets, path_options, positive_float, positive_int, solver_options,
    with_defaults)
from ..runner import (
    Timer, master_tractions, max_rel_diff, newton_log, prepare_output, solve_or_report, solver_entries,
    summary_header, use_solver, write_series, write_summary)

NAME = "cylinders"
RTOL = 1e-10
#: the size from which the load path starts from coarser meshes: with the dual mortar
#: weights Newton needs few iterations from rest, and the coarse levels pay only from
#: about here (measured solve times in docs/cli.md, `signorini cylinders`)
MIN_GUIDED_DOFS = 100_000
#: increments with friction (P over the first half, Q over the second), and without
STEPS_FRICTION, STEPS = 10, 1

CYLINDERS_SET = with_defaults({
    "R1": "radius of the lower cylinder [mm]", "R2": "radius of the upper cylinder [mm]",
    "E1": "Young's modulus of the lower cylinder [N/mm²]", "E2": "of the upper [N/mm²]",
    "nu1": "Poisson's ratio of the lower cylinder", "nu2": "of the upper",
    "P": "normal force per unit thickness [N/mm]",
    "mu": "Coulomb friction coefficient (0: frictionless)",
    "Q": "tangential force per unit thickness after P [N/mm], below mu P",
    "eps": "normal augmentation parameter, default E0/h", "eps_t": "tangential, default E0/h"},
    DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    p = sub.add_parser(
        NAME, formatter_class=Formatter,
        help="two elastic cylinders in contact (Hertz; with friction and Q, Mindlin)",
        description="Two elastic cylinders (R1 below, R2 above) pressed together by the force P "
                    "in plane strain, non-matching meshes joined by a mortar contact pair; with "
                    "--set mu=0.3 --set Q=0.015 a tangential force Q < mu P follows P (Mindlin's "
                    "partial slip). Writes contact.csv (the lower, slave surface: x, p_N, p_T, the "
                    "stick/slip status, dp_N_d<name>, dp_T_d<name>), contact_upper.csv (the upper "
                    "surface's tractions from its contact forces), summary.json (b and p0 against "
                    "Hertz, c/b against Mindlin, Newton log, DDM vs FD), pressure.png, "
                    "sensitivity.png, traction.png (with friction) and cylinders.vtu. " + UNITS)
    # the meshes follow R1 and R2 (shape parameters): no fixed-mesh note
    command_options(p, CYLINDERS_SET, example="mu=0.3", fixed_mesh=False)
    p.add_argument("--n-fine", type=positive_int, default=24, metavar="N",
                   help="the lower body's cells across the fine zone (1.5 b0 on each side)")
    p.add_argument("--ratio", type=positive_float, default=2 / 3, metavar="F",
                   help="the upper body's cell count at the interface relative to the lower's")
    path_options(p, steps_help=f"load increments (default {STEPS} frictionless, {STEPS_FRICTION} "
                               "with friction)")
    coarse_start_option(p)
    solver_options(p)
    newton_options(p, RTOL)


def execute(args) -> int:
    params = parse_sets(args.set, CYLINDERS_SET)
    s = run(args.out, params, refine=args.refine, n_fine=args.n_fine, ratio=args.ratio,
            steps=args.steps, fd_check=not args.no_fd, solver=args.solver,
            options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter),
            coarse_start=not args.no_coarse_start, force_size=args.force_size)
    zone = f", c/b = {s['c_over_b']['computed']:.3f} (Mindlin {s['c_over_b']['analytical']:.3f})" \
        if isinstance(s.get("c_over_b"), dict) else ""
    print(f"Two cylinders ({s['mesh']['dofs']} DOFs, {s['steps']} increment(s)): "
          f"p0 = {s['p0']['computed']:.5g} (Hertz {s['p0']['analytical']:.5g}, "
          f"{100 * s['p0']['rel_error']:+.2f} %), b = {s['b']['computed']:.4g} "
          f"(Hertz {s['b']['analytical']:.4g}){zone}{validity.note(s)}; Newton iterations "
          f"{sum(s['newton_iterations'])}{fmt_coarse(s['coarse_start'])}; DDM vs FD (max rel. diff.): "
          f"{fmt_fd(s['ddm_vs_fd_rel_diff'])}; solver {s['solver']}")
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, n_fine: int = 24, ratio: float = 2 / 3,
        steps=None, fd_check: bool = True, sensitivities=None, options=None, fd_step: float = 1e-5,
        solver="auto", coarse_start: bool = True, force_size: bool = False) -> dict:
    """Solve the two-cylinder problem with DDM sensitivities and write the results
    into ``out``; returns the summary. Sensitivities: R1, R2, E1, P (and mu, Q with
    friction). The FD check re-solves the whole path at phi +- h (h = ``fd_step``
    max(|phi|, 1)) and compares p_N and p_T over the contact zone. From 50,000
    DOFs on (``coarse_start``) the load path is started from coarser meshes of
    the same grid lines, solved along it first (docs/theory.md §10.3).
    ``force_size``: run even if the meshes are estimated not to fit in memory."""
    clock = Timer()
    out = prepare_output(out)
    options = options or NewtonOptions(rtol=RTOL)
    solver = use_solver(solver)
    pb = cylinders_problem(params, refine=refine, n_fine=n_fine, ratio=ratio,
                           force_size=force_size, solver=solver)
    v = pb.params
    friction = v["mu"] > 0
    steps = steps or (STEPS_FRICTION if friction else STEPS)
    if sensitivities is None:
        sensitivities = ["R1", "R2", "E1", "P"] + (["mu", "Q"] if friction else [])
    hv = {k: v[k] for k in ("P", "R1", "R2", "E1", "E2", "nu1", "nu2", "mu", "Q")}
    an = analytical(**hv)
    top = pb.mesh.nodes[pb.mesh.node_sets["lower.top"]]
    xs = np.sort(top[:, 0])
    h = float(np.min(np.diff(xs)))
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "contact_cell_size": h,
                 "upper_contact_cell_size": float(np.min(np.diff(np.sort(
                     pb.mesh.nodes[pb.mesh.node_sets["upper.bottom"], 0])))),
                 "refine": refine, "n_fine": n_fine, "ratio": ratio}
    t0 = clock()
    timing.mark("solve")
    guide, coarse = None, []
    skipped = hertz.coarse_start_skipped(pb, coarse_start, MIN_GUIDED_DOFS)
    if skipped is None:
        guide, coarse = hertz.coarse_start_for(
            pb, lambda r, n: cylinders_problem(params, refine=r, n_fine=n, ratio=ratio),
            refine, n_fine, steps=steps, options=options, solver=solver)
    sol = solve_or_report(out, NAME, pb, {"params": v, "mesh": mesh_info}, series=steps > 1,
                          steps=steps, wrt=sensitivities, options=options, solver=solver, start=guide)
    warn_failed_levels(sol, coarse)
    t_solve = clock() - t0
    timing.mark("output")
    c = _lower(sol, sensitivities)
    up = _upper(sol)
    io.write_csv(out / "contact.csv", c)
    io.write_csv(out / "contact_upper.csv", up)
    io.write_vtu(sol, out / "cylinders.vtu")
    if steps > 1:
        write_series(sol, out / "cylinders.pvd")
    closed = c["p_N"] > 0
    b_fe = 0.5 * float(c["x"][closed].max() - c["x"][closed].min()) if closed.any() else 0.0
    p0_fe = float(c["p_N"].max())
    invalid = _validity(sol, b_fe, an["R"], pb)
    _figures(out, c, up, an, hv, friction, sensitivities)
    zone = None
    if friction:  # the stick half-width: both halves, interpolated (as the rigid frictional Hertz)
        halves = []
        for side in (1.0, -1.0):
            keep = side * c["x"] >= 0
            halves.append(stick_zone({"x_ref": (side * c["x"][keep])[:, None], "p_N": c["p_N"][keep],
                                      "p_T": c["p_T"][keep], "status": c["status"][keep]}, v["mu"]))
        zone = {"c": 0.5 * (halves[0]["c"] + halves[1]["c"]), "b": 0.5 * (halves[0]["a"] + halves[1]["a"]),
                "c_brackets": [z["c_bracket"] for z in halves]}
    ddm_fd = {}
    if fd_check:
        timing.mark("sensitivities")
        inside = np.abs(c["x"]) < 0.9 * an["b"]

        def both(s):  # the rows and signs of contact.csv, as the DDM's columns
            cc = _lower(s, [])
            return np.concatenate([cc["p_N"][inside], cc["p_T"][inside]])
        ddm_fd = {n: max_rel_diff(np.concatenate([c[f"dp_N_d{n}"][inside], c[f"dp_T_d{n}"][inside]]),
                                  finite_difference(pb, n, both, steps=steps, options=options,
                                                    rel_step=fd_step, solver=solver,
                                                    start=sol if guide is not None else None))
                  for n in sensitivities}
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "steps": steps,
        "coarse_start": coarse if coarse else (skipped or "no coarser mesh"),
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "p0": {"computed": p0_fe, "analytical": float(an["p0"]), "rel_error": p0_fe / an["p0"] - 1},
        "b": {"computed": b_fe, "analytical": float(an["b"]), "rel_error": b_fe / an["b"] - 1,
              "error_in_cells": (b_fe - an["b"]) / h,
              "note": "half the span of the closed nodes of the lower surface"},
        "c_over_b": ({"computed": zone["c"] / zone["b"], "analytical": float(an["c"] / an["b"]),
                      "rel_error": zone["c"] / zone["b"] / (an["c"] / an["b"]) - 1,
                      "c": zone["c"], "c_brackets": zone["c_brackets"]}
                     if friction else "frictionless"),
        "analytical_comparison": validity.comparison(invalid),
        **newton_log(sol),
        "ddm_vs_fd_rel_diff": ddm_fd if fd_check else "not computed (--no-fd)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


#: what to change when the contact outgrows the bodies or their fine zone, both sized by
#: the nominal values (there is no option for their size)
_SMALLER = "reduce the load (--set P=...) or stiffen the bodies (--set E1=... --set E2=...)"


def _validity(sol, b: float, R: float, pb) -> list[str]:
    """The validity warnings (:mod:`signorini.app.validity`) of the contact
    half-width ``b``: against the relative radius R = R1 R2 / (R1 + R2), the
    bodies' half-width and depth (each body's, from its contact face) and the
    fine zone."""
    X, sets = pb.mesh.nodes, pb.mesh.node_sets
    W = min(float(np.abs(X[sets[f], 0]).max()) for f in ("lower.top", "upper.bottom"))
    return validity.check(
        sol, b, [validity.half_space(W, "each body's half-width and depth",
                                     "reduce the load (--set P=...): the bodies are sized by the "
                                     "nominal radii", ", so the bodies are no longer half-spaces"),
                 validity.fine_zone(extents()[2], _SMALLER)],
        symbol="b", radius=R, radius_note=" (R = R1 R2/(R1 + R2))",
        radius_hint="reduce the load P or increase R1 and R2")


def _lower(sol, names) -> dict:
    """contact.csv: the slave (lower) surface's nodes sorted by x: x, y, p_N, p_T
    (the tangential traction on the lower body along +x), status, sensitivities."""
    c = sol.contact()
    order = np.argsort(c["x_ref"][:, 0])
    # the slave's tangent T0 runs along its edges (right to left on a top face):
    # the traction along +x is -p_T
    cols = {"x": c["x_ref"][order, 0], "y": c["x_ref"][order, 1], "p_N": c["p_N"][order],
            "p_T": -c["p_T"][order]}
    if "status" in c:
        cols["status"] = c["status"][order]
    for n in names:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"][order]
        cols[f"dp_T_d{n}"] = -c[f"dp_T_d{n}"][order]
    return cols


def _upper(sol) -> dict:
    """contact_upper.csv: the master (upper) surface's nodes sorted by x: the contact
    force on each node over its area (:func:`~signorini.app.runner.master_tractions`),
    as a pressure p_N and a traction p_T along +x."""
    f = master_tractions(sol)
    X, t = f["X"], f["t"]
    order = np.argsort(X[:, 0])
    return {"x": X[order, 0], "y": X[order, 1], "p_N": -np.sum(t * f["N"], axis=1)[order],
            "p_T": t[order, 0]}


def _figures(out, c, up, an, v, friction: bool, names) -> None:
    b = an["b"]
    xa = np.linspace(-1.5 * b, 1.5 * b, 600)
    plots.curves(out / "pressure.png", [
        {"x": xa, "y": pressure(xa, **v), "label": "Hertz"},
        {"x": c["x"], "y": c["p_N"], "label": "FE, lower surface (multipliers)", "style": "points"},
        {"x": up["x"], "y": up["p_N"], "label": "FE, upper surface (nodal forces / areas)",
         "style": "points"}],
        xlabel="x [mm]", ylabel="p_N [N/mm²]", title="Two cylinders: contact pressure",
        xlim=(-1.5 * b, 1.5 * b))
    if "R1" in names:
        R, R1 = an["R"], v["R1"]
        xi = xa / b
        inside = np.abs(xi) < 0.995
        s = np.sqrt(np.where(inside, 1 - xi**2, 1.0))
        dp = np.where(inside, an["p0"] / (2 * R) * (2 * xi**2 - 1) / s, 0.0) * (R / R1) ** 2
        plots.curves(out / "sensitivity.png", [
            {"x": xa[inside], "y": dp[inside], "label": "Hertz"},
            {"x": c["x"], "y": c["dp_N_dR1"], "label": "FE, DDM", "style": "points"}],
            xlabel="x [mm]", ylabel="Dp_N/DR1 [N/mm³]",
            title="Sensitivity of the pressure to the lower radius", xlim=(-1.5 * b, 1.5 * b))
    if friction:
        plots.curves(out / "traction.png", [
            {"x": xa, "y": shear(xa, **v), "label": "Mindlin"},
            {"x": c["x"], "y": c["p_T"], "label": "FE, lower surface", "style": "points"},
            {"x": xa, "y": v["mu"] * pressure(xa, **v), "label": "mu x Hertz pressure"}],
            xlabel="x [mm]", ylabel="q [N/mm²]", title="Two cylinders: tangential traction",
            xlim=(-1.5 * b, 1.5 * b))
