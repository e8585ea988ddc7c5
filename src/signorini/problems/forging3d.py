"""Upsetting of a billet that is not axisymmetric, between flat rigid dies
(docs/theory.md §12.9): a square cross-section with rounded corners,
finite-strain J2 plasticity on F-bar hexahedra, Coulomb friction on the die.

One eighth of the billet (symmetry planes x = 0, y = 0 and the mid-plane
z = 0): 0 <= z <= h0 = 1. The cross-section is a blend, linear in the shape
parameters, of a square and a circle: a point of the parameter square
(xi, eta) in [0, 1]^2 at ring s = max(xi, eta) and position tau = min / max
along its ring is placed at

    x_xy = s [square Sq(tau) + (round + bulge (1 - (z/h0)^2)) Ci(tau)],

Sq the square's boundary ((1, tau) on the side x = max), Ci the circle's
((cos, sin)(pi tau / 4)), so ``square`` = 0.45, ``round`` = 0.25 (nominal) is
a square of half-width 0.7 h0 whose corners are rounded, ``square`` = 0 a
circular billet of radius ``round``, and ``bulge`` a barrel. Because x is
linear in (square, round, bulge), the design velocities are exact: the mesh
at any parameter value is the mesh of that preform, built from the nominal
one, and finite differences of outputs equal the DDM.

The die (normal (0, 0, -1)) starts on the top face and moves down by
``stroke`` in ``steps`` increments; contact candidates are the top face and
the upper part of the lateral surface. Objective: the lateral surface's
deviation from a circular cylinder at the end,
F = mean over the lateral nodes of (r_k - mean r)^2, r_k = |x_xy| current.
"""

from __future__ import annotations

import numpy as np

from .._jax import jax, jnp
from ..algorithms.newton import NewtonOptions
from ..contact import Contact, Coulomb
from ..contact.obstacles3d import Plane
from .values import checked_values
from ..errors import InputError
from ..fem.element import FBAR
from ..fem.loads import Fixed
from ..fem.mesh3d import Mesh3D, box
from ..fem.solid import cell_volume
from ..linsolve import check_size
from ..linsolve.memory import history_extra
from ..materials.j2 import J2Plasticity
from ..model.problem import Problem

H0 = 1.0
SHAPE = ("square", "round", "bulge")
DEFAULTS = {"square": 0.45, "round": 0.25, "bulge": 0.0, "mu": 0.2, "sigma_y": 100.0, "H": 0.0,
            "E": 1.0e4, "nu": 0.3, "stroke": 0.4 * H0}
#: the parameters whose sensitivities the command reports
REPORTED = SHAPE + ("mu", "sigma_y")
#: increments the size estimate counts when the run's are not given (the command's default)
STEPS = 20

#: the size guard's memory beyond the linear solver's model (docs/cli.md), fitted to peak
#: resident memory measured on this problem: the J2 F-bar kernels' working memory, about
#: 260 kB per cell up to the 4,096 cells of one chunk (1.07 GB measured at 4,096 and 0.87-1.0 GB
#: at 8,000 to 21,952 cells for one element-tangent evaluation) and 0.85 GB of programs (the
#: DDM's JVPs, the update); the whole command at 8,000 cells peaked at 2.74 GB against the
#: 0.76 GB the solver's model alone gives
KERNEL_BYTES_PER_CELL = 2.6e5
KERNEL_CELLS = 4096
PROGRAM_BYTES = 0.85 * 1024.0**3
#: a cell's share of the state kept for every increment, and of its sensitivity once per
#: parameter (measured 738 bytes a cell: its 8 Gauss points' C_p^-1 and alpha, 640 bytes,
#: with its share of the displacements and the contact history)
HISTORY_BYTES_PER_CELL = 740


def check_mesh_size(mesh: tuple[int, int], *, steps: int = STEPS, sensitivities: int = len(REPORTED),
                    force: bool = False, solver="auto") -> float:
    """The size guard of the forging3d mesh (cells across the section's half, cells
    in z), before it is built (:func:`signorini.linsolve.check_size`): the
    solver's model plus the J2 kernels' working memory and the history kept for
    ``steps`` increments with ``sensitivities`` parameters' sensitivities (the
    command's: its ``--steps``, its five parameters and, with the finite-difference
    check, one run more). Returns the estimate in bytes."""
    ns, nz = mesh
    cells, n_dof = ns * ns * nz, 3 * (ns + 1) ** 2 * (nz + 1)
    extra = history_extra(cells, n_dof, history_per_cell=HISTORY_BYTES_PER_CELL, steps=steps,
                          sensitivities=sensitivities, program=PROGRAM_BYTES,
                          kernel_per_cell=KERNEL_BYTES_PER_CELL, kernel_cells=KERNEL_CELLS)
    return check_size(n_dof, force=force, what="the 3-D forging mesh", dim=3, solver=solver,
                      extra=extra, hint="a coarser mesh (smaller --mesh) or fewer --steps")


def section(xi, eta):
    """(s, Sq (n, 2), Ci (n, 2)) of parameter points (xi, eta) in [0, 1]^2."""
    xi, eta = np.asarray(xi, float), np.asarray(eta, float)
    s = np.maximum(xi, eta)
    tau = np.where(s > 0, np.minimum(xi, eta) / np.where(s > 0, s, 1.0), 0.0)
    side_x = xi >= eta  # on the ring's side x = max
    sq = np.where(side_x[:, None], np.column_stack([np.ones_like(tau), tau]),
                  np.column_stack([tau, np.ones_like(tau)]))
    a = 0.25 * np.pi * tau
    ci = np.where(side_x[:, None], np.column_stack([np.cos(a), np.sin(a)]),
                  np.column_stack([np.sin(a), np.cos(a)]))
    return s, sq, ci


def forging3d_problem(params: dict | None = None, *, mesh: tuple[int, int] = (6, 6),
                      lateral_fraction: float = 0.5, force_size: bool = False,
                      solver="auto", steps: int = STEPS,
                      sensitivities: int = len(REPORTED)) -> Problem:
    """The billet's eighth (parameters square, round, bulge, mu, sigma_y, H, E, nu,
    stroke, eps, eps_t); ``mesh`` = (cells across the section's half, cells in z);
    ``force_size``: build it even if it is estimated not to fit in memory with
    ``solver`` (the run's linear solver), ``steps`` increments and
    ``sensitivities`` parameters (:func:`check_mesh_size`)."""
    values = checked_values("3-D forging problem", DEFAULTS, params, extra=("eps", "eps_t"),
                            tag="forging3d")
    ns, nz = mesh
    if isinstance(ns, bool) or not (isinstance(ns, (int, np.integer)) and isinstance(nz, (int, np.integer))) \
            or ns < 1 or nz < 1:
        raise InputError(f"forging3d mesh needs whole numbers >= 1, got {mesh!r}")
    if not 0 < values["stroke"] < H0:
        raise InputError(f"the die stroke must lie in (0, h0) = (0, {H0}), got {values['stroke']}")
    if not 0 < lateral_fraction <= 1:
        raise InputError(f"lateral_fraction must lie in (0, 1], got {lateral_fraction}")
    if values["round"] + min(values["bulge"], 0.0) <= 0 or values["square"] < 0:
        raise InputError(f"the preform needs round + bulge > 0 and square >= 0, got round = "
                         f"{values['round']}, bulge = {values['bulge']}, square = {values['square']}")
    check_mesh_size((ns, nz), steps=steps, sensitivities=sensitivities, force=force_size,
                    solver=solver)

    unit = box(np.linspace(0, 1, ns + 1), np.linspace(0, 1, ns + 1), np.linspace(0, H0, nz + 1))
    xi, eta, z = unit.nodes.T
    s, sq, ci = section(xi, eta)
    zeta2 = (z / H0) ** 2
    V = {"square": s[:, None] * sq, "round": s[:, None] * ci,
         "bulge": s[:, None] * (1 - zeta2)[:, None] * ci}
    V = {k: np.column_stack([v, np.zeros(len(z))]) for k, v in V.items()}
    nodes = sum(DEFAULTS[k] * V[k] for k in SHAPE) + np.column_stack([0 * z, 0 * z, z])

    faces = unit.face_sets
    lateral = np.concatenate([faces["x1"], faces["y1"]])
    upper = lateral[np.all(z[lateral] >= (1 - lateral_fraction) * H0 - 1e-12, axis=1)]
    face_sets = dict(faces, die=np.concatenate([upper, faces["z1"]]), lateral=lateral)
    node_sets = dict(unit.node_sets, lateral=np.unique(lateral))
    m = Mesh3D(nodes, unit.cells, node_sets, face_sets)

    values.setdefault("eps", DEFAULTS["E"] / H0)
    values.setdefault("eps_t", values["eps"])
    die = Plane(point=(0.0, 0.0, H0), normal_vector=(0.0, 0.0, -1.0),
                motion=(0.0, 0.0, lambda p: -p["stroke"]))
    return Problem(
        mesh=m,
        material=J2Plasticity(E="E", nu="nu", sigma_y="sigma_y", H="H"),
        params=values,
        fixed=(Fixed("x0", 0), Fixed("y0", 1), Fixed("z0", 2)),
        contact=(Contact(die, "die", Coulomb(mu="mu", eps_n="eps", eps_t="eps_t"), kinematics="finite"),),
        shape=V,
        shape_nominal={k: DEFAULTS[k] for k in SHAPE},
        formulation=FBAR,
    )


def options(rtol: float = 1e-10, max_iter: int = NewtonOptions.max_iter):
    """Newton options of the 3-D forging runs (a line search on the residual norm,
    as the axisymmetric forging's)."""
    return NewtonOptions(rtol=rtol, max_iter=max_iter, line_search=True)


def out_of_round(model, nodes: np.ndarray):
    """Response F(w, params, t) = mean over ``nodes`` of (r_k - mean r)^2, r_k the
    current distance of node k from the z axis: 0 for a circular cylinder."""
    def F(w, params, t):
        X = model.reference(params)
        u, _ = model.split(w)
        x = X[nodes, :2] + u[nodes, :2]
        r = jnp.sqrt(jnp.sum(x * x, axis=1))
        return jnp.mean((r - jnp.mean(r)) ** 2)
    return F


def die_force(model):
    """Response: the axial force of the die on the eighth, sum A_S p_N n_z (the die's
    normal is -z)."""
    def force(w, params, t):
        f = model.contact_fields(w, params, t, 0)
        return (f["area"] * f["p_N"]).sum()
    return force


def cell_volumes(model, x) -> np.ndarray:
    """(n_cells,) volumes of the cells with nodal positions x (n_nodes, 3)."""
    return np.asarray(jax.vmap(lambda xe: cell_volume(xe, model.kinematics))(
        jnp.asarray(x)[model.conn]))


def volume(model, x) -> float:
    """Volume of the eighth with nodal positions x (n_nodes, 3)."""
    return float(cell_volumes(model, x).sum())


def elastic_volume_ratio(model, x, stress, params) -> float:
    """V / V0 that the elastic compressibility alone gives: plastic flow keeps the
    volume, and the mean Cauchy stress p of a cell sets its elastic J by the
    material's volumetric law, kappa/2 (J^2 - 1) = p J, i.e. J = p/kappa +
    sqrt((p/kappa)^2 + 1); so V0 = sum V_cell / J_cell."""
    p = np.trace(np.asarray(stress), axis1=1, axis2=2) / 3.0
    kappa = params["E"] / (3.0 * (1.0 - 2.0 * params["nu"]))
    q = p / kappa
    J = q + np.sqrt(q * q + 1.0)
    V = cell_volumes(model, x)
    return float(V.sum() / np.sum(V / J))
