"""Plane-strain Hertz contact of a rigid cylinder on an elastic block (paper 5.1).

Symmetric half model: block 0 <= x <= W, -H <= y <= 0, symmetry u_x = 0 on
x = 0, uniform pressure on the bottom with resultant P/2, so the block is held
only by the contact with the cylinder (centre (0, R), touching at the origin).
The mesh is graded: uniform cells of size ~a0/16 near the contact, growing
geometrically away from it; the block is 20 a0 wide and deep so that it acts
as a half-space. a0 is the Hertz half-width at the *nominal* parameter values
(:data:`DEFAULTS`, or ``nominal=``): the mesh never depends on the values a
run is made with, so finite differences of outputs equal the DDM.

Design parameters: E, nu, P, R, eps and the shape parameter ``bump`` (the
amplitude of a smooth ring-shaped crown on the top face that leaves the
initial contact point in place; design velocity V = (0, b(X) (1 + Y/H)),
b = s (1 - s)^2 with s = (X/2a)^2 for X < 2a).
"""

from __future__ import annotations

import logging

import numpy as np

from ..contact import AugmentedLagrangian, Contact, Penalty
from .values import checked_values
from ..errors import InputError, SolverError
from ..fem.loads import Fixed, Pressure
from ..materials import LinearElastic, NeoHooke
from ..fem.mesh import graded_coordinates, rectangle
from ..contact.obstacles import Circle
from ..model.problem import Problem
from ..model.kernels import Model
from ..linsolve import check_size
from .. import responses
from ..algorithms.coarse_to_fine import solve_coarse_to_fine
from ..algorithms.prolongation import Prolongation
from ..algorithms.stepping import model_for

log = logging.getLogger("signorini")

DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 1.2, "R": 1.0}


def analytical(P, R, E, nu) -> dict:
    """Half-width a, peak pressure p0 and their R-derivatives (docs/theory.md §8, paper eq. 22)."""
    a = np.sqrt(4.0 * P * R * (1.0 - nu**2) / (np.pi * E))
    p0 = 2.0 * P / (np.pi * a)
    return {"a": a, "p0": p0, "da_dR": a / (2 * R), "dp0_dR": -p0 / (2 * R)}


def pressure(x, P, R, E, nu):
    """p_N(x) = p0 sqrt(1 - (x/a)^2) for |x| < a, 0 outside (eq. 22)."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(x) / h["a"]
    return np.where(np.abs(xi) < 1, h["p0"] * np.sqrt(np.clip(1 - xi**2, 0, None)), 0.0)


def pressure_dR(x, P, R, E, nu):
    """Dp_N/DR at constant P: p0/(2R) (2 xi^2 - 1)/sqrt(1 - xi^2) for |xi| < 1."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(x) / h["a"]
    inside = np.abs(xi) < 1
    s = np.sqrt(np.where(inside, 1 - xi**2, 1.0))
    return np.where(inside, h["p0"] / (2 * R) * (2 * xi**2 - 1) / s, 0.0)


def check_mesh_options(refine, n_fine, size: float, zone: float) -> None:
    """The graded meshes' options: whole numbers refine >= 0 and n_fine >= 1, and a
    fine zone narrower than the block (both in units of a0)."""
    _check_counts(refine, n_fine)
    if not (np.isfinite(size) and np.isfinite(zone) and 0 < zone < size):
        raise InputError(f"the fine zone must be narrower than the block: need 0 < zone < block, "
                         f"got zone = {zone} a0, block = {size} a0")


def _check_counts(refine, n_fine) -> None:
    """Whole numbers refine >= 0 and n_fine >= 1."""
    for k, v in (("refine", refine), ("n_fine", n_fine)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < (0 if k == "refine" else 1):
            raise InputError(f"{k} must be an integer >= {0 if k == 'refine' else 1}, got {v!r}")


def check_fine_zone(refine: int, n_fine: int, *, dim: int = 2, what: str = "the mesh",
                    force: bool = False, solver="auto",
                    hint: str = "a coarser mesh (smaller --refine or --n-fine)") -> None:
    """The size guard before a graded mesh's grid lines are built: its fine zone
    alone (n_fine 2^refine cells across, 2/3 of that deep; in 3-D as wide in the
    second direction) is a lower bound of the mesh, refused at once if it cannot
    fit (:func:`signorini.linsolve.check_size`); building the grid lines of a mesh
    that large would itself exhaust the time or the memory."""
    _check_counts(refine, n_fine)
    nf = int(n_fine) * 2 ** min(int(refine), 64)
    nodes = (nf + 1) ** (dim - 1) * (max(round(nf * 2 / 3), 1) + 1)
    check_size(dim * nodes, dim=dim, force=force, what=what, solver=solver, hint=hint,
               lower_bound=True)


def mesh_coordinates(nominal: dict | None = None, *, refine: int = 0, n_fine: int = 24,
                     size: float = 20.0, zone: float = 1.5):
    """Graded grid lines (xs, ys) of the half model and the nominal half-width a0.

    The mesh depends only on the *nominal* values (``nominal``, default
    :data:`DEFAULTS`) and on the mesh options, never on the parameter values of
    a run: a run at R + dR has the same mesh as a run at R, so finite
    differences of outputs equal the DDM sensitivities.

    Args:
        nominal: E, nu, P, R used to size the mesh (a0 = Hertz half-width).
        refine: each level halves the cell size everywhere (x2 cells per direction).
        n_fine: cells across the fine zone at refine 0.
        size: block width and depth in units of a0.
        zone: width of the uniformly fine zone in units of a0 (its depth is 2/3 of it).
    """
    nom = dict(DEFAULTS)
    nom.update(nominal or {})
    check_mesh_options(refine, n_fine, size, zone)
    a0 = analytical(nom["P"], nom["R"], nom["E"], nom["nu"])["a"]
    k = 2**refine
    nf = n_fine * k
    growth = 1.2 ** (1.0 / k)
    W = H = size * a0
    xs = graded_coordinates(W, zone * a0, nf, growth)
    ys = -graded_coordinates(H, zone * a0 * 2.0 / 3.0, max(int(round(nf * 2 / 3)), 1), growth)[::-1]
    return xs, ys, a0


def hertz_problem(params: dict | None = None, *, refine: int = 0, method: str = "al",
                  finite_strain: bool = False, n_fine: int = 24, size: float = 20.0,
                  zone: float = 1.5, nominal: dict | None = None, force_size: bool = False,
                  multipliers_per_node: int | None = None, solver="auto") -> Problem:
    """Build the Hertz half model.

    Args:
        params: overrides of the defaults E=100, nu=0.3, P=1.2, R=1 (and eps, bump).
        refine: each level halves the cell size everywhere (x2 cells per direction).
        method: ``"al"`` (augmented Lagrangian) or ``"penalty"``.
        finite_strain: neo-Hookean total-Lagrangian block instead of linear elasticity.
        n_fine: cells across the fine zone at refine 0.
        size: block width and depth in units of the nominal half-width a0.
        zone: width of the fine zone in units of a0.
        nominal: the values that size the mesh (default :data:`DEFAULTS`); the
            parameter values in ``params`` never change the mesh.
        force_size: build the mesh even if it is estimated not to fit in memory.
        multipliers_per_node: for the size estimate (default: that of ``method``).
        solver: the linear solver the run will use, for the size estimate.

    The default ``eps`` is E0 / h with the nominal E0 and the contact cell size h
    (a number, so that ``E`` changes nothing else).
    """
    values = checked_values("Hertz problem", DEFAULTS, params, extra=("eps", "bump"),
                            positive=("E", "P", "R"))
    LinearElastic().check(values)
    if method not in ("al", "penalty"):
        raise InputError(f"unknown contact method {method!r}; use 'al' or 'penalty'")
    nom = dict(DEFAULTS)
    nom.update(nominal or {})
    check_fine_zone(refine, n_fine, what="the Hertz mesh", force=force_size, solver=solver)
    xs, ys, a0 = mesh_coordinates(nom, refine=refine, n_fine=n_fine, size=size, zone=zone)
    m = multipliers_per_node if multipliers_per_node is not None else (1 if method == "al" else 0)
    check_size(2 * len(xs) * len(ys) + m * len(xs), force=force_size, what="the Hertz mesh",
               solver=solver)
    mesh = rectangle(xs, ys)
    H = -ys[0]
    h = xs[1] - xs[0]
    values.setdefault("eps", nom["E"] / h)
    values.setdefault("bump", 0.0)
    X = mesh.nodes
    r2 = (X[:, 0] / (2 * a0)) ** 2
    b = np.where(r2 < 1, r2 * (1 - r2) ** 2, 0.0)
    V = np.column_stack([np.zeros(len(X)), b * (1 + X[:, 1] / H)])
    meth = AugmentedLagrangian("eps") if method == "al" else Penalty("eps")
    material = NeoHooke() if finite_strain else LinearElastic()
    return Problem(
        mesh=mesh,
        material=material,
        params=values,
        fixed=(Fixed("left", 0),),
        loads=(Pressure("bottom", lambda p: 0.5 * p["P"], resultant=True),),
        contact=(Contact(Circle(radius="R", centre=(0.0, "R")), "top", meth),),
        shape={"bump": V},
        shape_nominal={"bump": 0.0},
    )


def contact_work(model, surface: int = 0):
    """Response W(w, params, t) = sum_S A_S p_N,S (g_0,S - g_S) of ``model``: the
    work of the contact pressure on the closure of the initial gap g_0 (the gap
    at u = 0), :func:`signorini.responses.contact_work` as a function of (w,
    params, t). The scalar response of the adjoint runs."""
    work = responses.contact_work(surface)(model)
    return lambda w, params, t: work(w, params, t, None)


def fine_cell_size(problem: Problem) -> float:
    """Smallest top-edge length (the contact resolution)."""
    return problem.mesh.min_edge_length("top")


#: the coarsest start mesh has this many cells across the fine zone
COARSEST = 12
#: at most this many coarse meshes before the requested one
MAX_COARSE_LEVELS = 3


def coarse_levels(refine: int, n_fine: int = 24, coarsest: int = COARSEST) -> list[tuple[int, int]]:
    """(refine, n_fine) of the meshes that start a one-step solve, coarsest first:
    the cell count across the fine zone halved (rounded up) down to ``coarsest``, at most
    :data:`MAX_COARSE_LEVELS` of them (see :mod:`signorini.algorithms.coarse_to_fine`)."""
    out, r, n = [], refine, n_fine
    while len(out) < MAX_COARSE_LEVELS:
        if r > 0:
            r -= 1
        elif (n + 1) // 2 >= coarsest:
            n = (n + 1) // 2  # an odd count: the meshes are not nested, the start is interpolated
        else:
            break
        out.append((r, n))
    return out[::-1]


#: the CLIs start from coarser meshes only from this many DOFs on: below it,
#: compiling (or loading from the compilation cache) the coarse meshes' kernels
#: costs more than the few cheap Newton iterations they save (docs/theory.md §10.3)
MIN_GUIDED_DOFS = 50_000


def coarse_start_skipped(pb, coarse_start: bool, min_dofs: int | None = None) -> str | None:
    """Why a CLI run does not start from coarser meshes (None: it does); ``min_dofs``:
    the size below which the coarse levels cost more than they save (default
    :data:`MIN_GUIDED_DOFS`)."""
    if not coarse_start:
        return "off"
    if min_dofs is None:
        min_dofs = MIN_GUIDED_DOFS
    n = model_for(pb).n_dof
    if n < min_dofs:
        return f"not used below {min_dofs} DOFs ({n} here): it costs more than it saves"
    return None


def coarse_start_for(pb, build, refine: int, n_fine: int, *, steps: int, options, solver,
                     coarsest: int = COARSEST):
    """(guide, levels): the meshes ``build(refine, n_fine)`` of
    :func:`coarse_levels`, solved coarse to fine along the whole load path, the
    finest of them a ``guide`` for ``solve(pb, start=...)``; (None, []) without
    a coarser mesh. A failing coarse level guides only over the increments it
    converged (recorded in ``levels``). When the fine mesh runs by its kinds'
    programs (``Model.by_kind``), only the levels that do too are solved."""
    coarse = [build(r, n) for r, n in coarse_levels(refine, n_fine, coarsest)]
    if model_for(pb).by_kind:
        # the fine mesh runs by its kinds' programs, which serve every mesh as large; a
        # level small enough for programs of its own (Model.WHOLE_MESH_UP_TO) loads or
        # compiles them in every process: more than the few iterations it saves the next
        coarse = [c for c in coarse if c.mesh.n_cells > Model.WHOLE_MESH_UP_TO]
    if not coarse:
        return None, []
    Prolongation.prepare(model_for(coarse[-1]), model_for(pb))  # built while the levels solve
    try:
        return solve_coarse_to_fine(coarse, steps=steps, options=options, solver=solver,
                                    whole_path=False)
    except SolverError as e:  # not a Newton failure (those guide as far as they got)
        log.info("coarse start failed (%s); Newton starts from the undeformed state and the "
                 "predictor", e)
        return None, [{"failed": str(e)}]
