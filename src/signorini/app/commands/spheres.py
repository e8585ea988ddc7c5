"""``signorini spheres``: two elastic spheres pressed together (Hertz) and, with
friction, sheared by a tangential force (Cattaneo–Mindlin): the 3-D two-body
contact example (a mortar pair between non-matching hexahedral meshes); DDM
sensitivities to the shape and the modulus of either body, the loads and mu,
checked by central differences."""

from __future__ import annotations

import numpy as np

from ... import timing
from ...errors import InputError
from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...post import files as io
from ...post import plots
from ...problems.hertz3d import pressure_dR
from ...problems.hertz_friction import stick_zone
from ...problems.spheres import (
    DEFAULTS,
    analytical,
    extents,
    pressure,
    shear,
    spheres_problem,
)
from .. import validity
from ..options import (
    UNITS_SOLID,
    Formatter,
    command_options,
    finish,
    fmt_fd,
    newton_options,
    parse_sets,
    path_options,
    positive_float,
    positive_int,
    solver_options,
    with_defaults,
)
from ..runner import (
    Timer,
    master_tractions,
    max_rel_diff,
    newton_log,
    prepare_output,
    solve_or_report,
    solver_entries,
    summary_header,
    use_solver,
    write_series,
    write_summary,
)

NAME = "spheres"
RTOL = 1e-10
#: the lower body's cells across the fine zone (1.5 a0 from the axis)
N_FINE = 8
#: increments with friction (P over the first half, Q over the second), and without
STEPS_FRICTION, STEPS = 10, 1
#: what --wrt may name (mu and Q with friction only)
WRT = ("R1", "R2", "E1", "E2", "P", "mu", "Q")

SPHERES_SET = with_defaults({
    "R1": "radius of the lower sphere [mm]", "R2": "radius of the upper sphere [mm]",
    "E1": "Young's modulus of the lower sphere [N/mm²]", "E2": "of the upper [N/mm²]",
    "nu1": "Poisson's ratio of the lower sphere", "nu2": "of the upper",
    "P": "normal force [N]",
    "mu": "Coulomb friction coefficient (0: frictionless)",
    "Q": "tangential force along x after P [N], below mu P",
    "eps": "normal augmentation parameter, default E0/h", "eps_t": "tangential, default E0/h"},
    DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    p = sub.add_parser(
        NAME, formatter_class=Formatter,
        help="two elastic spheres in contact in 3-D (Hertz; with friction and Q, Cattaneo-Mindlin)",
        description="Two elastic spheres (R1 below, R2 above) pressed together by the force P, "
                    "hexahedral meshes that do not match joined by a 3-D mortar contact pair "
                    "(quarter model; with friction the half model); with --set mu=0.3 --set "
                    "Q=0.015 a tangential force Q < mu P follows P (Cattaneo-Mindlin's partial "
                    "slip). Writes contact.csv (the lower, slave surface: x, y, z, r, p_N, with "
                    "friction the tangential traction p_x, p_y on the lower body and the "
                    "stick/slip status, dp_N_d<name>), contact_upper.csv (the upper surface's "
                    "pressure from its contact forces), summary.json (a and p0 against Hertz, "
                    "c/a against Cattaneo-Mindlin, Newton log, DDM vs FD), pressure.png, "
                    "sensitivity.png, traction.png (with friction) and spheres.vtu. " + UNITS_SOLID)
    command_options(p, SPHERES_SET, example="mu=0.3", fixed_mesh=False)
    p.add_argument("--n-fine", type=positive_int, default=N_FINE, metavar="N",
                   help="the lower body's cells across the fine zone (1.5 a0 from the axis)")
    p.add_argument("--ratio", type=positive_float, default=2 / 3, metavar="F",
                   help="the upper body's cell count at the interface relative to the lower's")
    path_options(p, steps_help=f"load increments (default {STEPS} frictionless, {STEPS_FRICTION} "
                               "with friction)")
    p.add_argument("--wrt", nargs="+", choices=WRT, metavar="NAME",
                   help="the parameters of the DDM sensitivities (and of the FD check), among "
                        + ", ".join(WRT) + " (default R1 R2 E1 P, and mu Q with friction); each "
                        "costs one more solve per increment")
    solver_options(p)
    newton_options(p, RTOL)


def execute(args) -> int:
    params = parse_sets(args.set, SPHERES_SET)
    s = run(args.out, params, refine=args.refine, n_fine=args.n_fine, ratio=args.ratio,
            steps=args.steps, fd_check=not args.no_fd, solver=args.solver,
            sensitivities=list(dict.fromkeys(args.wrt)) if args.wrt else None,
            options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter), force_size=args.force_size)
    zone = (f", c/a = {s['c_over_a']['computed']:.3f} (Cattaneo-Mindlin "
            f"{s['c_over_a']['analytical']:.3f})" if isinstance(s.get("c_over_a"), dict) else "")
    print(f"Two spheres ({s['mesh']['dofs']} DOFs, {s['steps']} increment(s)): "
          f"p0 = {s['p0']['computed']:.5g} (Hertz {s['p0']['analytical']:.5g}, "
          f"{100 * s['p0']['rel_error']:+.2f} %), a = {s['a']['computed']:.4g} "
          f"(Hertz {s['a']['analytical']:.4g}){zone}{validity.note(s)}; Newton iterations "
          f"{sum(s['newton_iterations'])}; DDM vs FD (max rel. diff.): "
          f"{fmt_fd(s['ddm_vs_fd_rel_diff'])}; solver {s['solver']}")
    return finish(args, s)


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, n_fine: int = N_FINE,
        ratio: float = 2 / 3, steps=None, fd_check: bool = True, sensitivities=None, options=None,
        fd_step: float = 1e-5, solver="auto", force_size: bool = False) -> dict:
    """Solve the two-sphere problem with DDM sensitivities and write the results
    into ``out``; returns the summary. Sensitivities: R1, R2, E1, P (and mu, Q
    with friction). The FD check re-solves the whole path at phi +- h (h =
    ``fd_step`` max(|phi|, 1)) and compares p_N (and with friction the tangential
    tractions) at the lower surface's nodes inside r < 0.9 a.
    ``force_size``: run even if the meshes are estimated not to fit in memory."""
    clock = Timer()
    out = prepare_output(out)
    options = options or NewtonOptions(rtol=RTOL)
    solver = use_solver(solver)
    pb = spheres_problem(params, refine=refine, n_fine=n_fine, ratio=ratio, force_size=force_size,
                         solver=solver)
    v = pb.params
    friction = v["mu"] > 0
    steps = steps or (STEPS_FRICTION if friction else STEPS)
    if sensitivities is None:
        sensitivities = ["R1", "R2", "E1", "P"] + (["mu", "Q"] if friction else [])
    elif not friction and {"mu", "Q"} & set(sensitivities):
        raise InputError("spheres: sensitivities to mu and Q need friction (--set mu=0.3 --set "
                         "Q=0.015); without it the path has no tangential force")
    hv = {k: v[k] for k in ("P", "R1", "R2", "E1", "E2", "nu1", "nu2", "mu", "Q")}
    an = analytical(**hv)
    X, sets = pb.mesh.nodes, pb.mesh.node_sets
    ys = np.unique(X[sets["lower.z1"], 1])
    h = float(ys[1] - ys[0])
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "contact_cell_size": h,
                 "upper_contact_cell_size": float(np.diff(np.unique(X[sets["upper.z0"], 1]))[0]),
                 "model": "half (y >= 0)" if friction else "quarter (x, y >= 0)",
                 "refine": refine, "n_fine": n_fine, "ratio": ratio}
    t0 = clock()
    timing.mark("solve")
    sol = solve_or_report(out, NAME, pb, {"params": v, "mesh": mesh_info}, series=steps > 1,
                          steps=steps, wrt=sensitivities, options=options, solver=solver)
    t_solve = clock() - t0
    timing.mark("output")
    c = _lower(sol, sensitivities)
    up = _upper(sol)
    io.write_csv(out / "contact.csv", {k: val for k, val in c.items() if k != "line"})
    io.write_csv(out / "contact_upper.csv", up)
    io.write_vtu(sol, out / "spheres.vtu")
    if steps > 1:
        write_series(sol, out / "spheres.pvd")
    closed = c["p_N"] > 0
    a_fe = float(c["r"][closed].max()) if closed.any() else 0.0
    p0_fe = float(c["p_N"].max())
    invalid = _validity(sol, a_fe, an["R"], pb)
    _figures(out, c, up, an, hv, friction, sensitivities)
    zone = None
    if friction:  # the stick radius along the line y = 0, on both sides, interpolated
        halves = []
        for side in (1.0, -1.0):
            line = c["line"]
            keep = side * line["x"] >= 0
            halves.append(stick_zone({"x_ref": (side * line["x"][keep])[:, None],
                                      "p_N": line["p_N"][keep], "p_T": line["p_x"][keep],
                                      "status": line["status"][keep]}, v["mu"]))
        zone = {"c": 0.5 * (halves[0]["c"] + halves[1]["c"]), "a": 0.5 * (halves[0]["a"] + halves[1]["a"]),
                "c_brackets": [z["c_bracket"] for z in halves]}
    ddm_fd = {}
    if fd_check:
        timing.mark("sensitivities")
        inside = c["r"] < 0.9 * an["a"]

        def columns(s, cc=None):
            cc = _lower(s, []) if cc is None else cc
            parts = [cc["p_N"][inside]]
            if friction:
                parts += [cc["p_x"][inside], cc["p_y"][inside]]
            return np.concatenate(parts)

        def ddm(n):
            parts = [c[f"dp_N_d{n}"][inside]]
            if friction:
                parts += [c[f"dp_x_d{n}"][inside], c[f"dp_y_d{n}"][inside]]
            return np.concatenate(parts)
        ddm_fd = {n: max_rel_diff(ddm(n), finite_difference(pb, n, columns, steps=steps, options=options,
                                                            rel_step=fd_step, solver=solver, start=sol))
                  for n in sensitivities}
    timing.mark("output")
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "steps": steps,
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "p0": {"computed": p0_fe, "analytical": float(an["p0"]), "rel_error": p0_fe / an["p0"] - 1},
        "a": {"computed": a_fe, "analytical": float(an["a"]), "rel_error": a_fe / an["a"] - 1,
              "error_in_cells": (a_fe - an["a"]) / h,
              "note": "the largest radius of a closed node of the lower surface"},
        "c_over_a": ({"computed": zone["c"] / zone["a"], "analytical": float(an["c"] / an["a"]),
                      "rel_error": zone["c"] / zone["a"] / (an["c"] / an["a"]) - 1,
                      "c": zone["c"], "c_brackets": zone["c_brackets"],
                      "note": "along y = 0, both sides averaged, interpolated between nodes"}
                     if friction else "frictionless"),
        "analytical_comparison": validity.comparison(invalid),
        **newton_log(sol),
        "ddm_vs_fd_rel_diff": ddm_fd if fd_check else "not computed (--no-fd)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


_SMALLER = "reduce the load (--set P=...) or stiffen the bodies (--set E1=... --set E2=...)"


def _validity(sol, a: float, R: float, pb) -> list[str]:
    """The validity warnings (:mod:`signorini.app.validity`) of the contact radius
    ``a``: against the relative radius R = R1 R2 / (R1 + R2), the bodies' size and
    the fine zone."""
    X, sets = pb.mesh.nodes, pb.mesh.node_sets
    W = min(float(X[sets[f], 1].max()) for f in ("lower.z1", "upper.z0"))
    return validity.check(
        sol, a, [validity.half_space(W, "each body's half-width and depth",
                                     "reduce the load (--set P=...): the bodies are sized by the "
                                     "nominal radii", ", so the bodies are no longer half-spaces"),
                 validity.fine_zone(extents()[2], _SMALLER)],
        label="contact radius", radius=R, radius_note=" (R = R1 R2/(R1 + R2))",
        radius_hint="reduce the load P or increase R1 and R2")


def _lower(sol, names) -> dict:
    """contact.csv: the slave (lower) surface's nodes: x, y, z, r, p_N; with friction
    the tangential traction on the lower body (p_x, p_y) and the status;
    dp_N_d<name> (and dp_x_d<name>, dp_y_d<name>); ``line``: the nodes on y = 0."""
    c = sol.contact()
    X = c["x_ref"]
    r = np.hypot(X[:, 0], X[:, 1])
    cols = {"x": X[:, 0], "y": X[:, 1], "z": X[:, 2], "r": r, "p_N": c["p_N"]}
    friction = "status" in c

    def along(pt):  # (nc, 2) in the basis (t1, t2) -> the x and y components
        vec = pt[:, :1] * c["t1"] + pt[:, 1:] * c["t2"]
        return vec[:, 0], vec[:, 1]
    if friction:
        cols["p_x"], cols["p_y"] = along(c["p_T"])
        cols["status"] = c["status"]
    for n in names:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
        if friction:
            cols[f"dp_x_d{n}"], cols[f"dp_y_d{n}"] = along(c[f"dp_T_d{n}"])
    on = np.abs(X[:, 1]) <= 1e-12 * max(float(r.max()), 1.0)
    cols["line"] = {k: val[on] for k, val in cols.items()}
    return cols


def _upper(sol) -> dict:
    """contact_upper.csv: the master (upper) surface's nodes: x, y, z, r and the
    pressure p_N from the contact force on each node over its area
    (:func:`~signorini.app.runner.master_tractions`)."""
    f = master_tractions(sol)
    X = f["X"]
    return {"x": X[:, 0], "y": X[:, 1], "z": X[:, 2], "r": np.hypot(X[:, 0], X[:, 1]),
            "p_N": -np.sum(f["t"] * f["N"], axis=1)}


def _figures(out, c, up, an, v, friction: bool, names) -> None:
    a = an["a"]
    ra = np.linspace(0, 1.5 * a, 400)
    plots.curves(out / "pressure.png", [
        {"x": ra, "y": pressure(ra, **v), "label": "Hertz"},
        {"x": c["r"], "y": c["p_N"], "label": "FE, lower surface (multipliers)", "style": "points"},
        {"x": up["r"], "y": up["p_N"], "label": "FE, upper surface (nodal forces / areas)",
         "style": "points"}],
        xlabel="r [mm]", ylabel="p_N [N/mm²]", title="Two spheres: contact pressure", xlim=(0, 1.5 * a))
    if "R1" in names:
        rs = np.linspace(0, 0.995 * a, 400)
        scale = (an["R"] / v["R1"]) ** 2  # dR/dR1
        dp = pressure_dR(rs, v["P"], an["R"], an["E_star"], 0.0) * scale
        plots.curves(out / "sensitivity.png", [
            {"x": np.concatenate([rs, [a, 1.5 * a]]), "y": np.concatenate([dp, [0, 0]]), "label": "Hertz"},
            {"x": c["r"], "y": c["dp_N_dR1"], "label": "FE, DDM", "style": "points"}],
            xlabel="r [mm]", ylabel="Dp_N/DR1 [N/mm³]",
            title="Sensitivity of the pressure to the lower radius", xlim=(0, 1.5 * a))
    if friction:
        line = c["line"]
        xa = np.linspace(-1.5 * a, 1.5 * a, 600)
        plots.curves(out / "traction.png", [
            {"x": xa, "y": shear(xa, **v), "label": "Cattaneo-Mindlin"},
            {"x": line["x"], "y": np.abs(line["p_x"]), "label": "FE, lower surface, y = 0", "style": "points"},
            {"x": xa, "y": v["mu"] * pressure(np.abs(xa), **v), "label": "mu x Hertz pressure"}],
            xlabel="x [mm]", ylabel="q [N/mm²]", title="Two spheres: tangential traction",
            xlim=(-1.5 * a, 1.5 * a))
