"""The result of :func:`signorini.solve`: increments, fields and sensitivities."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._jax import jax, to_device
from .._programs import Program
from ..errors import InputError
from .newton import StepLog
from ..params import as_jax, unit_tangents
from ..contact.friction import STATUS_NAMES


@dataclass
class Increment:
    """One converged load increment.

    Attributes:
        t: load factor at the end of the increment.
        w: (n_dof,) unknowns (displacements then multipliers).
        newton: the Newton log of the increment.
        reactions: (n_prescribed,) residual R = f_int + f_contact - f_ext at the
            prescribed DOFs, which is the force of the supports on the body
            (equilibrium f_int + f_contact = f_ext + r).
        sens: parameter name -> dw/dphi (n_dof,).
        timing: DDM timings (factorisation, pseudo-load, back-substitution) in s.
        state: history data after the increment (path-dependent problems; None
            between checkpoints of ``solve(method=Adjoint(checkpoint=k))``, recomputed on demand).
        state_sens: its sensitivities.
        switches: points on a switch of the contact or plasticity law
            (:mod:`signorini.sensitivity.nonsmooth`).
        factor: the converged tangent's factorisation (``solve(method=Adjoint(factors="store"))``).
    """
    t: float
    w: np.ndarray
    newton: StepLog
    reactions: np.ndarray
    sens: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    state: object = None
    state_sens: object = None
    switches: dict | None = None
    factor: object = None


class Solution:
    """Converged increments of a solve and everything derived from them.

    Index ``i`` selects an increment (default ``-1``: the last one), ``surface``
    a contact surface (the index in ``Problem.contact``, default 0). Nodal arrays
    are (n_nodes, dim): dim = 2 in 2-D, components (x, y) in plane strain and
    (r, z) in axisymmetry; dim = 3, (x, y, z), on a 3-D mesh. Forces (reactions,
    their sensitivities) are per unit thickness in plane strain, over the whole
    circumference in axisymmetry, whole forces in 3-D.
    """
    def __init__(self, model, params: dict, names: list[str]):
        self.model = model
        self.params = params
        self.names = names
        self.increments: list[Increment] = []
        self.log: list[StepLog] = []
        self.status = "running"
        self.reason = ""  # why the solve failed (status "failed")
        self.label: str | None = None  # name of the solve in logs ("base", "FD R+", ...)
        self.warnings: list[str] = []  # suspicious results found on the way (see signorini.checks)
        self.solver: str | None = None  # linear solver used (``auto`` resolved)
        self.linear_solver = None  # that solver object
        #: what the algebraic coarse start of the first increment did, if it ran
        #: (algorithms.coarse_algebraic): coarse unknowns, iterations, time, or why abandoned
        self.coarse_start: dict | None = None
        self.symmetric: bool | None = None  # symmetric factorisation of the tangent?
        self.shape_gradient = None  # (n_nodes, dim) adjoint gradient written with the last increment
        self.jax_params = as_jax(params)
        self._kept_contact: dict = {}  # (increment, surface) -> (its Increment, names, contact())

    # -------------------------------------------------------------- basics
    def __repr__(self):
        return (f"Solution(status={self.status!r}, increments={len(self.increments)}, "
                f"n_dof={self.model.n_dof}, sensitivities={self.names})")

    def _inc(self, i) -> Increment:
        if not self.increments:
            raise InputError("the solution has no converged increment")
        n = len(self.increments)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise InputError(f"increment index must be an integer, got {i!r}")
        if not -n <= i < n:
            raise InputError(f"increment index {i} is out of range: the solution has {n} converged "
                             f"increment(s), indices 0..{n - 1} (or -1 for the last)")
        return self.increments[i]

    def _surface(self, k):
        n = len(self.model.surfaces)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -n <= k < n:
            raise InputError(f"contact surface index {k!r} is out of range: the problem has {n} "
                             "contact surface(s)")
        return self.model.surfaces[k]

    @property
    def newton_iterations(self) -> list[int]:
        """Newton iterations of each converged increment."""
        return [inc.newton.iterations for inc in self.increments]

    def displacement(self, i: int = -1) -> np.ndarray:
        """(n_nodes, dim) nodal displacements (u_x, u_y[, u_z]; axisymmetric: u_r, u_z)."""
        return self._inc(i).w[: self.model.dim * self.model.n_nodes].reshape(-1, self.model.dim)

    def reference(self) -> np.ndarray:
        """(n_nodes, dim) reference coordinates X(phi)."""
        return np.asarray(self.model.reference(self.jax_params))

    def current(self, i: int = -1) -> np.ndarray:
        """(n_nodes, dim) current coordinates x = X + u."""
        return self.reference() + self.displacement(i)

    def multipliers(self, i: int = -1, surface: int = 0) -> np.ndarray:
        """(nc, m) contact multipliers of a surface's nodes, nominal tractions
        (lam_N <= 0): m = 1 frictionless (lam_N), m = 0 with :class:`~signorini.Penalty`;
        with friction m = 2 in 2-D (lam_N, lam_T) and m = 3 in 3-D (lam_N, lam_T1,
        lam_T2 in the tangent basis ``t1``, ``t2`` of :meth:`contact`)."""
        s = self._surface(surface)
        w = self._inc(i).w
        return w[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)

    def reactions(self, i: int = -1) -> np.ndarray:
        """(n_nodes, dim) reaction forces of the supports on the body (0 where free)."""
        d = self.model.dim
        r = np.zeros(d * self.model.n_nodes)
        r[self.model.prescribed] = self._inc(i).reactions  # R_p = f_int - f_ext = r
        return r.reshape(-1, d)

    def reaction_sensitivity(self, name: str, i: int = -1) -> np.ndarray:
        """(n_nodes, dim) DDM sensitivity of :meth:`reactions` (0 where free).

        With history (friction) the residual also depends on the state before the
        increment, so its tangent D state_n / D phi enters the JVP (docs/theory.md §1)."""
        self._check_name(name)
        return self.reaction_sensitivities(i)[name]

    def reaction_sensitivities(self, i: int = -1) -> dict:
        """{name: (n_nodes, dim) DDM sensitivity of :meth:`reactions`} for every
        parameter of the solve, in one pass."""
        m = self.model
        if m.has_history:
            def rows(w, p, t, st):  # the friction cases at w itself: one program for every increment
                cases = jax.lax.stop_gradient(m.cases(w, p, t, st)) if m.has_contact_history else None
                return m.residual(w, p, t, st, cases)[m.prescribed]
            d = self.history_response(rows, i, key=("reactions-history",))[1]
        else:
            d = self.response(lambda w, p, t: m.residual(w, p, t)[m.prescribed], i, key=("reactions",))[1]
        out = {}
        for name in self.names:
            r = np.zeros(m.dim * m.n_nodes)
            r[m.prescribed] = np.asarray(d[name])
            out[name] = r.reshape(-1, m.dim)
        return out

    def state_before(self, i: int = -1):
        """(state_n, its sensitivities) at the start of increment i (path-dependent
        problems): the state after increment i-1, or the initial state."""
        self._inc(i)
        n = range(len(self.increments))[i]
        if n > 0:
            prev = self.increments[n - 1]
            return self.state_after(n - 1), prev.state_sens
        m = self.model
        sdot = m.initial_state_sensitivity(self.jax_params, self.names) if self.names else None
        return m.initial_state(np.zeros(m.n_dof), self.jax_params), sdot

    def state_after(self, n: int):
        """History state after increment n, replayed by ``model.update`` from the
        last kept state before it when ``solve(method=Adjoint(checkpoint=k))`` dropped it."""
        self._inc(n)
        n = range(len(self.increments))[n]  # a negative index counts from the end
        inc = self.increments[n]
        if inc.state is not None or not self.model.has_history:
            return inc.state
        return self.replay(n)[n]

    def replay(self, n: int) -> dict:
        """{k: state after increment k} for the increments from the last kept state
        before n up to n (the dropped segment of ``solve(method=Adjoint(checkpoint=k))`` that ends
        at n), recomputed by ``model.update`` from the stored unknowns."""
        j = n
        while j >= 0 and self.increments[j].state is None:
            j -= 1
        m = self.model
        state = (m.initial_state(np.zeros(m.n_dof), self.jax_params) if j < 0 else
                 self.increments[j].state)
        out = {}
        for k in range(j + 1, n + 1):
            inc_k = self.increments[k]
            state = out[k] = m.compiled.update(to_device(inc_k.w), self.jax_params, inc_k.t, state)
        return out

    # ------------------------------------------------------- sensitivities
    def _check_name(self, name):
        if name not in self.names:
            raise InputError(f"no sensitivity for {name!r}; solved with sensitivities={self.names}")

    def w_sensitivity(self, name: str, i: int = -1) -> np.ndarray:
        """(n_dof,) DDM sensitivity Dw/Dphi of all unknowns (displacements, multipliers)."""
        self._check_name(name)
        return self._inc(i).sens[name]

    def displacement_sensitivity(self, name: str, i: int = -1) -> np.ndarray:
        """(n_nodes, dim) Du/Dphi."""
        d = self.model.dim
        return self.w_sensitivity(name, i)[: d * self.model.n_nodes].reshape(-1, d)

    def multiplier_sensitivity(self, name: str, i: int = -1, surface: int = 0) -> np.ndarray:
        """(nc, m) DDM sensitivity of :meth:`multipliers`."""
        s = self._surface(surface)
        wd = self.w_sensitivity(name, i)
        return wd[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)

    def response(self, fn: Callable, i: int = -1, with_sensitivities: bool = True, key=None):
        """Value and DDM sensitivities of a response F = fn(w, params, t) (paper eq. 5).

        ``fn`` is a JAX-traceable function of the unknowns w (n_dof,), the
        parameter dict and the load factor t. ``key`` (hashable) caches the
        compiled function on the model for reuse (the same key must always mean
        the same ``fn``). Returns (value, {name: DF/Dphi}).
        """
        return self.evaluate(fn, i, with_sensitivities, key, with_state=False)

    def contact(self, i: int = -1, surface: int = 0) -> dict:
        """The contact surface's nodes at increment ``i``: a dict of arrays, one row
        per contact node (nc rows).

        * ``node`` (nc,): the mesh nodes; ``x_ref``, ``x`` (nc, dim): their
          reference and current positions.
        * ``gap`` (nc,) (>= 0: open), ``p_N`` (nc,): the contact pressure (>= 0);
          ``area`` (nc,): the equivalent area A_S (per unit thickness in plane
          strain, of the surface of revolution in axisymmetry, of the faces in
          3-D), so that ``sum(area * p_N)`` is the contact force.
        * ``p_T``: the tangential traction on the body, (nc,) in 2-D (along the
          obstacle's tangent), (nc, 2) in 3-D with friction (in the basis ``t1``,
          ``t2``); 0 without friction.
        * ``dp_N_d<name>``, ``dp_T_d<name>``, ``dgap_d<name>`` for every parameter
          of the solve: their DDM sensitivities, shaped as the values.
        * With friction: ``status`` (nc,) ``"open"``, ``"stick"`` or ``"slip"``,
          and ``slip``, the slip g_T of the increment ((nc,) in 2-D, (nc, 2) in
          3-D in the basis ``t1``, ``t2``).
        * In 3-D: ``normal`` (the obstacle's unit normal n', into the body),
          ``t1``, ``t2`` (the tangent basis) and ``traction`` (the contact force
          on the body per reference area, a vector: what the supports balance),
          each (nc, 3); ``dtraction_d<name>`` its DDM sensitivities.
        """
        inc = self._inc(i)
        self._surface(surface)
        key = (range(len(self.increments))[i], range(len(self.model.surfaces))[surface])
        kept = self._kept_contact
        found = kept.get(key)
        if not (found and found[0] is inc and found[1] == (tuple(self.names), tuple(inc.sens))):
            # kept: a command's table, its VTU file and its series ask for the last increment
            # three times, each time the whole surface with its sensitivities
            if len(kept) >= 4:
                kept.pop(next(iter(kept)))
            found = kept[key] = (inc, (tuple(self.names), tuple(inc.sens)), self._contact(i, surface))
        return {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in found[2].items()}

    def _contact(self, i: int, surface: int) -> dict:
        """:meth:`contact`, computed."""
        m = self.model
        s = self._surface(surface)
        out = {"node": s.nodes, "x_ref": self.reference()[s.nodes], "x": self.current(i)[s.nodes]}
        if m.dim == 3 and not m.by_kind:  # one program: the contact inputs (a pair's clip) once
            history = bool(m.has_history)
            fn = ((lambda w, p, t, st: m.contact_report(w, p, t, st, surface)) if history else
                  (lambda w, p, t: m.contact_report(w, p, t, None, surface)))
            (val, aux), sens = self.evaluate(fn, i, True, ("contact-report", surface), history,
                                             aux=True)
            out.update(val)
            out.update(aux)
            if "status" in aux:
                out["status"] = np.array([STATUS_NAMES[k] for k in aux["status"]])
            for name, d in sens.items():
                for key, v in d.items():
                    out[f"d{key}_d{name}"] = v  # dgap_d<name>, dp_N_d<name>, ...
            return out
        val, sens = self._contact_fields(i, surface)
        out.update({k: np.asarray(v) for k, v in val.items()})
        for name, d in sens.items():
            out[f"dp_N_d{name}"] = np.asarray(d["p_N"])
            out[f"dp_T_d{name}"] = np.asarray(d["p_T"])
            out[f"dgap_d{name}"] = np.asarray(d["gap"])
        if s.contact.method.status is not None:  # friction: open / stick / slip, slip increment

            st, gt = m.compiled.status(to_device(self._inc(i).w), self.jax_params, self._inc(i).t,
                               self.state_before(i)[0], surface)
            out["status"] = np.array([STATUS_NAMES[k] for k in np.asarray(st)])
            out["slip"] = np.asarray(gt)
        if m.dim == 3:
            out.update(self._traction_vectors(i, surface))
        return out

    def _traction_vectors(self, i: int, surface: int) -> dict:
        """3-D: ``normal`` n' (the obstacle's, into the body), the basis ``t1``, ``t2``
        of the tangential tractions p_T and ``traction``, the contact force on the
        body per reference area (what the supports balance), each (nc, 3)."""
        inc = self._inc(i)
        n, t1, t2, f = (np.asarray(a) for a in self.model.frames(
            to_device(inc.w), self.jax_params, inc.t, self.state_before(i)[0], surface))
        out = {"normal": n, "t1": t1, "t2": t2, "traction": f}
        if self.names:  # the traction vectors' DDM sensitivities, (nc, 3) each
            m = self.model
            _, d = self.history_response(lambda w, p, t, st: m.contact_frames(w, p, t, st, surface)[3],
                                         i, key=("traction", surface))
            out.update({f"dtraction_d{name}": np.asarray(v) for name, v in d.items()})
        return out

    def switch_points(self) -> list[dict]:
        """Every switch point of the path (docs/theory.md §11), a row per increment,
        kind and contact surface: ``{"increment", "t", "kind", "surface", "nodes"}``
        for the contact kinds (``weakly_active``: closed without pressure;
        ``stick_slip``: on the Coulomb cone; ``master_end``, ``partner_change``:
        a pair's master surface ends or changes under a node), ``{"increment",
        "t", "kind": "elastic_plastic", "surface": None, "cells"}`` for cells with
        Gauss points on the yield surface. Empty lists are left out."""
        rows = []
        for k, inc in enumerate(self.increments):
            for kind, found in (inc.switches or {}).items():
                if kind == "elastic_plastic":
                    if len(found):
                        rows.append({"increment": k, "t": float(inc.t), "kind": kind,
                                     "surface": None, "cells": list(found)})
                    continue
                for surface, nodes in enumerate(found):
                    if len(nodes):
                        rows.append({"increment": k, "t": float(inc.t), "kind": kind,
                                     "surface": surface, "nodes": list(nodes)})
        return rows

    def _directions(self, i: int):
        """(w_dot (k, n_dof), unit tangents e) of increment i's sensitivities."""
        inc = self._inc(i)
        return (np.stack([inc.sens[n] for n in self.names]),
                unit_tangents(self.jax_params, self.names))

    def _contact_fields(self, i: int, surface: int):
        """(gap, p_N, p_T, area of a surface's nodes, {name: their derivatives}): a
        response program of the model on a mesh evaluated by whole-mesh programs,
        else the contact kind's programs (JVP along the DDM sensitivities)."""
        m, inc = self.model, self._inc(i)
        if self.names and not m.by_kind:  # the value comes with the JVPs (evaluate)
            fn = lambda w, p, t: m.contact_fields(w, p, t, surface)  # noqa: E731
            return self.response(fn, i, key=("contact", surface))
        # the model's own program (the increment checks run it): no response program
        val = m.compiled.fields(inc.w, self.jax_params, float(inc.t), surface)
        if not self.names:
            return val, {}
        wd, e = self._directions(i)
        _, per = m.contact_jvp("fields", (0, 1, 2), inc.w, self.jax_params, inc.t, None, wd, e)
        g, pN, pT = per[surface]
        return val, {n: {"gap": g[k], "p_N": pN[k], "p_T": pT[k]} for k, n in enumerate(self.names)}

    def stress(self, i: int = -1):
        """(Element-averaged Cauchy stress (n_cells, 3, 3), {name: its DDM
        sensitivity}); in 2-D the full tensor too, its [2, 2] entry the
        out-of-plane stress sigma_zz in plane strain and the hoop stress in
        axisymmetry. With a material history it is the stress of the update from
        the state before increment i, whose sensitivity the JVP carries too. A
        response program of the model on a mesh evaluated by whole-mesh programs,
        else the element kind's programs."""
        m, inc = self.model, self._inc(i)
        if not m.by_kind:
            if m.n_state:
                return self.history_response(lambda w, p, t, st: m.stresses(w, p, st), i,
                                             key=("stress-history",))
            return self.response(lambda w, p, t: m.stresses(w, p), i, key=("stress",))
        state, sdot = self.state_before(i) if m.n_state else (None, None)
        if not self.names:
            ue, Xe, mp, he = m._cell_arrays(inc.w, self.jax_params, state)
            (val,) = m.cells("stress", (0,), (ue, Xe, he), mp)
            return val, {}
        wd, e = self._directions(i)
        (val,), (d,) = m.element_value_jvp("stress", (0,), inc.w, self.jax_params, state, wd, e,
                                           sdot)
        return val, {n: d[k] for k, n in enumerate(self.names)}

    def history_response(self, fn: Callable, i: int = -1, key=None):
        """Value and DDM sensitivities of F = fn(w, params, t, state_n) for a quantity
        that also depends on the history before increment i (stresses of a plastic
        material, reactions with friction): the JVP carries D state_n / D phi too."""
        return self.evaluate(fn, i, True, key, with_state=True)

    def evaluate(self, fn, i, with_sensitivities, key, with_state, aux: bool = False):
        """fn(w, params, t[, state_n]) and its JVPs along (w_dot_k, e_k[, state_dot_k]);
        with ``aux``, fn returns (value, aux) and so does this, aux without JVPs."""
        inc = self._inc(i)
        w = to_device(inc.w)
        state, sdot = self.state_before(i) if with_state else (None, None)
        cache = self.model.cache
        if key is not None and (key, with_state) in cache:
            val_fn, jvp_fn = cache[(key, with_state)]
        else:
            # kept between processes only for the package's own responses, whose code
            # the programs' key covers; the caller's key names the function (docstring),
            # but an objective's own numbering (Objective without a response_key) names
            # it in this process only
            own = (key is not None and getattr(fn, "__module__", "").startswith("signorini.")
                   and not (isinstance(key, tuple) and key[:1] == ("signorini.optimize",)))
            program = self.model.program if own else (lambda f, name: Program(f, name))
            name = f"response:{key!r}:{with_state}" + (":aux" if aux else "")
            val_fn = program(fn, name)

            def value_and_jvp(w, p, t, st, a, b, c):
                # the value once, and its linear map along every direction: the value
                # comes with the JVPs at no extra cost (no value program to compile)
                f = lambda w_, p_, s_: fn(w_, p_, t, *s_)  # noqa: E731
                if aux:
                    val, lin, extra = jax.linearize(f, w, p, st, has_aux=True)
                    return (val, extra), jax.vmap(lin)(a, b, c)
                val, lin = jax.linearize(f, w, p, st)
                return val, jax.vmap(lin)(a, b, c)

            jvp_fn = program(value_and_jvp, name + ":jvp")
            if key is not None:
                cache[(key, with_state)] = (val_fn, jvp_fn)
        extra = (state,) if with_state else ()
        t = np.float64(inc.t)  # one type for t whatever the caller stored: one compilation
        if not with_sensitivities or not self.names:
            return jax.tree_util.tree_map(np.asarray, val_fn(w, self.jax_params, t, *extra)), {}
        e = unit_tangents(self.jax_params, self.names)
        wd = to_device(np.stack([inc.sens[n] for n in self.names]))
        val, d = jvp_fn(w, self.jax_params, t, extra, wd, e, (sdot,) if with_state else ())
        # in NumPy: no eager JAX op per name when indexing
        val, d = (jax.tree_util.tree_map(np.asarray, x) for x in (val, d))
        return val, {n: jax.tree_util.tree_map(lambda v, k=k: v[k], d)
                     for k, n in enumerate(self.names)}
