"""Axisymmetric upsetting of a billet between flat rigid dies (paper 5.3,
docs/theory.md §9): finite-strain J2 plasticity, Coulomb friction on the die,
a Bezier preform shape with five shape parameters.

Half model (symmetry plane Z = 0): 0 <= Z <= h0, 0 <= R <= r0(Z) with
r0(Z) = sum_k phi_k B_k^4(Z / h0) (Bernstein polynomials of degree 4;
phi_k = 0.7 h0 for all k is a cylinder of radius 0.7 h0). The structured
n_r x n_z mesh blends linearly from the axis to the free surface,
R_ij = (i / n_r) r0(Z_j), so the design velocity of phi_k is
V_k = ((i / n_r) B_k(Z_j / h0), 0). The die (normal (0, -1)) starts on the top
face and moves down by ``stroke`` (default h0 / 2: 50 % height reduction of
the billet) in ``steps`` increments. Contact candidates: the top face and the
upper part of the lateral surface (the bulge folds onto the die); the axis
node has no friction multiplier (its u_r is prescribed).

Objective (paper eq. 24): F = sum_k (r_k - r_opt)^2 over the lateral nodes,
r_k = R_k + u_r,k at the end, r_opt = h0.
"""

from __future__ import annotations

import math

import numpy as np

from ..contact import Contact, Coulomb
from ..fem.element import FBAR
from .values import checked_values
from ..errors import InputError
from ..fem.kinematics import Axisymmetric
from ..fem.loads import Fixed
from ..materials.j2 import J2Plasticity
from ..fem.mesh import Mesh, rectangle
from ..contact.obstacles import Line
from ..model.problem import Problem
from ..linsolve import check_size
from ..linsolve.memory import history_extra
from .._jax import jax, jnp
from ..algorithms.newton import NewtonOptions
from ..fem import element

H0 = 1.0
SHAPE = tuple(f"phi{k}" for k in range(5))
DEFAULTS = {**{k: 0.7 * H0 for k in SHAPE}, "mu": 0.2, "sigma_y": 100.0, "H": 0.0,
            "E": 1.0e4, "nu": 0.3, "stroke": 0.5 * H0}
#: the parameters of the paper's Table 1 analogue
TABLE1 = SHAPE + ("mu", "sigma_y")


def bernstein(xi):
    """(len(xi), 5) Bernstein polynomials B_k^4(xi)."""
    xi = np.asarray(xi, dtype=float)[:, None]
    k = np.arange(5)[None, :]
    return np.array([math.comb(4, i) for i in range(5)])[None, :] * xi**k * (1 - xi) ** (4 - k)


def radius(phi, Z, h0: float = H0):
    """r0(Z) of the Bezier preform."""
    return bernstein(np.asarray(Z) / h0) @ np.asarray(phi, dtype=float)


def parse_mesh(text: str) -> tuple[int, int]:
    """'NRxNZ' -> (n_r, n_z), both >= 1."""
    try:
        a, b = str(text).lower().split("x")
        nr, nz = int(a), int(b)
    except ValueError:
        raise InputError(f"--mesh expects NRxNZ with whole numbers, e.g. 10x20; got {text!r}") from None
    if nr < 1 or nz < 1:
        raise InputError(f"--mesh needs at least one cell in each direction, got {text!r}")
    return nr, nz


#: increments the size estimate counts when the run's are not given (the command's default)
STEPS = 50
#: the size guard's memory beyond the linear solver's model (docs/cli.md), fitted to peak
#: resident memory measured on this problem (``--no-fd``, PARDISO): 1.31 GiB at 3,200 cells
#: with 51 increments, 2.07 GiB at 8,192 cells with 37, against 0.44 and 0.51 GiB for the
#: solver's model alone. The J2 F-bar quadrilaterals' programs, PROGRAM_BYTES, and their
#: working memory, about 40 kB a cell up to two chunks of 4,096 cells side by side (0.31 GB
#: measured for one element-tangent evaluation at 8,192 cells, 0.22 GB at 20,000); a cell's
#: share of the state kept for every increment and of its sensitivity once per parameter
#: (349 bytes measured: 4 Gauss points' C_p^-1 and alpha, with its share of the
#: displacements and the contact history)
PROGRAM_BYTES = 0.4 * 1024.0**3
KERNEL_BYTES_PER_CELL = 4.0e4
KERNEL_CELLS = 8192
HISTORY_BYTES_PER_CELL = 350


def check_mesh_size(mesh: tuple[int, int], lateral_fraction: float = 0.5, *, force: bool = False,
                    solver="auto", steps: int = STEPS, sensitivities: int = len(TABLE1)) -> float:
    """The size guard of the forging mesh (n_r, n_z), before it is built
    (:func:`signorini.linsolve.check_size`): the solver's model plus the J2
    kernels' memory and the history kept for ``steps`` increments with
    ``sensitivities`` parameters' sensitivities (the command's: its ``--steps``,
    Table 1's seven parameters and, with the finite-difference check, one run
    more). Returns the estimate in bytes."""
    nr, nz = mesh
    n_contact = (nr + 1) + int(np.ceil(lateral_fraction * nz))
    cells, n_dof = nr * nz, 2 * (nr + 1) * (nz + 1) + 2 * n_contact
    extra = history_extra(cells, n_dof, history_per_cell=HISTORY_BYTES_PER_CELL, steps=steps,
                          sensitivities=sensitivities, program=PROGRAM_BYTES,
                          kernel_per_cell=KERNEL_BYTES_PER_CELL, kernel_cells=KERNEL_CELLS)
    return check_size(n_dof, force=force, what="the forging mesh", solver=solver, extra=extra,
                      hint="a coarser mesh (smaller --mesh) or fewer --steps")


def forging_problem(params: dict | None = None, *, mesh: tuple[int, int] = (10, 20),
                    lateral_fraction: float = 0.5, formulation=FBAR, force_size: bool = False,
                    solver="auto", steps: int = STEPS, sensitivities: int = len(TABLE1)) -> Problem:
    """The forging half model (parameters phi0..phi4, mu, sigma_y, H, E, nu, stroke, eps, eps_t).

    The mesh is built at the *nominal* shape (:data:`DEFAULTS`, the cylinder);
    ``params`` phi_k move it along the design velocities, so a run at phi + dphi
    differs from one at phi only through X(phi) (finite differences = DDM).

    Args:
        params: overrides of :data:`DEFAULTS`.
        mesh: (n_r, n_z) cells.
        lateral_fraction: upper fraction of the lateral surface that may touch the die.
        formulation: element formulation (F-bar by default; ``element.STANDARD`` locks).
        force_size: build the mesh even if it is estimated not to fit in memory.
        solver: the run's linear solver, for that estimate.
    """
    values = checked_values("forging problem", DEFAULTS, params, extra=("eps", "eps_t"), tag="forging")
    nr, nz = mesh
    if isinstance(nr, bool) or not (isinstance(nr, (int, np.integer)) and isinstance(nz, (int, np.integer))) \
            or nr < 1 or nz < 1:
        raise InputError(f"forging mesh needs n_r, n_z >= 1 (whole numbers), got {mesh!r}")
    if not 0 < values["stroke"] < H0:
        raise InputError(f"the die stroke must lie in (0, h0) = (0, {H0}), got {values['stroke']}")
    if not 0 < lateral_fraction <= 1:
        raise InputError(f"lateral_fraction must lie in (0, 1], got {lateral_fraction}")
    check_shape([values[k] for k in SHAPE])
    check_mesh_size(mesh, lateral_fraction, force=force_size, solver=solver, steps=steps,
                    sensitivities=sensitivities)

    unit = rectangle(np.linspace(0.0, 1.0, nr + 1), np.linspace(0.0, H0, nz + 1))
    s, Z = unit.nodes[:, 0], unit.nodes[:, 1]
    B = bernstein(Z / H0)  # (n_nodes, 5)
    phi_nom = np.array([DEFAULTS[k] for k in SHAPE])
    nodes = np.column_stack([s * (B @ phi_nom), Z])
    V = {k: np.column_stack([s * B[:, i], np.zeros(len(s))]) for i, k in enumerate(SHAPE)}

    # contact candidates: the upper lateral edges (upwards) then the top face (towards the axis)
    right, top = unit.edge_sets["right"], unit.edge_sets["top"]
    upper = right[Z[right[:, 0]] >= (1 - lateral_fraction) * H0 - 1e-12]
    die_edges = np.concatenate([upper, top])
    node_sets = dict(unit.node_sets, axis=unit.node_sets["left"], lateral=unit.node_sets["right"])
    edge_sets = dict(unit.edge_sets, die=die_edges)
    m = Mesh(nodes, unit.cells, node_sets, edge_sets)

    # eps ~ E / h0 (not E / cell): with E / cell, stick/slip states cycle in Newton (measured:
    # cuts on 4x8 and 10x20 meshes); the nominal E, so that eps is a number, not a function of E
    values.setdefault("eps", DEFAULTS["E"] / H0)
    values.setdefault("eps_t", values["eps"])
    die = Line(point=(0.0, H0), normal_vector=(0.0, -1.0), motion=(0.0, lambda p: -p["stroke"]))
    return Problem(
        mesh=m,
        material=J2Plasticity(E="E", nu="nu", sigma_y="sigma_y", H="H"),
        params=values,
        fixed=(Fixed("axis", 0), Fixed("bottom", 1)),
        contact=(Contact(die, "die", Coulomb(mu="mu", eps_n="eps", eps_t="eps_t"), kinematics="finite"),),
        shape=V,
        shape_nominal={k: DEFAULTS[k] for k in SHAPE},
        kinematics=Axisymmetric(),
        formulation=formulation,
    )


def options(rtol: float = 1e-11, max_iter: int = NewtonOptions.max_iter):
    """Newton options of the forging runs: a line search on the residual norm stops
    stick/slip cycling without cutting load steps (the path stays the same)."""
    return NewtonOptions(rtol=rtol, max_iter=max_iter, line_search=True)


def check_shape(phi) -> None:
    """r0(Z) > 0 on [0, h0] (the preform must not pinch to the axis)."""
    Z = np.linspace(0.0, H0, 201)
    r = radius(phi, Z)
    if r.min() <= 0:
        k = int(np.argmin(r))
        raise InputError(f"the Bezier preform has r0 = {r[k]:.4g} <= 0 at Z = {Z[k]:.3g} "
                         f"(phi = {np.round(phi, 6).tolist()}); every radius must stay positive: "
                         "raise the phi_k near there")


def lateral_nodes(problem: Problem) -> np.ndarray:
    """The free-surface nodes (i = n_r, j = 0..n_z), bottom to top."""
    n = problem.mesh.node_set("lateral")
    return n[np.argsort(problem.mesh.nodes[n, 1])]


def objective(model, nodes: np.ndarray, r_opt: float = H0):
    """Response F(w, params, t) = sum_k (R_k + u_r,k - r_opt)^2 over ``nodes`` (eq. 24)."""
    def F(w, params, t):
        X = model.reference(params)
        u, _ = model.split(w)
        r = X[nodes, 0] + u[nodes, 0]
        return ((r - r_opt) ** 2).sum()
    return F


def die_force(model):
    """Response: total axial force of the die on the billet (full 2 pi), sum A_S p_N."""
    def force(w, params, t):
        f = model.contact_fields(w, params, t, 0)
        return (f["area"] * f["p_N"]).sum()
    return force


def body_volume(model, x) -> float:
    """Volume of the body of revolution (full 2 pi) with nodal positions x (n_nodes, 2)."""
    def cell(xe):
        _, detJ = element.physical_gradients(element.DN_PARENT, xe)
        return model.kinematics.volume_weights(xe, element.N_PARENT, element.GAUSS_WEIGHTS * detJ).sum()

    return float(jax.vmap(cell)(jnp.asarray(x)[model.conn]).sum())
