"""The constant element stiffness of a linear body, kept per parameter set, and
what the linear solvers are told of the tangent (its analysis values, the
residual's row weights).

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from .._jax import to_device


class ModelStiffness:
    """The constant element stiffness of a linear body, kept per parameter set;
    the tangent's analysis values and row weights."""

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
        """Ke (n_cells, 8, 8) of a linear body, computed once per values of the
        element parameters (E, nu, shape parameters may differ between solves;
        :meth:`element_key`)."""
        key = self.element_key(params)
        if self._ke is None or self._ke[0] != key:
            Ke = self.compiled.stiffness(params)
            Ke.flags.writeable = False  # unchanged: the assembly keeps its scatter
            self._ke = (key, Ke)
        return self._ke[1]

    def _element_stiffness_eager(self, params) -> np.ndarray:
        """K_e (n_cells, 8, 8) of a linear body (the tangent at u = 0): a whole-mesh
        program, or the element kind's programs."""
        if self.by_kind:
            return self._element_stiffness_cells(params)
        return np.array(self._stiffness_whole(params))

    def analysis_tangent(self, params):
        """Free-free tangent at the reference state with every contact node closed
        (and sticking), the values a sparse solver should analyse the pattern with:
        the pivots it then chooses suit any active set (docs/theory.md §10.1).

        Each normal multiplier is set just past the switch, lam_N = -eps_N g - delta
        (lam^_N = -delta, delta = 1e-9 (1 + max eps_N |g|)): closed, with a
        negligible curvature term lam^_N d2g of finite kinematics. None if the
        model has no multipliers or a normal multiplier row does not come out
        closed (zero diagonal)."""
        lam_n = [s.lam_offset + s.n_mult * np.arange(s.nodes.size) for s in self.surfaces if s.n_mult]
        if not lam_n:
            return None
        w = np.zeros(self.n_dof)
        for i, s in enumerate(self.surfaces):
            if s.n_mult:
                eps = float(np.ravel(s.contact.method.row_scale(s.contact.method.values(params)))[0])
                g = np.asarray(self.compiled.fields(to_device(w), params, 0.0, i)["gap"])
                lam = np.zeros((s.nodes.size, s.n_mult))
                lam[:, 0] = -eps * g - 1e-9 * (1.0 + eps * float(np.max(np.abs(g))))
                w[s.lam_offset: s.lam_offset + lam.size] = lam.ravel()
        state_0 = self.initial_state(np.zeros(self.n_dof), params)
        _, blocks = self.local_tangents(w, params, 0.0, state_0)
        K = self.pattern.assemble(blocks)
        if not np.all(K.diagonal()[np.searchsorted(self.free, np.concatenate(lam_n))] == 0.0):
            return None
        return K

    def convergence_weights(self, params) -> np.ndarray:
        """(n_dof,) row weights giving every residual row force units."""
        wts = np.ones(self.n_dof)
        for s in self.surfaces:
            cp = s.contact.method.values(params)
            wts[s.lam_dofs] = np.asarray(s.contact.method.row_scale(cp), dtype=float)  # scalar or (m,)
        return wts
