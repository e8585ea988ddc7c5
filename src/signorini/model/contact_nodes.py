"""The contact part of the residual and tangent, the friction case flags and
the contact fields, evaluated through the contact kinds' programs
(:mod:`signorini.model.nodes`): the model gathers its contact nodes' data, the
kind's programs run over chunks of them, the model scatters the results back.

Only what depends on the parameters and the load factor, not on the unknowns
(external forces, the contact nodes' areas and reference normals, the obstacle
geometry and the methods' values), comes from a program of the model itself
(:meth:`ModelContactNodes._contact_geometry_impl`), evaluated once per call.

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from ..contact.area import nodal_normals


class ModelContactNodes:
    """The contact part of residual and tangent, case flags and contact fields."""

    def _contact_geometry_impl(self, params, t):
        """(external forces (n_dof,), per surface (A, X_S, N_S, geo, cp)): the
        inputs of the contact kernels that do not depend on the unknowns."""
        X = self.reference(params)
        out = []
        for s in self.surfaces:
            c = s.contact
            out.append((self.kinematics.contact_areas(X, s.edges, s.nodes), X[s.nodes],
                        nodal_normals(X, s.edges, s.nodes), c.obstacle.geometry(params, t),
                        c.method.values(params)))
        return self.external_forces(X, params, t), tuple(out)

    def external_force_vector(self, params, t) -> np.ndarray:
        """(n_dof,) the external forces at t (from the same program as the contact
        geometry: one program per model for both)."""
        return np.asarray(self._contact_geometry(params, t)[0])

    def _node_items(self, i: int, w, geometry, state_n, history: bool = True):
        """(items, shared) of surface i's nodes for its contact kind's programs."""
        s = self.surfaces[i]
        A, XS, NS, geo, cp = geometry[i]
        XS = np.asarray(XS)
        x = XS + w[: 2 * self.n_nodes].reshape(-1, 2)[s.nodes]
        lam = w[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)
        hs = None
        if history and s.has_history:
            self._node_history(i, state_n)  # a clear error without a state
            hs = (np.asarray(state_n[1][i]), np.asarray(s.tangential, dtype=float))
        return (x, lam, np.asarray(A), XS, np.asarray(NS), hs), (geo, cp)

    def contact_tangents(self, w, params, t, state_n=None):
        """(R (n_dof,) of the contact and external forces, [Kc_s (nc_s, k, k)])."""
        w = np.asarray(w)
        fext, geometry = self._contact_geometry(params, t)
        R = -np.asarray(fext)
        blocks = []
        for i, s in enumerate(self.surfaces):
            items, shared = self._node_items(i, w, geometry, state_n)
            Kc, rc = self.node_kernels[i]("tangent", (0, 1), items, shared)
            R += np.bincount(s.dofs.ravel(), weights=rc.ravel(), minlength=self.n_dof)
            blocks.append(Kc)
        return R, blocks

    def contact_residual(self, w, params, t, state_n=None):
        """(n_dof,) the residual of the contact and external forces."""
        w = np.asarray(w)
        fext, geometry = self._contact_geometry(params, t)
        R = -np.asarray(fext)
        for i, s in enumerate(self.surfaces):
            items, shared = self._node_items(i, w, geometry, state_n)
            (rc,) = self.node_kernels[i]("residual", (0,), items, shared)
            R += np.bincount(s.dofs.ravel(), weights=rc.ravel(), minlength=self.n_dof)
        return R

    def _cases_eager(self, w, params, t, state_n):
        """:meth:`cases` (NumPy) from the contact kinds' programs."""
        w = np.asarray(w)
        geometry = self._contact_geometry(params, t)[1]
        out = []
        for i, s in enumerate(self.surfaces):
            if not s.has_history:
                out.append(None)
                continue
            items, shared = self._node_items(i, w, geometry, state_n)
            out.append(self.node_kernels[i]("cases", (0,), items, shared)[0])
        return tuple(out)

    def _fields_eager(self, w, params, t, surface: int = 0):
        """:meth:`contact_fields` (NumPy) from the contact kind's programs."""
        w = np.asarray(w)
        geometry = self._contact_geometry(params, t)[1]
        items, shared = self._node_items(surface, w, geometry, None, history=False)
        g, pN, pT = self.node_kernels[surface]("fields", (0, 1, 2), items, shared)
        return {"gap": g, "p_N": pN, "p_T": pT, "area": items[2]}
