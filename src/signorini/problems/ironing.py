"""Ironing: a deformable die pressed into a block and slid along it with
friction, in plane strain at finite strain: the finite-sliding example of
two-body contact (docs/theory.md §13, docs/cli.md).

The block (neo-Hooke E1, nu1) is the rectangle [0, L] x [0, H], its bottom
clamped. The die (neo-Hooke E2, nu2, stiffer) is a block of half-width A and
height D whose bottom is the circular arc of radius R touching the block's top
at (X0, H) at t = 0; its top is moved rigidly: down by d over the first part of
the path (t <= T_PRESS), then along the block by s at that depth. The block's
top (the finer and softer surface) is the slave of a mortar pair with finite
kinematics whose candidate partners cover the whole slide (``slide``), so every
block node under the die's path changes master (die) segments as the die's
nodes pass over it: those partner changes
are reported per increment (summary.json ``partner_changes``), and the weighted
gap and slip are continuously differentiable across them, which the finite
differences along the path confirm.

The die force is the force of its support on the die: F_N = -sum of the
vertical reactions (pressing), F_T = sum of the horizontal ones (pulling),
both per unit thickness.

The die's arc is a shape parameter: a node at column x and relative height e
(0 on the arc, 1 on the top) lies at y = y_arc(x; R) + e (y_top - y_arc), so
its design velocity is exact; the grid lines never depend on a run's values.
"""

from __future__ import annotations

import numpy as np

from ..contact import Coulomb
from ..contact.mortar import pair
from ..errors import InputError
from ..fem.loads import Fixed, Ramp
from ..fem.mesh import Mesh, merge, rectangle
from ..linsolve import check_size
from ..materials import Bodies, NeoHooke
from ..model.problem import Problem
from .values import checked_values

DEFAULTS = {"E1": 100.0, "nu1": 0.3, "E2": 1000.0, "nu2": 0.3, "R": 1.0, "mu": 0.3, "d": 0.06,
            "s": 1.5}
#: the block's length and height, the die's half-width, height and start
L, H, A, D, X0 = 4.0, 1.0, 0.5, 0.5, 1.0
#: bytes per (slave node x candidate segment x patch coordinate) of the finite-sliding
#: pair's kernels at their peak (their forward-over-reverse Jacobians), and bytes of
#: their compilation: fitted to the peak memory of `signorini ironing --no-fd` at
#: refine 0 and 1 (1.57 and 3.88 GB; docs/benchmarks.md, the size guard)
PAIR_BYTES, PAIR_BASE = 3.45e3, 0.8 * 1024.0**3
#: the part of the path over which the die is pressed in
T_PRESS = 0.2
#: the block's cells along its top; the others follow (:func:`cell_counts`)
CELLS = 96


def cell_counts(cells: int = CELLS, refine: int = 0) -> tuple[int, int, int, int]:
    """(block along, block across, die along its arc, die across): the block's top
    ``cells`` x 2^refine cells, its height an eighth of that, the die's arc a sixth
    (its cells 1.5 times the block's: the block's top is the finer surface) and
    its height a quarter of the arc's (at least 2)."""
    n = checked_cells("ironing problem", cells, refine)
    arc = max(n // 6, 4)
    return n, max(n // 8, 2), arc, max(arc // 4, 2)


def checked_cells(problem: str, cells, refine) -> int:
    """The block's cells along its top, ``cells`` x 2^refine, after the options'
    checks (both ironing problems: :func:`cell_counts`,
    :func:`signorini.problems.ironing3d.cell_counts`)."""
    if isinstance(cells, bool) or not isinstance(cells, (int, np.integer)) or cells < 24:
        raise InputError(f"{problem}: cells (the block's cells along its top) must be an "
                         f"integer >= 24, got {cells!r}")
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or refine < 0:
        raise InputError(f"refine must be an integer >= 0, got {refine!r}")
    return int(cells) * 2**int(refine)


#: the die's depth over the path, relative to d, and its travel along the block, relative to s
press, slide = Ramp(0.0, T_PRESS), Ramp(T_PRESS, 1.0)


def check_params(params: dict | None) -> dict:
    """The run's values: DEFAULTS updated by ``params`` (eps, eps_t allowed), checked."""
    return checked_params("ironing problem", DEFAULTS, params, X0)


def checked_params(problem: str, defaults: dict, params: dict | None, x0: float, *,
                   poisson: bool = False) -> dict:
    """``defaults`` updated by ``params`` (eps, eps_t allowed) as floats, checked
    for both ironing problems (die at ``x0``): signs, Poisson's ratios in (-1,
    0.5) if ``poisson``, the die's radius, depth and slide."""
    values = checked_values(problem, defaults, params, extra=("eps", "eps_t"),
                            positive=("E1", "E2", "R", "d"), nonnegative=("mu", "s"))
    values = {k: float(v) for k, v in values.items()}
    for k in ("nu1", "nu2") if poisson else ():
        if not -1.0 < values[k] < 0.5:
            raise InputError(f"{problem}: Poisson's ratio {k} = {values[k]} must lie in (-1, 0.5)")
    if not values["R"] > A * 1.05:
        raise InputError(f"{problem}: the die's radius R = {values['R']} must exceed its "
                         f"half-width {A} (by 5 %): the arc spans the die's bottom")
    if not values["d"] < 0.3 * H:
        raise InputError(f"{problem}: the depth d = {values['d']} must stay below 0.3 H = "
                         f"{0.3 * H} (the block's height is {H})")
    if x0 + values["s"] + A > L - 0.25:
        raise InputError(f"{problem}: the slide s = {values['s']} takes the die off the block "
                         f"(its end reaches x = {x0 + values['s'] + A}, the block ends at {L}); "
                         f"keep s <= {L - 0.25 - x0 - A}")
    return values


def _die(R: float, nx: int, ny: int):
    """(mesh, V = dX/dR) of the die: columns over [X0 - A, X0 + A], relative heights."""
    m = rectangle(np.linspace(X0 - A, X0 + A, nx + 1), np.linspace(0.0, 1.0, ny + 1))
    y, dy = die_heights(m.nodes[:, 0], m.nodes[:, 1], R, X0)
    V = np.column_stack([np.zeros_like(y), dy])
    return Mesh(np.column_stack([m.nodes[:, 0], y]), m.cells, m.node_sets, m.edge_sets), V


def die_heights(x, e, R: float, x0: float):
    """(height, d height/dR) of the die's nodes at column ``x`` and relative height
    ``e`` (0 on the arc of radius R about x = ``x0`` touching the block's top, 1 on
    the die's top H + D): the die of both ironing problems."""
    r = np.sqrt(R**2 - (x - x0) ** 2)
    arc = H + R - r
    top = H + D
    return arc + e * (top - arc), (1.0 - e) * (1.0 - R / r)


def check_mesh_size(refine: int = 0, cells: int = CELLS, *, force: bool = False, solver="auto") -> None:
    """The size guard of the ironing meshes before they are built
    (:func:`signorini.linsolve.check_size`): the unknowns of both bodies and the
    pair's multipliers, and the finite-sliding pair's kernels, whose size grows
    like the cube of the cells (every block node under the die's path carries
    every die segment of the arc as a candidate)."""
    cell_counts(cells, refine)  # the options' checks
    # beyond 2^40 every count is refused: the counts of so many levels would be huge numbers
    nbx, nby, ndx, ndy = cell_counts(cells, min(int(refine), 40))
    nc = nbx + 1
    n_dof = 2 * ((nbx + 1) * (nby + 1) + (ndx + 1) * (ndy + 1)) + 2 * nc
    check_size(n_dof, force=force, what="the ironing problem", solver=solver,
               # candidates x nodes x patch coordinates grow like the cells^3, n_dof^1.5
               extra=lambda n: PAIR_BASE + PAIR_BYTES * nc * ndx * 2 * (3 + 2 * ndx) * (n / n_dof) ** 1.5,
               hint="coarser meshes (smaller --refine or --cells)")


def ironing_problem(params: dict | None = None, *, refine: int = 0, cells: int = CELLS,
                    force_size: bool = False, solver="auto") -> Problem:
    """Build the ironing problem (values: :data:`DEFAULTS` updated by ``params``).

    Args:
        params: overrides of E1, nu1, E2, nu2, R, mu, d, s and eps, eps_t
            (default E1/h for both, h the block's cell size along its top).
        refine: each level halves the cells of both bodies.
        cells: the block's cells along its top (see :func:`cell_counts`).
        force_size: build the meshes even if they are estimated not to fit in
            memory with ``solver`` (the run's linear solver).
    """
    values = check_params(params)
    check_mesh_size(refine, cells, force=force_size, solver=solver)
    nbx, nby, ndx, ndy = cell_counts(cells, refine)
    block = rectangle(np.linspace(0.0, L, nbx + 1), np.linspace(0.0, H, nby + 1))
    die, V = _die(values["R"], ndx, ndy)
    fixed = (Fixed("block.bottom", 0), Fixed("block.bottom", 1),
             Fixed("die.top", 0, "s", ramp=slide), Fixed("die.top", 1, lambda p: -p["d"], ramp=press))
    return finite_problem(merge({"block": block, "die": die}), block.n_nodes, V, values, params,
                          L / nbx, ("block.top", "die.bottom"), fixed, DEFAULTS["s"])


def finite_problem(mesh, n_block: int, V, values: dict, params: dict | None, h: float,
                   surfaces: tuple[str, str], fixed, nominal_s: float) -> Problem:
    """The problem of either ironing on the merged ``mesh`` (the block's ``n_block``
    nodes first, then the die's, whose design velocity to R is ``V``): neo-Hookean
    bodies, eps and eps_t E1/h unless in ``params`` (``h`` the block's cells along
    its top), a Coulomb pair with finite kinematics from the slave to the master
    set of ``surfaces`` whose candidates cover the slide."""
    for key in ("eps", "eps_t"):
        if key not in (params or {}):
            values[key] = DEFAULTS["E1"] / h
    method = Coulomb("mu", "eps", "eps_t")
    # the candidates cover the nominal slide and the run's (extra candidates
    # that never overlap contribute exactly nothing: the pairing does not
    # change the solution), with two block cells to spare
    reach = max(values["s"], nominal_s) + 2 * h
    contact = pair(*surfaces, method, "finite", slide=reach)
    return Problem(mesh=mesh,
                   material=Bodies({"block": NeoHooke("E1", "nu1"), "die": NeoHooke("E2", "nu2")}),
                   params=values, fixed=fixed, contact=(contact,),
                   shape={"R": np.concatenate([np.zeros((n_block, V.shape[1])), V])},
                   shape_nominal={"R": values["R"]})


def die_force(solution, i: int = -1, names=()) -> dict:
    """The die force at increment i: F_N (pressing), F_T (along the slide) and,
    for each name, their DDM sensitivities dF_N_d<name>, dF_T_d<name>."""
    return support_force(solution, "die.top", 1, i, names)


def support_force(solution, nodes: str, normal: int, i: int = -1, names=()) -> dict:
    """The force of the supports of the node set ``nodes`` at increment i, both
    ironing problems' die force: F_N = minus its component ``normal`` (pressing),
    F_T = its x component and, for each name, dF_N_d<name>, dF_T_d<name>."""
    top = solution.model.problem.mesh.node_sets[nodes]
    r = solution.reactions(i)[top].sum(axis=0)
    out = {"F_N": -float(r[normal]), "F_T": float(r[0])}
    sens = solution.reaction_sensitivities(i) if names else {}
    for n in names:
        dr = sens[n][top].sum(axis=0)
        out[f"dF_N_d{n}"] = -float(dr[normal])
        out[f"dF_T_d{n}"] = float(dr[0])
    return out
