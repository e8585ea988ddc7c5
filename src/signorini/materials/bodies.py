"""Several bodies in one mesh, each with its own material.

:class:`Bodies` maps body names to materials: of one law (the same class, e.g.
two :class:`~signorini.materials.LinearElastic` with their own E and nu), whose
element kernels are evaluated with each cell's own values; or of several laws
(an elastic die on a plastic billet), each law's kernels on its own bodies'
cells (the model groups the cells by law and kind). A body is the node set of
its name (what :func:`signorini.fem.mesh.merge` makes, or a gmsh physical
surface); every cell belongs to exactly one body.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._jax import jnp
from ..errors import InputError


@dataclass(frozen=True, init=False)
class Bodies:
    """Each body with its own material.

    Args:
        materials: body name (a node set of the mesh) -> material. Of one law
            (class): its kernels with per-body constants. Of several laws: each
            law's kernels on its bodies' cells; the problem then has the largest
            history of them (a body without plastic history carries zeros), is
            finite-strain if one of them is, and, unless the problem names an
            element formulation, uses F-bar for the cells of a law with history
            and the standard element for the others.

    Example::

        Bodies({"lower": LinearElastic(E="E1", nu="nu1"),
                "upper": LinearElastic(E="E2", nu="nu2")})
        Bodies({"die": NeoHooke(E="E_die"), "billet": J2Plasticity()})
    """

    materials: tuple

    def __init__(self, materials: Mapping):
        items = tuple(dict(materials).items())
        if not items:
            raise InputError("Bodies needs at least one body: {name: material}")
        object.__setattr__(self, "materials", items)

    @property
    def laws(self) -> list:
        """The distinct laws (classes), in the order of the bodies."""
        return list(dict.fromkeys(type(m) for _, m in self.materials))

    @property
    def law(self):
        """The material that supplies the law (the first body's)."""
        return self.materials[0][1]

    def law_of(self, cls):
        """The first body's material of law ``cls`` (its kernels serve every body of it)."""
        return next(m for _, m in self.materials if type(m) is cls)

    def __getattr__(self, name):  # the law's members: n_state, energy, update, ...
        if name.startswith("__") or name == "materials":
            raise AttributeError(name)
        if len(self.laws) > 1:
            raise AttributeError(f"Bodies of several laws ({', '.join(c.__name__ for c in self.laws)}) "
                                 f"have no one {name!r}: each law's kernels run on its own cells")
        return getattr(self.materials[0][1], name)

    @property
    def n_state(self) -> int:
        return max(int(m.n_state) for _, m in self.materials)

    @property
    def finite_strain(self) -> bool:
        return any(m.finite_strain for _, m in self.materials)

    @property
    def linear(self) -> bool:
        return all(m.linear for _, m in self.materials)

    @property
    def yield_ratio(self):
        """The first law's with one, or None: whether some cells have a yield ratio."""
        return next((m.yield_ratio for _, m in self.materials if m.yield_ratio is not None), None)

    @property
    def equivalent_plastic_strain(self):
        return next((m.equivalent_plastic_strain for _, m in self.materials
                     if m.equivalent_plastic_strain is not None), None)

    #: the stress is not proportional to one constant of the whole mesh
    stress_proportional_to = None

    def initial_state(self):
        return self._one_law("initial_state").initial_state()

    def update(self, H, h_n, mp):
        return self._one_law("update").update(H, h_n, mp)

    def _one_law(self, name: str):
        if len(self.laws) > 1:
            raise InputError(f"Bodies of several laws ({', '.join(c.__name__ for c in self.laws)}) "
                             f"have no one {name}: each law's kernels run on its own cells")
        return self.materials[0][1]

    def specs(self):
        return tuple(s for _, m in self.materials for s in m.specs())

    def check(self, params):
        for name, m in self.materials:
            try:
                m.check(params)
            except InputError as e:
                raise InputError(f"body {name!r}: {e}") from None

    def values(self, params):
        """Per-body values {key: (n_bodies,)} (:meth:`BoundBodies.values` gives per-cell
        ones); of several laws, the keys of all of them (1.0 for a body whose law
        has not that key: never read, its kernels read their own)."""
        vals = [m.values(params) for _, m in self.materials]
        keys = list(dict.fromkeys(k for v in vals for k in v))
        return {k: jnp.stack([jnp.asarray(v.get(k, 1.0), dtype=float) for v in vals]) for k in keys}

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
    """:class:`Bodies` with the body index of every cell (made by the model):
    :meth:`groups` the cells of each law."""

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

    def law_index(self) -> list:
        """[(the material serving a law, indices of its bodies' cells)], one per law."""
        materials = self.bodies.materials
        law = np.array([self.bodies.laws.index(type(m)) for _, m in materials])[self.index]
        return [(self.bodies.law_of(c), np.nonzero(law == k)[0]) for k, c in enumerate(self.bodies.laws)]

