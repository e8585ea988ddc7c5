"""``signorini hertz3d``: a rigid sphere pressed into an elastic block, in three
dimensions (quarter model of hexahedra) or, with ``--axisymmetric``, the same
problem in the axisymmetric model; frictionless against Hertz's solution, or
with Coulomb friction (``--set mu=0.3``) along a monotonic load path; DDM
sensitivities checked by central differences."""

from __future__ import annotations

import dataclasses

import numpy as np

from ... import timing
from .. import validity
from ...algorithms.coarse_to_fine import warn_failed_levels
from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...post import files as io, plots
from ...problems import hertz
from ...problems.hertz3d import DEFAULTS, analytical, hertz3d_problem, pressure, pressure_dR
from ...problems.hertz_friction import stick_zone
from ..options import (
    UNITS_3D, Formatter, adjoint_option, coarse_start_option, command_options, finish, fmt_fd,
    newton_options, parse_sets, path_options, positive_float, positive_int, print_adjoint,
    solver_options, with_defaults)
from ..runner import (
    Timer, adjoint_report, max_rel_diff, newton_log, prepare_output, solve_or_report, solver_entries,
    summary_header, use_solver, write_series, write_summary)

NAME = "hertz3d"
#: cells across the fine zone by default: the 3-D quarter model resolves the contact disc
#: with 8 (p0 within 0.03 % of Hertz); the axisymmetric model's contact is one line of
#: nodes, 6 closed with 8 cells (p0 3 % off Hertz, too few nodes), -0.9 % with 16, -0.55 %
#: with 24, -0.38 % with 32 (3,600 DOFs, solved in the same time as 8)
N_FINE, N_FINE_AXISYMMETRIC = 8, 32
#: Newton's default tolerance of this command (--rtol)
RTOL = 1e-10
#: the coarsest mesh of a coarse start has this many cells across the fine zone
COARSEST = 4
#: the increments of a frictional run (the path matters), and of a frictionless one
STEPS_FRICTION, STEPS = 10, 1

#: what --wrt may name
WRT = ("R", "E", "P", "mu", "nu")
HERTZ3D_SET = with_defaults({
    "E": "Young's modulus [N/mm²]", "nu": "Poisson's ratio", "P": "total force [N]",
    "R": "sphere radius [mm]", "mu": "Coulomb friction coefficient (0: frictionless)",
    "eps": "normal augmentation parameter [N/mm³], default E0/h (nominal E0, contact cell h)",
    "eps_t": "tangential augmentation parameter [N/mm³], default eps"}, DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    a0 = analytical(DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])["a"]
    p = sub.add_parser(
        NAME, formatter_class=Formatter,
        help="a rigid sphere on an elastic block in 3-D (or --axisymmetric), with or without friction",
        description="A rigid sphere (radius R) pressed with the force P into an elastic block, "
                    "quarter model of graded hexahedra held only by the contact; with --set mu=0.3 "
                    "Coulomb friction along a monotonic path of --steps increments. Writes "
                    "contact.csv (x, y, z, r, p_N, with friction the radial and circumferential "
                    "tractions and the stick/slip status, dp_N_d<name>), summary.json (p0 and a "
                    "against Hertz, c/a with friction, Newton log, DDM vs FD), pressure.png, "
                    "sensitivity.png (and traction.png with friction) and hertz3d.vtu. "
                    "--axisymmetric solves the same problem with the axisymmetric model and writes "
                    "the same files. " + UNITS_3D)
    command_options(p, HERTZ3D_SET, example="mu=0.3",
                    refine="halve every cell N times (each level: 8x the unknowns in 3-D)")
    p.add_argument("--n-fine", type=positive_int, default=None, metavar="N",
                   help=f"cells across the fine zone at --refine 0 (default {N_FINE}; "
                        f"{N_FINE_AXISYMMETRIC} with --axisymmetric, whose single line of contact "
                        "nodes needs more cells than the 3-D model's disc of them)")
    p.add_argument("--block", type=positive_float, default=12.0, metavar="B",
                   help=f"block width and depth in units of the nominal contact radius a0 "
                        f"(a0 = {a0:.4g} mm: Hertz's radius at the default parameters)")
    p.add_argument("--zone-width", type=positive_float, default=1.5, metavar="Z",
                   help="width of the uniformly fine mesh zone at the contact, in units of a0")
    p.add_argument("--axisymmetric", action="store_true",
                   help="solve the same sphere problem with the axisymmetric model")
    path_options(p, steps_help=f"equal load increments (default {STEPS} frictionless, "
                               f"{STEPS_FRICTION} with friction)")
    p.add_argument("--wrt", nargs="+", choices=WRT, metavar="NAME",
                   help="the parameters of the DDM sensitivities (and of the FD check and the "
                        "adjoint), among " + ", ".join(WRT) + " (default R E P, and mu with "
                        "friction); each costs one more solve per increment")
    adjoint_option(p, "the contact work W = sum A p_N (g0 - g)")
    coarse_start_option(p)
    solver_options(p)
    newton_options(p, RTOL)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    params = parse_sets(args.set, HERTZ3D_SET)
    s = run(args.out, params, refine=args.refine, n_fine=args.n_fine, steps=args.steps,
            axisymmetric=args.axisymmetric, fd_check=not args.no_fd, solver=args.solver,
            size=args.block, zone=args.zone_width, force_size=args.force_size,
            adjoint=args.adjoint, coarse_start=not args.no_coarse_start,
            sensitivities=list(dict.fromkeys(args.wrt)) if args.wrt else None,
            options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter))
    zone = f", c/a = {s['c_over_a']:.3f}" if isinstance(s.get("c_over_a"), float) else ""
    print(f"Hertz {s['model']} ({s['mesh']['dofs']} DOFs, {s['steps']} increment(s)): "
          f"p0 = {s['p0']['computed']:.5g} (Hertz {s['p0']['analytical']:.5g}, "
          f"{100 * s['p0']['rel_error']:+.2f} %), a = {s['a']['computed']:.4g} "
          f"(Hertz {s['a']['analytical']:.4g}){zone}{validity.note(s)}; Newton iterations "
          f"{sum(s['newton_iterations'])}; DDM vs FD (max rel. diff.): "
          f"{fmt_fd(s['ddm_vs_fd_rel_diff'])}; solver {s['solver']}")
    print_adjoint(s)
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, n_fine: int | None = None, steps=None,
        axisymmetric: bool = False, fd_check: bool = True, sensitivities=None, options=None,
        fd_step: float = 1e-5, solver="auto", size: float = 12.0, zone: float = 1.5,
        force_size: bool = False, adjoint: bool = False, coarse_start: bool = True) -> dict:
    """Solve the sphere-on-block problem with DDM sensitivities and write the results.

    Writes ``contact.csv``, ``summary.json``, ``pressure.png``, ``sensitivity.png``
    (with friction ``traction.png``), ``hertz3d.vtu`` (and ``hertz3d.pvd``, one
    VTU per increment, when ``steps > 1``) into ``out``; returns the summary.
    Sensitivities: R, E, P (and mu with friction). The FD check re-solves the
    whole path at phi +- h, h = ``fd_step`` max(|phi|, 1), on the same mesh
    (sized by the nominal values only), and compares p_N inside r < 0.9 a.
    ``coarse_start``: from 50,000 DOFs on, Newton starts from the solution of
    coarser meshes (n_fine halved, down to :data:`COARSEST`), interpolated; only
    the first iterate changes, not the result.
    """
    clock = Timer()
    if n_fine is None:
        n_fine = N_FINE_AXISYMMETRIC if axisymmetric else N_FINE
    out = prepare_output(out)
    options = options or NewtonOptions(rtol=RTOL)
    if not coarse_start:  # nor the algebraic coarse start of a mesh without coarser ones
        options = dataclasses.replace(options, start="rest")
    solver = use_solver(solver)
    pb = hertz3d_problem(params, refine=refine, n_fine=n_fine, size=size, zone=zone,
                         axisymmetric=axisymmetric, force_size=force_size, solver=solver)
    v = pb.params
    friction = v["mu"] > 0
    steps = steps or (STEPS_FRICTION if friction else STEPS)
    if sensitivities is None:
        sensitivities = ["R", "E", "P"] + (["mu"] if friction else [])
    an = analytical(v["P"], v["R"], v["E"], v["nu"])
    xs = np.unique(pb.mesh.nodes[:, 0])
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells,
                 "contact_cell_size": float(xs[1] - xs[0]), "block_over_a0": size,
                 "zone_over_a0": zone, "refine": refine, "n_fine": n_fine}
    t0 = clock()
    timing.mark("solve")
    guide, levels = None, []
    skipped = hertz.coarse_start_skipped(pb, coarse_start)
    if skipped is None:
        guide, levels = hertz.coarse_start_for(
            pb, lambda r, n: hertz3d_problem(params, refine=r, n_fine=n, size=size, zone=zone,
                                             axisymmetric=axisymmetric),
            refine, n_fine, steps=steps, options=options, solver=solver, coarsest=COARSEST)
    sol = solve_or_report(out, NAME, pb, {"params": v, "mesh": mesh_info}, series=steps > 1,
                          steps=steps, wrt=sensitivities, options=options, solver=solver, start=guide)
    warn_failed_levels(sol, levels)
    t_solve = clock() - t0
    c = _contact_columns(sol, axisymmetric)
    closed = c["p_N"] > 0
    a_fe = float(c["r"][closed].max()) if closed.any() else 0.0
    p0_fe = float(c["p_N"].max())
    a0 = analytical(DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])["a"]  # sizes the mesh
    invalid = _validity(sol, a_fe, v, pb, zone * a0)

    timing.mark("output")
    _figures(out, c, an, v, friction, sensitivities)
    io.write_csv(out / "contact.csv", {k: val for k, val in c.items() if k != "line"})
    io.write_vtu(sol, out / "hertz3d.vtu")
    if steps > 1:
        write_series(sol, out / "hertz3d.pvd")
    zone_info = stick_zone(c["line"], v["mu"]) if friction else None
    adj = None
    if adjoint:
        timing.mark("sensitivities")
        work = hertz.contact_work(sol.model)
        _, dW = sol.history_response(lambda w, p, t, s: work(w, p, t), key=("contact-work",))
        adj = adjoint_report(out, sol, hertz.contact_work, sensitivities,
                             "contact work W = sum A p_N (g0 - g) at P (hertz.contact_work)", solver,
                             {n: float(d) for n, d in dW.items()})
    ddm_fd = {}
    if fd_check:
        timing.mark("sensitivities")
        inner = c["r"] < 0.9 * an["a"]
        ddm_fd = {n: max_rel_diff(c[f"dp_N_d{n}"][inner], finite_difference(
            pb, n, lambda s: _contact_columns(s, axisymmetric)["p_N"][inner], steps=steps,
            options=options, rel_step=fd_step, solver=solver, start=sol))
            for n in sensitivities}
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "model": "axisymmetric" if axisymmetric else "3-D quarter model",
        "steps": steps,
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "p0": {"computed": p0_fe, "analytical": an["p0"], "rel_error": p0_fe / an["p0"] - 1},
        "a": {"computed": a_fe, "analytical": an["a"], "rel_error": a_fe / an["a"] - 1,
              "error_in_cells": (a_fe - an["a"]) / mesh_info["contact_cell_size"]},
        "coarse_start": levels if levels else (
            {"algebraic": sol.coarse_start} if sol.coarse_start else (skipped or "no coarser mesh")),
        "c_over_a": zone_info["c_over_a"] if friction else "frictionless",
        "c_over_a_bracket": zone_info["c_over_a_bracket"] if friction else "frictionless",
        "analytical_comparison": validity.comparison(invalid),
        **newton_log(sol),
        "ddm_vs_fd_rel_diff": ddm_fd if fd_check else "not computed (--no-fd)",
        "adjoint": adj if adjoint else "not computed (use --adjoint)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


def _validity(sol, a: float, v: dict, pb, zone_width: float) -> list[str]:
    """The validity warnings (:mod:`signorini.app.validity`) of the contact radius
    ``a``: against R, the block (its width and depth, the same in both models) and
    the fine zone (``zone_width``: its lateral extent)."""
    X = pb.mesh.nodes
    W = min(float(X[:, 0].max()), float(-X[:, -1].min()))
    return validity.check(sol, a, [validity.half_space(W, "the block width and depth"),
                                   validity.fine_zone(zone_width)],
                          label="contact radius", radius=v["R"])


def _contact_columns(sol, axisymmetric: bool) -> dict:
    """contact.csv's columns: x, y, z, r, p_N, with friction p_r (radial traction on
    the body), p_theta (circumferential) and status, dp_N_d<name>; ``line``: the
    nodes along the x axis as a 1-D contact dict (for the stick zone)."""
    c = sol.contact()
    x = c["x_ref"]
    if axisymmetric:
        X = np.column_stack([x[:, 0], np.zeros(len(x)), x[:, 1]])
    else:
        X = x
    r = np.hypot(X[:, 0], X[:, 1])
    cols = {"x": X[:, 0], "y": X[:, 1], "z": X[:, 2], "r": r, "p_N": c["p_N"]}
    friction = "status" in c
    if friction:
        if axisymmetric:  # p_T along the circle's tangent, which points to +r at its bottom
            p_r, p_t = c["p_T"] + 0.0, np.zeros(len(r))
        else:
            pt = c["p_T"][:, :1] * c["t1"] + c["p_T"][:, 1:] * c["t2"]
            safe = np.where(r > 0, r, 1.0)
            e_r = np.column_stack([X[:, 0] / safe, X[:, 1] / safe, np.zeros(len(r))])
            e_t = np.column_stack([-X[:, 1] / safe, X[:, 0] / safe, np.zeros(len(r))])
            p_r = np.where(r > 0, np.sum(pt * e_r, axis=1), 0.0)
            p_t = np.where(r > 0, np.sum(pt * e_t, axis=1), 0.0)
        cols.update({"p_r": p_r, "p_theta": p_t, "status": c["status"]})
    for k in c:
        if k.startswith("dp_N_d"):
            cols[k] = c[k]
    on = np.abs(X[:, 1]) < 1e-12 * max(float(r.max()), 1.0)
    cols["line"] = {"x_ref": X[on][:, :1], "p_N": c["p_N"][on],
                    "p_T": cols["p_r"][on] if friction else np.zeros(int(on.sum())),
                    "status": c["status"][on] if friction else np.full(int(on.sum()), "slip")}
    return cols


def _figures(out, c, an, v, friction: bool, sensitivities) -> None:
    """pressure.png and sensitivity.png (DDM against Hertz's dp/dR); with friction
    traction.png (the radial and circumferential tractions)."""
    a = an["a"]
    ra = np.linspace(0, 1.5 * a, 400)
    plots.curves(out / "pressure.png", [
        {"x": ra, "y": pressure(ra, v["P"], v["R"], v["E"], v["nu"]), "label": "Hertz"},
        {"x": c["r"], "y": c["p_N"], "label": "FE" + (f", mu = {v['mu']:g}" if friction else ""),
         "style": "points"}],
        xlabel="r [mm]", ylabel="p_N [N/mm²]", title="Sphere on a block: contact pressure",
        xlim=(0, 1.5 * a))
    if "R" in sensitivities:
        rs = np.linspace(0, 0.995 * a, 400)
        plots.curves(out / "sensitivity.png", [
            {"x": np.concatenate([rs, [a, 1.5 * a]]),
             "y": np.concatenate([pressure_dR(rs, v["P"], v["R"], v["E"], v["nu"]), [0, 0]]),
             "label": "Hertz"},
            {"x": c["r"], "y": c["dp_N_dR"], "label": "FE, DDM", "style": "points"}],
            xlabel="r [mm]", ylabel="Dp_N/DR [N/mm³]",
            title="Sensitivity of the pressure to the sphere radius", xlim=(0, 1.5 * a))
    if friction:
        plots.curves(out / "traction.png", [
            {"x": c["r"], "y": c["p_r"], "label": "radial p_r", "style": "points"},
            {"x": c["r"], "y": c["p_theta"], "label": "circumferential p_theta", "style": "points"},
            {"x": ra, "y": v["mu"] * pressure(ra, v["P"], v["R"], v["E"], v["nu"]),
             "label": "mu x Hertz pressure"}],
            xlabel="r [mm]", ylabel="traction [N/mm²]",
            title="Sphere on a block: friction tractions", xlim=(0, 1.5 * a))
