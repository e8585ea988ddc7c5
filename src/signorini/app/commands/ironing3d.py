"""``signorini ironing3d``: a deformable half-cylinder die pressed into a block
and slid along it with friction at finite strain, in 3-D (two-body contact of
hexahedral surfaces with finite sliding); the die force along the path with its
DDM sensitivities, checked by central differences of the whole path, and the
partner changes and switch points of the path. The 3-D counterpart of
``signorini ironing`` (same options and outputs, plus --fd-names): its command
class with the 3-D problem, texts and contact.csv."""

from __future__ import annotations

import numpy as np

from ...problems import ironing3d as problem
from ..options import UNITS_SOLID
from .ironing import RTOL, SENSITIVITIES, Ironing, fd_names_option, ironing_set  # noqa: F401

IRONING3D_SET = ironing_set("die's half-cylinder", problem.DEFAULTS)


class Ironing3D(Ironing):
    """``signorini ironing3d``: :class:`~signorini.app.commands.ironing.Ironing` on
    :mod:`signorini.problems.ironing3d` (the half model)."""

    NAME = "ironing3d"
    problem = problem
    build = staticmethod(problem.ironing3d_problem)
    STEPS = 10
    SET = IRONING3D_SET
    #: friction alone, for a default run of a few minutes (each costs two re-solves of
    #: the path, ~90 s each on two cores at the default mesh); --fd-names chooses others
    FD_NAMES = ("mu",)
    SLAVE, DIE_BOTTOM, COUNT_SLAVE_NODES = "block.path", "die.z0", True
    TITLE = "Ironing in 3-D"
    FORCE_TITLE, FORCE_UNIT = "Ironing in 3-D: die force along the path (half model)", "N"
    TOP_EDGE = ("the slave part of the block's top (under the die's path)",
                ", so the die presses where no contact is sought")
    HELP = "a deformable half-cylinder die pressed into a block and slid along it, in 3-D"
    DESCRIPTION = (
        "Ironing in 3-D at finite strain: a stiff neo-Hookean die whose bottom is a "
        "half-cylinder (radius R, its axis across the block) is pressed into a "
        f"neo-Hookean block to the depth d over the first {problem.T_PRESS:g} of the path, "
        "then slid along it by s with Coulomb friction mu; half model (symmetry plane "
        "y = 0, the block's side free, the die longer than the block is wide), "
        "hexahedra, a 3-D mortar contact pair with finite kinematics (the block's "
        "top under the die's path the slave). Forces on the half model. "
        "Writes force.csv (per increment: depth, slide, die "
        "force F_N and F_T, their DDM sensitivities and, unless --no-fd, central "
        "differences of the whole path), contact.csv (the block's top at the end), "
        "summary.json (forces, DDM vs FD, partner changes and switch points of the "
        "path, Newton log), force.png, sensitivity.png and an ironing3d.pvd series "
        "(one VTU per body and increment). " + UNITS_SOLID)
    CELLS_HELP = ("the block's cells along its top (at least 24); its height gets N/8, its "
                  "half-width N/24 (at least 1), the die's arc N/6 (cells 1.5 times the "
                  "block's), its height a quarter of that, its half-length as many as "
                  "the block's half-width")

    def contact_columns(self, sol) -> dict:
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


COMMAND = Ironing3D()
NAME, STEPS, FD_NAMES = COMMAND.NAME, COMMAND.STEPS, COMMAND.FD_NAMES
add_parser, execute, run = COMMAND.add_parser, COMMAND.execute, COMMAND.run
