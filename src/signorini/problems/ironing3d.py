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

from ..contact import Coulomb
from ..contact.mortar import pair
from ..errors import InputError
from ..fem.loads import Fixed, Ramp
from ..fem.mesh import merge
from ..fem.mesh3d import Mesh3D, box
from ..linsolve import check_size
from ..materials import Bodies, NeoHooke
from ..model.kernels import Model
from ..model.problem import Problem
from .values import checked_values

DEFAULTS = {"E1": 100.0, "nu1": 0.3, "E2": 1000.0, "nu2": 0.3, "R": 1.0, "mu": 0.3, "d": 0.06,
            "s": 0.5}
#: the block's length and height, the die's half-width (along x), height and start
#: (those of the 2-D problem, but X0 moved by 0.03 so that the die's ends do not sit
#: exactly over block nodes at t = 0: a master-end switch), the block's half-width and
#: the die's half-length (along y)
L, H, A, D, X0, B, BD = 4.0, 1.0, 0.5, 0.5, 1.03, 0.25, 0.3125
#: bytes per (slave node x face pair x patch coordinate) of the finite-sliding pair's
#: tangent program (second derivatives of the face clips, all slave nodes at once):
#: the single buffers XLA asked for, 10.5 GB at 75,600 and 23.7 GB at 172,800 of them
#: (139 and 137 kB); and bytes besides (compilation, the solver), so that the default's
#: estimate (4.5 GB) covers its measured peaks, 3.2-4.5 GB (docs/benchmarks.md, Ironing in 3-D)
PAIR_BYTES, PAIR_BASE = Model.PAIR_TANGENT_BYTES, 3.0 * 1024.0**3
#: the part of the path over which the die is pressed in
T_PRESS = 0.2
#: the block's cells along its top; the others follow (:func:`cell_counts`)
CELLS = 24


def cell_counts(cells: int = CELLS, refine: int = 0) -> tuple[int, int, int, int, int, int]:
    """(block along x, across y, through z, die along its arc, across y, through z):
    the block's top ``cells`` x 2^refine cells along x, its half-width a twelfth of
    that (at least 2), its height an eighth; the die's arc a sixth (its cells 1.5
    times the block's: the block's top is the finer surface), as many cells across
    its (longer) half-length as the block (so they do not match), its height a
    quarter of the arc's (at least 2)."""
    if isinstance(cells, bool) or not isinstance(cells, (int, np.integer)) or cells < 24:
        raise InputError(f"ironing3d problem: cells (the block's cells along its top) must be an "
                         f"integer >= 24, got {cells!r}")
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or refine < 0:
        raise InputError(f"refine must be an integer >= 0, got {refine!r}")
    n = int(cells) * 2**int(refine)
    arc = max(n // 6, 4)
    across = max(n // 24, 1)
    return n, across, max(n // 8, 2), arc, across, max(arc // 4, 2)


#: the die's depth over the path, relative to d, and its travel along the block, relative to s
press, slide = Ramp(0.0, T_PRESS), Ramp(T_PRESS, 1.0)


def check_params(params: dict | None) -> dict:
    """The run's values: DEFAULTS updated by ``params`` (eps, eps_t allowed), checked."""
    values = checked_values("ironing3d problem", DEFAULTS, params, extra=("eps", "eps_t"),
                            positive=("E1", "E2", "R", "d"), nonnegative=("mu", "s"))
    values = {k: float(v) for k, v in values.items()}
    for k in ("nu1", "nu2"):
        if not -1.0 < values[k] < 0.5:
            raise InputError(f"ironing3d problem: Poisson's ratio {k} = {values[k]} must lie in "
                             "(-1, 0.5)")
    if not values["R"] > A * 1.05:
        raise InputError(f"ironing3d problem: the die's radius R = {values['R']} must exceed its "
                         f"half-width {A} (by 5 %): the arc spans the die's bottom")
    if not values["d"] < 0.3 * H:
        raise InputError(f"ironing3d problem: the depth d = {values['d']} must stay below 0.3 H = "
                         f"{0.3 * H} (the block's height is {H})")
    if X0 + values["s"] + A > L - 0.25:
        raise InputError(f"ironing3d problem: the slide s = {values['s']} takes the die off the "
                         f"block (its end reaches x = {X0 + values['s'] + A}, the block ends at "
                         f"{L}); keep s <= {L - 0.25 - X0 - A}")
    return values


def _die(R: float, nx: int, ny: int, nz: int):
    """(mesh, V = dX/dR) of the die: columns over [X0 - A, X0 + A], relative heights."""
    m = box(np.linspace(X0 - A, X0 + A, nx + 1), np.linspace(0.0, BD, ny + 1),
            np.linspace(0.0, 1.0, nz + 1))
    x, e = m.nodes[:, 0], m.nodes[:, 2]
    r = np.sqrt(R**2 - (x - X0) ** 2)
    z_arc = H + R - r
    dz_arc = 1.0 - R / r
    top = H + D
    z = z_arc + e * (top - z_arc)
    V = np.zeros_like(m.nodes)
    V[:, 2] = (1.0 - e) * dz_arc
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


def _sizes(refine: int, cells: int, s: float) -> tuple[int, int]:
    """(unknowns, size of the pair's kernels) of a mesh: the slave nodes x the
    faces around one x its candidates x its patch coordinates (every slave node
    carries every die face as a candidate)."""
    nbx, nby, nbz, ndx, ndy, ndz = cell_counts(cells, refine)
    h = L / nbx
    columns = int(np.floor((X0 + A + s) / h)) - int(np.ceil((X0 - A) / h)) + 3
    nc = min(columns, nbx + 1) * (nby + 1)
    n_dof = 3 * ((nbx + 1) * (nby + 1) * (nbz + 1) + (ndx + 1) * (ndy + 1) * (ndz + 1)) + 3 * nc
    faces_around = 4 if nby > 1 else 2
    patch = 3 * (min(nby + 1, 3) * 3 + (ndx + 1) * (ndy + 1))
    return n_dof, nc * faces_around * ndx * ndy * patch


def check_mesh_size(refine: int = 0, cells: int = CELLS, *, s: float = DEFAULTS["s"],
                    force: bool = False, solver="auto") -> None:
    """The size guard of the ironing3d meshes before they are built
    (:func:`signorini.linsolve.check_size`): the unknowns of both bodies and the
    pair's multipliers, and the finite-sliding pair's kernels (their tangents,
    second derivatives of the face clips), whose size is the slave nodes x the
    faces around one x its candidate die faces x its patch's coordinates: like
    the cells^6 (n_dof^2) as both bodies are refined. ``s``: the slide (the
    slave part of the block's top follows it; the nominal one if smaller)."""
    cell_counts(cells, refine)  # the options' checks
    # beyond 2^40 every count is refused: the counts of so many levels would be huge numbers
    n_dof, kernels = _sizes(min(int(refine), 40), cells, max(float(s), DEFAULTS["s"]))
    check_size(n_dof, force=force, what="the ironing3d problem", dim=3, solver=solver,
               extra=lambda n: PAIR_BASE + PAIR_BYTES * kernels * (n / n_dof) ** 2,
               hint="coarser meshes (smaller --refine or --cells)")


def ironing3d_problem(params: dict | None = None, *, refine: int = 0, cells: int = CELLS,
                      force_size: bool = False, solver="auto") -> Problem:
    """Build the 3-D ironing problem (values: :data:`DEFAULTS` updated by ``params``).

    Args:
        params: overrides of E1, nu1, E2, nu2, R, mu, d, s and eps, eps_t
            (default E1/h for both, h the block's cell size along its top).
        refine: each level halves the cells of both bodies.
        cells: the block's cells along its top (see :func:`cell_counts`).
        force_size: build the meshes even if they are estimated not to fit in
            memory with ``solver`` (the run's linear solver).
    """
    values = check_params(params)
    check_mesh_size(refine, cells, s=values["s"], force=force_size, solver=solver)
    nbx, nby, nbz, ndx, ndy, ndz = cell_counts(cells, refine)
    block = box(np.linspace(0.0, L, nbx + 1), np.linspace(0.0, B, nby + 1),
                np.linspace(0.0, H, nbz + 1))
    block = _with_symmetry_set(block, "z0")
    die, V = _die(values["R"], ndx, ndy, ndz)
    die = _with_symmetry_set(die, "z1")
    mesh = merge({"block": block, "die": die})
    shape = {"R": np.concatenate([np.zeros_like(block.nodes), V])}
    h = L / nbx
    for key in ("eps", "eps_t"):
        if key not in (params or {}):
            values[key] = DEFAULTS["E1"] / h
    method = Coulomb("mu", "eps", "eps_t")
    # the candidates cover the nominal slide and the run's (extra candidates
    # that never overlap contribute exactly nothing: the pairing does not
    # change the solution), with two block cells to spare
    reach = max(values["s"], DEFAULTS["s"]) + 2 * h
    block_top = slave_zone(mesh, max(values["s"], DEFAULTS["s"]))
    mesh = Mesh3D(mesh.nodes, mesh.cells, mesh.node_sets, {**mesh.face_sets, "block.path": block_top})
    contact = pair("block.path", "die.z0", method, "finite", slide=reach)
    fixed = (Fixed("block.z0", 0), Fixed("block.z0", 1), Fixed("block.z0", 2),
             Fixed("block.symmetry", 1), Fixed("die.symmetry", 1), Fixed("die.z1", 1),
             Fixed("die.z1", 0, "s", ramp=slide), Fixed("die.z1", 2, lambda p: -p["d"], ramp=press))
    return Problem(mesh=mesh,
                   material=Bodies({"block": NeoHooke("E1", "nu1"), "die": NeoHooke("E2", "nu2")}),
                   params=values, fixed=fixed, contact=(contact,),
                   shape=shape, shape_nominal={"R": values["R"]})


def die_force(solution, i: int = -1, names=()) -> dict:
    """The die force at increment i (on the half model): F_N (pressing), F_T
    (along the slide) and, for each name, their DDM sensitivities dF_N_d<name>,
    dF_T_d<name>."""
    top = solution.model.problem.mesh.node_sets["die.z1"]
    r = solution.reactions(i)[top].sum(axis=0)
    out = {"F_N": -float(r[2]), "F_T": float(r[0])}
    sens = solution.reaction_sensitivities(i) if names else {}
    for n in names:
        dr = sens[n][top].sum(axis=0)
        out[f"dF_N_d{n}"] = -float(dr[2])
        out[f"dF_T_d{n}"] = float(dr[0])
    return out
