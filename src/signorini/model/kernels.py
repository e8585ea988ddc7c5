"""A :class:`Problem` compiled into JAX kernels.

Two pure functions are the source of truth (docs/theory.md §1)::

    R     = residual(w, params, t, state_n)      # internal + contact - external forces
    state = update(w, params, t, state_n)        # history after convergence at t

with the state a pytree ``(w_n, contact history, material history)``:

* ``w_n`` (n_dof,): the unknowns of the previous converged increment;
* contact history: per contact surface, the slip coordinates s_n (nc,) of its
  nodes on the obstacle (friction), or None;
* material history: (n_cells, 4, n_state) at the Gauss points (plasticity:
  C_p^{-1} and alpha), or None for materials without history.

Residual and update are built from per-element kernels (:mod:`signorini.fem.element`,
which take the kinematics and the formulation) and per-contact-node kernels
(gradients of the contact pseudo-potentials), ``vmap``-ed. Newton gets the
kernels' Jacobians block by block (:meth:`Model.local_tangents`, assembled
sparsely once per pattern); the DDM pseudo-load is a JVP of ``residual`` in
(params, w_p, state_n), the history sensitivity a JVP of ``update`` in
(w, params, state_n) (:mod:`signorini.sensitivity`). The DOF layout lives in
:mod:`signorini.model.dofs`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..fem import element
from .._programs import Program
from .._jax import jax, jnp, to_device
from ..fem.assembly import SparsityPattern
from ..contact.area import nodal_normals
from .dofs import DofLayout
from ..errors import InputError
from ..contact.obstacles import Linearized
from .fields import ModelFields
from .geometry import NODES, ModelGeometry  # noqa: F401  (NODES: re-exported)
from .history import ModelHistory
from .identity import stable_digest, structure_key
from .problem import Problem
from .stiffness import ModelStiffness
from .validation import ModelChecks



@dataclass(frozen=True)
class Compiled:
    """The model's compiled programs that solvers and outputs call eagerly (each
    the ``jax.jit`` of the pure method of the same name)."""

    residual: Callable      #: Model.residual(w, params, t, state_n)
    cases: Callable         #: Model.cases(w, params, t, state_n)
    status: Callable        #: Model.contact_status(w, params, t, state_n, surface)
    fields: Callable        #: Model.contact_fields(w, params, t, surface)
    update: Callable        #: Model.update(w, params, t, state_n)
    switch_fields: Callable  #: Model.switch_fields(w, params, t, state_n)
    stiffness: Callable     #: element stiffness of a linear body, Ke(params)


class Model(ModelGeometry, ModelChecks, ModelHistory, ModelStiffness, ModelFields):
    """Kernels, DOF layout and sparsity pattern of a :class:`Problem`.

    The class is assembled from one part per concern, each in its own module:
    :class:`~signorini.model.geometry.ModelGeometry` (reference geometry, loads,
    prescribed values), :class:`~signorini.model.validation.ModelChecks`
    (parameter checks), :class:`~signorini.model.history.ModelHistory` (history
    update and its sensitivity), :class:`~signorini.model.stiffness.ModelStiffness`
    (a linear body's kept element stiffness, the tangent's analysis values) and
    :class:`~signorini.model.fields.ModelFields` (post-processing); this module
    holds the residual, the contact inputs and the tangent.

    ``structure``: the problem's :func:`~signorini.model.identity.structure_key`
    when the caller has it already (:func:`signorini.algorithms.stepping.model_for`),
    so that it is not computed twice.

    Besides those of its :class:`~signorini.model.dofs.DofLayout` (``layout``):

    Attributes:
        kinematics, formulation: of the elements (plane strain / axisymmetric,
            standard / F-bar).
        pattern: the sparsity pattern of the free-free tangent.
        fext: compiled external forces ``fext(X, params, t)``.
        cache: compiled DDM / response functions, reused across solves.
        compiled: the compiled programs solvers and outputs call (:class:`Compiled`).
    """

    def __init__(self, problem: Problem, structure=None):
        self.problem = p = problem
        self.layout = layout = DofLayout(p)
        self._check_names()
        self.kinematics = p.kinematics
        self.kinematics.check_mesh(p.mesh.nodes)
        self.formulation = p.resolved_formulation()
        self.material = p.material
        self.n_state = int(p.material.n_state)
        self.load_edges = [p.mesh.edge_set(l.edges) for l in p.loads]
        finite = p.material.finite_strain
        self.linear_contact = [
            c.kinematics == "linear" or (c.kinematics == "auto" and not finite) for c in p.contact]
        self.reference_nodes = p.mesh.nodes
        self.shape_names = list(p.shape)
        self._V = {k: to_device(np.asarray(v, dtype=float)) for k, v in p.shape.items()}
        self._X0 = to_device(np.asarray(p.mesh.nodes, dtype=float))
        self._X0N = [nodal_normals(self.reference_nodes, s.edges, s.nodes) for s in layout.surfaces]

        # linear elastic body (small strain, standard element): its stiffness does not
        # depend on w, so it is computed once per parameter set and reused by every
        # Newton iteration, which then costs the contact kernels and a block product only
        self.linear_elements = (bool(p.material.linear) and not self.n_state
                                and isinstance(self.formulation, element.Standard))
        self._ke = None  # (element_key, Ke as JAX array, Ke as NumPy array)
        self._element_names = self.element_parameters()  # what Ke depends on (element_key)
        self._fixed_groups = None  # (distinct Fixed, index of each prescribed DOF's)
        self.pattern = SparsityPattern(layout.block_dofs(), layout.n_dof, layout.free)
        # content digest of the problem's structure: the key of this model's programs
        # on disk (None: some component is known only by identity, memory only)
        try:
            self.key = stable_digest(structure_key(p) if structure is None else structure)
        except TypeError:
            self.key = None
        program = self.program
        self.fext = program(self.external_forces, "fext")
        self.cache: dict = {}
        self._local = program(self._local_impl, "local")
        # friction: the case flags and the tangent in one program: one dispatch per Newton
        # evaluation instead of two, which matters on small meshes, where a dispatch
        # costs more than the work (docs/theory.md §10.2)
        self._local_cases = program(self._local_cases_impl, "local_cases")
        self.compiled = Compiled(
            residual=program(self.residual, "residual"), cases=program(self.cases, "cases"),
            status=program(self.contact_status, "status", static_argnums=4),
            fields=program(self.contact_fields, "fields", static_argnums=3),
            update=program(self.update, "update"),
            switch_fields=program(self.switch_fields, "switch_fields"),
            stiffness=program(lambda p: self._elements(jnp.zeros(self.n_dof), p, None, True)[1],
                              "stiffness"))
        self._reference = program(self._reference_impl, "reference")
        self.prescribed_at = program(self.prescribed_values, "prescribed")  # one program, not an op per Fixed
        self._update_jvp = program(jax.vmap(
            lambda w, p, t, s, wd, e, sd: jax.jvp(lambda w_, p_, s_: self.update(w_, p_, t, s_),
                                                  (w, p, s), (wd, e, sd))[1],
            (None, None, None, None, 0, 0, 0)), "update_jvp")

    def program(self, fn, name: str, static_argnums=()) -> Program:
        """``jax.jit(fn)`` kept between processes under this model's key and ``name``
        (:class:`signorini._programs.Program`): ``fn`` must be fixed by the model and
        ``name`` (a function of a caller's own needs a name of its own)."""
        return Program(fn, name, self.key, static_argnums=static_argnums)

    # ----------------------------------------------------- layout delegation
    n_nodes = property(lambda self: self.layout.n_nodes)
    n_dof = property(lambda self: self.layout.n_dof)
    conn = property(lambda self: self.layout.conn)
    edofs = property(lambda self: self.layout.edofs)
    surfaces = property(lambda self: self.layout.surfaces)
    prescribed = property(lambda self: self.layout.prescribed)
    free = property(lambda self: self.layout.free)

    @property
    def _tangential(self):
        """Per surface: its friction mask (see :class:`signorini.model.dofs.Surface`)."""
        return [s.tangential for s in self.surfaces]

    def split(self, w):
        return self.layout.split(w)

    def block_dofs(self):
        return self.layout.block_dofs()

    @property
    def has_history(self) -> bool:
        """True if some contact surface (friction) or the material carries history."""
        return self.has_contact_history or self.n_state > 0

    @property
    def has_contact_history(self) -> bool:
        return any(s.has_history for s in self.surfaces)




    #: eps outside [1e-8, 1e8] x E/h makes the tangent ill-conditioned to no benefit
    EPS_RANGE = (1e-8, 1e8)

    def contact_inputs(self, s, X, u, lam, params, t):
        """Per-node inputs of a surface: positions x, multipliers, areas A, obstacle
        geometry, method values, and (X, reference normals) for linearised kinematics."""
        c = s.contact
        A = self.kinematics.contact_areas(X, s.edges, s.nodes)
        x = X[s.nodes] + u[s.nodes]
        geo = c.obstacle.geometry(params, t)
        cp = c.method.values(params)
        return x, lam, A, geo, cp, (X[s.nodes], nodal_normals(X, s.edges, s.nodes))

    def _surface_inputs(self, w, params, t):
        """(index, surface, x, lam, A, geo, cp, Xs) for every contact surface."""
        X = self.reference(params)
        u, lams = self.split(w)
        for i, s in enumerate(self.surfaces):
            yield (i, s) + self.contact_inputs(s, X, u, lams[i], params, t)

    def obstacle_at(self, s, Xs):
        """The obstacle as seen by one contact node (linearised kinematics if asked)."""
        if self.linear_contact[self.surfaces.index(s)]:
            return Linearized(s.contact.obstacle, *Xs)
        return s.contact.obstacle

    def _node_history(self, i: int, state_n, cases=None):
        """Per-node history input of surface i for ``method.residual``: None, or
        (s_n (nc,), tangential mask (nc,)[, case flags]) for friction surfaces."""
        s = self.surfaces[i]
        if not s.has_history:
            return None
        if state_n is None:
            raise InputError(
                f"contact surface {s.contact.edges!r} has friction, which needs the history "
                "state_n = (w_n, contact history, material history); start from "
                "model.initial_state(w, params)")
        h = (state_n[1][i], jnp.asarray(s.tangential))
        return h if cases is None else h + (cases[i],)

    def _material_history(self, state_n):
        """(n_cells, 4, n_state) Gauss-point history, or None for materials without it."""
        if not self.n_state:
            return None
        if state_n is None or len(state_n) < 3 or state_n[2] is None:
            raise InputError(
                f"the material {type(self.material).__name__} has history (plasticity), which "
                "needs state_n = (w_n, contact history, material history); start from "
                "model.initial_state(w, params)")
        return state_n[2]

    def cases(self, w, params, t, state_n):
        """Case flags of every node of the friction surfaces (None elsewhere),
        evaluated in their own pass so that one Newton tangent uses one set of
        flags (see :meth:`signorini.contact.friction.Coulomb.residual`)."""
        out = []
        for i, s, x, lam, _, geo, cp, Xs in self._surface_inputs(w, params, t):
            if not s.has_history:
                out.append(None)
                continue
            h = self._node_history(i, state_n)
            out.append(jax.vmap(lambda xs, ls, hs, X0, s=s, geo=geo, cp=cp: s.contact.method.cases(
                xs, ls, geo, self.obstacle_at(s, X0), cp, hs))(x, lam, h, Xs))
        return tuple(out)

    def _elements(self, w, params, state_n, tangent: bool):
        """vmap of the element kernel over all cells: (r (n_cells, 8), [K], h (n_cells, 4, ns))."""
        X = self.reference(params)
        u, _ = self.split(w)
        mp = self.material.values(params)
        hn = self._material_history(state_n)
        kin, form, mat = self.kinematics, self.formulation, self.material
        if tangent:
            f = lambda ue, Xe, he: element.element_residual_tangent(ue, Xe, mat, mp, he, kin, form)
        else:
            f = lambda ue, Xe, he: element.element_update(ue, Xe, mat, mp, he, kin, form)
        return self._over_cells(f, u, X, hn)

    #: element kernels run over chunks of CELL_CHUNK cells on meshes of at least
    #: CHUNKED_FROM cells: one vmap over every cell streams each intermediate of
    #: the kernel through memory, a chunk keeps them in cache; below the threshold
    #: the intermediates of one vmap fit in cache and the loop over chunks would
    #: only add overhead (docs/theory.md §10.2)
    CELL_CHUNK = 16384
    CHUNKED_FROM = 65536

    def _over_cells(self, f, u, X, hn):
        """f(u_e, X_e, h_e) mapped over the cells (h_e None without history): a
        vmap, or on large meshes a ``lax.map`` over chunks of vmaps (the last
        chunk padded with copies of cell 0, dropped from the result)."""
        conn = np.asarray(self.conn)
        n = conn.shape[0]
        axes = (0, 0, 0 if hn is not None else None)
        if n < max(self.CHUNKED_FROM, 2 * self.CELL_CHUNK):
            return jax.vmap(f, axes)(u[conn], X[conn], hn)
        u, X = to_device(u), to_device(X)  # indexed by traced chunks of cells
        hn = None if hn is None else to_device(hn)
        size = self.CELL_CHUNK
        k = -(-n // size)
        cells = np.concatenate([np.arange(n), np.zeros(k * size - n, dtype=int)]).reshape(k, size)

        def chunk(ce):
            c, e = ce
            return jax.vmap(f, axes)(u[e], X[e], None if hn is None else hn[c])

        out = jax.lax.map(chunk, (cells, conn[cells]))
        return jax.tree_util.tree_map(lambda a: a.reshape((k * size,) + a.shape[2:])[:n], out)

    # --------------------------------------------------------------- residual
    def residual(self, w, params, t, state_n=None, cases=None, part: str = "all"):
        """Global residual R (n_dof,) = internal + contact - external forces;
        multiplier rows hold the contact-law equations (paper eqs. 19-20).
        ``part``: ``"elements"`` (internal forces only) or ``"rest"`` (external
        and contact forces only) split it for the DDM pseudo-loads."""
        R = jnp.zeros(self.n_dof)
        if part != "rest":
            re = self._elements(w, params, state_n, tangent=False)[0]
            R = R.at[self.edofs.ravel()].add(re.ravel())
        if part == "elements":
            return R
        R = R - self.external_forces(self.reference(params), params, t)
        for i, s, x, lam, A, geo, cp, Xs in self._surface_inputs(w, params, t):
            h = self._node_history(i, state_n, cases)
            method = s.contact.method
            rc = jax.vmap(lambda xs, ls, a, hs, X0, s=s, method=method, geo=geo, cp=cp: method.residual(
                xs, ls, a, geo, self.obstacle_at(s, X0), cp, hs),
                (0, 0, 0, 0 if h is not None else None, 0))(x, lam, A, h, Xs)
            R = R.at[s.dofs.ravel()].add(rc.ravel())
        return R

    def _local_impl(self, w, params, t, state_n=None, cases=None, Ke=None):
        """Residual and the Jacobian blocks of every element and contact node
        (``Ke``: the constant element stiffness of a linear body, if known; it is
        then not returned again, the blocks start with the contact blocks: as an
        output, Ke would be copied out of the compiled program on every call, a
        copy as large as the whole element stiffness)."""
        if Ke is None:
            re, Ke_new, _ = self._elements(w, params, state_n, tangent=True)
            blocks = [Ke_new]
            R = jnp.zeros(self.n_dof).at[self.edofs.ravel()].add(re.ravel())
        else:
            R = self.linear_forces(Ke, w)
            blocks = []
        R = R - self.external_forces(self.reference(params), params, t)
        for i, s, x, lam, A, geo, cp, Xs in self._surface_inputs(w, params, t):
            h = self._node_history(i, state_n, cases)
            method = s.contact.method

            def node(xs, ls, a, hs, X0, s=s, method=method, geo=geo, cp=cp):
                obstacle = self.obstacle_at(s, X0)

                def r(v):
                    out = method.residual(v[:2], v[2:], a, geo, obstacle, cp, hs)
                    return out, out
                return jax.jacfwd(r, has_aux=True)(jnp.concatenate([xs, ls]))

            Kc, rc = jax.vmap(node, (0, 0, 0, 0 if h is not None else None, 0))(x, lam, A, h, Xs)
            R = R.at[s.dofs.ravel()].add(rc.ravel())
            blocks.append(Kc)
        return R, blocks

    def _local_cases_impl(self, w, params, t, state_n, Ke=None):
        """:meth:`_local_impl` with the friction case flags computed first, once, and
        passed to every node as data (docs/theory.md §3.4)."""
        return self._local_impl(w, params, t, state_n, self.cases(w, params, t, state_n), Ke)

    def local_tangents(self, w, params, t, state_n=None):
        """(R (n_dof,), [Ke (ne, 8, 8), Kc_s (nc_s, k, k), ...]) as NumPy arrays."""
        Ke, Ke_np = self.element_stiffness(params) if self.linear_elements else (None, None)
        if self.has_contact_history:
            R, blocks = self._local_cases(w, params, t, state_n, Ke)
        else:
            R, blocks = self._local(w, params, t, state_n, None, Ke)
        head = [] if Ke_np is None else [Ke_np]
        return np.asarray(R), head + [np.asarray(b) for b in blocks]
