"""The constant element stiffness of a linear body, kept per parameter set.

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from .._jax import jnp


class ModelStiffness:
    """The constant element stiffness of a linear body, kept per parameter set."""

    def element_parameters(self) -> set[str] | None:
        """Names on which the internal forces depend through the material or the
        shape (None: unknown, a material value is a function of the parameters)."""
        specs = list(self.material.specs())
        if any(callable(v) for v in specs):
            return None
        return {v for v in specs if isinstance(v, str)} | set(self.shape_names)

    def element_key(self, params) -> tuple:
        """The values the element kernels depend on (material and shape parameters;
        every value if unknown): Ke and dKe/dphi are kept while it is unchanged,
        so a solve for another obstacle radius, load or friction coefficient reuses
        them instead of running the element kernels over every cell again."""
        names = params if self._element_names is None else self._element_names
        return tuple(sorted((k, float(params[k])) for k in names))

    def element_stiffness(self, params):
        """(Ke JAX, Ke NumPy) (n_cells, 8, 8) of a linear body, computed once per
        values of the element parameters (E, nu, shape parameters may differ
        between solves; :meth:`element_key`)."""
        key = self.element_key(params)
        if self._ke is None or self._ke[0] != key:
            Ke = self.compiled.stiffness(params)
            self._ke = (key, Ke, np.asarray(Ke))
        return self._ke[1], self._ke[2]

    def linear_forces(self, Ke, w):
        """(n_dof,) internal forces sum_e K_e u_e of a linear body with element
        stiffness Ke (n_cells, 8, 8) (traceable)."""
        re = jnp.einsum("eij,ej->ei", Ke, w[self.edofs])
        return jnp.zeros(self.n_dof).at[self.edofs.ravel()].add(re.ravel())
