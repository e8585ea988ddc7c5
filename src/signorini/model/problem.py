"""The definition of a boundary-value problem with contact.

A :class:`Problem` is an immutable description: mesh, material, parameter
values, boundary conditions, loads, contact surfaces and shape design
velocities. :func:`signorini.solve` turns it into a :class:`~signorini.model.Model`
(kernels, DOF layout, sparsity) and solves it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, UnknownParameterError
from ..fem.kinematics import PLANE_STRAIN
from ..fem.mesh import Mesh
from ..fem.element import FBAR, STANDARD
from ..fem.solid import Solid3D
from ..interfaces import ContactLaw, ElementFormulation, Kinematics, Material, Obstacle, require


@dataclass(frozen=True)
class Problem:
    """A contact problem: a 2-D one (plane strain or axisymmetric) on a
    :class:`~signorini.fem.mesh.Mesh` of quadrilaterals, or a 3-D one on a
    :class:`~signorini.fem.mesh3d.Mesh3D` of hexahedra or tetrahedra.

    Attributes:
        mesh: the reference mesh (at the nominal parameter values): 2-D, in the
            (x, y) plane, or for axisymmetry the (r, z) half plane r >= 0; or 3-D.
        material: e.g. :class:`~signorini.materials.LinearElastic`.
        params: name -> nominal value of every named parameter.
        fixed: prescribed displacements (:class:`~signorini.fem.loads.Fixed`:
            components 0, 1 in 2-D, 0, 1, 2 in 3-D).
        loads: boundary loads (:class:`~signorini.fem.loads.Pressure`, ``Traction``)
            on edge sets in 2-D, face sets in 3-D.
        contact: contact surfaces (:class:`~signorini.contact.Contact`: rigid
            obstacles of the mesh's dimension, or pairs of bodies,
            :func:`~signorini.contact.pair`, in 2-D and 3-D).
        shape: name -> design velocity field V (n_nodes, dim). The reference
            coordinates are X(phi) = X0 + sum_k (phi_k - phi_k0) V_k, where
            phi_k0 is the value of ``k`` in ``params`` when the mesh was made
            (``shape_nominal``, defaulting to ``params``).
        shape_nominal: nominal values of the shape parameters.
        kinematics: of a 2-D mesh,
            :class:`~signorini.fem.kinematics.PlaneStrain` (default) or
            :class:`~signorini.fem.kinematics.Axisymmetric` (about the z axis;
            loads, forces and areas over the whole circumference). A 3-D mesh
            needs none: leave the default, and the kinematics of its cells are
            taken (2-D kinematics given with a 3-D mesh are an error).
        formulation: :class:`~signorini.fem.element.Standard` (full Gauss
            quadrature: 2x2 on quadrilaterals, 2x2x2 on hexahedra, one point on
            tetrahedra) or :class:`~signorini.fem.element.FBar` (quadrilaterals
            and hexahedra); default (None): F-bar for materials with history
            (plasticity; tetrahedra have no F-bar: give ``Standard()``), standard
            otherwise.
    """
    mesh: Mesh
    material: object
    params: Mapping[str, float]
    fixed: tuple = ()
    loads: tuple = ()
    contact: tuple = ()
    shape: Mapping[str, np.ndarray] = field(default_factory=dict)
    shape_nominal: Mapping[str, float] | None = None
    kinematics: object = PLANE_STRAIN
    formulation: object = None

    def __post_init__(self):
        if "nodes" in self.params:
            raise InputError("the parameter name 'nodes' is reserved for the gradient with respect "
                             "to every nodal coordinate (signorini.gradient); rename the parameter")
        object.__setattr__(self, "params", {k: float(v) for k, v in self.params.items()})
        object.__setattr__(self, "fixed", tuple(self.fixed))
        object.__setattr__(self, "loads", tuple(self.loads))
        object.__setattr__(self, "contact", tuple(self.contact))
        shape = {}
        for k, V in self.shape.items():
            V = np.asarray(V, dtype=float)
            if V.shape != self.mesh.nodes.shape:
                raise InputError(
                    f"design velocity {k!r} has shape {V.shape}, expected {self.mesh.nodes.shape}"
                )
            if k not in self.params:
                raise UnknownParameterError(
                    f"shape parameter {k!r} has no value in params; add it (its nominal value)"
                )
            shape[k] = V
        object.__setattr__(self, "shape", shape)
        if self.shape_nominal is None:
            object.__setattr__(self, "shape_nominal", {k: self.params[k] for k in shape})
        if self.mesh.nodes.shape[1] == 3:  # a 3-D mesh: its own kinematics
            if self.kinematics is PLANE_STRAIN:
                object.__setattr__(self, "kinematics",
                                   Solid3D(None if self.mesh.mixed else self.mesh.cell))
            elif getattr(self.kinematics, "dim", 2) != 3:
                raise InputError(f"{self.kinematics.name} kinematics need a 2-D mesh; this mesh is "
                                 "3-D (leave kinematics at its default for a 3-D body)")
        require(self.material, Material, "material")
        require(self.kinematics, Kinematics, "kinematics")
        if self.formulation is not None:
            require(self.formulation, ElementFormulation, "element formulation")
        for c in self.contact:
            require(c.method, ContactLaw, "contact law")
            require(c.obstacle, Obstacle, "obstacle")

    def resolved_formulation(self):
        """The element formulation used (the default depends on the material)."""
        form = self.formulation
        if form is None:
            form = FBAR if self.material.n_state else STANDARD
        if not form.linear and not self.material.finite_strain:
            raise InputError(f"the {form.name} formulation is for finite-strain materials; "
                             f"{type(self.material).__name__} is a small-strain law: use "
                             "formulation=Standard() or a finite-strain material (NeoHooke)")
        return form

    def with_params(self, **values: float) -> Problem:
        """A copy with some parameter values changed (names must exist)."""
        for k in values:
            if k not in self.params:
                raise UnknownParameterError(
                    f"unknown parameter {k!r}; this problem defines {sorted(self.params)}"
                )
        return dataclasses.replace(self, params={**self.params, **values})
