"""``signorini ironing``: a deformable die pressed into a block and slid along
it with friction at finite strain (two-body contact with finite sliding); the
die force along the path with its DDM sensitivities, checked by central
differences of the whole path, and the partner changes and switch points of
the path.

The command is :class:`Ironing`, a class whose attributes name the problem
module and what differs in 3-D: ``signorini ironing3d``
(:mod:`signorini.app.commands.ironing3d`) is its subclass, with the same run,
options and outputs."""

from __future__ import annotations

import numpy as np

from ... import timing
from ...algorithms.newton import NewtonOptions
from ...design.finite_differences import finite_difference
from ...errors import InputError
from ...post import files as io, plots
from ...problems import ironing as ironing2d
from ...sensitivity import nonsmooth
from .. import validity
from ..options import (
    UNITS, Formatter, command_options, finish, fmt_fd, newton_options, parse_sets,
    path_options, positive_int, solver_options, with_defaults)
from ..runner import (
    Timer, max_rel_diff, newton_log, prepare_output, solve_or_report, solver_entries, summary_header,
    use_solver, write_series, write_summary)

RTOL = 1e-10
SENSITIVITIES = ("mu", "E1", "E2", "R", "d", "s")


def ironing_set(die: str, defaults: dict) -> dict:
    """The ``--set`` names of both ironing commands with their help (``die``: what
    the die's radius R is the radius of) and defaults."""
    return with_defaults({
        "E1": "Young's modulus of the block [N/mm²]", "nu1": "Poisson's ratio of the block",
        "E2": "Young's modulus of the die [N/mm²]", "nu2": "Poisson's ratio of the die",
        "R": f"radius of the {die} [mm]", "mu": "Coulomb friction coefficient",
        "d": "depth the die is pressed to [mm]", "s": "distance the die slides [mm]",
        "eps": "normal augmentation parameter, default E1/h", "eps_t": "tangential, default E1/h"},
        defaults)


IRONING_SET = ironing_set("die's arc", ironing2d.DEFAULTS)


def fd_names_option(text: str) -> tuple[str, ...]:
    """The names of --fd-names (comma-separated, each one of SENSITIVITIES)."""
    names = tuple(n.strip() for n in str(text).split(",") if n.strip())
    bad = [n for n in names if n not in SENSITIVITIES]
    if not names or bad:
        raise InputError(f"--fd-names: {', '.join(bad) or 'no name'}: name one or more of "
                         f"{', '.join(SENSITIVITIES)}, separated by commas")
    return names


def _nodes(mesh, name: str) -> np.ndarray:
    """The nodes of the node set ``name`` or, if there is none, of the face set."""
    return mesh.node_sets[name] if name in mesh.node_sets else np.unique(mesh.face_sets[name])


def _spacing(x) -> float:
    """The smallest spacing of the distinct coordinates ``x`` (equal to 1e-9 of
    their range: one)."""
    d = np.diff(np.sort(np.asarray(x)))
    return float(np.min(d[d > 1e-9 * np.ptp(x)]))


class Ironing:
    """``signorini ironing``: its problem (:mod:`signorini.problems.ironing`), parser,
    run and outputs. The class attributes are what the 3-D command changes."""

    NAME = "ironing"
    problem = ironing2d
    build = staticmethod(ironing2d.ironing_problem)
    STEPS = 50
    SET = IRONING_SET
    #: the parameters the FD check compares by default, and the option --fd-names to
    #: choose them; None: all the sensitivities, no option
    FD_NAMES: tuple[str, ...] | None = None
    #: the slave surface and the die's bottom (node sets, else face sets); whether
    #: summary.json's mesh counts the slave nodes
    SLAVE, DIE_BOTTOM, COUNT_SLAVE_NODES = "block.top", "die.bottom", False
    #: the run's name in what it prints and in its force figure, the force's unit
    TITLE, FORCE_TITLE, FORCE_UNIT = "Ironing", "Ironing: die force along the path", "N/mm"
    #: the validity check's name of the slave surface's reach, and what lies beyond it
    TOP_EDGE = ("the block's top", ", so the die presses on the block's corner")
    HELP = "a deformable die pressed into a block and slid along it (finite sliding, friction)"
    DESCRIPTION = (
        "Ironing in plane strain at finite strain: a stiff neo-Hookean die with a "
        "rounded bottom (radius R) is pressed into a neo-Hookean block to the depth d "
        f"over the first {ironing2d.T_PRESS:g} of the path, then slid along it by s with "
        "Coulomb friction mu; a mortar contact pair with finite kinematics (the "
        "block's top the slave). Writes force.csv (per increment: depth, slide, die "
        "force F_N and F_T, their DDM sensitivities and, unless --no-fd, central "
        "differences of the whole path), contact.csv (the block's top at the end), "
        "summary.json (forces, DDM vs FD, partner changes and switch points of the "
        "path, Newton log), force.png, sensitivity.png and an ironing.pvd series. " + UNITS)
    CELLS_HELP = ("the block's cells along its top (at least 24); its height gets N/8, the "
                  "die's arc N/6 (cells 1.5 times the block's), its height a quarter of that")

    def add_parser(self, sub) -> None:
        """Add this command's sub-parser to ``sub``."""
        p = sub.add_parser(self.NAME, formatter_class=Formatter, help=self.HELP,
                           description=self.DESCRIPTION)
        # the die's mesh follows R (a shape parameter): no fixed-mesh note
        command_options(p, self.SET, example="mu=0.2", fixed_mesh=False,
                        refine="halve every cell of both bodies N times")
        p.add_argument("--cells", type=positive_int, default=self.problem.CELLS, metavar="N",
                       help=self.CELLS_HELP)
        if self.FD_NAMES is not None:
            p.add_argument("--fd-names", default=",".join(self.FD_NAMES), metavar="N1,N2",
                           help="the parameters whose DDM sensitivities the FD check compares (any "
                                "of " + ", ".join(SENSITIVITIES) + "; the DDM of all of them is "
                                "always written)")
        path_options(p, steps=self.STEPS, fd="two re-solves of the path per parameter",
                     steps_help=f"load increments over the whole path (the first "
                                f"{self.problem.T_PRESS:g} of them press)")
        solver_options(p)
        newton_options(p, RTOL)

    def execute(self, args) -> int:
        params = parse_sets(args.set, self.SET)
        fd = {} if self.FD_NAMES is None else {"fd_names": fd_names_option(args.fd_names)}
        s = self.run(args.out, params, refine=args.refine, cells=args.cells, steps=args.steps,
                     fd_check=not args.no_fd, solver=args.solver,
                     options=NewtonOptions(rtol=args.rtol, max_iter=args.max_iter),
                     force_size=args.force_size, **fd)
        print(f"{self.TITLE} ({s['mesh']['dofs']} DOFs, {s['steps']} increments): die force at the "
              f"end F_N = {s['force_final']['F_N']:.5g}, F_T = {s['force_final']['F_T']:.5g} "
              f"(F_T/F_N over the slide {s['force_ratio_sliding']['mean']:.4f}, mu = "
              f"{s['params']['mu']:g}); partner changes in {len(s['partner_changes'])} increments; "
              f"Newton iterations {sum(s['newton_iterations'])}; DDM vs FD of the forces along the "
              f"path (max rel. diff.): {fmt_fd(s['ddm_vs_fd_rel_diff'])}; solver {s['solver']}")
        return finish(args, s)

    def forces(self, sol, names=()) -> dict:
        """The die force at every increment (columns of force.csv)."""
        rows = [self.problem.die_force(sol, i, names) for i in range(len(sol.increments))]
        return {k: np.array([r[k] for r in rows]) for k in rows[0]}

    @timing.recorded
    def run(self, out, params: dict | None = None, *, refine: int = 0, cells: int | None = None,
            steps: int | None = None, fd_check: bool = True, sensitivities=None, fd_names=None,
            options=None, fd_step: float = 1e-5, solver="auto", force_size: bool = False) -> dict:
        """Solve the ironing problem with DDM sensitivities of the die force along the
        path and write the results into ``out``; returns the summary. ``cells``,
        ``steps``: default the problem's CELLS and the command's STEPS. The FD check
        re-solves the whole path at phi +- h (h = ``fd_step`` max(|phi|, 1)) for each
        of ``fd_names`` (default FD_NAMES, else all) that is among the sensitivities
        and compares F_N and F_T at every increment. ``force_size``: run even if the
        meshes are estimated not to fit in memory."""
        clock = Timer()
        cells = self.problem.CELLS if cells is None else cells
        steps = self.STEPS if steps is None else steps
        out = prepare_output(out)
        options = options or NewtonOptions(rtol=RTOL)
        solver = use_solver(solver)
        pb = self.build(params, refine=refine, cells=cells, force_size=force_size, solver=solver)
        v = pb.params
        names = list(SENSITIVITIES if sensitivities is None else sensitivities)
        fd_names = (self.FD_NAMES or names) if fd_names is None else fd_names
        slave = _nodes(pb.mesh, self.SLAVE)
        mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "refine": refine,
                     "block_cells_along_top": cells * 2**refine,
                     **({"slave_nodes": int(slave.size)} if self.COUNT_SLAVE_NODES else {}),
                     "block_contact_cell_size": _spacing(pb.mesh.nodes[slave, 0]),
                     "die_contact_cell_size": _spacing(pb.mesh.nodes[_nodes(pb.mesh, self.DIE_BOTTOM), 0])}
        t0 = clock()
        timing.mark("solve")
        sol = solve_or_report(out, self.NAME, pb, {"params": v, "mesh": mesh_info}, steps=steps,
                              wrt=names, options=options, solver=solver)
        t_solve = clock() - t0
        timing.mark("sensitivities")
        F = self.forces(sol, names)
        t = np.array([inc.t for inc in sol.increments])
        cols = {"increment": np.arange(1, len(t) + 1), "t": t,
                "depth": v["d"] * np.asarray(self.problem.press(t)),
                "slide": v["s"] * np.asarray(self.problem.slide(t)), **F}
        ddm_fd = {}
        if fd_check:
            def both(s):
                f = self.forces(s)
                return np.concatenate([f["F_N"], f["F_T"]])
            for n in [n for n in fd_names if n in names]:
                fd = finite_difference(pb, n, both, steps=steps, options=options, rel_step=fd_step,
                                       solver=solver)
                cols[f"FD_dF_N_d{n}"], cols[f"FD_dF_T_d{n}"] = fd[: len(t)], fd[len(t):]
                ddm_fd[n] = max(max_rel_diff(F[f"dF_N_d{n}"], cols[f"FD_dF_N_d{n}"]),
                                max_rel_diff(F[f"dF_T_d{n}"], cols[f"FD_dF_T_d{n}"]))
        timing.mark("output")
        io.write_csv(out / "force.csv", cols)
        io.write_csv(out / "contact.csv", self.contact_columns(sol))
        write_series(sol, out / f"{self.NAME}.pvd")
        self.figures(out, cols, names, v)
        t_press = self.problem.T_PRESS
        sliding = t > t_press + 0.25 * (1.0 - t_press)  # past the start of the slide
        ratio = F["F_T"][sliding] / F["F_N"][sliding] if sliding.any() else np.array([np.nan])
        changes = nonsmooth.partner_changes(sol)
        self.validity(sol, mesh_info["block_contact_cell_size"])
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

    def validity(self, sol, h: float) -> list[str]:
        """The validity warnings (:mod:`signorini.app.validity`) of the contact zone at
        the end, measured from the die's centre: it must stay a block cell ``h``
        inside the die's rounded face (beyond, the die's corners press into the
        block) and inside the slave surface (the problem's own checks keep the die
        over it, so this one only guards them); too few closed nodes. There is no
        analytical solution to compare with."""
        x = sol.current()[:, 0]
        mesh = sol.model.problem.mesh
        die, top = x[_nodes(mesh, self.DIE_BOTTOM)], x[_nodes(mesh, self.SLAVE)]
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
            validity.edge(float(min(centre - top.min(), top.max() - centre)), h, *self.TOP_EDGE,
                          "slide less far (--set s=...)")],
            label="contact half-width about the die's centre")

    def contact_columns(self, sol) -> dict:
        """contact.csv: the block's top (the slave surface) at the end, sorted by x: x
        (current), p_N, p_T (the traction on the block along +x), status, sensitivities."""
        c = sol.contact()
        order = np.argsort(c["x"][:, 0])
        cols = {"x": c["x"][order, 0], "y": c["x"][order, 1], "p_N": c["p_N"][order],
                "p_T": -c["p_T"][order], "status": c["status"][order]}
        for n in sol.names:
            cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"][order]
        return cols

    def figures(self, out, cols, names, v) -> None:
        """force.png (F_N, F_T and mu F_N along the slide) and sensitivity.png (phi
        dF_T/dphi, the DDM's lines and the FD's points)."""
        x = cols["slide"]
        plots.curves(out / "force.png", [
            {"x": x, "y": cols["F_N"], "label": "F_N (pressing)"},
            {"x": x, "y": cols["F_T"], "label": "F_T (along the slide)"},
            {"x": x, "y": v["mu"] * cols["F_N"], "label": "mu F_N"}],
            xlabel="slide [mm] (0 while pressing)", ylabel=f"die force [{self.FORCE_UNIT}]",
            title=self.FORCE_TITLE)
        series = []
        for n in names:
            scale = abs(v[n]) or 1.0
            series.append({"x": x, "y": scale * cols[f"dF_T_d{n}"], "label": f"{n} dF_T/d{n}, DDM"})
            if f"FD_dF_T_d{n}" in cols:
                series.append({"x": x, "y": scale * cols[f"FD_dF_T_d{n}"], "label": f"FD ({n})",
                               "style": "points"})
        plots.curves(out / "sensitivity.png", series, xlabel="slide [mm] (0 while pressing)",
                     ylabel=f"phi dF_T/dphi [{self.FORCE_UNIT}]",
                     title="Sensitivity of the tangential die force along the path")


COMMAND = Ironing()
NAME, STEPS = COMMAND.NAME, COMMAND.STEPS
add_parser, execute, run = COMMAND.add_parser, COMMAND.execute, COMMAND.run
