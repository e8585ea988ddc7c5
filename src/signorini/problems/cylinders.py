"""Two elastic cylinders pressed together in plane strain (Hertz), then sheared
(Mindlin): the two-body contact example (docs/theory.md §13, docs/cli.md).

Each body is the part of its cylinder near the contact, |x| <= W and a depth H
below (lower cylinder, radius R1, centre (0, -R1)) or above (upper, R2, centre
(0, R2)) the initial contact point at the origin: a block whose face towards
the other body is the circular arc. The two meshes do not match along the
interface (the upper one is coarser); the lower surface is the slave of the
mortar pair.

Supports and loads: the lower body's bottom is held vertically (which also
keeps it from rotating); the upper body's sides are held horizontally (which
keeps it from rotating, so that the couple of a tangential load is carried by
the supports, not by a shift of the contact pressure) and its top carries the
force P (a uniform pressure of resultant P). With friction, a tangential force
Q (a uniform traction of resultant Q on the lower body's bottom) follows P: P
over the first half of the increments, Q over the second (Mindlin's loading);
the lower body is then held horizontally by the friction alone. Without
friction, one node of the lower body's bottom is held horizontally.

Hertz (1/R = 1/R1 + 1/R2, 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2)::

    b = sqrt(4 P R / (pi E*)),  p0 = 2 P / (pi b),  p(x) = p0 sqrt(1 - x^2/b^2);

Mindlin (elastically similar bodies, Q < mu P): stick zone |x| < c,
c = b sqrt(1 - Q/(mu P)), shear traction
q(x) = mu p0 [sqrt(1 - x^2/b^2) - (c/b) sqrt(1 - x^2/c^2)] (the second term
only for |x| < c).

The grid lines (their x and the rows' relative depths) are sized by the
*nominal* values (:data:`DEFAULTS`) and the mesh options, never by the values
of a run; the radii move the nodes smoothly: a node at column x and relative
depth eta of a body lies at y = y_arc(x; R) + eta (y_bottom - y_arc), so the
shape design velocities dX/dR1, dX/dR2 are exact, and a run at R1 + h has the
nodes of the run at R1 moved by h V + O(h^2).
"""

from __future__ import annotations

import numpy as np


from ..contact import AugmentedLagrangian, Coulomb
from ..contact.mortar import pair
from .values import check_partial_slip, checked_values
from ..errors import InputError
from ..fem.loads import Fixed, Pressure, Ramp, Traction
from ..fem.mesh import Mesh, graded_coordinates, merge, rectangle
from ..materials import Bodies, LinearElastic
from ..model.problem import Problem
from ..linsolve import check_size
from .hertz import check_fine_zone, check_mesh_options

DEFAULTS = {"R1": 1.0, "R2": 1.0, "E1": 100.0, "E2": 100.0, "nu1": 0.3, "nu2": 0.3, "P": 0.1,
            "mu": 0.0, "Q": 0.0}
#: the half-width and the depth of each body, in units of the nominal radius R1
WIDTH = 0.5


def analytical(P, R1, R2, E1, E2, nu1, nu2, mu=0.0, Q=0.0) -> dict:
    """Hertz half-width b and peak pressure p0; with mu > 0, Mindlin's stick
    half-width c (docs/theory.md §13.6)."""
    R = 1.0 / (1.0 / R1 + 1.0 / R2)
    Es = 1.0 / ((1 - nu1**2) / E1 + (1 - nu2**2) / E2)
    b = np.sqrt(4.0 * P * R / (np.pi * Es))
    out = {"R": R, "E_star": Es, "b": b, "p0": 2.0 * P / (np.pi * b)}
    if mu > 0:
        out["c"] = b * np.sqrt(max(1.0 - Q / (mu * P), 0.0))
    return out


def pressure(x, **v):
    """Hertz p(x)."""
    h = analytical(**v)
    xi = np.asarray(x) / h["b"]
    return np.where(np.abs(xi) < 1, h["p0"] * np.sqrt(np.clip(1 - xi**2, 0, None)), 0.0)


def shear(x, **v):
    """Mindlin's q(x) (magnitude; with mu = 0: zero)."""
    h = analytical(**v)
    if "c" not in h:
        return np.zeros_like(np.asarray(x, dtype=float))
    return partial_slip(x, h["b"], h["c"], h["p0"], v["mu"])


def partial_slip(x, a, c, p0, mu):
    """The tangential traction of Mindlin's partial slip (magnitude) at distance
    |x| from the centre of a contact of half-width or radius a, stick zone c:
    mu p0 sqrt(1 - x²/a²) - (c/a) mu p0 sqrt(1 - x²/c²), the second term for
    |x| < c (two cylinders, and Cattaneo–Mindlin's two spheres along a radius)."""
    x = np.abs(np.asarray(x, dtype=float))
    q = mu * p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    inner = (c / a) * np.sqrt(np.clip(1 - (x / max(c, 1e-300)) ** 2, 0, None))
    return q - mu * p0 * np.where(x < c, inner, 0.0)


def _arc(x, R, side):
    """y of the arc at x and dy/dR: lower body (side -1) top, upper (side +1) bottom."""
    s = np.sqrt(R**2 - x**2)
    return side * (R - s), side * (1.0 - R / s)


def grid(nominal: dict | None = None, *, refine: int = 0, n_fine: int = 24, ratio: float = 2 / 3,
         size: float = 15.0, zone: float = 1.5):
    """Grid lines of the two bodies: (x columns of the lower, of the upper, relative
    depths of the lower's rows, of the upper's, b0, W) from the nominal values."""
    check_mesh_options(refine, n_fine, size, zone)
    if not 0.1 <= ratio <= 10:
        raise InputError(f"ratio (upper/lower cell counts at the interface) must be in [0.1, 10], got {ratio}")
    b0, W, fine = extents(nominal, size=size, zone=zone)
    k = 2**refine
    growth = 1.2 ** (1.0 / k)

    def columns(n):
        half = graded_coordinates(W, fine, n, growth)
        return np.concatenate([-half[:0:-1], half])

    def rows(n):
        d = graded_coordinates(W, fine * 2 / 3, max(int(round(n * 2 / 3)), 1), growth)
        return d / W  # relative depth 0 (at the arc) .. 1 (at the far face)

    n1 = n_fine * k
    n2 = max(int(round(n_fine * ratio)) * k, 1)
    return columns(n1), columns(n2), rows(n1), rows(n2), b0, W


def extents(nominal: dict | None = None, *, size: float = 15.0, zone: float = 1.5):
    """(b0, W, fine) of the grid sized by the nominal values: Hertz's half-width
    b0, each body's half-width and depth W, and the half-width of the uniformly
    fine zone at the contact (zone b0, at most half the bodies' width)."""
    nom = {**DEFAULTS, **(nominal or {})}
    b0 = analytical(nom["P"], nom["R1"], nom["R2"], nom["E1"], nom["E2"], nom["nu1"], nom["nu2"])["b"]
    W = WIDTH * min(nom["R1"], nom["R2"])
    if size * b0 > W:
        size = W / b0
    return b0, W, min(zone, 0.5 * size) * b0


def touch_offset(xs1, xs2, R1, R2) -> float:
    """How far the upper body is lowered so that the two discretised arcs are in
    contact at the lower surface's central node: 1.5 x the N_0-weighted average of
    the gap between the two polygons over that node's segments (> 0 since the arcs
    curve away from each other; the node's dual-weighted gap, its nodal gap, is 0
    when they touch), a few 1e-3 of the cell size. Without it no node would be
    in compression at the start and
    the upper body, held only by the contact, would float (singular first
    tangent). It is computed from the *nominal* radii: a fixed part of the mesh."""
    j = len(xs1) // 2
    h1 = xs1[j + 1] - xs1[j]
    x = np.linspace(-h1, h1, 40001)
    g = np.interp(x, xs2, _arc(xs2, R2, +1)[0]) - np.interp(x, xs1, _arc(xs1, R1, -1)[0])
    N = 1.0 - np.abs(x) / h1
    return 1.5 * float(np.trapezoid(N * g, x) / np.trapezoid(N, x))


def _body(xs, eta, R, W, side):
    """(mesh, V = dX/dR) of one body: columns xs, relative depths eta (0 at the arc)."""
    # rectangle on (x, s) with s = -eta (lower) or +eta (upper) increasing
    if side < 0:
        m = rectangle(xs, -eta[::-1])
        e = -m.nodes[:, 1]
    else:
        m = rectangle(xs, eta)
        e = m.nodes[:, 1]
    x = m.nodes[:, 0]
    ya, dya = _arc(x, R, side)
    yfar = side * W
    y = ya + e * (yfar - ya)
    V = np.column_stack([np.zeros_like(x), (1.0 - e) * dya])
    return Mesh(np.column_stack([x, y]), m.cells, m.node_sets, m.edge_sets), V


def cylinders_problem(params: dict | None = None, *, refine: int = 0, n_fine: int = 24,
                      ratio: float = 2 / 3, nominal: dict | None = None,
                      kinematics: str = "auto", force_size: bool = False,
                      solver="auto") -> Problem:
    """Build the two-cylinder problem.

    Args:
        params: overrides of :data:`DEFAULTS` (R1, R2, E1, E2, nu1, nu2, P, mu, Q)
            and eps, eps_t.
        refine: each level halves the cell size everywhere.
        n_fine: the lower body's cells across the fine zone (1.5 b0 on each side).
        ratio: the upper body's cell count at the interface relative to the lower's.
        nominal: the values that size the grid (default :data:`DEFAULTS`).
        kinematics: of the contact pair ("auto": linearised, the bodies being
            linear elastic).
        force_size: build the meshes even if they are estimated not to fit in
            memory with ``solver`` (the run's linear solver).

    With mu > 0 the problem has friction (Coulomb) and the load path P then Q;
    the radii are shape parameters (their meshes at the run's values, the
    design velocities exact).
    """
    values = checked_values("cylinders problem", DEFAULTS, params, extra=("eps", "eps_t"),
                            positive=("R1", "R2", "E1", "E2", "P"), nonnegative=("mu", "Q"))
    values = {k: float(v) for k, v in values.items()}
    check_partial_slip("cylinders problem", values)
    what = "the two-cylinder mesh"
    hint = "a coarser mesh (smaller --refine or --n-fine)"
    # the lower body's fine zone on one side of the contact: a lower bound
    check_fine_zone(refine, n_fine, what=what, force=force_size, solver=solver, hint=hint)
    xs1, xs2, e1, e2, b0, W = grid(nominal, refine=refine, n_fine=n_fine, ratio=ratio)
    multipliers = (2 if values["mu"] > 0 else 1) * len(xs1)
    check_size(2 * (len(xs1) * len(e1) + len(xs2) * len(e2)) + multipliers, force=force_size,
               what=what, solver=solver, hint=hint)
    if W > 0.999 * min(values["R1"], values["R2"]):
        raise InputError("cylinders problem: the radii are too small for the grid (built for the "
                         "nominal radii); pass nominal= with radii near those of the run")
    low, V1 = _body(xs1, e1, values["R1"], W, -1)
    up, V2 = _body(xs2, e2, values["R2"], W, +1)
    nom = {**DEFAULTS, **(nominal or {})}
    up = Mesh(up.nodes - [0.0, touch_offset(xs1, xs2, nom["R1"], nom["R2"])], up.cells,
              up.node_sets, up.edge_sets)
    mesh = merge({"lower": low, "upper": up})
    zeros1, zeros2 = np.zeros_like(V2), np.zeros_like(V1)
    shape = {"R1": np.concatenate([V1, zeros1]), "R2": np.concatenate([zeros2, V2])}
    centre = int(mesh.node_sets["lower.bottom"][np.argmin(np.abs(low.nodes[low.node_sets["bottom"], 0]))])
    mesh = Mesh(mesh.nodes, mesh.cells, {**mesh.node_sets, "lower.centre": [centre]}, mesh.edge_sets)
    h = xs1[len(xs1) // 2 + 1] - xs1[len(xs1) // 2]
    E0 = min(DEFAULTS["E1"], DEFAULTS["E2"]) if nominal is None else min(nominal.get("E1", 100.0),
                                                                         nominal.get("E2", 100.0))
    if "eps" not in (params or {}):
        values["eps"] = E0 / h
    if "eps_t" not in (params or {}):
        values["eps_t"] = E0 / h
    friction = values["mu"] > 0
    width = 2.0 * W
    fixed = [Fixed("lower.bottom", 1), Fixed("upper.left", 0), Fixed("upper.right", 0)]
    loads = [Pressure("upper.top", "P", resultant=True, ramp=_first if friction else _whole)]
    if friction:
        loads.append(Traction("lower.bottom", (lambda p: p["Q"] / width, 0.0), ramp=_second))
        method = Coulomb("mu", "eps", "eps_t")
    else:
        fixed.append(Fixed("lower.centre", 0))
        method = AugmentedLagrangian("eps")
    return Problem(mesh=mesh,
                   material=Bodies({"lower": LinearElastic("E1", "nu1"),
                                    "upper": LinearElastic("E2", "nu2")}),
                   params=values, fixed=tuple(fixed), loads=tuple(loads),
                   contact=(pair("lower.top", "upper.bottom", method, kinematics),),
                   shape=shape, shape_nominal={"R1": values["R1"], "R2": values["R2"]})


def _whole(t):
    return t


#: P over the first half of the path, Q over the second (Mindlin's loading)
_first, _second = Ramp(0.0, 0.5), Ramp(0.5, 1.0)
