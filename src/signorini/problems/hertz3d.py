"""Hertz contact of a rigid sphere on an elastic block, in three dimensions
(docs/theory.md §12.8), and the same problem in the axisymmetric model.

Quarter model: block 0 <= x, y <= W, -H <= z <= 0, symmetry u_x = 0 on x = 0
and u_y = 0 on y = 0, a uniform pressure on the bottom with resultant P/4, so
that the block is held only by the contact with the sphere (radius R, centre
(0, 0, R), touching at the origin). The mesh is graded: cubes of size ~a0 /
n_fine in the fine zone at the contact, growing geometrically away from it;
a0 is Hertz's radius at the *nominal* parameters (:data:`DEFAULTS`), so a run
at other values has the same mesh and finite differences of outputs equal the
DDM sensitivities.

With ``mu > 0`` the contact is Coulomb friction, the force growing to P in
``steps`` increments (monotonic indentation: a stick zone r < c and a slip
annulus c < r < a). The axisymmetric model (``axisymmetric=True``) is the same
sphere and block in the (r, z) half-plane with the same grading: the two
models can be compared node by node along a radius.

Design parameters: E, nu, P, R, mu, eps, eps_t.
"""

from __future__ import annotations

import numpy as np

from ..contact import AugmentedLagrangian, Contact, Coulomb
from ..contact.obstacles import Circle
from ..contact.obstacles3d import Sphere
from .values import checked_values
from ..errors import InputError
from ..fem.kinematics import Axisymmetric
from ..fem.loads import Fixed, Pressure
from ..fem.mesh import graded_coordinates, rectangle
from ..fem.mesh3d import Mesh3D, box, with_box_sets
from ..linsolve import check_size
from ..linsolve.memory import iterative_hint
from ..materials import LinearElastic
from ..model.problem import Problem
from .hertz import check_fine_zone, check_mesh_options

DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 0.1, "R": 1.0, "mu": 0.0}


def analytical(P, R, E, nu) -> dict:
    """Hertz's sphere on a half-space: a = (3 P R / (4 E*))^(1/3), p0 = 3 P / (2 pi a²),
    E* = E / (1 - nu²), and their derivatives with respect to R at constant P."""
    Es = E / (1.0 - nu**2)
    a = (3.0 * P * R / (4.0 * Es)) ** (1.0 / 3.0)
    p0 = 3.0 * P / (2.0 * np.pi * a**2)
    return {"a": a, "p0": p0, "E_star": Es, "da_dR": a / (3 * R), "dp0_dR": -2.0 * p0 / (3 * R)}


def pressure(r, P, R, E, nu):
    """p_N(r) = p0 sqrt(1 - (r/a)²) for r < a, 0 outside."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(r) / h["a"]
    return np.where(xi < 1, h["p0"] * np.sqrt(np.clip(1 - xi**2, 0, None)), 0.0)


def pressure_dR(r, P, R, E, nu):
    """Dp_N/DR at constant P: p0 / (3R) (3 xi² - 2) / sqrt(1 - xi²) for xi = r/a < 1."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(r) / h["a"]
    inside = xi < 1
    s = np.sqrt(np.where(inside, 1 - xi**2, 1.0))
    return np.where(inside, h["p0"] / (3 * R) * (3 * xi**2 - 2) / s, 0.0)


def grid(nominal: dict | None = None, *, refine: int = 0, n_fine: int = 8, size: float = 12.0,
         zone: float = 1.5):
    """(lateral lines 0..W, vertical lines -H..0, a0) of the graded quarter model:
    n_fine 2^refine cells across the fine zone (zone a0 wide, 2/3 of it deep),
    growth 1.3^(1/2^refine) beyond it, W = H = size a0 (sized by the nominal values
    only)."""
    nom = {**DEFAULTS, **(nominal or {})}
    check_mesh_options(refine, n_fine, size, zone)
    a0 = analytical(nom["P"], nom["R"], nom["E"], nom["nu"])["a"]
    k = 2**refine
    nf = n_fine * k
    growth = 1.3 ** (1.0 / k)
    xs = graded_coordinates(size * a0, zone * a0, nf, growth)
    zs = -graded_coordinates(size * a0, zone * a0 * 2.0 / 3.0, max(int(round(nf * 2 / 3)), 1),
                             growth)[::-1]
    return xs, zs, a0


def tetrahedral_block(*, n_fine: int = 8, seed: int = 0, size: float = 12.0,
                      zone: float = 1.5):
    """The graded block of :func:`hertz3d_problem` as an unstructured tetrahedral
    mesh: the points of its grid moved at random (``seed``) by up to a fifth of the
    local spacing, not across the box's faces, then tetrahedralised by Delaunay;
    the box's node and face sets (``x0`` ... ``z1``). A mesh without coarser ones,
    as a user's file would be (tests and benchmarks of the algebraic coarse start)."""
    from scipy.spatial import Delaunay  # noqa: PLC0415  (lazy: scipy.spatial)

    xs, zs, _ = grid(n_fine=n_fine, size=size, zone=zone)
    Z, Y, X = np.meshgrid(zs, xs, xs, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    lo, hi = P.min(axis=0), P.max(axis=0)

    def spacing(g, v):
        i = np.clip(np.searchsorted(g, v), 1, len(g) - 1)
        return g[i] - g[i - 1]

    h = np.column_stack([spacing(xs, P[:, 0]), spacing(xs, P[:, 1]), spacing(zs, P[:, 2])])
    J = np.random.default_rng(seed).uniform(-0.2, 0.2, P.shape) * h.min(axis=1)[:, None]
    J[np.isclose(P, lo) | np.isclose(P, hi)] = 0.0
    P = P + J
    cells = Delaunay(P).simplices
    e = P[cells[:, 1:]] - P[cells[:, :1]]
    flip = np.einsum("ij,ij->i", np.cross(e[:, 0], e[:, 1]), e[:, 2]) < 0
    cells[flip] = cells[flip][:, [0, 2, 1, 3]]
    return with_box_sets(Mesh3D(P, cells))


def hertz3d_problem(params: dict | None = None, *, refine: int = 0, n_fine: int = 8,
                    size: float = 12.0, zone: float = 1.5, axisymmetric: bool = False,
                    force_size: bool = False, solver="auto") -> Problem:
    """The sphere-on-block quarter model (or, ``axisymmetric``, its axisymmetric
    twin). ``eps`` defaults to E0 / h (nominal E0, contact cell size h) and
    ``eps_t`` to ``eps``; ``mu > 0`` makes the contact Coulomb friction.
    ``force_size``: build the mesh even if it is estimated not to fit in memory
    with ``solver`` (the run's linear solver)."""
    values = checked_values("3-D Hertz problem", DEFAULTS, params, extra=("eps", "eps_t"),
                            positive=("E", "P", "R"))
    if values["mu"] < 0:
        raise InputError(f"the friction coefficient must be >= 0, got mu={values['mu']}")
    LinearElastic().check(values)
    dim = 2 if axisymmetric else 3
    what = "the axisymmetric Hertz mesh" if axisymmetric else "the 3-D Hertz mesh"
    hint = "a coarser mesh (smaller --refine or --n-fine)" + (
        "" if axisymmetric else iterative_hint(solver))
    check_fine_zone(refine, n_fine, dim=dim, what=what, force=force_size, solver=solver, hint=hint)
    xs, zs, _ = grid(refine=refine, n_fine=n_fine, size=size, zone=zone)
    friction = values["mu"] > 0
    m = 1 + (2 if friction else 0) if not axisymmetric else (2 if friction else 1)
    n_dof = (2 * len(xs) * len(zs) + m * len(xs)) if axisymmetric else \
        (3 * len(xs) ** 2 * len(zs) + m * len(xs) ** 2)
    check_size(n_dof, force=force_size, what=what, dim=dim, solver=solver, hint=hint)
    h = float(xs[1] - xs[0])
    values.setdefault("eps", DEFAULTS["E"] / h)
    values.setdefault("eps_t", values["eps"])
    law = (Coulomb(mu="mu", eps_n="eps", eps_t="eps_t") if friction
           else AugmentedLagrangian("eps"))
    if not friction:
        values.pop("eps_t")
    if axisymmetric:
        return Problem(
            mesh=rectangle(xs, zs), material=LinearElastic(), params=values,
            kinematics=Axisymmetric(), fixed=(Fixed("left", 0),),
            loads=(Pressure("bottom", "P", resultant=True),),
            contact=(Contact(Circle(radius="R", centre=(0.0, "R")), "top", law),))
    return Problem(
        mesh=box(xs, xs, zs), material=LinearElastic(), params=values,
        fixed=(Fixed("x0", 0), Fixed("y0", 1)),
        loads=(Pressure("z0", lambda p: 0.25 * p["P"], resultant=True),),
        contact=(Contact(Sphere(radius="R", centre=(0.0, 0.0, "R")), "z1", law),))
