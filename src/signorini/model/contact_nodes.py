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

from .._jax import jax

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

    def contact_geometry(self, params, t):
        """:meth:`_contact_geometry_impl`, compiled (t as float64: one program);
        the last result is kept for the same parameter dict and t (every Newton
        evaluation of an increment asks for it)."""
        last = getattr(self, "_geometry_last", None)
        if last is not None and last[0] is params and last[1] == float(t):
            return last[2]
        out = self._contact_geometry(params, np.float64(t))
        self._geometry_last = (params, float(t), out)
        return out

    def external_force_vector(self, params, t) -> np.ndarray:
        """(n_dof,) the external forces at t (from the same program as the contact
        geometry: one program per model for both)."""
        return np.asarray(self.contact_geometry(params, t)[0])

    def _node_kernels(self, i: int):
        """Surface i's contact kind's programs, on this rank's block of its nodes
        while :meth:`~signorini.model.elements.ModelElements.sharing`."""
        shares = self._shares()
        kernels = self.node_kernels[i]
        return kernels if shares is None else shares[1][i].over(kernels)

    def _node_items(self, i: int, w, geometry, state_n, history: bool = True, cases=None):
        """(items, shared) of surface i's nodes for its contact kind's programs
        (``cases``: the case flags of every surface, held fixed, or None)."""
        s = self.surfaces[i]
        A, XS, NS, geo, cp = geometry[i]
        XS = np.asarray(XS)
        x = XS + w[: self.dim * self.n_nodes].reshape(-1, self.dim)[s.nodes]
        lam = w[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)
        hs = None
        if history and s.has_history:
            if state_n is None:
                self._node_history(i, state_n)  # raises the error that names the missing state
            hs = (np.asarray(state_n[1][i]),) + tuple(np.asarray(a, dtype=float)
                                                      for a in s.history_data)
        items = (x, lam, np.asarray(A), XS, np.asarray(NS), hs)
        if hs is not None and cases is not None:
            items += (jax.tree_util.tree_map(np.asarray, cases[i]),)
        return items, (geo, cp)

    def _node_dots(self, i: int, w_dot, geometry_dot, state_dot_n):
        """The tangents of :meth:`_node_items` along batched directions: (items'
        (k, nc, ...) or None, shared's) from w_dot (k, n_dof), the geometry's JVP
        and the state's sensitivity."""
        s = self.surfaces[i]
        k = w_dot.shape[0]
        _, dA, dXS, dNS, dgeo, dcp = (None,) + tuple(geometry_dot[1][i])
        dXS = np.asarray(dXS)
        dx = dXS + w_dot[:, : self.dim * self.n_nodes].reshape(k, -1, self.dim)[:, s.nodes]
        dlam = w_dot[:, s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(
            k, s.nodes.size, s.n_mult)
        dhs = None
        if s.has_history:
            shape = (k, s.nodes.size) + ((self.dim,) if self.dim == 3 else ())  # s_n or y_n
            dsn = np.zeros(shape) if state_dot_n is None else np.asarray(state_dot_n[1][i])
            dhs = (dsn,) + tuple(np.zeros((k,) + np.shape(a)) for a in s.history_data)
        return (dx, dlam, np.asarray(dA), dXS, np.asarray(dNS), dhs), (dgeo, dcp)

    def contact_jvp(self, name: str, outs: tuple, w, params, t, state_n, w_dot, e,
                    state_dot_n=None, cases=None):
        """Per surface: the JVP of the contact kernel ``name``'s outputs ``outs``
        along the batched tangents (w_dot (k, n_dof), e, state_dot_n), a tuple of
        (k, nc, ...) arrays; the case flags ``cases`` held fixed if given.
        Returns (the external forces' JVP (k, n_dof), [per surface])."""
        w, w_dot = np.asarray(w), np.asarray(w_dot)
        # the geometry and its tangents from one program
        (_, geometry), geometry_dot = self._contact_geometry_jvp(params, np.float64(t), e)
        out = []
        for i, s in enumerate(self.surfaces):
            # the fields (gap, tractions) read no history
            items, shared = self._node_items(i, w, geometry, state_n, name != "fields", cases)
            dots, sdots = self._node_dots(i, w_dot, geometry_dot, state_dot_n)
            dots = dots[:5] + ((dots[5],) if items[5] is not None else (None,))
            dots += (None,) * (len(items) - len(dots))
            out.append(self._node_kernels(i).jvp(name, outs, items, shared, dots + (sdots,)))
        return np.asarray(geometry_dot[0]), out

    def contact_pseudo_load(self, w, params, t, state_n, w_dot, e, state_dot_n, cases):
        """(k, n_dof) JVP of the residual of the contact and external forces."""
        fext_dot, per = self.contact_jvp("residual", (0,), w, params, t, state_n, w_dot, e,
                                         state_dot_n, cases)
        P = -fext_dot
        for s, (dr,) in zip(self.surfaces, per):
            for j in range(P.shape[0]):
                P[j] += np.bincount(s.dofs.ravel(), weights=dr[j].ravel(), minlength=self.n_dof)
        return P

    def _contact_geometry_jvp_impl(self, params, t, e):
        """(the contact geometry, its JVPs batched over the tangents e)."""
        f = lambda p: self._contact_geometry_impl(p, t)
        return f(params), jax.vmap(lambda d: jax.jvp(f, (params,), (d,))[1])(e)

    def contact_tangents(self, w, params, t, state_n=None):
        """(R (n_dof,) of the contact and external forces, [Kc_s (nc_s, k, k)])."""
        w = np.asarray(w)
        fext, geometry = self.contact_geometry(params, t)
        R = -np.asarray(fext)
        blocks = []
        for i, s in enumerate(self.surfaces):
            items, shared = self._node_items(i, w, geometry, state_n)
            Kc, rc = self._node_kernels(i)("tangent", (0, 1), items, shared)
            R += np.bincount(s.dofs.ravel(), weights=rc.ravel(), minlength=self.n_dof)
            blocks.append(Kc)
        return R, blocks

    def contact_residual(self, w, params, t, state_n=None):
        """(n_dof,) the residual of the contact and external forces."""
        w = np.asarray(w)
        fext, geometry = self.contact_geometry(params, t)
        R = -np.asarray(fext)
        for i, s in enumerate(self.surfaces):
            items, shared = self._node_items(i, w, geometry, state_n)
            (rc,) = self._node_kernels(i)("residual", (0,), items, shared)
            R += np.bincount(s.dofs.ravel(), weights=rc.ravel(), minlength=self.n_dof)
        return R

    def _cases_eager(self, w, params, t, state_n):
        """:meth:`cases`: a whole-mesh program, or (NumPy) the contact kinds' programs."""
        if not self.by_kind:
            return self._cases_whole(w, params, t, state_n)
        w = np.asarray(w)
        geometry = self.contact_geometry(params, t)[1]
        out = []
        for i, s in enumerate(self.surfaces):
            if not s.has_history:
                out.append(None)
                continue
            items, shared = self._node_items(i, w, geometry, state_n)
            out.append(self._node_kernels(i)("cases", (0,), items, shared)[0])
        return tuple(out)

    def _switch_fields_eager(self, w, params, t, state_n=None):
        """:meth:`switch_fields`: its program, or, where no contact law has a stick
        branch and no material a yield ratio, the contact fields alone (the program
        the increment checks run: one program fewer to compile)."""
        if any(s.contact.method.stick_margin is not None for s in self.surfaces) or (
                self.n_state and self.material.yield_ratio is not None):
            return self._switch_fields_whole(w, params, t, state_n)
        out = []
        for i, s in enumerate(self.surfaces):
            f = self._fields_eager(w, params, t, i)
            out.append({"gap": f["gap"], "p_N": f["p_N"], "stick_margin": np.full(s.nodes.size, np.inf)})
        return tuple(out), None

    def _fields_eager(self, w, params, t, surface: int = 0):
        """:meth:`contact_fields`: a whole-mesh program, or (NumPy) the contact kind's
        programs."""
        if not self.by_kind:
            return self._fields_whole(w, params, t, surface)
        w = np.asarray(w)
        geometry = self.contact_geometry(params, t)[1]
        items, shared = self._node_items(surface, w, geometry, None, history=False)
        g, pN, pT = self._node_kernels(surface)("fields", (0, 1, 2), items, shared)
        return {"gap": g, "p_N": pN, "p_T": pT, "area": items[2]}
