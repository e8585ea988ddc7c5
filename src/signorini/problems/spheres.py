"""Two elastic spheres pressed together (Hertz), then sheared (Cattaneo–Mindlin):
the 3-D two-body contact example (docs/theory.md §13.11, docs/cli.md).

Each body is the part of its sphere near the contact: a block of half-width and
depth W below (lower sphere, radius R1, centre (0, 0, -R1)) or above (upper,
R2, centre (0, 0, R2)) the initial contact point at the origin, whose face
towards the other body is the spherical cap. Frictionless: the quarter x, y >=
0 (planes of symmetry x = 0 and y = 0); with friction the tangential force Q
along x breaks the x = 0 symmetry: the half y >= 0. The meshes (hexahedra)
do not match along the interface (the upper one is coarser); the lower surface
is the slave of the mortar pair.

Supports and loads (those of `signorini cylinders` in 3-D): the lower body's
bottom is held vertically; the upper body's lateral faces x = ±W are held
along x (with friction; without, the symmetry planes hold it) and its top
carries the force P (a uniform pressure of resultant P over the whole sphere,
its share on the model). With friction a tangential force Q (a uniform
traction on the lower body's bottom) follows P: P over the first half of the
increments, Q over the second; the lower body is then held along x by the
friction alone.

Hertz (1/R = 1/R1 + 1/R2, 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2)::

    a = (3 P R / (4 E*))^(1/3),  p0 = 3 P / (2 pi a^2),  p(r) = p0 sqrt(1 - r^2/a^2);

Cattaneo–Mindlin (elastically similar spheres, Q < mu P): stick radius
c = a (1 - Q/(mu P))^(1/3).

The grid lines are sized by the *nominal* values (:data:`DEFAULTS`) and the
mesh options, never by a run's values; the radii move the nodes smoothly (a
node at (x, y) and relative depth eta lies at z = z_cap(r; R) + eta (z_far -
z_cap)), so the design velocities dX/dR1, dX/dR2 are exact and finite
differences of outputs equal the DDM.
"""

from __future__ import annotations

import numpy as np

from ..contact import AugmentedLagrangian, Coulomb
from ..contact.mortar import pair
from ..errors import InputError
from ..fem.loads import Fixed, Pressure, Ramp, Traction
from ..fem.mesh import graded_coordinates, merge
from ..fem.mesh3d import Mesh3D, box
from ..linsolve import check_size
from ..linsolve.memory import iterative_hint
from ..materials import Bodies, LinearElastic
from ..model.problem import Problem
from .cylinders import partial_slip
from .hertz import check_fine_zone, check_mesh_options
from .values import check_partial_slip, checked_values

DEFAULTS = {"R1": 1.0, "R2": 1.0, "E1": 100.0, "E2": 100.0, "nu1": 0.3, "nu2": 0.3, "P": 0.1,
            "mu": 0.0, "Q": 0.0}
#: each body's half-width and depth, in units of the smaller nominal radius
WIDTH = 0.5
#: P over the first half of the path, Q over the second (Mindlin's loading)
_FIRST, _SECOND = Ramp(0.0, 0.5), Ramp(0.5, 1.0)


def analytical(P, R1, R2, E1, E2, nu1, nu2, mu=0.0, Q=0.0) -> dict:
    """Hertz's radius a and peak pressure p0; with mu > 0, the stick radius c of
    Cattaneo–Mindlin (docs/theory.md §13.11)."""
    R = 1.0 / (1.0 / R1 + 1.0 / R2)
    Es = 1.0 / ((1 - nu1**2) / E1 + (1 - nu2**2) / E2)
    a = (3.0 * P * R / (4.0 * Es)) ** (1.0 / 3.0)
    out = {"R": R, "E_star": Es, "a": a, "p0": 3.0 * P / (2.0 * np.pi * a**2)}
    if mu > 0:
        out["c"] = a * max(1.0 - Q / (mu * P), 0.0) ** (1.0 / 3.0)
    return out


def pressure(r, **v):
    """Hertz p(r)."""
    h = analytical(**v)
    xi = np.asarray(r) / h["a"]
    return np.where(xi < 1, h["p0"] * np.sqrt(np.clip(1 - xi**2, 0, None)), 0.0)


def shear(r, **v):
    """Cattaneo–Mindlin's tangential traction along a radius (magnitude; mu = 0: zero)."""
    h = analytical(**v)
    if "c" not in h:
        return np.zeros_like(np.asarray(r, dtype=float))
    return partial_slip(r, h["a"], h["c"], h["p0"], v["mu"])


def _cap(r, R, side):
    """z of the cap at radius r and dz/dR: lower body (side -1) top, upper (+1) bottom."""
    s = np.sqrt(R**2 - r**2)
    return side * (R - s), side * (1.0 - R / s)


def extents(nominal: dict | None = None, *, size: float = 12.0, zone: float = 1.5):
    """(a0, W, fine): Hertz's radius at the nominal values, each body's half-width
    and depth W, the width of the uniformly fine zone at the contact."""
    nom = {**DEFAULTS, **(nominal or {})}
    a0 = analytical(nom["P"], nom["R1"], nom["R2"], nom["E1"], nom["E2"], nom["nu1"], nom["nu2"])["a"]
    W = WIDTH * min(nom["R1"], nom["R2"])
    size = min(size, W / a0)
    return a0, W, min(zone, 0.5 * size) * a0


def grid(nominal: dict | None = None, *, refine: int = 0, n_fine: int = 8, ratio: float = 2 / 3,
         half: bool = False, size: float = 12.0, zone: float = 1.5):
    """Grid lines of the two bodies: (x lines of the lower, y lines of the lower,
    x and y lines of the upper, relative depths of the lower's rows and of the
    upper's, a0, W), sized by the nominal values. ``half``: x from -W (the
    half model), else from 0."""
    check_mesh_options(refine, n_fine, size, zone)
    if not 0.1 <= ratio <= 10:
        raise InputError(f"ratio (upper/lower cell counts at the interface) must be in [0.1, 10], got {ratio}")
    a0, W, fine = extents(nominal, size=size, zone=zone)
    k = 2**refine
    growth = 1.3 ** (1.0 / k)

    def lines(n):
        return graded_coordinates(W, fine, n, growth)

    def rows(n):
        return graded_coordinates(W, fine * 2 / 3, max(int(round(n * 2 / 3)), 1), growth) / W

    n1 = n_fine * k
    n2 = max(int(round(n_fine * ratio)) * k, 1)
    y1, y2 = lines(n1), lines(n2)
    x1 = np.concatenate([-y1[:0:-1], y1]) if half else y1
    x2 = np.concatenate([-y2[:0:-1], y2]) if half else y2
    return x1, y1, x2, y2, rows(n1), rows(n2), a0, W


def _bilinear(xs, ys, Z, x, y):
    """The bilinear interpolation of nodal values Z (len(ys), len(xs)) at (x, y)."""
    i = np.clip(np.searchsorted(xs, x) - 1, 0, len(xs) - 2)
    j = np.clip(np.searchsorted(ys, y) - 1, 0, len(ys) - 2)
    u = (x - xs[i]) / (xs[i + 1] - xs[i])
    v = (y - ys[j]) / (ys[j + 1] - ys[j])
    return ((1 - u) * (1 - v) * Z[j, i] + u * (1 - v) * Z[j, i + 1] + u * v * Z[j + 1, i + 1]
            + (1 - u) * v * Z[j + 1, i])


def touch_offset(x1, y1, x2, y2, R1, R2) -> float:
    """How far the upper body is lowered so that the two faceted caps are in
    contact at the lower surface's central node: 1.5 x the N_0-weighted mean gap
    between the two surfaces over that node's face (> 0 since the caps curve
    away from each other; the node's dual-weighted gap is its nodal gap, 0 where
    they touch), a small fraction of the cell size. Without it no node would be
    in compression at the start and the upper body, held by the contact alone,
    would float (a singular first tangent). From the *nominal* radii: a fixed
    part of the mesh (docs/theory.md §13.11)."""
    h = float(y1[1] - y1[0])
    t = np.linspace(0.0, h, 201)
    X, Y = np.meshgrid(t, t)
    low = _bilinear(y1, y1, _cap(np.hypot(*np.meshgrid(y1, y1)), R1, -1)[0], X, Y)
    up = _bilinear(y2, y2, _cap(np.hypot(*np.meshgrid(y2, y2)), R2, +1)[0], X, Y)
    N = (1.0 - X / h) * (1.0 - Y / h)
    w = np.outer(*(2 * [np.r_[0.5, np.ones(199), 0.5]]))
    return 1.5 * float(np.sum(w * N * (up - low)) / np.sum(w * N))


def _body(xs, ys, eta, R, W, side):
    """(mesh, V = dX/dR) of one body: lines xs, ys, relative depths eta (0 at the cap)."""
    if side < 0:
        m = box(xs, ys, -eta[::-1])
        e = -m.nodes[:, 2]
    else:
        m = box(xs, ys, eta)
        e = m.nodes[:, 2]
    r = np.hypot(m.nodes[:, 0], m.nodes[:, 1])
    zc, dzc = _cap(r, R, side)
    z = zc + e * (side * W - zc)
    V = np.zeros_like(m.nodes)
    V[:, 2] = (1.0 - e) * dzc
    return Mesh3D(np.column_stack([m.nodes[:, :2], z]), m.cells, m.node_sets, m.face_sets), V


def spheres_problem(params: dict | None = None, *, refine: int = 0, n_fine: int = 8,
                    ratio: float = 2 / 3, nominal: dict | None = None, kinematics: str = "auto",
                    force_size: bool = False, solver="auto") -> Problem:
    """Build the two-sphere problem.

    Args:
        params: overrides of :data:`DEFAULTS` (R1, R2, E1, E2, nu1, nu2, P, mu, Q)
            and eps, eps_t.
        refine: each level halves the cell size everywhere.
        n_fine: the lower body's cells across the fine zone (1.5 a0 from the axis).
        ratio: the upper body's cell count at the interface relative to the lower's.
        nominal: the values that size the grid (default :data:`DEFAULTS`).
        kinematics: of the contact pair ("auto": linearised, the bodies being
            linear elastic).
        force_size: build the meshes even if they are estimated not to fit in
            memory with ``solver`` (the run's linear solver).

    With mu > 0 the problem has friction (Coulomb), the half model and the load
    path P then Q; the radii are shape parameters.
    """
    values = checked_values("spheres problem", DEFAULTS, params, extra=("eps", "eps_t"),
                            positive=("R1", "R2", "E1", "E2", "P"), nonnegative=("mu", "Q"))
    values = {k: float(v) for k, v in values.items()}
    check_partial_slip("spheres problem", values)
    friction = values["mu"] > 0
    what = "the two-sphere mesh"
    hint = "a coarser mesh (smaller --refine or --n-fine)" + iterative_hint(solver)
    check_fine_zone(refine, n_fine, dim=3, what=what, force=force_size, solver=solver, hint=hint)
    x1, y1, x2, y2, e1, e2, a0, W = grid(nominal, refine=refine, n_fine=n_fine, ratio=ratio, half=friction)
    n_nodes = len(x1) * len(y1) * len(e1) + len(x2) * len(y2) * len(e2)
    check_size(3 * n_nodes + (3 if friction else 1) * len(x1) * len(y1), force=force_size, what=what,
               dim=3, solver=solver, hint=hint)
    if np.sqrt(2.0) * W > 0.999 * min(values["R1"], values["R2"]):
        raise InputError("spheres problem: the radii are too small for the grid (built for the "
                         "nominal radii); pass nominal= with radii near those of the run")
    low, V1 = _body(x1, y1, e1, values["R1"], W, -1)
    up, V2 = _body(x2, y2, e2, values["R2"], W, +1)
    nom = {**DEFAULTS, **(nominal or {})}
    dz = touch_offset(x1[x1 >= 0], y1, x2[x2 >= 0], y2, nom["R1"], nom["R2"])
    up = Mesh3D(up.nodes - [0.0, 0.0, dz], up.cells, up.node_sets, up.face_sets)
    mesh = merge({"lower": low, "upper": up})
    shape = {"R1": np.concatenate([V1, np.zeros_like(V2)]), "R2": np.concatenate([np.zeros_like(V1), V2])}
    h = float(y1[1] - y1[0])
    E0 = min(nom["E1"], nom["E2"])
    values.setdefault("eps", E0 / h)
    values.setdefault("eps_t", E0 / h)
    share = 0.5 if friction else 0.25  # the model's part of the whole sphere
    fixed = [Fixed("lower.z0", 2), Fixed("lower.y0", 1), Fixed("upper.y0", 1)]
    loads = [Pressure("upper.z1", lambda p: share * p["P"], resultant=True,
                      ramp=_FIRST if friction else Ramp(0.0, 1.0))]
    if friction:
        fixed += [Fixed("upper.x0", 0), Fixed("upper.x1", 0)]
        area = float(np.ptp(x1) * np.ptp(y1))
        loads.append(Traction("lower.z0", (lambda p: share * p["Q"] / area, 0.0, 0.0), ramp=_SECOND))
        method = Coulomb("mu", "eps", "eps_t")
    else:
        values.pop("eps_t")
        fixed += [Fixed("lower.x0", 0), Fixed("upper.x0", 0)]
        method = AugmentedLagrangian("eps")
    return Problem(mesh=mesh,
                   material=Bodies({"lower": LinearElastic("E1", "nu1"),
                                    "upper": LinearElastic("E2", "nu2")}),
                   params=values, fixed=tuple(fixed), loads=tuple(loads),
                   contact=(pair("lower.z1", "upper.z0", method, kinematics),),
                   shape=shape, shape_nominal={"R1": values["R1"], "R2": values["R2"]})
