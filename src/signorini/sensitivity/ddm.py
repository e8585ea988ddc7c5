"""Direct differentiation (DDM) sensitivities, paper eqs. 3-6 (docs/theory.md §1).

After each converged increment, for all design parameters phi_k at once::

    P_k  = dR/dphi_k + dR/dw_p . dw_p/dphi_k + dR/d(state_n) . d(state_n)/dphi_k   (one batched JVP)
    K dw_k/dphi = -P_k                                                              (one back-substitution each)

with K the exact tangent at the converged state, already factorised. No
iterations: the multipliers' sensitivities come out of the same solve.
:func:`signorini.design.finite_differences.finite_difference` computes the same
derivatives by central differences, for checking.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from .._jax import jax, to_device
from ..errors import NonDifferentiableError
from ..params import unit_tangents


def proportional_parameter(model) -> str | None:
    """The design parameter to which a linear body's element stiffness is
    proportional, or None.

    A material may name, in ``stress_proportional_to``, the constant its stress is
    proportional to at fixed other constants (the elastic materials: E, at fixed
    nu). If that constant is a parameter name used nowhere else in the material
    and not a shape parameter, then K_e(phi) = E K_e(E = 1) and the pseudo-load
    of E is the internal force over E: one product with the kept K_e instead of
    a JVP of the element kernels over every cell, and no dK_e/dE."""
    field = model.material.stress_proportional_to
    if field is None or not model.linear_elements or model.element_parameters() is None:
        return None
    spec = getattr(model.material, field)
    if not isinstance(spec, str) or list(model.material.specs()).count(spec) != 1 \
            or spec in model.shape_names:
        return None
    return spec


class DDM:
    """Batched DDM pseudo-loads and sensitivity solves for one model.

    Args:
        model: the :class:`~signorini.model.Model`.
        names: design parameters (must be keys of the parameter dict).
    """

    def __init__(self, model, names: Sequence[str]):
        self.model = model
        self.names = list(names)

        def wp_dot(params, t, e):
            return jax.jvp(lambda p: model.prescribed_values(p, t), (params,), (e,))[1]

        self._wp_dot = model.program(jax.vmap(wp_dot, (None, None, 0)), "ddm_wp_dot")

        # meshes evaluated by whole-mesh programs (Model.by_kind false): the pseudo-load
        # is a JVP of the residual (all of it, or its internal or other forces only)
        def pseudo(w, params, t, state_n, cases, w_dot, e, state_dot_n, part):
            f = lambda w_, p_, s_: model.residual(w_, p_, t, s_, cases, part)
            return jax.jvp(f, (w, params, state_n), (w_dot, e, state_dot_n))[1]

        axes = (None, None, None, None, None, 0, 0, 0)
        self._pseudo = {part: model.program(jax.vmap(lambda *a, part=part: pseudo(*a, part), axes),
                                            f"ddm_pseudo_{part}")
                        for part in ("all", "elements", "rest")}

        def material_pseudo(w, params, t, e_el):
            # tangents on the element parameters only, the displacements held: the
            # other parameters' tangents are symbolic zeros, so the geometry (without
            # shape parameters) is not differentiated, as it would be with a one-hot
            # tangent on every parameter
            f = lambda sub: model.residual(w, {**params, **sub}, t, None, None, "elements")
            return jax.jvp(f, ({k: params[k] for k in e_el},), (e_el,))[1]

        self._material_pseudo = model.program(jax.vmap(material_pseudo, (None, None, None, 0)),
                                              "ddm_material_pseudo")
        self._dke_whole = model.program(jax.vmap(lambda p, e: jax.jvp(
            model.stiffness_pure, (p,), (e,))[1],
            (None, 0)), "ddm_dke")
        # Names whose pseudo-load has no internal-force part can skip the element
        # kernels (the costly half of a pseudo-load): those that enter neither the
        # material nor the shape, nor a prescribed displacement, nor (plasticity)
        # the element history.
        el = model.element_parameters()
        self._element_names = None if (el is None or model.n_state) else el
        # A linear body's internal forces are K_e(phi) u_e: along a load path their
        # pseudo-load is (dK_e/dphi_k) u_e + K_e du_e/dphi_k, with dK_e/dphi_k
        # computed once per parameter values (``reuse_stiffness``)
        self._dke = None  # (key, names, (n, n_cells, 8, 8) NumPy)
        self._proportional = proportional_parameter(model)
        # the free DOFs are np.nonzero of this mask (dofs.DofLayout): sorted, so the
        # mask visits them in the order of the solution's rows
        self._free_mask = np.zeros(model.n_dof, dtype=bool)
        self._free_mask[model.free] = True

    def solve(self, factor, w, params, t, state_n=None, state_dot_n=None,
              reuse_stiffness: bool = False):
        """Sensitivities dw/dphi (n_names, n_dof) at a converged increment:
        :meth:`pseudo_loads`, then :meth:`back_substitute`.

        Args:
            factor: factorisation of the free-free tangent at ``w``.
            state_dot_n: sensitivities of the previous state (batched over names).
            reuse_stiffness: for a linear body, compute dK_e/dphi once and keep it
                for the next increments (twice the cost of one element pseudo-load,
                then a batched product per increment: worth it on a load path).

        Returns:
            (w_dot, timings) with w_dot (n_names, n_dof) including the prescribed DOFs.
        """
        return self.back_substitute(factor, self.pseudo_loads(w, params, t, state_n, state_dot_n,
                                                              reuse_stiffness))

    def pseudo_loads(self, w, params, t, state_n=None, state_dot_n=None,
                     reuse_stiffness: bool = False) -> tuple:
        """The right-hand sides of the sensitivity solve at a converged increment,
        which need no factorisation: ``(P_free, w_dot, seconds)`` for
        :meth:`back_substitute`, with P_free (n_free, n_names) the free rows of
        the pseudo-loads (contiguous columns, as the solvers take them) and w_dot
        (n_names, n_dof) the sensitivities of the prescribed DOFs (free rows zero).

        ``solve`` computes them before factorising the converged tangent: right
        after a factorisation, MKL's threads still hold the cores for
        ``KMP_BLOCKTIME`` (1 ms) and would slow the JAX kernels of the
        pseudo-loads (docs/theory.md §10.2).

        Raises:
            NonDifferentiableError: a pseudo-load's free rows or a prescribed
                sensitivity are not finite (rows the solve does not use are not
                checked: they never reach the sensitivities)."""
        m = self.model
        t0 = time.perf_counter()
        e = unit_tangents(params, self.names)
        w_dot = np.zeros((len(self.names), m.n_dof))
        if m.prescribed.size:
            w_dot[:, m.prescribed] = np.asarray(self._wp_dot(params, t, e))
        # friction: the branch of every node fixed as in the converged tangent
        cases = m.compiled.cases(w, params, t, state_n) if m.has_contact_history else None
        P = self._pseudo_loads(w, params, t, state_n, cases, w_dot, e, state_dot_n, reuse_stiffness)
        # the free rows with contiguous columns: a take along the last axis (fancy
        # indexing on that axis goes through NumPy's general advanced-indexing
        # machinery, a take through a dedicated loop)
        P_free = np.take(P, m.free, axis=1).T
        # a finite column sum has finite terms (one pass, no temporary); only where a sum
        # is not finite (or a sum of finite terms overflowed) is every entry looked at
        finite = np.isfinite(P_free.sum(axis=0))
        if not finite.all():
            finite = np.isfinite(P_free).all(axis=0)
        if m.prescribed.size:  # the free rows of w_dot are still zero
            finite &= np.isfinite(w_dot[:, m.prescribed]).all(axis=1)
        bad = [n for n, ok in zip(self.names, finite) if not ok]
        if bad:  # before any solve: a solver would call the NaN a singular tangent
            raise NonDifferentiableError(
                f"the sensitivities of {', '.join(map(repr, bad))} are not finite (NaN/inf in the "
                f"pseudo-load) at t={t:.6g}: some expression of the problem is not differentiable "
                f"at these parameter values (e.g. sqrt at 0). It need not be an expression of "
                f"these parameters: JAX's tangent through such a point is NaN for every one")
        return P_free, w_dot, time.perf_counter() - t0

    def back_substitute(self, factor, loads: tuple, guess=None):
        """(w_dot, timings): the sensitivities from :meth:`pseudo_loads` ``loads``
        and a factorisation of the free-free tangent at the same converged state.

        ``guess`` (n_names, n_dof): an estimate of w_dot an iterative solver starts
        from (``factor.takes_guess``; the solve's accuracy is the same without)."""
        P_free, w_dot, t_pseudo = loads
        t1 = time.perf_counter()
        X0 = None
        if guess is not None and getattr(factor, "takes_guess", False):
            X0 = -np.take(guess, self.model.free, axis=1).T
        X = (factor.solve(P_free) if X0 is None else factor.solve(P_free, guess=X0)) \
            .reshape(P_free.shape[0], -1)
        # back row by row through a mask of the free DOFs, one contiguous row at a
        # time (fancy indexing on the last axis of the whole array goes through
        # NumPy's general advanced-indexing machinery)
        for k in range(len(self.names)):
            w_dot[k, self._free_mask] = -X[:, k]
        return w_dot, {"pseudo_load": t_pseudo, "back_substitution": time.perf_counter() - t1}

    def _pseudo_loads(self, w, params, t, state_n, cases, w_dot, e, state_dot_n,
                      reuse_stiffness=False) -> np.ndarray:
        """(n_names, n_dof) pseudo-loads; element kernels only for the names that
        need them."""
        m = self.model
        moves = np.any(w_dot[:, m.prescribed] != 0.0, axis=1) if m.prescribed.size else \
            np.zeros(len(self.names), bool)
        if self._element_names is None:
            el = np.ones(len(self.names), bool)
        else:
            el = np.array([n in self._element_names for n in self.names]) | moves
        if not m.by_kind:
            return self._pseudo_loads_whole(w, params, t, state_n, cases, w_dot, e, state_dot_n,
                                            reuse_stiffness, el, moves)
        # the contact and external forces' part: the contact kinds' programs
        P = m.contact_pseudo_load(w, params, t, state_n, w_dot, e, state_dot_n, cases)
        k = np.nonzero(el)[0]
        if not k.size:
            return P
        if reuse_stiffness and m.linear_elements and self._linear_pseudo(P, k, w, params, w_dot):
            return P
        if m.linear_elements and self._proportional is not None:
            # K_e proportional to E: dK_e/dE u_e = K_e u_e / E (the displacements held)
            prop = [j for j in k if self.names[j] == self._proportional and not moves[j]]
            if prop:
                P[prop[0]] += self._internal_forces(w, params) / float(params[self._proportional])
                k = np.array([j for j in k if j != prop[0]], dtype=int)
        if k.size:
            sub = jax.tree_util.tree_map(lambda a: np.asarray(a)[k], (w_dot, e, state_dot_n))
            P[k] += m.scatter(m.element_jvp("update", (0,), w, params, state_n, *sub)[0])
        return P

    def _pseudo_loads_whole(self, w, params, t, state_n, cases, w_dot, e, state_dot_n,
                            reuse_stiffness, el, moves) -> np.ndarray:
        """:meth:`_pseudo_loads` by the model's whole-mesh programs (``el``: the names
        whose pseudo-load has an internal-force part, ``moves``: those that move a
        prescribed displacement)."""
        m = self.model
        wd = to_device(w_dot)
        args = (w, params, t, state_n, cases)
        if self._element_names is None or (
                el.all() and (self._proportional not in self.names or moves.any())):
            return np.asarray(self._pseudo["all"](*args, wd, e, state_dot_n))
        P = np.array(self._pseudo["rest"](*args, wd, e, state_dot_n))
        k = np.nonzero(el)[0]
        if not k.size:
            return P
        if reuse_stiffness and m.linear_elements and self._linear_pseudo(P, k, w, params, w_dot):
            return P
        if moves[k].any():
            sub = jax.tree_util.tree_map(lambda a: a[k], (wd, e, state_dot_n))
            P[k] += np.asarray(self._pseudo["elements"](*args, *sub))
            return P
        # no prescribed motion: the internal forces see the parameters only
        prop = [j for j in k if self.names[j] == self._proportional]
        if prop:  # K_e proportional to it: dK_e/dE u_e = K_e u_e / E
            P[prop[0]] += self._internal_forces(w, params) / float(params[self._proportional])
        k = np.array([j for j in k if self.names[j] != self._proportional], dtype=int)
        if k.size:
            # only the design names: a tangent of zeros on another element parameter
            # (a shape parameter not designed) would still differentiate the geometry
            e_el = {n: to_device(np.asarray(e[n])[k]) for n in self.names
                    if n in self._element_names and n != self._proportional}
            P[k] += np.asarray(self._material_pseudo(w, params, t, e_el))
        return P

    def _internal_forces(self, w, params) -> np.ndarray:
        """(n_dof,) internal forces K_e u_e of a linear body, from its kept K_e."""
        return self.model.linear_forces_np(self.model.element_stiffness(params), w)

    #: largest dK_e/dphi kept (bytes); above it the pseudo-load is a JVP every increment
    DKE_BUDGET = 512 * 2**20

    def _linear_pseudo(self, P, k, w, params, w_dot) -> bool:
        """Add (dK_e/dphi_k) u_e + K_e du_e/dphi_k to P[k] (a linear body); False
        if dK_e/dphi would exceed :attr:`DKE_BUDGET`."""
        m = self.model
        mat = [j for j in k if self.names[j] in self._element_names
               and self.names[j] != self._proportional]  # dK_e/dE = K_e / E: not kept
        if len(mat) * m.edofs.size * m.edofs.shape[1] * 8 > self.DKE_BUDGET:
            return False
        key = m.element_key(params)  # dK_e/dphi depends on these values only
        names = tuple(self.names[j] for j in mat)
        if mat and (self._dke is None or self._dke[:2] != (key, names)):
            e = unit_tangents(params, list(names))
            if m.by_kind:
                dke = m.element_jvp("tangent", (1,), np.zeros(m.n_dof), params, None, None, e,
                                    None)[0]
            else:
                dke = np.asarray(self._dke_whole(params, e))
            self._dke = (key, names, dke)
        Ke = m.element_stiffness(params)
        ue = np.asarray(w)[m.edofs]
        flat = m.edofs.ravel()
        for j in k:
            re = np.zeros(m.edofs.shape)
            if j in mat:
                re += np.einsum("eij,ej->ei", self._dke[2][mat.index(j)], ue)
            v = w_dot[j][m.edofs]  # K_e du_e/dphi
            if self.names[j] == self._proportional:  # + dK_e/dE u_e = K_e u_e / E
                v = v + ue / float(params[self._proportional])
            if np.any(v):
                re += np.einsum("eij,ej->ei", Ke, v)
            P[j] += np.bincount(flat, weights=re.ravel(), minlength=m.n_dof)
        return True
