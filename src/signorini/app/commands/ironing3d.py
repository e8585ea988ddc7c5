"""``signorini ironing3d``: a deformable half-cylinder die pressed into a block
and slid along it with friction at finite strain, in 3-D (two-body contact of
hexahedral surfaces with finite sliding); the die force along the path with its
DDM sensitivities, checked by central differences of the whole path, and the
partner changes and switch points of the path. The 3-D counterpart of
``signorini ironing`` (same options, same outputs)."""

from __future__ import annotations

import numpy as np

from ... import timing
from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...errors import InputError
from ...post import files as io
from ...post import plots
from ...problems.ironing3d import (
    CELLS,
    DEFAULTS,
    T_PRESS,
    die_force,
    ironing3d_problem,
    press,
    slide,
)
from ...sensitivity import nonsmooth
from .. import validity
from ..options import (
    UNITS,
    Formatter,
    command_options,
    finish,
    fmt_fd,
    newton_options,
    parse_sets,
    path_options,
    positive_int,
    solver_options,
    with_defaults,
)
from ..runner import (
    Timer,
    max_rel_diff,
    newton_log,
    prepare_output,
    solve_or_report,
    solver_entries,
    summary_header,
    use_solver,
    write_summary,
)

NAME = "ironing3d"
RTOL = 1e-10
STEPS = 10
SENSITIVITIES = ("mu", "E1", "E2", "R", "d", "s")
#: the parameters whose DDM the FD check compares by default: friction alone, for a
#: default run of a few minutes (each costs two re-solves of the path, ~90 s each on
#: two cores at the default mesh); --fd-names chooses others
FD_NAMES = ("mu",)

IRONING3D_SET = with_defaults({
    "E1": "Young's modulus of the block [N/mm²]", "nu1": "Poisson's ratio of the block",
    "E2": "Young's modulus of the die [N/mm²]", "nu2": "Poisson's ratio of the die",
    "R": "radius of the die's half-cylinder [mm]", "mu": "Coulomb friction coefficient",
    "d": "depth the die is pressed to [mm]", "s": "distance the die slides [mm]",
    "eps": "normal augmentation parameter, default E1/h", "eps_t": "tangential, default E1/h"},
    DEFAULTS)


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    p = sub.add_parser(
        NAME, formatter_class=Formatter,
        help="a deformable half-cylinder die pressed into a block and slid along it, in 3-D",
        description="Ironing in 3-D at finite strain: a stiff neo-Hookean die whose bottom is a "
                    "half-cylinder (radius R, its axis across the block) is pressed into a "
                    f"neo-Hookean block to the depth d over the first {T_PRESS:g} of the path, "
                    "then slid along it by s with Coulomb friction mu; half model (symmetry plane "
                    "y = 0, the block's side free, the die longer than the block is wide), "
                    "hexahedra, a 3-D mortar contact pair with finite kinematics (the block's "
                    "top under the die's path the slave). Forces on the half model. "
                    "Writes force.csv (per increment: depth, slide, die "
                    "force F_N and F_T, their DDM sensitivities and, unless --no-fd, central "
                    "differences of the whole path), contact.csv (the block's top at the end), "
                    "summary.json (forces, DDM vs FD, partner changes and switch points of the "
                    "path, Newton log), force.png, sensitivity.png and an ironing3d.pvd series "
                    "(one VTU per body and increment). " + UNITS)
    # the die's mesh follows R (a shape parameter): no fixed-mesh note
    command_options(p, IRONING3D_SET, example="mu=0.2", fixed_mesh=False,
                    refine="halve every cell of both bodies N times")
    p.add_argument("--cells", type=positive_int, default=CELLS, metavar="N",
                   help="the block's cells along its top (at least 24); its height gets N/8, its "
                        "half-width N/24 (at least 1), the die's arc N/6 (cells 1.5 times the "
                        "block's), its height a quarter of that, its half-length as many as "
                        "the block's half-width")
    p.add_argument("--fd-names", default=",".join(FD_NAMES), metavar="N1,N2",
                   help="the parameters whose DDM sensitivities the FD check compares (any of "
                        + ", ".join(SENSITIVITIES) + "; the DDM of all of them is always written)")
    path_options(p, steps=STEPS, fd="two re-solves of the path per parameter",
                 steps_help=f"load increments over the whole path (the first {T_PRESS:g} of them press)")
    solver_options(p)
    newton_options(p, RTOL)


def execute(args) -> int:
    params = parse_sets(args.set, IRONING3D_SET)
    fd_names = fd_names_option(args.fd_names)
    s = run(args.out, params, refine=args.refine, cells=args.cells, steps=args.steps, fd_check=not args.no_fd,
            fd_names=fd_names,
            solver=args.solver, options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter),
            force_size=args.force_size)
    print(f"Ironing in 3-D ({s['mesh']['dofs']} DOFs, {s['steps']} increments): die force at the end "
          f"F_N = {s['force_final']['F_N']:.5g}, F_T = {s['force_final']['F_T']:.5g} "
          f"(F_T/F_N over the slide {s['force_ratio_sliding']['mean']:.4f}, mu = {s['params']['mu']:g}); "
          f"partner changes in {len(s['partner_changes'])} increments; Newton iterations "
          f"{sum(s['newton_iterations'])}; DDM vs FD of the forces along the path (max rel. "
          f"diff.): {fmt_fd(s['ddm_vs_fd_rel_diff'])}; solver {s['solver']}")
    return finish(args, s)


def fd_names_option(text: str) -> tuple[str, ...]:
    """The names of --fd-names (comma-separated, each one of SENSITIVITIES)."""
    names = tuple(n.strip() for n in str(text).split(",") if n.strip())
    bad = [n for n in names if n not in SENSITIVITIES]
    if not names or bad:
        raise InputError(f"--fd-names: {', '.join(bad) or 'no name'}: name one or more of "
                         f"{', '.join(SENSITIVITIES)}, separated by commas")
    return names


def _forces(sol, names=()) -> dict:
    """The die force at every increment (columns of force.csv)."""
    rows = [die_force(sol, i, names) for i in range(len(sol.increments))]
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


@timing.recorded
def run(out, params: dict | None = None, *, refine: int = 0, cells: int = CELLS, steps: int = STEPS,
        fd_check: bool = True, sensitivities=None, fd_names=FD_NAMES, options=None,
        fd_step: float = 1e-5, solver="auto", force_size: bool = False) -> dict:
    """Solve the ironing problem with DDM sensitivities of the die force along the
    path and write the results into ``out``; returns the summary. The FD check
    re-solves the whole path at phi +- h (h = ``fd_step`` max(|phi|, 1)) for each
    of ``fd_names`` that is among the sensitivities and compares F_N and F_T at
    every increment. ``force_size``: run even if the
    meshes are estimated not to fit in memory."""
    clock = Timer()
    out = prepare_output(out)
    options = options or NewtonOptions(rtol=RTOL)
    solver = use_solver(solver)
    pb = ironing3d_problem(params, refine=refine, cells=cells, force_size=force_size, solver=solver)
    v = pb.params
    names = list(SENSITIVITIES if sensitivities is None else sensitivities)
    top = np.unique(pb.mesh.face_sets["block.path"])
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "refine": refine,
                 "block_cells_along_top": cells * 2**refine,
                 "slave_nodes": int(top.size),
                 "block_contact_cell_size": _spacing(pb.mesh.nodes[top, 0]),
                 "die_contact_cell_size": _spacing(pb.mesh.nodes[np.unique(
                     pb.mesh.face_sets["die.z0"]), 0])}
    t0 = clock()
    timing.mark("solve")
    sol = solve_or_report(out, NAME, pb, {"params": v, "mesh": mesh_info}, steps=steps, wrt=names,
                          options=options, solver=solver)
    t_solve = clock() - t0
    timing.mark("sensitivities")
    F = _forces(sol, names)
    t = np.array([inc.t for inc in sol.increments])
    cols = {"increment": np.arange(1, len(t) + 1), "t": t, "depth": v["d"] * np.asarray(press(t)),
            "slide": v["s"] * np.asarray(slide(t)), **F}
    ddm_fd = {}
    if fd_check:
        def both(s):
            f = _forces(s)
            return np.concatenate([f["F_N"], f["F_T"]])
        for n in [n for n in fd_names if n in names]:
            fd = finite_difference(pb, n, both, steps=steps, options=options, rel_step=fd_step,
                                   solver=solver)
            cols[f"FD_dF_N_d{n}"], cols[f"FD_dF_T_d{n}"] = fd[: len(t)], fd[len(t):]
            ddm_fd[n] = max(max_rel_diff(F[f"dF_N_d{n}"], cols[f"FD_dF_N_d{n}"]),
                            max_rel_diff(F[f"dF_T_d{n}"], cols[f"FD_dF_T_d{n}"]))
    timing.mark("output")
    io.write_csv(out / "force.csv", cols)
    io.write_csv(out / "contact.csv", _block_top(sol))
    io.write_pvd(sol, out / "ironing3d.pvd")
    _figures(out, cols, names, v)
    sliding = t > T_PRESS + 0.25 * (1.0 - T_PRESS)  # past the start of the slide
    ratio = F["F_T"][sliding] / F["F_N"][sliding] if sliding.any() else np.array([np.nan])
    changes = nonsmooth.partner_changes(sol)
    _validity(sol, mesh_info["block_contact_cell_size"])
    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "steps": steps,
        **solver_entries(solver, sol),
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "force_final": {"F_N": float(F["F_N"][-1]), "F_T": float(F["F_T"][-1])},
        "force_max": {"F_N": float(F["F_N"].max()), "F_T": float(F["F_T"].max())},
        "force_ratio_sliding": {"mean": float(np.mean(ratio)), "min": float(np.min(ratio)),
                                "max": float(np.max(ratio)),
                                "note": "F_T / F_N over the last three quarters of the slide"},
        "partner_change_count": int(sum(len(n) for r in changes for n in r["nodes"])),
        **newton_log(sol),
        "ddm_vs_fd_rel_diff": ddm_fd if fd_check else "not computed (--no-fd)",
        "ddm_vs_fd_note": "max over the path of |DDM - FD| / max|DDM| for F_N and F_T",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    return write_summary(out, summary, sol)


def _spacing(x) -> float:
    """The smallest spacing of distinct coordinates ``x``."""
    x = np.unique(np.round(np.asarray(x), 12))
    return float(np.min(np.diff(x)))


def _validity(sol, h: float) -> list[str]:
    """The validity warnings (:mod:`signorini.app.validity`) of the contact zone at
    the end, measured from the die's centre: it must stay a block cell ``h``
    inside the die's rounded face (beyond, the die's corners press into the
    block) and inside the slave part of the block's top (the problem sizes it by
    the slide, so this one only guards it); too few closed nodes. There is no
    analytical solution to compare with."""
    x = sol.current()[:, 0]
    faces = sol.model.problem.mesh.face_sets
    die, top = x[np.unique(faces["die.z0"])], x[np.unique(faces["block.path"])]
    centre = 0.5 * (die.min() + die.max())
    c = sol.contact()
    closed = c["x"][c["p_N"] > 0, 0]
    if not closed.size:
        return validity.check(sol, 0.0)
    a = float(max(closed.max() - centre, centre - closed.min()))
    return validity.check(sol, a, [
        validity.edge(0.5 * float(die.max() - die.min()), h, "the die's rounded face",
                      ", so the die's corners press into the block (a pressure singular there "
                      "and mesh-dependent)", "press less deep (--set d=...)"),
        validity.edge(float(min(centre - top.min(), top.max() - centre)), h,
                      "the slave part of the block's top (under the die's path)",
                      ", so the die presses where no contact is sought", "slide less far (--set s=...)")],
        label="contact half-width about the die's centre")


def _block_top(sol) -> dict:
    """contact.csv: the block's top under the die's path (the slave surface) at the
    end, sorted by y then x: x, y, z (current), p_N, p_x, p_y (the tangential
    traction on the block along +x, +y: that of the contact force, less its
    normal part), status, sensitivities of p_N."""
    c = sol.contact()
    order = np.lexsort((c["x"][:, 0], np.round(c["x_ref"][:, 1], 9)))
    n = c["normal"]
    tan = c["traction"] - np.sum(c["traction"] * n, axis=1)[:, None] * n
    cols = {"x": c["x"][order, 0], "y": c["x"][order, 1], "z": c["x"][order, 2],
            "p_N": c["p_N"][order], "p_x": tan[order, 0], "p_y": tan[order, 1],
            "status": c["status"][order]}
    for n in sol.names:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"][order]
    return cols


def _figures(out, cols, names, v) -> None:
    x = cols["slide"]
    plots.curves(out / "force.png", [
        {"x": x, "y": cols["F_N"], "label": "F_N (pressing)"},
        {"x": x, "y": cols["F_T"], "label": "F_T (along the slide)"},
        {"x": x, "y": v["mu"] * cols["F_N"], "label": "mu F_N"}],
        xlabel="slide [mm] (0 while pressing)", ylabel="die force [N]",
        title="Ironing in 3-D: die force along the path (half model)")
    series = []
    for n in names:
        scale = abs(v[n]) or 1.0
        series.append({"x": x, "y": scale * cols[f"dF_T_d{n}"], "label": f"{n} dF_T/d{n}, DDM"})
        if f"FD_dF_T_d{n}" in cols:
            series.append({"x": x, "y": scale * cols[f"FD_dF_T_d{n}"], "label": f"FD ({n})",
                           "style": "points"})
    plots.curves(out / "sensitivity.png", series, xlabel="slide [mm] (0 while pressing)",
                 ylabel="phi dF_T/dphi [N]",
                 title="Sensitivity of the tangential die force along the path")
