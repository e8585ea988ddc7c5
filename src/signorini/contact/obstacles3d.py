"""Rigid obstacles in three dimensions, and a user-defined surface in two or three.

:class:`Plane`, :class:`Sphere` and :class:`Cylinder` are obstacles of a 3-D mesh
(:class:`~signorini.fem.mesh3d.Mesh3D`); a 2-D problem, plane strain or
axisymmetric, uses :class:`~signorini.contact.obstacles.Line` and
:class:`~signorini.contact.obstacles.Circle`. :class:`Implicit` works with either:
in 3-D with any contact law, friction included (the Coulomb disc), in 2-D
frictionless (it has no slip coordinate along a line).

Each obstacle gives, for a point ``x`` and its resolved geometry ``geo =
obstacle.geometry(params, t)``, the gap ``gap(x, geo)`` (>= 0: separated), the
unit normal ``normal(x, geo)`` pointing from the obstacle into the body, and the
closest point ``closest(x, geo)`` in the obstacle's own frame (relative to
``geo["c"]``, the reference point that moves with the obstacle, and in the axes
that turn with it: a point carried along with the obstacle keeps its closest
point, so it does not slip). All are pure JAX functions, differentiated by
autodiff with respect to the point and to the obstacle's parameters
(docs/theory.md §12.3). Every geometry carries ``geo["shift"]``, the obstacle's
translation since t = 0, and ``geo["Q"]``, its rotation since t = 0 (3 x 3).

A 3-D obstacle moves along ``motion`` (a translation of its reference point) and
turns by ``rotation`` about that point: a rotation vector (axis times angle in
radians; the obstacle turns by t times it) or legs ((vector, ramp), ...) as for
the motion, applied in their order, each about its axis fixed in space through
the moving reference point (docs/theory.md §12.3).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .._jax import jax, jnp
from ..errors import InputError
from ..params import Spec, resolve
from .obstacles import is_legs, motion_legs, motion_specs, shift_at


def _vector(spec, params):
    return jnp.stack([jnp.asarray(resolve(s, params), dtype=float) for s in spec])


def _unit(v):
    return v / jnp.sqrt(v @ v)


def _nonzero(spec, params, what: str) -> None:
    v = _vector(spec, params)
    if not float(jnp.sqrt(v @ v)) > 0:
        raise InputError(f"the {what} must be a non-zero vector, got {[float(a) for a in v]}")


def _positive(spec, params, what: str) -> None:
    r = float(resolve(spec, params))
    if not r > 0:
        raise InputError(f"the {what} must be positive, got {r}")


def _rodrigues(w):
    """exp([w]x): the rotation by |w| about w / |w|, smooth at w = 0 (series)."""
    s = w @ w
    small = s < 1e-8
    ss = jnp.where(small, 1.0, s)
    r = jnp.sqrt(ss)
    a = jnp.where(small, 1.0 - s / 6.0 + s * s / 120.0, jnp.sin(r) / r)
    b = jnp.where(small, 0.5 - s / 24.0 + s * s / 720.0, (1.0 - jnp.cos(r)) / ss)
    K = jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return jnp.eye(3) + a * K + b * (K @ K)


def rotation_at(rotation, params, t):
    """The obstacle's rotation (3 x 3) from its pose at t = 0 at the load factor t:
    the legs' rotations composed in their order (the last applied last)."""
    Q = jnp.eye(3)
    if rotation is None:
        return Q
    legs = rotation if is_legs(rotation) else ((rotation, None),)
    for vec, ramp in legs:
        f = t if ramp is None else ramp(t) - ramp(0.0)
        Q = _rodrigues(f * _vector(vec, params)) @ Q
    return Q


def _rotation_legs(rotation, what: str):
    return motion_legs(rotation, 3, what + " (rotation)")


class _Surface:
    """What every obstacle of this module derives from its shape in its own frame:
    ``_gap``, ``_normal`` and ``_closest`` of ``y = Q^T (x - c)`` (the point in the
    obstacle's axes, relative to its reference point). The shape's own vectors
    (a plane's normal, a cylinder's axis) are those at t = 0."""

    def _local(self, x, geo):
        return geo["Q"].T @ (x - geo["c"])

    def gap(self, x, geo):
        return self._gap(self._local(x, geo), geo)

    def normal(self, x, geo):
        return geo["Q"] @ self._normal(self._local(x, geo), geo)

    def closest(self, x, geo):
        """The closest point in the obstacle's own frame (relative to its
        reference point, in its turning axes)."""
        return self._closest(self._local(x, geo), geo)

    def project(self, x, geo):
        """The closest point of the obstacle, in the global frame."""
        return geo["c"] + geo["Q"] @ self.closest(x, geo)

    def _frame(self, params, t):
        """(shift, Q): the translation and rotation since t = 0."""
        return shift_at(self.motion, params, t, 3), rotation_at(self.rotation, params, t)

    def _rotation_specs(self):
        return motion_specs(self.rotation)

    def coordinate(self, x, geo):
        raise InputError(f"{type(self).__name__} has no slip coordinate along a line (the 2-D "
                         "friction law's history); friction on it is the Coulomb-disc law "
                         "(signorini.contact.friction3d.CoulombDisc)")


@dataclass(frozen=True)
class Plane(_Surface):
    """Rigid plane through ``point`` (moving as ``point + t * motion``, turning
    by ``rotation`` about it) with the unit normal ``normal_vector`` (normalised
    on use) pointing into the body: a flat die (3-D; in 2-D:
    :class:`~signorini.contact.obstacles.Line`)."""

    point: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)
    normal_vector: tuple[Spec, Spec, Spec] = (0.0, 0.0, -1.0)
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)
    rotation: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))
        object.__setattr__(self, "rotation", _rotation_legs(self.rotation, type(self).__name__))

    def specs(self):
        return (*self.point, *self.normal_vector, *motion_specs(self.motion),
                *self._rotation_specs())

    def geometry(self, params, t):
        shift, Q = self._frame(params, t)
        return {"c": _vector(self.point, params) + shift,
                "n": _unit(_vector(self.normal_vector, params)), "shift": shift, "Q": Q}

    def check(self, params):
        _nonzero(self.normal_vector, params, "plane's normal")

    @staticmethod
    def _gap(y, geo):
        return y @ geo["n"]

    @staticmethod
    def _normal(y, geo):
        return geo["n"]

    @staticmethod
    def _closest(y, geo):
        return y - (y @ geo["n"]) * geo["n"]


@dataclass(frozen=True)
class Sphere(_Surface):
    """Rigid sphere of radius ``radius`` centred at ``centre + t * motion``,
    turning by ``rotation`` about its centre (a spinning or rolling ball drags
    what sticks to it); the body lies outside (3-D; an axisymmetric model of a
    sphere on the axis: :class:`~signorini.contact.obstacles.Circle` centred at
    r = 0)."""

    radius: Spec = "R"
    centre: tuple[Spec, Spec, Spec] = (0.0, 0.0, "R")
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)
    rotation: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))
        object.__setattr__(self, "rotation", _rotation_legs(self.rotation, type(self).__name__))

    def specs(self):
        return (self.radius, *self.centre, *motion_specs(self.motion), *self._rotation_specs())

    def geometry(self, params, t):
        shift, Q = self._frame(params, t)
        return {"R": jnp.asarray(resolve(self.radius, params), dtype=float),
                "c": _vector(self.centre, params) + shift, "shift": shift, "Q": Q}

    def check(self, params):
        _positive(self.radius, params, "sphere's radius")

    @staticmethod
    def _gap(y, geo):
        return jnp.sqrt(y @ y) - geo["R"]

    @staticmethod
    def _normal(y, geo):
        return _unit(y)

    @staticmethod
    def _closest(y, geo):
        return geo["R"] * _unit(y)


@dataclass(frozen=True)
class Cylinder(_Surface):
    """Rigid circular cylinder of radius ``radius`` around the axis through
    ``centre + t * motion`` along ``axis`` (normalised on use), turning by
    ``rotation`` about the centre (a roller turning about ``axis``, or a
    cylinder tilted); the body lies outside (3-D; a plane-strain model of a
    long cylinder: :class:`~signorini.contact.obstacles.Circle`)."""

    radius: Spec = "R"
    centre: tuple[Spec, Spec, Spec] = (0.0, 0.0, "R")
    axis: tuple[Spec, Spec, Spec] = (0.0, 1.0, 0.0)
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)
    rotation: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))
        object.__setattr__(self, "rotation", _rotation_legs(self.rotation, type(self).__name__))

    def specs(self):
        return (self.radius, *self.centre, *self.axis, *motion_specs(self.motion),
                *self._rotation_specs())

    def geometry(self, params, t):
        shift, Q = self._frame(params, t)
        return {"R": jnp.asarray(resolve(self.radius, params), dtype=float),
                "c": _vector(self.centre, params) + shift, "a": _unit(_vector(self.axis, params)),
                "shift": shift, "Q": Q}

    def check(self, params):
        _positive(self.radius, params, "cylinder's radius")
        _nonzero(self.axis, params, "cylinder's axis")

    @staticmethod
    def _radial(y, geo):
        return y - (y @ geo["a"]) * geo["a"], y @ geo["a"]

    @classmethod
    def _gap(cls, y, geo):
        r, _ = cls._radial(y, geo)
        return jnp.sqrt(r @ r) - geo["R"]

    @classmethod
    def _normal(cls, y, geo):
        return _unit(cls._radial(y, geo)[0])

    @classmethod
    def _closest(cls, y, geo):
        r, along = cls._radial(y, geo)
        return along * geo["a"] + geo["R"] * _unit(r)


@dataclass(frozen=True)
class Implicit(_Surface):
    """A rigid surface given by a signed distance ``distance(y, p)``: a JAX
    function of the point ``y`` relative to the obstacle's reference point
    (``origin + t * motion``, in the obstacle's axes when it turns by
    ``rotation``, 3-D only) and of the dict ``p`` of the values of
    ``parameters`` (name -> parameter spec), positive outside the obstacle (where
    the body is). Works with two coordinates (a 2-D problem: (x, y) in plane
    strain, (r, z) in axisymmetry; frictionless laws only) or three (a 3-D mesh;
    every law, Coulomb friction included); ``origin`` and ``motion`` have as many.

    The gap is the function's value, the normal its normalised gradient
    (autodiff), the closest point ``y - g n`` (exact when the function is a
    distance; to first order in g otherwise). Example, a sphere of radius ``R``::

        import jax.numpy as jnp
        import signorini as sg

        sg.Implicit(lambda y, p: jnp.sqrt(y @ y) - p["R"], {"R": "R"}, origin=(0, 0, "R"))
    """

    distance: Callable
    parameters: Mapping[str, Spec] = field(default_factory=dict)
    origin: tuple = (0.0, 0.0, 0.0)
    motion: tuple | None = None
    rotation: tuple | None = None

    def __post_init__(self):
        dim = len(tuple(self.origin))
        object.__setattr__(self, "motion", motion_legs(self.motion, dim, "Implicit"))
        if self.rotation is not None and dim != 3:
            raise InputError("Implicit: a rotation needs a 3-D obstacle (three origin "
                             f"coordinates), got {dim}")
        object.__setattr__(self, "rotation", _rotation_legs(self.rotation, "Implicit"))

    def specs(self):
        return (*self.parameters.values(), *self.origin, *motion_specs(self.motion),
                *self._rotation_specs())

    def geometry(self, params, t):
        origin = _vector(self.origin, params)
        dim = origin.shape[0]
        shift = shift_at(self.motion, params, t, dim)
        Q = rotation_at(self.rotation, params, t) if dim == 3 else jnp.eye(dim)
        p = {k: jnp.asarray(resolve(s, params), dtype=float) for k, s in self.parameters.items()}
        return {"c": origin + shift, "p": p, "shift": shift, "Q": Q}

    def check(self, params):
        geo = self.geometry(params, 0.0)
        y = geo["c"] + 1.0
        try:
            g = self.distance(y, geo["p"])
            if jnp.shape(g) != ():
                raise InputError(f"Implicit: the distance function must return a scalar, got "
                                 f"shape {jnp.shape(g)}")
            n = jax.grad(self.distance)(y, geo["p"])
        except InputError:
            raise
        except Exception as e:  # noqa: BLE001  (a user function: say which and why)
            raise InputError(f"Implicit: the distance function cannot be evaluated at a point "
                             f"with {geo['c'].shape[0]} coordinates and parameters "
                             f"{sorted(geo['p'])}: {type(e).__name__}: {e}") from None
        if not bool(jnp.all(jnp.isfinite(n))):
            raise InputError("Implicit: the distance function's gradient is not finite at a test "
                             "point; it must be differentiable (write it with jax.numpy)")

    def _gap(self, y, geo):
        return self.distance(y, geo["p"])

    def _normal(self, y, geo):
        return _unit(jax.grad(self.distance)(y, geo["p"]))

    def _closest(self, y, geo):
        return y - self._gap(y, geo) * self._normal(y, geo)
