"""A :class:`Problem` compiled into JAX kernels and a DOF layout.

Unknowns ``w`` (n_dof,) = [U (2 n_nodes, node-major), Lambda (multipliers of
each contact surface, node-major)]. Prescribed displacement DOFs are part of
``w`` (their values are set, not solved for); the rest are *free*.

One pure function is the source of truth::

    R = residual(w, params, t, state_n)      # state_n = (w_n, history_n)

It is built from the per-element kernel (gradient of the element energy) and
the per-contact-node kernel (gradient of the contact pseudo-potential), both
``vmap``-ed. Newton gets the same kernels' Jacobians block by block (elements:
material-point autodiff contracted with B, :func:`element.element_residual_tangent`)
(:meth:`Model.local_tangents`, assembled sparsely), the DDM pseudo-load is a
JVP of ``residual`` in (params, w_p, state_n) (:mod:`signorini.sensitivity`).

Path dependence (friction, docs/theory.md §1 and §3): ``history_n`` holds, per contact
surface, the slip coordinates s_n (nc,) of its nodes (None without friction).
:meth:`Model.update_state` applies the pure update h(w, phi) after each
converged increment and carries its sensitivity by a JVP; frictionless models
have no state (``initial_state`` returns None) and run exactly as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import element
from ._jax import jax, jnp
from .contact.area import check_edges, contact_nodes, equivalent_areas, nodal_normals
from .errors import InputError, SignoriniError
from .mesh import check_orientation
from .obstacles import Linearized
from .params import as_jax, check_names, names_in, resolve, unit_tangents
from .problem import Problem


@dataclass(frozen=True)
class Surface:
    """Static data of one contact surface."""

    contact: object  # Contact
    edges: np.ndarray  # (n_edges, 2)
    nodes: np.ndarray  # (nc,) mesh node indices
    lam_offset: int  # first multiplier DOF
    n_mult: int
    dofs: np.ndarray  # (nc, 2 + n_mult) DOFs of each contact element

    @property
    def lam_dofs(self) -> np.ndarray:
        return self.dofs[:, 2:]


class Model:
    """Kernels, DOF layout and sparsity of a :class:`Problem`."""

    def __init__(self, problem: Problem):
        self.problem = p = problem
        mesh = p.mesh
        self.n_nodes = mesh.n_nodes
        self.conn = mesh.cells
        self.edofs = np.stack([2 * self.conn, 2 * self.conn + 1], axis=-1).reshape(-1, 8)
        self._check_names()
        self._X0_np = mesh.nodes
        used = np.zeros(mesh.n_nodes, bool)
        used[self.conn.ravel()] = True
        if not used.all():
            lone = np.nonzero(~used)[0]
            raise InputError(
                f"{lone.size} node(s) belong to no cell (first: node {int(lone[0])} at "
                f"{mesh.nodes[lone[0]].round(6).tolist()}); their displacements would be "
                "undetermined. Remove unused nodes from the mesh (e.g. geometry points of a gmsh "
                "file) and renumber the cells")

        # contact surfaces and multiplier DOFs
        off = 2 * self.n_nodes
        surfaces = []
        for c in p.contact:
            edges = mesh.edge_set(c.edges)
            check_edges(edges, c.edges)
            nodes = contact_nodes(edges)
            for other in surfaces:
                common = np.intersect1d(nodes, other.nodes)
                if common.size:
                    raise InputError(
                        f"contact surfaces {other.contact.edges!r} and {c.edges!r} share "
                        f"{common.size} node(s) (first: node {int(common[0])}); a node may belong "
                        "to one Contact only: split the edge sets, or use one Contact per obstacle "
                        "on disjoint parts of the boundary")
            m = c.method.n_multipliers
            lam = off + np.arange(len(nodes) * m).reshape(len(nodes), m)
            dofs = np.concatenate([2 * nodes[:, None], 2 * nodes[:, None] + 1, lam], axis=1)
            surfaces.append(Surface(c, edges, nodes, off, m, dofs))
            off += len(nodes) * m
        self.surfaces = tuple(surfaces)
        self.n_dof = off

        # prescribed DOFs
        pres, seen = [], {}
        for f in p.fixed:
            if f.component not in (0, 1):
                raise InputError(f"Fixed({f.node_set!r}): component must be 0 or 1, got {f.component}")
            for n in mesh.node_set(f.node_set):
                d = 2 * int(n) + f.component
                if d in seen:
                    raise InputError(
                        f"inconsistent boundary sets: DOF {f.component} of node {n} is prescribed "
                        f"by both {seen[d]!r} and {f.node_set!r}; prescribe each DOF once"
                    )
                seen[d] = f.node_set
                pres.append((d, f))
        self.prescribed = np.array([d for d, _ in pres], dtype=np.int64)
        self._pres_fixed = [f for _, f in pres]
        mask = np.ones(self.n_dof, bool)
        mask[self.prescribed] = False
        self.free = np.nonzero(mask)[0]
        for s in self.surfaces:
            both = np.isin(2 * s.nodes, self.prescribed) & np.isin(2 * s.nodes + 1, self.prescribed)
            if both.any():
                n = int(s.nodes[np.argmax(both)])
                raise InputError(
                    f"inconsistent boundary sets: contact node {n} of {s.contact.edges!r} has both "
                    "displacement components prescribed, so contact there is meaningless; remove it "
                    "from the contact set or free one component"
                )
        self._tangential = [self._tangential_mask(s) for s in self.surfaces]
        self.load_edges = [mesh.edge_set(l.edges) for l in p.loads]
        finite = getattr(p.material, "finite_strain", True)
        self.linear_contact = [
            c.kinematics == "linear" or (c.kinematics == "auto" and not finite) for c in p.contact]

        # weights of the convergence norm: multiplier rows scaled to force units
        self._shape_names = list(p.shape)
        self._V = {k: jnp.asarray(v) for k, v in p.shape.items()}
        self._X0 = jnp.asarray(mesh.nodes)

        self._local = jax.jit(self._local_impl)
        self._residual = jax.jit(self.residual)
        self._cases = jax.jit(self.cases)
        self._status = jax.jit(self.contact_status, static_argnums=4)
        self._fields = jax.jit(self.contact_fields, static_argnums=3)
        self._history_fn = jax.jit(self.history)
        self._history_jvp = jax.jit(jax.vmap(
            lambda w, p, t, wd, e: jax.jvp(lambda w_, p_: self.history(w_, p_, t), (w, p), (wd, e))[1],
            (None, None, None, 0, 0)))

    # ------------------------------------------------------------------ setup
    def _check_names(self):
        p = self.problem
        specs = list(p.material.specs())
        for f in p.fixed:
            specs += f.specs()
        for l in p.loads:
            specs += l.specs()
        for c in p.contact:
            specs += c.specs()
        check_names(names_in(specs), p.params, "the problem definition")
        for s in specs:  # expressions are evaluated once here, before any JAX tracing
            if isinstance(s, str):
                continue
            try:
                v = np.asarray(resolve(s, p.params), dtype=float)
            except SignoriniError:
                raise
            except (TypeError, ValueError):
                raise InputError(f"a load, support, material or contact value is {s!r}, which is "
                                 "not a number, a parameter name or a function of the "
                                 "parameters") from None
            if not np.all(np.isfinite(v)):
                raise InputError(f"a load, support, material or contact value evaluates to {v} "
                                 "(NaN or inf); every value must be a finite number")

    def check(self, params: dict) -> None:
        """Validate parameter values (positive modulus, radius, eps; no inverted element)."""
        p = self.problem
        p.material.check(params)
        for s in self.surfaces:
            c = s.contact
            c.obstacle.check(params)
            c.method.check(params)
            self._check_regularisation(s, params)
        if self._shape_names:
            X = np.asarray(self.reference(as_jax(params)))
            check_orientation(X, self.conn, "reference mesh at the given shape parameters")

    #: eps outside [1e-8, 1e8] x E/h makes the tangent ill-conditioned to no benefit
    EPS_RANGE = (1e-8, 1e8)

    def _check_regularisation(self, s: Surface, params) -> None:
        """eps (penalty / augmentation) must be finite and not absurd next to E/h."""
        vals = {k: float(v) for k, v in s.contact.method.values(params).items() if k.startswith("eps")}
        try:
            E = float(resolve(self.problem.material.E, params))
        except AttributeError:
            return
        X = self._X0_np
        h = float(np.linalg.norm(X[s.edges[:, 1]] - X[s.edges[:, 0]], axis=1).mean())
        scale = E / h
        lo, hi = self.EPS_RANGE
        for k, v in vals.items():
            if not np.isfinite(v) or not lo * scale <= v <= hi * scale:
                raise InputError(
                    f"contact {s.contact.edges!r}: {k} = {v:.4g} is outside [{lo:g}, {hi:g}] x E/h "
                    f"= [{lo * scale:.3g}, {hi * scale:.3g}] (E = {E:.4g}, mean contact cell h = "
                    f"{h:.3g}); such a value only ruins the conditioning of the tangent. "
                    f"Use eps of the order of E/h = {scale:.3g}")

    def _tangential_mask(self, s: Surface):
        """(nc,) 1.0 where a history (friction) node carries lam_T, 0.0 where its
        tangential displacement is prescribed (symmetry line: g_T would be
        identically 0 and the stick row of lam_T zero, docs/theory.md §3); None for
        methods without history. "Tangential" = the prescribed component is closer
        to the body's reference tangent than to its normal (nominal mesh)."""
        if not getattr(s.contact.method, "has_history", False):
            return None
        N = np.asarray(nodal_normals(self._X0_np, s.edges, s.nodes))
        mask = np.ones(len(s.nodes))
        pres = set(self.prescribed.tolist())
        for k, n in enumerate(s.nodes):
            for c in (0, 1):
                if 2 * int(n) + c in pres and abs(N[k, 1 - c]) >= abs(N[k, c]):
                    mask[k] = 0.0  # |T_c| = |N_{1-c}|: prescribed component is tangential
        return mask

    @property
    def has_history(self) -> bool:
        """True if some contact surface carries history (friction)."""
        return any(m is not None for m in self._tangential)

    # ----------------------------------------------------------- pure kernels
    def reference(self, params):
        """X(phi) (n_nodes, 2): nominal mesh moved along the design velocities."""
        X = self._X0
        for k in self._shape_names:
            X = X + (params[k] - self.problem.shape_nominal[k]) * self._V[k]
        return X

    def split(self, w):
        """w -> (u (n_nodes, 2), [lam_s (nc_s, m_s) per surface])."""
        u = w[: 2 * self.n_nodes].reshape(-1, 2)
        lams = [w[s.lam_offset : s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)
                for s in self.surfaces]
        return u, lams

    def external_forces(self, X, params, t):
        """(n_dof,) consistent nodal forces of all loads at load factor t."""
        f = jnp.zeros(self.n_dof)
        for load, edges in zip(self.problem.loads, self.load_edges):
            fe = load.nodal_forces(X, edges, params, t)  # (n_edges, 2, 2)
            d = np.stack([2 * edges, 2 * edges + 1], axis=-1)
            f = f.at[d.ravel()].add(fe.ravel())
        return f

    def prescribed_values(self, params, t):
        """(n_prescribed,) prescribed displacement values at t."""
        if not len(self._pres_fixed):
            return jnp.zeros(0)
        return jnp.stack([jnp.asarray(resolve(f.value, params), dtype=float) * f.ramp(t)
                          for f in self._pres_fixed])

    def _contact_inputs(self, s: Surface, X, u, lam, params, t):
        c = s.contact
        A = equivalent_areas(X, s.edges, s.nodes)
        x = X[s.nodes] + u[s.nodes]
        geo = c.obstacle.geometry(params, t)
        cp = c.method.values(params)
        return x, lam, A, geo, cp, (X[s.nodes], nodal_normals(X, s.edges, s.nodes))

    def _obstacle_at(self, s: Surface, Xs):
        """The obstacle as seen by one contact node (linearised kinematics if asked)."""
        if self.linear_contact[self.surfaces.index(s)]:
            return Linearized(s.contact.obstacle, *Xs)
        return s.contact.obstacle

    def _node_history(self, i: int, state_n, cases=None):
        """Per-node history input of surface i for ``method.residual``: None, or
        (s_n (nc,), tangential mask (nc,)[, case flags]) for friction surfaces."""
        if self._tangential[i] is None:
            return None
        if state_n is None:
            raise InputError(
                f"contact surface {self.surfaces[i].contact.edges!r} has friction, which needs the "
                "history state_n = (w_n, history_n); start from model.initial_state(w, params)")
        h = (state_n[1][i], jnp.asarray(self._tangential[i]))
        return h if cases is None else h + (cases[i],)

    def cases(self, w, params, t, state_n):
        """Case flags of every node of the friction surfaces (None elsewhere),
        evaluated in their own pass so that one Newton tangent uses one set of
        flags (see :meth:`signorini.contact.friction.Coulomb.residual`)."""
        X = self.reference(params)
        u, lams = self.split(w)
        out = []
        for i, s in enumerate(self.surfaces):
            if self._tangential[i] is None:
                out.append(None)
                continue
            x, lam, _, geo, cp, Xs = self._contact_inputs(s, X, u, lams[i], params, t)
            h = self._node_history(i, state_n)
            out.append(jax.vmap(lambda xs, ls, hs, X0, s=s, geo=geo, cp=cp: s.contact.method.cases(
                xs, ls, geo, self._obstacle_at(s, X0), cp, hs))(x, lam, h, Xs))
        return tuple(out)

    # ---------------------------------------------------------------- history
    def history(self, w, params, t):
        """Pure history update h(w, phi) after convergence at t (docs/theory.md §1, §3): the slip
        coordinate s = s(x_S) of every node of a friction surface on the obstacle at
        t (linearised obstacle in small-strain runs); None for other surfaces."""
        X = self.reference(params)
        u, lams = self.split(w)
        out = []
        for i, s in enumerate(self.surfaces):
            if self._tangential[i] is None:
                out.append(None)
                continue
            x, _, _, geo, _, Xs = self._contact_inputs(s, X, u, lams[i], params, t)
            out.append(jax.vmap(lambda xs, X0, s=s, geo=geo: self._obstacle_at(s, X0).coordinate(
                xs, geo))(x, Xs))
        return tuple(out)

    def initial_state(self, w, params):
        """state_0 = (w_0, h_0) with s_0 = s(X(phi)) at t = 0; None without history."""
        if not self.has_history:
            return None
        w = jnp.asarray(w)
        return (w, self._history_fn(w, params, 0.0))

    def initial_state_sensitivity(self, params, names):
        """D state_0 / D phi_k batched over ``names``: (0, grad s . V_k + ds/dphi_k)."""
        if not self.has_history:
            return None
        e = unit_tangents(params, list(names))
        z = jnp.zeros((len(names), self.n_dof))
        return (z, self._history_jvp(jnp.zeros(self.n_dof), params, 0.0, z, e))

    def update_state(self, inc, params, t, state_n, state_dot, names):
        """New state (w, h(w, phi)) after a converged increment and its sensitivity
        (JVP of :meth:`history` with tangents (w_dot, e_k), batched over ``names``).
        Stores both on ``inc`` (``state``, ``state_sens``)."""
        if not self.has_history:
            return state_n, state_dot
        w = jnp.asarray(inc.w)
        state = (w, self._history_fn(w, params, t))
        sdot = None
        if state_dot is not None and len(names):
            wd = jnp.asarray(np.stack([inc.sens[n] for n in names]))
            sdot = (wd, self._history_jvp(w, params, t, wd, unit_tangents(params, list(names))))
        inc.state, inc.state_sens = state, sdot
        return state, sdot

    def residual(self, w, params, t, state_n=None, cases=None):
        """Global residual R (n_dof,) = internal + contact - external forces;
        multiplier rows hold the contact-law equations (paper eqs. 19-20)."""
        p = self.problem
        X = self.reference(params)
        u, lams = self.split(w)
        mp = p.material.values(params)
        re = jax.vmap(lambda ue, Xe: element.element_residual(ue, Xe, p.material, mp))(
            u[self.conn], X[self.conn])
        R = jnp.zeros(self.n_dof).at[self.edofs.ravel()].add(re.ravel())
        R = R - self.external_forces(X, params, t)
        for i, s in enumerate(self.surfaces):
            x, lam, A, geo, cp, Xs = self._contact_inputs(s, X, u, lams[i], params, t)
            h = self._node_history(i, state_n, cases)
            method = s.contact.method
            rc = jax.vmap(lambda xs, ls, a, hs, X0: method.residual(
                xs, ls, a, geo, self._obstacle_at(s, X0), cp, hs),
                (0, 0, 0, 0 if h is not None else None, 0))(x, lam, A, h, Xs)
            R = R.at[s.dofs.ravel()].add(rc.ravel())
        return R

    def _local_impl(self, w, params, t, state_n=None, cases=None):
        """Residual and the Jacobian blocks of every element and contact node."""
        p = self.problem
        X = self.reference(params)
        u, lams = self.split(w)
        mp = p.material.values(params)

        re, Ke = jax.vmap(lambda ue, Xe: element.element_residual_tangent(ue, Xe, p.material, mp))(
            u[self.conn], X[self.conn])
        R = jnp.zeros(self.n_dof).at[self.edofs.ravel()].add(re.ravel())
        R = R - self.external_forces(X, params, t)
        blocks = [Ke]
        for i, s in enumerate(self.surfaces):
            x, lam, A, geo, cp, Xs = self._contact_inputs(s, X, u, lams[i], params, t)
            h = self._node_history(i, state_n, cases)
            method = s.contact.method

            def node(xs, ls, a, hs, X0, s=s, method=method, geo=geo, cp=cp):
                obstacle = self._obstacle_at(s, X0)

                def r(v):
                    out = method.residual(v[:2], v[2:], a, geo, obstacle, cp, hs)
                    return out, out
                return jax.jacfwd(r, has_aux=True)(jnp.concatenate([xs, ls]))

            Kc, rc = jax.vmap(node, (0, 0, 0, 0 if h is not None else None, 0))(x, lam, A, h, Xs)
            R = R.at[s.dofs.ravel()].add(rc.ravel())
            blocks.append(Kc)
        return R, blocks

    def local_tangents(self, w, params, t, state_n=None):
        """(R (n_dof,), [Ke (ne, 8, 8), Kc_s (nc_s, k, k), ...]) as NumPy arrays."""
        cases = self._cases(w, params, t, state_n) if self.has_history else None
        R, blocks = self._local(w, params, t, state_n, cases)
        return np.asarray(R), [np.asarray(b) for b in blocks]

    def block_dofs(self) -> list[np.ndarray]:
        """DOF maps matching the blocks of :meth:`local_tangents`."""
        return [self.edofs] + [s.dofs for s in self.surfaces]

    def convergence_weights(self, params) -> np.ndarray:
        """(n_dof,) row weights giving every residual row force units."""
        wts = np.ones(self.n_dof)
        for s in self.surfaces:
            cp = s.contact.method.values(params)
            wts[s.lam_dofs] = np.asarray(s.contact.method.row_scale(cp), dtype=float)  # scalar or (m,)
        return wts

    # ------------------------------------------------------------ post-process
    def contact_fields(self, w, params, t, surface: int = 0):
        """Pure function: per-node gap g, p_N, p_T of a surface (each (nc,))."""
        s = self.surfaces[surface]
        X = self.reference(params)
        u, lams = self.split(w)
        x, lam, A, geo, cp, Xs = self._contact_inputs(s, X, u, lams[surface], params, t)
        meth = s.contact.method
        g = jax.vmap(lambda xs, X0: self._obstacle_at(s, X0).gap(xs, geo))(x, Xs)
        pN, pT = jax.vmap(lambda xs, ls, a, X0: meth.tractions(
            xs, ls, a, geo, self._obstacle_at(s, X0), cp))(x, lam, A, Xs)
        return {"gap": g, "p_N": pN, "p_T": pT, "area": A}

    def contact_status(self, w, params, t, state_n, surface: int = 0):
        """Pure function: per-node (status code, slip increment g_T) of a friction
        surface (codes of :mod:`signorini.contact.friction`); state_n = state
        *before* the increment of w."""
        s = self.surfaces[surface]
        X = self.reference(params)
        u, lams = self.split(w)
        x, lam, A, geo, cp, Xs = self._contact_inputs(s, X, u, lams[surface], params, t)
        meth = s.contact.method
        h = self._node_history(surface, state_n)
        st = jax.vmap(lambda xs, ls, a, hs, X0: meth.status(
            xs, ls, a, geo, self._obstacle_at(s, X0), cp, hs))(x, lam, A, h, Xs)
        gt = jax.vmap(lambda xs, hs, X0: meth.slip(xs, geo, self._obstacle_at(s, X0), hs))(x, h, Xs)
        return st, gt

    def stresses(self, w, params):
        """Pure function: element-averaged Cauchy stress (n_cells, 3, 3)."""
        p = self.problem
        X = self.reference(params)
        u, _ = self.split(w)
        mp = p.material.values(params)
        return jax.vmap(lambda ue, Xe: element.element_stress(ue, Xe, p.material, mp))(
            u[self.conn], X[self.conn])
