"""Post-processing: contact fields, friction status, switch fields and stresses
(pure functions of the state, compiled by the model).

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from .._jax import jax, jnp
from ..contact.friction3d import tangent_basis


class ModelFields:
    """Post-processing: contact fields, friction status, switch fields, stresses."""

    # ------------------------------------------------------------ post-process
    def contact_fields(self, w, params, t, surface: int = 0):
        """Pure function: per-node gap g, p_N, p_T and area of a surface (each (nc,))."""
        s = self.surfaces[surface]
        u, lams = self.split(w)
        x, lam, A, geo, cp, Xs = self.contact_inputs(s, self.reference(params), u, lams[surface],
                                                     params, t)
        g, pN, pT = self._gap_and_tractions(s, x, lam, A, geo, cp, Xs)
        return {"gap": g, "p_N": pN, "p_T": pT, "area": A}

    def _surface_state(self, w, params, t, state_n, surface: int):
        """(surface, its nodes' contact inputs x, lam, A, geo, cp, Xs, their history)."""
        s = self.surfaces[surface]
        u, lams = self.split(w)
        inputs = self.contact_inputs(s, self.reference(params), u, lams[surface], params, t)
        return (s,) + tuple(inputs) + (self._node_history(surface, state_n),)

    # Each of the following takes a surface's contact inputs (:meth:`_surface_state`), so
    # that :meth:`contact_report` computes them (the mortar clip of a pair) once for all.
    def _gap_and_tractions(self, s, x, lam, A, geo, cp, Xs):
        """Per node (nc,) each: the gap, p_N and |p_T|."""
        meth = s.contact.method
        g = jax.vmap(lambda xs, X0: self.obstacle_at(s, X0).gap(xs, geo))(x, Xs)
        pN, pT = jax.vmap(lambda xs, ls, a, X0: meth.tractions(
            xs, ls, a, geo, self.obstacle_at(s, X0), cp))(x, lam, A, Xs)
        return g, pN, pT

    def _frames_at(self, s, x, geo, Xs, h):
        """(3-D) per node (nc, 3) each: the obstacle's normal n' and the tangent basis
        (t1, t2) of the tangential multipliers (from the history's reference vector,
        or before any history from a coordinate axis)."""
        def frame(xs, hs, X0):
            n = self.obstacle_at(s, X0).normal(xs, geo)
            e = hs[1] if hs is not None else jnp.eye(3)[jnp.argmin(jnp.abs(X0[1]))]
            return (n,) + tangent_basis(n, e)
        return jax.vmap(frame, (0, 0 if h is not None else None, 0))(x, h, Xs)

    def _status_at(self, s, x, lam, A, geo, cp, Xs, h):
        """Per node (nc,) the friction status code and (nc, ...) the slip increment."""
        meth = s.contact.method
        st = jax.vmap(lambda xs, ls, a, hs, X0: meth.status(
            xs, ls, a, geo, self.obstacle_at(s, X0), cp, hs))(x, lam, A, h, Xs)
        gt = jax.vmap(lambda xs, hs, X0: meth.slip(xs, geo, self.obstacle_at(s, X0), hs))(x, h, Xs)
        return st, gt

    def contact_frames(self, w, params, t, state_n, surface: int = 0):
        """Pure function (3-D): per node of a surface (each (nc, 3)) the obstacle's
        normal n' at the node, the tangent basis (t1, t2) of its tangential
        multipliers, and the contact force on the body per reference area
        (:meth:`contact_forces` / A_S: what balances the supports; with linearised
        kinematics along the body's reference normal)."""
        inputs = self._surface_state(w, params, t, state_n, surface)
        s, x, _lam, A, geo, _cp, Xs, h = inputs
        return self._frames_at(s, x, geo, Xs, h) + (self._forces_at(*inputs) / A[:, None],)

    def contact_forces(self, w, params, t, state_n=None, surface: int = 0):
        """Pure function: (nc, dim) the contact force on the body at each node of a
        surface (minus its contact residual rows: what balances the supports; in
        axisymmetry over the whole circumference). For a pair, the force on the
        slave body at its nodes, gathered from every slave node's patch (the master
        body receives the opposite). ``state_n``: the state before the increment,
        needed with friction."""
        return self._forces_at(*self._surface_state(w, params, t, state_n, surface))

    def _forces_at(self, s, x, lam, A, geo, cp, Xs, h):
        """:meth:`contact_forces` from a surface's contact inputs (:meth:`_surface_state`)."""
        meth = s.contact.method
        d = self.dim
        rows = jax.vmap(lambda xs, ls, a, hs, X0: meth.residual(
            xs, ls, a, geo, self.obstacle_at(s, X0), cp, hs), (0, 0, 0, 0 if h is not None else None, 0))(
            x, lam, A, h, Xs)
        if s.patches is None:
            return -rows[:, :d]
        pn = s.patches.nodes  # (nc, P): a patch's rows, scattered as the residual is
        f = -rows[:, :pn.shape[1] * d].reshape(pn.shape + (d,))
        return jnp.zeros((self.n_nodes, d)).at[pn].add(f)[s.nodes]

    def contact_report(self, w, params, t, state_n, surface: int = 0):
        """Pure function: everything :meth:`Solution.contact` reports of a surface, its
        contact inputs (the mortar clip of a pair) computed once: ``(values, aux)``,
        ``values`` what has DDM sensitivities (``gap``, ``p_N``, ``p_T`` and in 3-D
        ``traction``, as :meth:`contact_fields` and :meth:`contact_frames`), ``aux``
        what has none (``area``; in 3-D ``normal``, ``t1``, ``t2``; with friction
        ``status`` and ``slip``, as :meth:`contact_status`)."""
        inputs = self._surface_state(w, params, t, state_n, surface)
        s, x, lam, A, geo, cp, Xs, h = inputs
        g, pN, pT = self._gap_and_tractions(s, x, lam, A, geo, cp, Xs)
        values, aux = {"gap": g, "p_N": pN, "p_T": pT}, {"area": A}
        if self.dim == 3:
            aux["normal"], aux["t1"], aux["t2"] = self._frames_at(s, x, geo, Xs, h)
            values["traction"] = self._forces_at(*inputs) / A[:, None]
        if s.contact.method.status is not None:
            aux["status"], aux["slip"] = self._status_at(*inputs)
        return values, aux

    def contact_status(self, w, params, t, state_n, surface: int = 0):
        """Pure function: per-node (status code, slip increment g_T) of a friction
        surface (codes of :mod:`signorini.contact.friction`); state_n = state
        *before* the increment of w."""
        return self._status_at(*self._surface_state(w, params, t, state_n, surface))

    def switch_fields(self, w, params, t, state_n=None):
        """Pure function: what decides the branches of the non-smooth laws at w
        (docs/theory.md §11): per surface ``{"gap", "p_N", "stick_margin"}`` (nc,)
        (stick margin |lam^_T| - rho, inf where there is no friction branch), and
        the yield ratio (n_cells, n_gauss) of a material with ``yield_ratio`` (None else);
        state_n is the state before the increment of w."""
        X = self.reference(params)
        u, lams = self.split(w)
        out = []
        for i, s in enumerate(self.surfaces):
            x, lam, A, geo, cp, Xs = self.contact_inputs(s, X, u, lams[i], params, t)
            meth = s.contact.method
            g, pN, _ = self._gap_and_tractions(s, x, lam, A, geo, cp, Xs)
            margin = jnp.full(s.nodes.size, jnp.inf)
            if meth.stick_margin is not None:
                h = self._node_history(i, state_n)
                margin = jax.vmap(lambda xs, ls, a, hs, X0, s=s, meth=meth, geo=geo, cp=cp: meth.stick_margin(
                    xs, ls, a, geo, self.obstacle_at(s, X0), cp, hs))(x, lam, A, h, Xs)
            out.append({"gap": g, "p_N": pN, "stick_margin": margin})
        ratio = None
        if self.n_state and self.material.yield_ratio is not None:
            mp = self.material.values(params)
            # (a law without a yield surface: never on it)
            ratio = self._over_cells(lambda ue, Xe, he, m, g: self.fem.element_yield_ratio(
                ue, Xe, g.law, m, he, g.kin, g.form) if g.law.yield_ratio is not None else
                jnp.full(g.n_gauss, jnp.inf), u, X, self._material_history(state_n), mp)
            for g in self.groups:  # a tetrahedron's padded points: its own value,
                if g.n_gauss < ratio.shape[1]:  # not 0 ("on the yield surface")
                    ratio = ratio.at[g.idx, g.n_gauss:].set(ratio[g.idx, :1])
        return tuple(out), ratio

    def stresses(self, w, params, state_n=None):
        """Pure function: element-averaged Cauchy stress (n_cells, 3, 3) (with
        material history: from the state before the increment of w)."""
        X = self.reference(params)
        u, _ = self.split(w)
        mp = self.material.values(params)
        hn = self._material_history(state_n)
        return self._over_cells(lambda ue, Xe, he, m, g: self.fem.element_stress(
            ue, Xe, g.law, m, he, g.kin, g.form), u, X, hn, mp)

    def gauss_mean(self, a) -> np.ndarray:
        """(n_cells, ...) the mean over each cell's own Gauss points of a
        Gauss-point array (n_cells, n_gauss, ...) (a mixed mesh's tetrahedra: their
        one point, not the padding)."""
        a = np.asarray(a)
        out = np.empty((a.shape[0],) + a.shape[2:])
        for g in self.groups:
            out[g.idx] = a[g.idx, :g.n_gauss].mean(axis=1)
        return out
