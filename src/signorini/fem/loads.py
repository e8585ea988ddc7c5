"""Prescribed displacements and boundary loads (dead loads, proportional stepping).

A load acts on a named boundary set of the mesh: an edge set of a 2-D mesh, a
face set of a 3-D one. Loads are integrated consistently with the kinematics:
per unit thickness in plane strain, over the full circumference 2 pi R in
axisymmetry, over the reference faces in 3-D.

Every value is a parameter spec (see :mod:`signorini.params`) multiplied by a
``ramp(t)`` of the load factor t in [0, 1] (default: ``t``, proportional loading).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._jax import jax, jnp
from .kinematics import PLANE_STRAIN
from .solid import face_integrals
from ..params import Spec, resolve
from ..errors import InputError


def _linear(t):
    return t


@dataclass(frozen=True)
class Ramp:
    """A load applied between the load factors ``start`` and ``end``: the ramp
    is 0 before ``start``, rises linearly to 1 at ``end`` and stays 1 after, so
    loads applied one after another are ramps of consecutive intervals, e.g.
    ``Pressure("top", "P", ramp=Ramp(0, 0.5))`` then
    ``Traction("side", ("Q", 0.0), ramp=Ramp(0.5, 1))``. Unlike a function
    written for it, a ``Ramp`` is known by its values, so a problem built again
    with it shares its compiled programs, also with later processes."""
    start: float = 0.0
    end: float = 1.0

    def __post_init__(self):
        ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                 for v in (self.start, self.end))
        if not ok or not self.start < self.end:
            raise InputError(f"Ramp(start, end) needs two finite numbers with start < end, got "
                             f"start={self.start!r}, end={self.end!r}")

    def __call__(self, t):
        return jnp.clip((t - self.start) / (self.end - self.start), 0.0, 1.0)


@dataclass(frozen=True)
class Table:
    """A piecewise-linear path through the points (``times[k]``, ``values[k]``) of
    the load factor t, constant before the first and after the last: load and
    unload (``Table((0, 0.5, 1), (0, 1, 0))``), cycles, holds. Like :class:`Ramp`
    it multiplies a load's, a support's or an obstacle's value, and is known by
    its values (a problem built again with it shares its compiled programs)."""
    times: tuple
    values: tuple

    def __post_init__(self):
        try:
            t = tuple(float(v) for v in self.times)
            v = tuple(float(x) for x in self.values)
        except (TypeError, ValueError):
            raise InputError(f"Table(times, values) needs two sequences of numbers, got "
                             f"{self.times!r}, {self.values!r}") from None
        if len(t) != len(v) or len(t) < 2:
            raise InputError(f"Table: times and values need the same length, at least 2; got "
                             f"{len(t)} and {len(v)}")
        if not all(np.isfinite(t + v)) or any(b <= a for a, b in zip(t, t[1:])):
            raise InputError(f"Table: the times must increase and every number be finite, got "
                             f"times={t}, values={v}")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "values", v)

    def __call__(self, t):
        return jnp.interp(t, jnp.asarray(self.times), jnp.asarray(self.values))


def _edge_weights(X, edges, kinematics):
    """(n_edges, 2): consistent weights int N_a dA of each edge end (per unit
    thickness: L/2 each; axisymmetric: 2 pi L (2 R_a + R_b) / 6)."""
    return jax.vmap(kinematics.edge_factors)(X[edges[:, 0]], X[edges[:, 1]])


@dataclass(frozen=True)
class Fixed:
    """Prescribed displacement ``value * ramp(t)`` of component ``component`` on
    the nodes of ``node_set``.

    The component is 0 or 1 in 2-D: in plane strain u_x, u_y; in axisymmetry
    u_r (radial; nodes on the axis need ``Fixed(..., 0)``) and u_z (axial). In
    3-D it is 0, 1 or 2: u_x, u_y, u_z. A symmetry plane or line holds the
    component normal to it, e.g. ``Fixed("x0", 0)`` on the plane x = 0.
    """
    node_set: str
    component: int
    value: Spec = 0.0
    ramp: Callable = _linear

    def specs(self):
        return (self.value,)


@dataclass(frozen=True)
class Pressure:
    """Uniform nominal pressure on the boundary set ``edges``: an edge set of a
    2-D mesh, a face set of a 3-D one (dead load along the reference normal).

    Positive pressure pushes into the body. With ``resultant=True`` the value is
    the resultant force and the pressure is value / the reference area of the
    set: in plane strain a force per unit thickness over the edges' length; in
    axisymmetry the force over the whole circumference, over the surface of
    revolution (2 pi R ds); in 3-D the force over the faces' area.
    """
    edges: str
    value: Spec
    resultant: bool = False
    ramp: Callable = _linear

    def specs(self):
        return (self.value,)

    def nodal_forces(self, X, edges: np.ndarray, params, t, kinematics=PLANE_STRAIN):
        """(n_edges, 2 ends, 2) consistent nodal forces of the load at t; on a 3-D
        body ``edges`` are faces and the forces (n_faces, k, 3)."""
        q = resolve(self.value, params) * self.ramp(t)
        if X.shape[-1] == 3:
            wts, nda = face_integrals(X, edges)
            if self.resultant:
                q = q / jnp.sum(wts)
            return -q * nda
        d = X[edges[:, 1]] - X[edges[:, 0]]
        L = jnp.linalg.norm(d, axis=1)
        n = jnp.stack([d[:, 1], -d[:, 0]], axis=1) / L[:, None]  # outward unit normal
        wts = _edge_weights(X, edges, kinematics)  # (n_edges, 2): int N_a dA
        if self.resultant:
            q = q / jnp.sum(wts)  # value / loaded area
        return -q * wts[:, :, None] * n[:, None, :]


@dataclass(frozen=True)
class Traction:
    """Uniform nominal traction vector on the boundary set ``edges``: an edge set
    of a 2-D mesh, a face set of a 3-D one (dead load).

    ``value`` has two components in 2-D, (t_x, t_y) in plane strain and (t_r,
    t_z) in axisymmetry, and three, (t_x, t_y, t_z), in 3-D; each a number or a
    parameter name. With ``resultant=True`` the value is the resultant force
    vector, divided by the reference area of the set as for :class:`Pressure`
    (per unit thickness in plane strain, the whole circumference in axisymmetry).
    """
    edges: str
    value: tuple[Spec, Spec]
    resultant: bool = False
    ramp: Callable = _linear

    def __post_init__(self):

        v = self.value
        if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) not in (2, 3):
            raise InputError(f"Traction({self.edges!r}): value must be a pair (t_x, t_y) (a 3-D "
                             f"body: a triple) of numbers or parameter names, got {v!r}; for a "
                             "normal load use Pressure")
        object.__setattr__(self, "value", tuple(v))

    def specs(self):
        return tuple(self.value)

    def nodal_forces(self, X, edges: np.ndarray, params, t, kinematics=PLANE_STRAIN):
        """(n_edges, 2 ends, 2) consistent nodal forces of the load at t; on a 3-D
        body ``edges`` are faces and the forces (n_faces, k, 3)."""
        if len(self.value) != X.shape[-1]:
            raise InputError(f"Traction({self.edges!r}): a {X.shape[-1]}-D body needs "
                             f"{X.shape[-1]} components, got {len(self.value)}")
        wts = face_integrals(X, edges)[0] if X.shape[-1] == 3 else _edge_weights(X, edges, kinematics)
        tr = jnp.stack([jnp.asarray(resolve(v, params), dtype=float) for v in self.value]) * self.ramp(t)
        if self.resultant:
            tr = tr / jnp.sum(wts)
        return wts[:, :, None] * tr[None, None, :]
