"""Ironing in 3-D: a deformable half-cylinder die pressed into a block and slid
along it with friction and finite sliding, at finite strain: the 3-D
finite-sliding example of two-body contact (docs/theory.md §13.12, docs/cli.md);
the 3-D counterpart of :mod:`signorini.problems.ironing`.

The block (neo-Hooke E1, nu1) is the box [0, L] x [-B, B] x [0, H], its bottom
clamped; by symmetry the model is its half y >= 0 (the plane y = 0 held along
y for both bodies), whose side y = B is free. The die (neo-Hooke E2, nu2,
stiffer) is a half-cylinder of radius R whose axis runs across the block
(along y): a block [X0 - A, X0 + A] x [0, BD] x [H, H + D] whose bottom is the
cylinder's arc in the x-z plane, touching the block's top along the line x =
X0 at t = 0. It is longer than the block is wide (BD > B), so the block's top
stays under the die across its whole width (a roller wider than the block: no
end of the die's surface crosses the block). Its top is moved rigidly: down by
d over the first part of the path (t <= T_PRESS), then along the block by s at
that depth. The block's top (the finer and softer surface) is the slave of a
3-D mortar pair with finite kinematics whose candidate partners cover the whole
slide (``slide``): the block's nodes under the die's path change master faces
as the die passes; those partner changes are reported per increment, and the
weighted gap and slip are continuously differentiable across them, which the
finite differences along the path confirm.

The die force is the force of its support on the die, on the half model: F_N
= -sum of the vertical reactions (pressing), F_T = sum of those along x
(pulling).

The die's arc is a shape parameter: a node at column x and relative height e
(0 on the arc, 1 on the top) lies at z = z_arc(x; R) + e (z_top - z_arc), so
its design velocity is exact; the grid lines never depend on a run's values.
"""

from __future__ import annotations

import numpy as np

from ..fem.loads import Fixed
from ..fem.mesh import merge
from ..fem.mesh3d import Mesh3D, box
from ..linsolve import check_size
from ..model.kernels import Model
from ..model.problem import Problem
from . import ironing
from .ironing import (
    T_PRESS,  # noqa: F401  (the path of both problems: the command reads it here)
    A,
    H,
    L,
    checked_cells,
    checked_params,
    press,
    slide,
)

DEFAULTS = {**ironing.DEFAULTS, "s": 0.5}
#: the die's start, the block's half-width and the die's half-length (along y); the
#: block's length L and height H, the die's half-width A (along x) and height D are
#: the 2-D problem's, X0 moved by 0.03 so that the die's ends do not sit exactly over
#: block nodes at t = 0 (a master-end switch)
X0, B, BD = 1.03, 0.25, 0.3125
#: the size guard's pair terms. The finite-sliding pair's tangent takes about 140 kB
#: per (slave node x face pair x patch coordinate) and evaluates its slave nodes in
#: batches of at most 1 GiB, at least one node (Model.PAIR_TANGENT_BYTES,
#: PAIR_BATCH_BYTES); what is not batched (the pair's residual, first derivatives of
#: the face clips, and the sensitivities, over all the slave nodes at once) takes
#: PAIR_REST per such unit of all the slave nodes; PAIR_BASE besides (compilation, the
#: other programs). Fitted to the peaks of `signorini ironing3d`: 3.76 GiB at --cells 32
#: (a batch of 1.06 GB, 15k units) and 5.59 GiB at --refine 1 (one node of 0.97 GB a
#: batch, 415k units; the peak after the path, with the sensitivities); the estimates
#: (4.48, 6.36 GiB; the default's 4.44 against 3.36 measured) exceed them by 14-32 %
#: (docs/benchmarks.md, Ironing in 3-D)
PAIR_BYTES, PAIR_BATCH = Model.PAIR_TANGENT_BYTES, Model.PAIR_BATCH_BYTES
PAIR_REST, PAIR_BASE = 5.0e3, 3.0 * 1024.0**3
#: the block's cells along its top; the others follow (:func:`cell_counts`)
CELLS = 24


def cell_counts(cells: int = CELLS, refine: int = 0) -> tuple[int, int, int, int, int, int]:
    """(block along x, across y, through z, die along its arc, across y, through z):
    the block's top ``cells`` x 2^refine cells along x, its half-width a twelfth of
    that (at least 2), its height an eighth; the die's arc a sixth (its cells 1.5
    times the block's: the block's top is the finer surface), as many cells across
    its (longer) half-length as the block (so they do not match), its height a
    quarter of the arc's (at least 2)."""
    n = checked_cells("ironing3d problem", cells, refine)
    arc = max(n // 6, 4)
    across = max(n // 24, 1)
    return n, across, max(n // 8, 2), arc, across, max(arc // 4, 2)


def check_params(params: dict | None) -> dict:
    """The run's values: DEFAULTS updated by ``params`` (eps, eps_t allowed), checked."""
    return checked_params("ironing3d problem", DEFAULTS, params, X0, poisson=True)


def _die(R: float, nx: int, ny: int, nz: int):
    """(mesh, V = dX/dR) of the die: columns over [X0 - A, X0 + A], relative heights."""
    m = box(np.linspace(X0 - A, X0 + A, nx + 1), np.linspace(0.0, BD, ny + 1),
            np.linspace(0.0, 1.0, nz + 1))
    z, dz = ironing.die_heights(m.nodes[:, 0], m.nodes[:, 2], R, X0)
    V = np.zeros_like(m.nodes)
    V[:, 2] = dz
    return Mesh3D(np.column_stack([m.nodes[:, :2], z]), m.cells, m.node_sets, m.face_sets), V


def _with_symmetry_set(m: Mesh3D, held: str) -> Mesh3D:
    """``m`` with the node set ``symmetry``: its nodes on the plane y = 0 but not in
    the node set ``held`` (held along y there already: each DOF is prescribed once)."""
    sym = np.setdiff1d(m.node_sets["y0"], m.node_sets[held])
    return Mesh3D(m.nodes, m.cells, {**m.node_sets, "symmetry": sym}, m.face_sets)


def slave_zone(mesh: Mesh3D, s: float) -> np.ndarray:
    """The faces of the block's top under the die's path: those whose x range meets
    [X0 - A, X0 + A + s] (the die's bottom never reaches beyond its half-width A
    about its centre). Only they are the pair's slave surface: the finite-sliding
    pair's kernels grow with its nodes."""
    top = mesh.face_sets["block.z1"]
    x = mesh.nodes[top, 0]
    tol = 1e-9 * L
    return top[(x.max(axis=1) > X0 - A + tol) & (x.min(axis=1) < X0 + A + s - tol)]


def _sizes(refine: int, cells: int, s: float) -> tuple[int, int, int]:
    """(unknowns, slave nodes, size of one slave node's tangent) of a mesh: the faces
    around a node x its candidates x its patch coordinates (every slave node
    carries every die face as a candidate)."""
    nbx, nby, nbz, ndx, ndy, ndz = cell_counts(cells, refine)
    h = L / nbx
    columns = int(np.floor((X0 + A + s) / h)) - int(np.ceil((X0 - A) / h)) + 3
    nc = min(columns, nbx + 1) * (nby + 1)
    n_dof = 3 * ((nbx + 1) * (nby + 1) * (nbz + 1) + (ndx + 1) * (ndy + 1) * (ndz + 1)) + 3 * nc
    faces_around = 4 if nby > 1 else 2
    patch = 3 * (min(nby + 1, 3) * 3 + (ndx + 1) * (ndy + 1))
    return n_dof, nc, faces_around * ndx * ndy * patch


def pair_bytes(nodes: float, node_units: float) -> float:
    """The memory of the finite-sliding pair's programs with ``nodes`` slave nodes of
    ``node_units`` (face pairs x patch coordinates) each: a batch of its tangent
    (Model._pair_batch: all the nodes if they take less than PAIR_BATCH, else about
    PAIR_BATCH, at least one node; an upper bound of the model's whole number of nodes
    per batch) and the programs over all the nodes at once."""
    node = PAIR_BYTES * node_units
    return max(min(nodes * node, PAIR_BATCH), node) + PAIR_REST * nodes * node_units


def check_mesh_size(refine: int = 0, cells: int = CELLS, *, s: float = DEFAULTS["s"],
                    force: bool = False, solver="auto") -> None:
    """The size guard of the ironing3d meshes before they are built
    (:func:`signorini.linsolve.check_size`): the unknowns of both bodies and the
    pair's multipliers, and the finite-sliding pair's programs (:func:`pair_bytes`):
    a slave node's tangent (second derivatives of the face clips) takes the faces
    around it x its candidate die faces x its patch's coordinates, like the
    cells^4 (n_dof^(4/3)) as both bodies are refined, and the slave nodes grow
    like the cells^2. ``s``: the slide (the slave part of the block's top follows
    it; the nominal one if smaller)."""
    cell_counts(cells, refine)  # the options' checks
    # beyond 2^40 every count is refused: the counts of so many levels would be huge numbers
    n_dof, nc, per_node = _sizes(min(int(refine), 40), cells, max(float(s), DEFAULTS["s"]))

    def extra(n):
        g = n / n_dof
        return PAIR_BASE + pair_bytes(nc * g ** (2 / 3), per_node * g ** (4 / 3))

    check_size(n_dof, force=force, what="the ironing3d problem", dim=3, solver=solver, extra=extra,
               hint="coarser meshes (smaller --refine or --cells)")


def ironing3d_problem(params: dict | None = None, *, refine: int = 0, cells: int = CELLS,
                      force_size: bool = False, solver="auto") -> Problem:
    """Build the 3-D ironing problem (values: :data:`DEFAULTS` updated by ``params``;
    the arguments of :func:`signorini.problems.ironing.ironing_problem`, ``cells``
    as in :func:`cell_counts`)."""
    values = check_params(params)
    check_mesh_size(refine, cells, s=values["s"], force=force_size, solver=solver)
    nbx, nby, nbz, ndx, ndy, ndz = cell_counts(cells, refine)
    block = box(np.linspace(0.0, L, nbx + 1), np.linspace(0.0, B, nby + 1),
                np.linspace(0.0, H, nbz + 1))
    block = _with_symmetry_set(block, "z0")
    die, V = _die(values["R"], ndx, ndy, ndz)
    die = _with_symmetry_set(die, "z1")
    mesh = merge({"block": block, "die": die})
    h = L / nbx
    block_top = slave_zone(mesh, max(values["s"], DEFAULTS["s"]))
    mesh = Mesh3D(mesh.nodes, mesh.cells, mesh.node_sets, {**mesh.face_sets, "block.path": block_top})
    fixed = (Fixed("block.z0", 0), Fixed("block.z0", 1), Fixed("block.z0", 2),
             Fixed("block.symmetry", 1), Fixed("die.symmetry", 1), Fixed("die.z1", 1),
             Fixed("die.z1", 0, "s", ramp=slide), Fixed("die.z1", 2, lambda p: -p["d"], ramp=press))
    return ironing.finite_problem(mesh, len(block.nodes), V, values, params, h,
                                  ("block.path", "die.z0"), fixed, DEFAULTS["s"])


def die_force(solution, i: int = -1, names=()) -> dict:
    """The die force at increment i (on the half model): F_N (pressing), F_T
    (along the slide) and, for each name, their DDM sensitivities dF_N_d<name>,
    dF_T_d<name>."""
    return ironing.support_force(solution, "die.z1", 2, i, names)
