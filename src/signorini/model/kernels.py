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
(gradients of the contact pseudo-potentials), ``vmap``-ed. What solvers call
eagerly runs the same kernels through programs compiled once per element and
contact kind, for every mesh (:mod:`signorini.model.cells`,
:mod:`signorini.model.nodes`): Newton gets their Jacobians block by block
(:meth:`Model.local_tangents`, assembled sparsely once per pattern); the DDM
pseudo-load is a JVP of the residual in (params, w_p, state_n), the history
sensitivity a JVP of ``update`` in (w, params, state_n)
(:mod:`signorini.sensitivity`), the elements' through their kind's programs.
The DOF layout lives in :mod:`signorini.model.dofs`.
"""

from __future__ import annotations

import functools

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
from .cells import CellKernels, cell_groups, element_family
from .contact_nodes import ModelContactNodes
from .elements import ModelElements
from .history import ModelHistory
from .identity import stable_digest, structure_key
from .nodes import NodeKernels
from .problem import Problem
from .stiffness import ModelStiffness
from .validation import ModelChecks



@dataclass(frozen=True)
class Compiled:
    """What solvers and outputs call eagerly: compiled programs of the pure
    method of the same name, or (``residual``, ``update``, ``stiffness``) the
    same values with the element part from the element kind's programs
    (:mod:`signorini.model.cells`), as NumPy arrays."""

    residual: Callable      #: Model.residual(w, params, t, state_n)
    cases: Callable         #: Model.cases(w, params, t, state_n)
    status: Callable        #: Model.contact_status(w, params, t, state_n, surface)
    fields: Callable        #: Model.contact_fields(w, params, t, surface)
    update: Callable        #: Model.update(w, params, t, state_n)
    switch_fields: Callable  #: Model.switch_fields(w, params, t, state_n)
    stiffness: Callable     #: element stiffness of a linear body, Ke(params) (n_cells, 8, 8)


class Model(ModelGeometry, ModelChecks, ModelHistory, ModelStiffness, ModelFields, ModelElements,
            ModelContactNodes):
    """Kernels, DOF layout and sparsity pattern of a :class:`Problem`.

    The class is assembled from one part per concern, each in its own module:
    :class:`~signorini.model.geometry.ModelGeometry` (reference geometry, loads,
    prescribed values), :class:`~signorini.model.validation.ModelChecks`
    (parameter checks), :class:`~signorini.model.history.ModelHistory` (history
    update and its sensitivity), :class:`~signorini.model.stiffness.ModelStiffness`
    (a linear body's kept element stiffness, the tangent's analysis values),
    :class:`~signorini.model.fields.ModelFields` (post-processing) and
    :class:`~signorini.model.elements.ModelElements` and
    :class:`~signorini.model.contact_nodes.ModelContactNodes` (the element and
    contact parts through the programs of their kinds, compiled once for every
    mesh: :mod:`signorini.model.cells`, :mod:`signorini.model.nodes`); this
    module holds the pure residual, the contact inputs and the tangent.

    ``structure``: the problem's :func:`~signorini.model.identity.structure_key`
    when the caller has it already (:func:`signorini.algorithms.stepping.model_for`),
    so that it is not computed twice.

    Besides those of its :class:`~signorini.model.dofs.DofLayout` (``layout``):

    Attributes:
        kinematics, formulation: of the elements (plane strain / axisymmetric,
            standard / F-bar).
        pattern: the sparsity pattern of the free-free tangent.
        cells, node_kernels: the programs of the element kind and of each contact
            surface's kind (compiled once for every mesh).
        cache: compiled DDM / response functions, reused across solves.
        compiled: the compiled programs solvers and outputs call (:class:`Compiled`).
    """

    def __init__(self, problem: Problem, structure=None):
        self.problem = p = problem
        self.layout = layout = DofLayout(p)
        self._check_names()
        self.kinematics = p.kinematics
        self.kinematics.check_mesh(p.mesh.nodes)
        self.dim = layout.dim
        #: the element kernels of the body's kind of cell: Q4 (2-D) or the 3-D cells
        self.fem = element_family(self.kinematics)
        self.formulation = p.resolved_formulation()
        # per-body materials: each cell's body
        self.material = p.material.bind(p.mesh) if hasattr(p.material, "bind") else p.material
        self.n_state = int(p.material.n_state)
        self.load_edges = [p.mesh.face_set(l.edges) if self.dim == 3 else p.mesh.edge_set(l.edges)
                           for l in p.loads]  # noqa: E741
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
        self._ke = None  # (element_key, Ke (n_cells, 8, 8))
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
        # how the element and contact kernels are evaluated (docs/theory.md §10.6): on a
        # mesh of at most WHOLE_MESH_UP_TO cells, by programs of this model over the whole
        # mesh (gathers, kernels and scatters fused: one dispatch per Newton evaluation);
        # on larger meshes by the programs of the element and contact kinds, compiled once
        # for every mesh and run over chunks of cells and nodes
        # (contact pairs and per-body materials: whole-mesh programs only, the kinds'
        # programs take one material and no patches)
        # the cells that share element kernels: one group, or one per kind of cell (a
        # mixed mesh) and material law (bodies of several laws), each mapped over its
        # own cells by the whole-mesh programs
        self.groups = cell_groups(p, self.kinematics, self.material, self.formulation)
        self.mixed = len(self.groups) > 1
        self.by_kind = (len(self.conn) > self.WHOLE_MESH_UP_TO
                        and all(s.patches is None for s in layout.surfaces)
                        and not getattr(self.material, "per_cell", False) and not self.mixed)
        self.cells = CellKernels.of(p.material, self.kinematics, self.formulation)
        self._edofs_ravel = None
        self.cache: dict = {}
        self.node_kernels = [NodeKernels.of(s.contact.method, s.contact.obstacle, lin)
                             for s, lin in zip(layout.surfaces, self.linear_contact)]
        # what the kinds' programs take that depends on the parameters and t only
        self._contact_geometry = program(self._contact_geometry_impl, "contact_geometry")
        self._contact_geometry_jvp = program(self._contact_geometry_jvp_impl, "contact_geometry_jvp")
        self._update_contact = program(
            lambda w, p, t, s: self.update(w, p, t, s, "contact"), "update_contact")
        # the whole-mesh programs (built only when called: a large mesh never builds them)
        # (a linear body's without the elements: the contact and external forces alone,
        # its element forces are K_e u_e in NumPy, faster than XLA's scatter over the
        # whole mesh)
        self._local = program(self._local_impl, "local")
        self._local_contact = program(functools.partial(self._local_impl, elements=False),
                                      "local_contact")
        # friction: the case flags and the tangent in one program: one dispatch per Newton
        # evaluation instead of two, which matters on small meshes, where a dispatch
        # costs more than the work (docs/theory.md §10.2)
        self._local_cases = program(self._local_cases_impl, "local_cases")
        self._local_cases_contact = program(
            functools.partial(self._local_cases_impl, elements=False), "local_cases_contact")
        self._residual_whole = program(self.residual, "residual")
        self._cases_whole = program(self.cases, "cases")
        self._fields_whole = program(self.contact_fields, "fields", static_argnums=3)
        self._update_whole = program(self.update, "update")
        self._stiffness_whole = program(self.stiffness_pure, "stiffness")
        self._update_jvp_whole = program(jax.vmap(
            lambda w, p, t, s, wd, e, sd: jax.jvp(lambda w_, p_, s_: self.update(w_, p_, t, s_),
                                                  (w, p, s), (wd, e, sd))[1],
            (None, None, None, None, 0, 0, 0)), "update_jvp")
        self.compiled = Compiled(
            residual=self._residual_eager, cases=self._cases_eager,
            status=program(self.contact_status, "status", static_argnums=4),
            fields=self._fields_eager,
            update=self._update_eager,
            switch_fields=self._switch_fields_eager,
            stiffness=self._element_stiffness_eager)
        self._switch_fields_whole = program(self.switch_fields, "switch_fields")
        self.frames = program(self.contact_frames, "frames", static_argnums=4)
        self._reference = program(self._reference_impl, "reference")
        self.prescribed_at = program(self.prescribed_values, "prescribed")  # one program, not an op per Fixed
        self._update_contact_jvp = program(jax.vmap(
            lambda w, p, t, s, wd, e, sd: jax.jvp(
                lambda w_, p_, s_: self.update(w_, p_, t, s_, "contact"), (w, p, s), (wd, e, sd))[1],
            (None, None, None, None, 0, 0, 0)), "update_contact_jvp")
        self._parameter_jvp = program(self._parameter_jvp_impl, "parameter_jvp")
        self._parameter_vjp = program(self._parameter_vjp_impl, "parameter_vjp")

    #: meshes of at most this many cells are evaluated by programs of their own over
    #: the whole mesh, larger ones by the programs of their element and contact kinds:
    #: per cell, a kind's chunks cost 1.2x of a whole-mesh program at 1.8k cells and
    #: 0.5-0.8x from 7k cells up, but on a small mesh each evaluation then takes more
    #: dispatches and gathers than the work itself (docs/benchmarks.md)
    WHOLE_MESH_UP_TO = 4096

    def program(self, fn, name: str, static_argnums=()) -> Program:
        """``jax.jit(fn)`` kept between processes under this model's key and ``name``
        (:class:`signorini._programs.Program`): ``fn`` must be fixed by the model and
        ``name`` (a function of a caller's own needs a name of its own)."""
        return Program(fn, name, self._program_key, static_argnums=static_argnums)

    def _program_key(self) -> str | None:
        """This model's key with the chunking of its cells (:meth:`_over_cells`) and
        the batches of a pair's nodes (:meth:`_pair_batch`) as they are when a program
        is traced: a model chunked otherwise traces other code."""
        if self.key is None:
            return None
        return stable_digest((self.key, self.CELL_CHUNK, self.CHUNKED_FROM, self.PAIR_BATCH_BYTES))

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
        geo = c.obstacle.geometry(params, t)
        cp = c.method.values(params)
        if s.patches is not None:  # a contact pair: each slave node's patch of nodes
            pn = s.patches.nodes
            linear = self.linear_contact[self.surfaces.index(s)]
            return (X[pn] + u[pn], lam, A, geo, cp, s.patches.inputs(X, linear))
        x = X[s.nodes] + u[s.nodes]
        return x, lam, A, geo, cp, (X[s.nodes], nodal_normals(X, s.edges, s.nodes))

    def _surface_inputs(self, w, params, t):
        """(index, surface, x, lam, A, geo, cp, Xs) for every contact surface."""
        X = self.reference(params)
        u, lams = self.split(w)
        for i, s in enumerate(self.surfaces):
            yield (i, s) + self.contact_inputs(s, X, u, lams[i], params, t)

    def obstacle_at(self, s, Xs):
        """The obstacle as seen by one contact node (linearised kinematics if asked)."""
        linear = self.linear_contact[self.surfaces.index(s)]
        if s.patches is not None:
            return s.patches.node(*Xs, linear=linear, axisymmetric=self.kinematics.name == "axisymmetric")
        if linear:
            return Linearized(s.contact.obstacle, *Xs)
        return s.contact.obstacle

    def _node_history(self, i: int, state_n, cases=None):
        """Per-node history input of surface i for ``method.residual``: None, or for
        friction surfaces (s_n (nc,), tangential mask (nc,)[, case flags]) in 2-D,
        (y_n (nc, 3), e_S (nc, 3), tangential mask (nc, 2)[, case flags]) in 3-D."""
        s = self.surfaces[i]
        if not s.has_history:
            return None
        if state_n is None:
            raise InputError(
                f"contact surface {s.contact.edges!r} has friction, which needs the history "
                "state_n = (w_n, contact history, material history); start from "
                "model.initial_state(w, params)")
        h = (state_n[1][i],) + tuple(jnp.asarray(a) for a in s.history_data)
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
        fem = self.fem
        if tangent:
            f = lambda ue, Xe, he, m, g: fem.element_residual_tangent(ue, Xe, g.law, m, he, g.kin, g.form)
        else:
            f = lambda ue, Xe, he, m, g: fem.element_update(ue, Xe, g.law, m, he, g.kin, g.form)
        return self._over_cells(f, u, X, hn, mp)

    #: element kernels run over chunks of CELL_CHUNK cells on meshes of at least
    #: CHUNKED_FROM cells: one vmap over every cell streams each intermediate of
    #: the kernel through memory, a chunk keeps them in cache; below the threshold
    #: the intermediates of one vmap fit in cache and the loop over chunks would
    #: only add overhead (docs/theory.md §10.2)
    CELL_CHUNK = 16384
    CHUNKED_FROM = 65536

    def _over_cells(self, f, u, X, hn, mp):
        """f(u_e, X_e, h_e, mp_e, g) mapped over the cells of every group g
        (:class:`~signorini.model.cells.CellGroup`: its kinematics, law and
        formulation; h_e None without history; mp_e the material values, each
        cell's own with per-body materials, :class:`~signorini.materials.Bodies`).
        Several groups (a mixed mesh, bodies of several laws): each over its own
        cells (a tetrahedron's nodes and Gauss points the first of its row, a law's
        history the first of the largest one's), every output padded with zeros
        to the largest group's shape: a tetrahedron's forces and tangent add
        nothing at its repeated node, the history beyond a cell's own is unused."""
        if not self.mixed:
            return self._map_cells(functools.partial(f, g=self.groups[0]), u, X,
                                   np.asarray(self.conn), hn, mp)
        per_cell = getattr(self.material, "per_cell", False)
        parts = []
        for g in self.groups:
            h = None if hn is None or not g.n_state else hn[g.idx, :g.n_gauss, :g.n_state]
            m = jax.tree_util.tree_map(lambda a, idx=g.idx: a[idx], mp) if per_cell else mp
            parts.append(self._map_cells(functools.partial(f, g=g), u, X,
                                         np.asarray(self.conn)[g.idx, :g.n_nodes], h, m))
        n = len(self.conn)

        def combine(*outs):
            shape = tuple(max(sizes) for sizes in zip(*(o.shape[1:] for o in outs)))
            whole = jnp.zeros((n,) + shape, outs[0].dtype)
            for g, o in zip(self.groups, outs):
                pad = [(0, 0)] + [(0, b - a) for a, b in zip(o.shape[1:], shape)]
                whole = whole.at[g.idx].set(jnp.pad(o, pad))
            return whole
        return jax.tree_util.tree_map(combine, *parts)

    def _map_cells(self, f, u, X, conn, hn, mp):
        """f(u_e, X_e, h_e, mp_e) over the cells ``conn``: a vmap, or on large meshes
        a ``lax.map`` over chunks of vmaps (the last chunk padded with copies of
        cell 0, dropped from the result)."""
        n = conn.shape[0]
        per_cell = getattr(self.material, "per_cell", False)
        axes = (0, 0, 0 if hn is not None else None, 0 if per_cell else None)
        if n < max(self.CHUNKED_FROM, 2 * self.CELL_CHUNK):
            return jax.vmap(f, axes)(u[conn], X[conn], hn, mp)
        u, X = to_device(u), to_device(X)  # indexed by traced chunks of cells
        hn = None if hn is None else to_device(hn)
        size = self.CELL_CHUNK
        k = -(-n // size)
        cells = np.concatenate([np.arange(n), np.zeros(k * size - n, dtype=int)]).reshape(k, size)

        def chunk(ce):
            c, e = ce
            return jax.vmap(f, axes)(u[e], X[e], None if hn is None else hn[c],
                                     jax.tree_util.tree_map(lambda a: a[c], mp) if per_cell else mp)

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

    def _local_impl(self, w, params, t, state_n=None, cases=None, elements=True):
        """Residual and the Jacobian blocks of every element and contact node, by a
        vmap over the whole mesh (``elements=False``: the contact and external forces
        and the contact blocks only)."""
        R = -self.external_forces(self.reference(params), params, t)
        blocks = []
        if elements:
            re, Ke_new, _ = self._elements(w, params, state_n, tangent=True)
            blocks = [Ke_new]
            R = R.at[self.edofs.ravel()].add(re.ravel())
        for i, s, x, lam, A, geo, cp, Xs in self._surface_inputs(w, params, t):
            h = self._node_history(i, state_n, cases)
            method = s.contact.method

            def node(xs, ls, a, hs, X0, s=s, method=method, geo=geo, cp=cp):
                obstacle = self.obstacle_at(s, X0)

                k = xs.size  # a pair's patch: (P, dim) positions

                def r(v):
                    out = method.residual(v[:k].reshape(xs.shape), v[k:], a, geo, obstacle, cp, hs)
                    return out, out
                return jax.jacfwd(r, has_aux=True)(jnp.concatenate([xs.ravel(), ls]))

            batch = self._pair_batch(i)
            if batch is None:
                Kc, rc = jax.vmap(node, (0, 0, 0, 0 if h is not None else None, 0))(x, lam, A, h, Xs)
            else:  # a finite-kinematics pair: its nodes a batch at a time (memory)
                Kc, rc = jax.lax.map(lambda a, node=node: node(*a), (x, lam, A, h, Xs),
                                     batch_size=batch)
            R = R.at[s.dofs.ravel()].add(rc.ravel())
            blocks.append(Kc)
        return R, blocks

    #: bytes of a finite-kinematics 3-D pair's tangent per slave node, face pair and
    #: patch coordinate (the forward-mode derivatives of its clips, measured on the
    #: buffers XLA asks for: docs/benchmarks.md, ironing in 3-D), and the memory a
    #: batch of its nodes may take
    PAIR_TANGENT_BYTES, PAIR_BATCH_BYTES = 1.4e5, 1.0 * 1024.0**3

    def _pair_batch(self, i: int) -> int | None:
        """How many slave nodes of surface i's pair the tangent evaluates at once:
        all (None) for linearised kinematics and 2-D pairs; for a 3-D pair with
        finite kinematics as many as take PAIR_BATCH_BYTES (the vmap over all of
        them asked for 10 GB on a 75-node surface with 4 candidates per face)."""
        s = self.surfaces[i]
        if s.patches is None or self.linear_contact[i] or self.dim != 3:
            return None
        nc, P = s.patches.nodes.shape
        per_node = self.PAIR_TANGENT_BYTES * s.patches.master_mask[0].size * 3 * P
        batch = max(1, int(self.PAIR_BATCH_BYTES // per_node))
        return None if batch >= nc else batch

    def stiffness_pure(self, params):
        """Pure function: the element stiffness K_e (n_cells, 8, 8) of a linear body,
        the tangent of every cell at u = 0 by a vmap over the whole mesh."""
        return self._elements(jnp.zeros(self.n_dof), params, None, True)[1]

    def _local_cases_impl(self, w, params, t, state_n, elements=True):
        """:meth:`_local_impl` with the friction case flags computed first, once, and
        passed to every node as data (docs/theory.md §3.4)."""
        return self._local_impl(w, params, t, state_n, self.cases(w, params, t, state_n),
                                elements)

    @staticmethod
    def without_material(state):
        """The state with its Gauss-point history left out (what the contact and
        load programs take: they do not read it, and it need not be copied to them)."""
        return None if state is None else (state[0], state[1], None)

    def local_tangents(self, w, params, t, state_n=None):
        """(R (n_dof,), [Ke (ne, 8, 8), Kc_s (nc_s, k, k), ...]) as NumPy arrays."""
        if not self.by_kind:
            lin = self.linear_elements
            if self.has_contact_history:
                R, blocks = (self._local_cases_contact if lin else self._local_cases)(
                    w, params, t, state_n)
            else:
                R, blocks = (self._local_contact if lin else self._local)(w, params, t, state_n)
            R = np.asarray(R)
            if not lin:
                return R, [np.asarray(b) for b in blocks]
            Ke = self.element_stiffness(params)
            return self.linear_forces_np(Ke, w) + R, [Ke] + [np.asarray(b) for b in blocks]
        # the cells' programs first: they run while the contact part is computed
        pending = None if self.linear_elements else self.element_tangents_start(w, params, state_n)
        R, blocks = self.contact_tangents(w, params, t, state_n)
        if self.linear_elements:
            Ke = self.element_stiffness(params)
            R_el = self.linear_forces_np(Ke, w)
        else:
            R_el, Ke = self.element_tangents_finish(pending)
        return R_el + R, [Ke] + blocks

    def _residual_eager(self, w, params, t, state_n=None):
        """:meth:`residual` (NumPy): a whole-mesh program, or the internal forces from
        the element kind's programs."""
        if not self.by_kind:
            return np.asarray(self._residual_whole(w, params, t, state_n))
        R = self.contact_residual(w, params, t, state_n)
        if self.linear_elements:
            R_el = self.linear_forces_np(self.element_stiffness(params), w)
        else:
            R_el = self.element_forces(w, params, state_n)[0]
        return R_el + R
