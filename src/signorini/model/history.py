"""The history of path-dependent problems: the pure update after convergence,
the initial state and their sensitivities (docs/theory.md §1, §3.5).

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import time


import numpy as np

from .._jax import jax, jnp, to_device
from ..params import unit_tangents


class ModelHistory:
    """The history of path-dependent problems: update, initial state, sensitivities."""

    # ---------------------------------------------------------------- history
    def update(self, w, params, t, state_n, part: str = "all"):
        """Pure history update after convergence at t (docs/theory.md §1, §3):
        (w, contact history, material history). Contact: the slip coordinate
        s = s(x_S) (2-D) or the closest point y(x_S) (3-D) of every node of a
        friction surface on the obstacle at t (linearised obstacle in
        small-strain runs). Material: the return map at
        every Gauss point from the history of the previous increment
        (``part="contact"``: left out, None)."""
        contact = []
        for i, s, x, _, _, geo, _, Xs in self._surface_inputs(w, params, t):
            if not s.has_history:
                contact.append(None)
                continue
            contact.append(jax.vmap(lambda xs, X0, s=s, geo=geo: s.contact.method.history_point(
                xs, geo, self.obstacle_at(s, X0)))(x, Xs))
        material = None
        if self.n_state and part == "all":
            material = self._elements(w, params, state_n, tangent=False)[1]
        return (w, tuple(contact), material)

    def _update_eager(self, w, params, t, state_n):
        """:meth:`update`: a whole-mesh program, or the Gauss-point history from the
        element kind's programs."""
        if not self.by_kind:
            return self._update_whole(w, params, t, state_n)
        w_, contact, _ = self._update_contact(w, params, t, self.without_material(state_n))
        material = self.element_history(w, params, state_n) if self.n_state else None
        return (w_, contact, material)

    def _update_jvp(self, w, params, t, state_n, w_dot, e, state_dot_n):
        """JVP of :meth:`update` along (w_dot, e, state_dot_n), batched over the
        directions (leading axis)."""
        if not self.by_kind:
            return self._update_jvp_whole(w, params, t, state_n, w_dot, e, state_dot_n)
        strip = self.without_material
        wd, contact, _ = self._update_contact_jvp(w, params, t, strip(state_n), w_dot, e,
                                                  strip(state_dot_n))
        material = None
        if self.n_state:
            # the history's JVP alone: the forces' (a JVP of a VJP) costs 3-4x more
            material = self.element_jvp("update", (1,), w, params, state_n, w_dot, e,
                                        state_dot_n)[0]
        return (wd, contact, material)

    def initial_state(self, w, params):
        """state_0 = (w_0, s_0 = s(X(phi)) at t = 0, virgin material); None without history."""
        if not self.has_history:
            return None
        w = jnp.asarray(w)
        h0 = None
        if self.n_state:
            shape = (len(self.conn), max(g.n_gauss for g in self.groups), self.n_state)
            if not self.mixed:
                h0 = jnp.broadcast_to(self.material.initial_state(), shape)
            else:  # each group's own virgin state, the rest of the rows zero
                h0 = jnp.zeros(shape)
                for g in self.groups:
                    if g.n_state:
                        h0 = h0.at[g.idx, :g.n_gauss, :g.n_state].set(g.law.initial_state())
        contact = self._update_contact(w, params, 0.0, (w, (None,) * len(self.surfaces), None))[1]
        return (w, contact, h0)

    def initial_state_sensitivity(self, params, names):
        """D state_0 / D phi_k batched over ``names``: (0, grad s . V_k + ds/dphi_k, 0)."""
        if not self.has_history:
            return None
        e = unit_tangents(params, list(names))
        z = jnp.zeros((len(names), self.n_dof))
        s0 = self.initial_state(jnp.zeros(self.n_dof), params)
        sd0 = jax.tree_util.tree_map(lambda a: jnp.zeros((len(names),) + a.shape), s0)
        strip = self.without_material
        contact = self._update_contact_jvp(jnp.zeros(self.n_dof), params, 0.0, strip(s0), z, e,
                                           strip(sd0))[1]
        return (z, contact, sd0[2])

    def update_state(self, inc, params, t, state_n, state_dot, names):
        """New state after a converged increment and its sensitivity (JVP of
        :meth:`update` with tangents (w_dot, e_k, state_dot_n), batched over
        ``names``). Stores both on ``inc`` (``state``, ``state_sens``)."""
        if not self.has_history:
            return state_n, state_dot
        w = to_device(inc.w)
        state = self.compiled.update(w, params, t, state_n)
        # the unknowns in the state are those of the increment: share inc.w instead of
        # keeping a second copy (half the memory per increment with friction)
        state = (inc.w,) + tuple(state[1:])
        sdot = None
        if state_dot is not None and len(names):
            t0 = time.perf_counter()
            wd = to_device(np.stack([inc.sens[n] for n in names]))
            sdot = self._update_jvp(w, params, t, state_n, wd, unit_tangents(params, list(names)),
                                    state_dot)
            jax.block_until_ready(sdot)
            inc.timing["history_sensitivity"] = time.perf_counter() - t0
        inc.state, inc.state_sens = state, sdot
        return state, sdot
