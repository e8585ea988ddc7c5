"""Rigid obstacles: gap, outward normal, projection and slip coordinate.

All functions are pure JAX functions of the point ``x`` (2,) and the resolved
geometry ``geo = obstacle.geometry(params, t)``, so they can be differentiated
with respect to the position and to the obstacle's own parameters (radius,
centre, ...). Normal ``n'`` points from the obstacle into the body; ``g >= 0``
means separated. Every geometry carries ``geo["shift"]``, the rigid translation
of the obstacle from its position at t = 0, which the linearised kinematics
subtract from the displacement (:class:`Linearized`). See docs/theory.md §6.
"""

from __future__ import annotations

from dataclasses import dataclass

from .._jax import jax, jnp
from ..errors import InputError
from ..params import Spec, resolve


def _point(spec, params):
    return jnp.stack([jnp.asarray(resolve(s, params), dtype=float) for s in spec])


def motion_legs(motion, dim: int, what: str) -> tuple:
    """An obstacle's ``motion`` as it is kept: a vector of ``dim`` parameter specs
    (the obstacle moves by t times it), or legs ((vector, ramp), ...), each
    vector moved along its ramp of t (:class:`~signorini.Ramp`,
    :class:`~signorini.Table` or a function of t): press then slide
    ``(((0, "-d"), Ramp(0, 0.5)), (("s", 0), Ramp(0.5, 1)))``, load and unload
    ``(((0, "-d"), Table((0, 0.5, 1), (0, 1, 0))),)``."""
    if motion is None:
        return None
    items = tuple(motion)
    legs = bool(items) and all(isinstance(m, (tuple, list)) and len(m) == 2 and callable(m[1])
                               for m in items)
    if not legs:
        if len(items) != dim or any(isinstance(m, (tuple, list)) for m in items):
            raise InputError(f"{what}: motion must be {dim} values (the obstacle moves by t times "
                             f"them) or legs ((vector, ramp), ...), got {motion!r}")
        return items
    out = []
    for vec, ramp in items:
        vec = tuple(vec)
        if len(vec) != dim:
            raise InputError(f"{what}: each leg of the motion needs a vector of {dim} values, got "
                             f"{vec!r}")
        out.append((vec, ramp))
    return tuple(out)


def is_legs(motion) -> bool:
    return bool(motion) and isinstance(motion[0], tuple)


def motion_specs(motion) -> tuple:
    """The parameter specs of a motion (vector or legs)."""
    if not motion:
        return ()
    return tuple(s for vec, _ in motion for s in vec) if is_legs(motion) else tuple(motion)


def shift_at(motion, params, t, dim: int):
    """The obstacle's translation from its place at t = 0 at the load factor t."""
    if motion is None:
        return jnp.zeros(dim)
    if is_legs(motion):
        return sum((ramp(t) - ramp(0.0)) * _point(vec, params) for vec, ramp in motion)
    return t * _point(motion, params)


@dataclass(frozen=True)
class Circle:
    """Rigid circle of radius ``radius`` and centre ``centre`` in the (x, y) plane;
    the body lies outside. In plane strain it is a cylinder along z; with
    :class:`~signorini.Axisymmetric` kinematics, the (r, z) half-plane, a
    centre on the axis (r = 0) makes it a sphere, and one off the axis a torus. In
    3-D use :class:`~signorini.Sphere` or :class:`~signorini.Cylinder`.

    The centre moves as ``centre + t * motion`` (t = load factor), or along
    legs of the motion, each a vector times its ramp (:func:`motion_legs`).
    The slip coordinate is s = radius * theta with theta measured from the
    downward vertical (branch cut at the top of the cylinder).
    """

    radius: Spec = "R"
    centre: tuple[Spec, Spec] = (0.0, "R")
    motion: tuple[Spec, Spec] = (0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 2, "Circle"))

    def specs(self):
        return (self.radius, *self.centre, *motion_specs(self.motion))

    def geometry(self, params, t):
        shift = shift_at(self.motion, params, t, 2)
        return {"R": jnp.asarray(resolve(self.radius, params), dtype=float),
                "c": _point(self.centre, params) + shift, "shift": shift}

    def check(self, params):
        r = float(resolve(self.radius, params))
        if not r > 0:
            raise InputError(f"the cylinder radius must be positive, got {r}")

    @staticmethod
    def gap(x, geo):
        d = x - geo["c"]
        return jnp.sqrt(d @ d) - geo["R"]

    @staticmethod
    def normal(x, geo):
        d = x - geo["c"]
        return d / jnp.sqrt(d @ d)

    @classmethod
    def project(cls, x, geo):
        return geo["c"] + geo["R"] * cls.normal(x, geo)

    @staticmethod
    def coordinate(x, geo):
        d = x - geo["c"]
        return geo["R"] * jnp.arctan2(d[0], -d[1])


@dataclass(frozen=True)
class Line:
    """Rigid straight die through ``point`` (moving as ``point + t * motion``, or
    along legs: :func:`motion_legs`),
    with unit normal ``normal`` pointing into the body (normalised on use), in the
    (x, y) plane. In plane strain it is a flat die along z; in axisymmetry, in the
    (r, z) half-plane, a normal along z makes it a flat punch face and one along r
    a cylindrical wall around the axis, and an oblique one a cone. In 3-D use
    :class:`~signorini.Plane`.
    The slip coordinate is the distance along the tangent t' = (-n2, n1)."""

    point: tuple[Spec, Spec] = (0.0, 0.0)
    normal_vector: tuple[Spec, Spec] = (0.0, -1.0)
    motion: tuple[Spec, Spec] = (0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 2, "Line"))

    def specs(self):
        return (*self.point, *self.normal_vector, *motion_specs(self.motion))

    def geometry(self, params, t):
        n = _point(self.normal_vector, params)
        n = n / jnp.sqrt(n @ n)
        shift = shift_at(self.motion, params, t, 2)
        return {"x0": _point(self.point, params) + shift, "n": n, "shift": shift}

    def check(self, params):
        n = _point(self.normal_vector, params)
        if not float(jnp.sqrt(n @ n)) > 0:
            raise InputError("the die normal must be a non-zero vector")

    @staticmethod
    def gap(x, geo):
        return (x - geo["x0"]) @ geo["n"]

    @staticmethod
    def normal(x, geo):
        return geo["n"]

    @classmethod
    def project(cls, x, geo):
        return x - cls.gap(x, geo) * geo["n"]

    @staticmethod
    def coordinate(x, geo):
        n = geo["n"]
        return (x - geo["x0"]) @ jnp.array([-n[1], n[0]])


class Linearized:
    """An obstacle seen with geometrically linear contact kinematics.

    This is the classical Signorini linearisation of small-strain analyses
    (the assumption of the analytical Hertz solution), written in the frame of
    the obstacle: with ``c = geo["shift"]`` the obstacle's rigid translation
    since t = 0, the node's displacement *relative to the obstacle*,
    ``w = u - c``, enters the gap only through its component along the body's
    reference outward normal N, and the slip coordinate only through its
    component along the body's tangent T = (-N2, N1). The expansion point is
    the reference position carried along with the obstacle, Y = X + c::

        g(x) = g(Y) + grad g(Y) . N (N . w),   s(x) = s(Y) + grad s(Y) . T (T . w),
        w = x - Y = u - c.

    A rigid translation of body and obstacle together therefore changes
    neither (docs/theory.md §6.3). In 3-D the closest point (the history of the
    Coulomb disc) is linearised in the body's reference tangent plane:
    ``y(x) = y(Y) + grad y(Y) . (I - N N^T) w`` (docs/theory.md §12.4).
    """

    def __init__(self, base, X, N):
        self.base = base
        self.X = X
        self.N = N
        if N.shape[-1] == 2:
            self.T = jnp.array([-N[1], N[0]])

    def _lin(self, f, x, geo, d):
        Y = self.X + geo["shift"]
        val, dv = jax.jvp(lambda y: f(y, geo), (Y,), (d * (d @ (x - Y)),))
        return val + dv

    def gap(self, x, geo):
        return self._lin(self.base.gap, x, geo, self.N)

    def coordinate(self, x, geo):
        return self._lin(self.base.coordinate, x, geo, self.T)

    def closest(self, x, geo):
        Y = self.X + geo["shift"]
        w = x - Y
        val, dv = jax.jvp(lambda y: self.base.closest(y, geo), (Y,), (w - self.N * (self.N @ w),))
        return val + dv

    def normal(self, x, geo):
        return self.base.normal(self.X + geo["shift"], geo)

    def project(self, x, geo):
        return self.base.project(self.X + geo["shift"], geo)
