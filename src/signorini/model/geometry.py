"""The reference geometry (shape parameters), the external forces and the
prescribed values at a load factor.

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from .._jax import jnp
from ..params import resolve

#: reserved parameter name: every nodal coordinate of the reference mesh (n_nodes, dim)
NODES = "nodes"


class ModelGeometry:
    """The reference geometry, the external forces and the prescribed values."""

    # ----------------------------------------------------------- pure kernels
    def reference(self, params):
        """X(phi) (n_nodes, dim): nominal mesh moved along the design velocities (and
        by ``params["nodes"]`` (n_nodes, dim), the shape field of every nodal
        coordinate, when an adjoint gradient asks for it: docs/theory.md §11)."""
        if not self.shape_names and NODES not in params:
            return self._X0
        return self._reference(params)  # compiled: called eagerly by checks and outputs

    def _reference_impl(self, params):
        X = self._X0
        for k in self.shape_names:
            X = X + (params[k] - self.problem.shape_nominal[k]) * self._V[k]
        if NODES in params:
            X = X + params[NODES]
        return X

    def external_forces(self, X, params, t):
        """(n_dof,) consistent nodal forces of all loads at load factor t."""
        f = jnp.zeros(self.n_dof)
        for load, edges in zip(self.problem.loads, self.load_edges):
            fe = load.nodal_forces(X, edges, params, t, self.kinematics)  # (n_edges, k, dim)
            d = self.dim * edges[..., None] + np.arange(self.dim)
            f = f.at[d.ravel()].add(fe.ravel())
        return f

    def prescribed_values(self, params, t):
        """(n_prescribed,) prescribed displacement values at t."""
        fixed = self.layout.prescribed_fixed
        if not len(fixed):
            return jnp.zeros(0)
        if self._fixed_groups is None:  # one value per Fixed, broadcast to its DOFs
            pos: dict = {}
            for f in fixed:
                pos.setdefault(id(f), (len(pos), f))
            self._fixed_groups = ([f for _, f in pos.values()],
                                  np.array([pos[id(f)][0] for f in fixed]))
        groups, index = self._fixed_groups
        vals = jnp.stack([jnp.asarray(resolve(f.value, params), dtype=float) * f.ramp(t) for f in groups])
        return vals[index]
