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
``geo["c"]``, the reference point that moves with the obstacle: a point carried
along with the obstacle keeps its closest point, so it does not slip). All are
pure JAX functions, differentiated by autodiff with respect to the point and
to the obstacle's parameters (docs/theory.md §12.3). Every geometry carries
``geo["shift"]``, the obstacle's translation since t = 0.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .._jax import jax, jnp
from ..errors import InputError
from ..params import Spec, resolve
from .obstacles import motion_legs, motion_specs, shift_at


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


class _Surface:
    """What every obstacle of this module derives from its ``closest`` point."""

    def project(self, x, geo):
        """The closest point of the obstacle, in the global frame."""
        return geo["c"] + self.closest(x, geo)

    def coordinate(self, x, geo):
        raise InputError(f"{type(self).__name__} has no slip coordinate along a line (the 2-D "
                         "friction law's history); friction on it is the Coulomb-disc law "
                         "(signorini.contact.friction3d.CoulombDisc)")


@dataclass(frozen=True)
class Plane(_Surface):
    """Rigid plane through ``point`` (moving as ``point + t * motion``) with the
    unit normal ``normal_vector`` (normalised on use) pointing into the body: a
    flat die (3-D; in 2-D: :class:`~signorini.contact.obstacles.Line`)."""

    point: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)
    normal_vector: tuple[Spec, Spec, Spec] = (0.0, 0.0, -1.0)
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))

    def specs(self):
        return (*self.point, *self.normal_vector, *motion_specs(self.motion))

    def geometry(self, params, t):
        shift = shift_at(self.motion, params, t, 3)
        return {"c": _vector(self.point, params) + shift,
                "n": _unit(_vector(self.normal_vector, params)), "shift": shift}

    def check(self, params):
        _nonzero(self.normal_vector, params, "plane's normal")

    @staticmethod
    def gap(x, geo):
        return (x - geo["c"]) @ geo["n"]

    @staticmethod
    def normal(x, geo):
        return geo["n"]

    @classmethod
    def closest(cls, x, geo):
        return x - geo["c"] - cls.gap(x, geo) * geo["n"]


@dataclass(frozen=True)
class Sphere(_Surface):
    """Rigid sphere of radius ``radius`` centred at ``centre + t * motion``; the
    body lies outside (3-D; an axisymmetric model of a sphere on the axis:
    :class:`~signorini.contact.obstacles.Circle` centred at r = 0)."""

    radius: Spec = "R"
    centre: tuple[Spec, Spec, Spec] = (0.0, 0.0, "R")
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))

    def specs(self):
        return (self.radius, *self.centre, *motion_specs(self.motion))

    def geometry(self, params, t):
        shift = shift_at(self.motion, params, t, 3)
        return {"R": jnp.asarray(resolve(self.radius, params), dtype=float),
                "c": _vector(self.centre, params) + shift, "shift": shift}

    def check(self, params):
        _positive(self.radius, params, "sphere's radius")

    @staticmethod
    def gap(x, geo):
        d = x - geo["c"]
        return jnp.sqrt(d @ d) - geo["R"]

    @staticmethod
    def normal(x, geo):
        return _unit(x - geo["c"])

    @classmethod
    def closest(cls, x, geo):
        return geo["R"] * cls.normal(x, geo)


@dataclass(frozen=True)
class Cylinder(_Surface):
    """Rigid circular cylinder of radius ``radius`` around the axis through
    ``centre + t * motion`` along ``axis`` (normalised on use); the body lies
    outside (3-D; a plane-strain model of a long cylinder:
    :class:`~signorini.contact.obstacles.Circle`)."""

    radius: Spec = "R"
    centre: tuple[Spec, Spec, Spec] = (0.0, 0.0, "R")
    axis: tuple[Spec, Spec, Spec] = (0.0, 1.0, 0.0)
    motion: tuple[Spec, Spec, Spec] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, 3, type(self).__name__))

    def specs(self):
        return (self.radius, *self.centre, *self.axis, *motion_specs(self.motion))

    def geometry(self, params, t):
        shift = shift_at(self.motion, params, t, 3)
        return {"R": jnp.asarray(resolve(self.radius, params), dtype=float),
                "c": _vector(self.centre, params) + shift, "a": _unit(_vector(self.axis, params)),
                "shift": shift}

    def check(self, params):
        _positive(self.radius, params, "cylinder's radius")
        _nonzero(self.axis, params, "cylinder's axis")

    @staticmethod
    def _radial(x, geo):
        d = x - geo["c"]
        return d - (d @ geo["a"]) * geo["a"], d @ geo["a"]

    @classmethod
    def gap(cls, x, geo):
        r, _ = cls._radial(x, geo)
        return jnp.sqrt(r @ r) - geo["R"]

    @classmethod
    def normal(cls, x, geo):
        return _unit(cls._radial(x, geo)[0])

    @classmethod
    def closest(cls, x, geo):
        r, along = cls._radial(x, geo)
        return along * geo["a"] + geo["R"] * _unit(r)


@dataclass(frozen=True)
class Implicit(_Surface):
    """A rigid surface given by a signed distance ``distance(y, p)``: a JAX
    function of the point ``y`` relative to the obstacle's reference point
    (``origin + t * motion``) and of the dict ``p`` of the values of
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

    def __post_init__(self):
        object.__setattr__(self, "motion", motion_legs(self.motion, len(tuple(self.origin)), "Implicit"))

    def specs(self):
        return (*self.parameters.values(), *self.origin, *motion_specs(self.motion))

    def geometry(self, params, t):
        origin = _vector(self.origin, params)
        shift = shift_at(self.motion, params, t, origin.shape[0])
        p = {k: jnp.asarray(resolve(s, params), dtype=float) for k, s in self.parameters.items()}
        return {"c": origin + shift, "p": p, "shift": shift}

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

    def gap(self, x, geo):
        return self.distance(x - geo["c"], geo["p"])

    def normal(self, x, geo):
        return _unit(jax.grad(self.distance)(x - geo["c"], geo["p"]))

    def closest(self, x, geo):
        return x - geo["c"] - self.gap(x, geo) * self.normal(x, geo)
