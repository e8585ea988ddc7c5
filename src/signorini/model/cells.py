"""The element kernels of an element kind, compiled once for every mesh
(:mod:`signorini.model.chunks`, docs/theory.md §10.6).

The kernels of :mod:`signorini.fem.element` (internal forces, tangent, history
update) depend on the kind of element only: kinematics x formulation x
material. An item is a cell: ``items = (u_e (4, 2), X_e (4, 2), h_e (4, n_state)
or None)``, and the material values ``mp`` are shared by every cell.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..fem import element, solid
from ..fem.element import FBAR, STANDARD
from .chunks import Chunked


class CellGroup(NamedTuple):
    """Cells that share their element kernels: one kind of cell (its kinematics)
    and one material law (with each cell's own values), with their element
    formulation. A model has one, or (a mixed mesh, bodies of several laws) one
    per kind and law (docs/theory.md §12.2)."""

    kin: object        #: kinematics of the cells' kind
    idx: np.ndarray    #: the cells
    law: object        #: the material whose kernels they take
    form: object       #: element formulation

    @property
    def n_gauss(self) -> int:
        return self.kin.n_gauss

    @property
    def n_nodes(self) -> int:
        return self.kin.cell.n_nodes if self.kin.dim == 3 else 4

    @property
    def n_state(self) -> int:
        return int(self.law.n_state)


def cell_groups(problem, kinematics, material, formulation) -> list[CellGroup]:
    """The groups of a problem's cells (``material`` the model's, bound to the
    mesh): by kind of cell (a mixed 3-D mesh) and by material law (Bodies of
    several laws). With one group, the problem's kinematics, material and
    formulation as they are."""
    mesh = problem.mesh
    n = len(mesh.cells)
    kinds = ([(kinematics, np.arange(n))] if kinematics.dim == 2 or not mesh.mixed else
             [(solid.Solid3D(c), idx) for c, idx in mesh.groups()])
    several = getattr(material, "per_cell", False) and len(material.bodies.laws) > 1
    laws = material.law_index() if several else [(material, np.arange(n))]
    if len(kinds) * len(laws) == 1:
        return [CellGroup(kinematics, np.arange(n), material, formulation)]
    groups = []
    for kin, ik in kinds:
        for law, il in laws:
            idx = np.intersect1d(ik, il)
            if not idx.size:
                continue
            form = problem.formulation
            if form is None:
                form = FBAR if law.n_state and (kin.dim == 2 or kin.cell.fbar) else STANDARD
            if not form.linear and not law.finite_strain:
                raise InputError(f"the {form.name} formulation is for finite-strain materials; the "
                                 f"{type(law).__name__} bodies are small-strain: leave the "
                                 "formulation to its default (F-bar only where a law has history)")
            groups.append(CellGroup(kin, idx, law, form))
    return groups


def element_family(kinematics):
    """The module of element kernels for a body of this kinematics: the 3-D cells
    (:mod:`signorini.fem.solid`) or the Q4 (:mod:`signorini.fem.element`); both
    take (u_e, X_e, material, mp, h_n, kinematics, formulation)."""
    return solid if kinematics.dim == 3 else element


class CellKernels(Chunked):
    """The element programs of one kind: ``CellKernels.of(material, kinematics,
    formulation)``. Kernels: ``"update"`` -> (r (8,), h (4, n_state)) and
    ``"tangent"`` -> (r (8,), K (8, 8), h), ``"stress"`` -> (element-averaged
    Cauchy stress (3, 3),)."""

    #: cells per chunk: chunks of 4096 while that many cells are left, the rest in
    #: chunks of 128, the chunks run side by side on the cores. From
    #: ``benchmarks/study_chunking.py`` (docs/benchmarks.md): chunks of 4096 cost
    #: 0.5-0.7x of one vmap over the whole mesh per cell from 14k DOFs up (a
    #: chunk's intermediates stay in cache); 128 bounds the padding of a small
    #: mesh and gives it chunks to share out (the forging's 200 cells: two)
    SIZES = (4096, 128)

    @property
    def side_by_side(self) -> bool:
        return self.parts[1].dim != 3  # chunks.Chunked.side_by_side

    def _kernel(self, name: str):
        m, k, f = self.parts
        fem = element_family(k)
        if name == "update":
            def update(items, mp):
                ue, Xe, he = items
                r, h = fem.element_update(ue, Xe, m, mp, he, k, f)
                return r.reshape(-1), h
            return update
        if name == "tangent":
            return lambda items, mp: fem.element_residual_tangent(*items[:2], m, mp, items[2], k, f)
        if name == "stress":
            return lambda items, mp: (fem.element_stress(*items[:2], m, mp, items[2], k, f),)
        raise KeyError(f"no element kernel {name!r}")
