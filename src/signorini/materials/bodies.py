"""Several bodies in one mesh, each with its own material constants.

:class:`Bodies` maps body names to materials of one law (the same class, e.g.
two :class:`~signorini.materials.LinearElastic` with their own E and nu): the
element kernels are those of the law, evaluated with each cell's own values.
A body is the node set of its name (what :func:`signorini.fem.mesh.merge`
makes, or a gmsh physical surface); every cell belongs to exactly one body.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._jax import jnp
from ..errors import InputError


@dataclass(frozen=True, init=False)
class Bodies:
    """One material law, each body with its own constants.

    Args:
        materials: body name (a node set of the mesh) -> material; every material
            of the same class (a mix of laws is not supported).

    Example::

        Bodies({"lower": LinearElastic(E="E1", nu="nu1"),
                "upper": LinearElastic(E="E2", nu="nu2")})
    """

    materials: tuple

    def __init__(self, materials: Mapping):
        items = tuple(dict(materials).items())
        if not items:
            raise InputError("Bodies needs at least one body: {name: material}")
        kinds = {type(m) for _, m in items}
        if len(kinds) > 1:
            raise InputError("Bodies: every body must have a material of the same law (class); got "
                             + ", ".join(f"{n}: {type(m).__name__}" for n, m in items)
                             + ". Use one law with per-body constants")
        object.__setattr__(self, "materials", items)

    @property
    def law(self):
        """The material that supplies the law (the first body's)."""
        return self.materials[0][1]

    def __getattr__(self, name):  # the law's members: n_state, energy, update, ...
        if name.startswith("__") or name == "materials":
            raise AttributeError(name)
        return getattr(self.materials[0][1], name)

    #: the stress is not proportional to one constant of the whole mesh
    stress_proportional_to = None

    def specs(self):
        return tuple(s for _, m in self.materials for s in m.specs())

    def check(self, params):
        for name, m in self.materials:
            try:
                m.check(params)
            except InputError as e:
                raise InputError(f"body {name!r}: {e}") from None

    def values(self, params):
        """Per-body values {key: (n_bodies,)} (:meth:`BoundBodies.values` gives per-cell ones)."""
        vals = [m.values(params) for _, m in self.materials]
        return {k: jnp.stack([jnp.asarray(v[k], dtype=float) for v in vals]) for k in vals[0]}

    def bind(self, mesh) -> BoundBodies:
        """The body index of every cell of ``mesh``."""
        index = np.full(len(mesh.cells), -1)
        for b, (name, _) in enumerate(self.materials):
            try:
                nodes = mesh.node_set(name)
            except InputError:
                raise InputError(f"Bodies: the mesh has no node set {name!r} for the body of that "
                                 f"name; node sets: {sorted(mesh.node_sets)}") from None
            inside = np.isin(mesh.cells, nodes).all(axis=1)
            twice = inside & (index >= 0)
            if twice.any():
                raise InputError(f"Bodies: cell {int(np.argmax(twice))} belongs to the bodies "
                                 f"{self.materials[index[np.argmax(twice)]][0]!r} and {name!r}; "
                                 "the bodies' node sets must not share a cell")
            index[inside] = b
        if (index < 0).any():
            k = int(np.argmax(index < 0))
            raise InputError(f"Bodies: cell {k} (nodes {mesh.cells[k].tolist()}) belongs to no body; "
                             f"every cell needs its nodes in one of {[n for n, _ in self.materials]}")
        return BoundBodies(self, index)


class BoundBodies:
    """:class:`Bodies` with the body index of every cell (made by the model)."""

    per_cell = True
    stress_proportional_to = None

    def __init__(self, bodies: Bodies, index: np.ndarray):
        self.bodies = bodies
        self.index = index

    def __getattr__(self, name):
        if name.startswith("__") or name in ("bodies", "index"):
            raise AttributeError(name)
        return getattr(self.bodies, name)

    def values(self, params):
        """{key: (n_cells,)}: each cell's own value."""
        return {k: v[self.index] for k, v in self.bodies.values(params).items()}
