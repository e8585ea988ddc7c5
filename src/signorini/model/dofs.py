"""The layout of the unknowns of a :class:`~signorini.model.problem.Problem`.

``w`` (n_dof,) = [U (2 or 3 per node, node-major), Lambda (the multipliers of each
contact surface, node-major)]. Prescribed displacement DOFs are part of ``w``
(their values are set, not solved for); the rest are *free*. Building the
layout is where inconsistent boundary data is caught: unused nodes, a DOF
prescribed twice, contact surfaces that share nodes or are not chains.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._jax import jax, jnp
from ..contact.area import check_edges, contact_nodes, nodal_normals
from ..contact.friction3d import disc, reference_axis
from ..contact import mortar3d
from ..contact.mortar import build_patches, is_mortar
from ..errors import InputError
from ..fem.mesh import parts


@dataclass(frozen=True)
class Surface:
    """Static data of one contact surface."""

    contact: object  # Contact
    edges: np.ndarray  # (n_edges, 2); in 3-D the faces (n_faces, 4 or 3)
    nodes: np.ndarray  # (nc,) mesh node indices
    lam_offset: int  # first multiplier DOF
    n_mult: int
    dofs: np.ndarray  # (nc, dim + n_mult) DOFs of each contact element
    #: friction: which tangential multipliers each node carries, (nc,) in 2-D, (nc, 2)
    #: in 3-D (1 where it does, 0 where its tangential motion is prescribed); None:
    #: no history
    tangential: np.ndarray | None
    axes: np.ndarray | None = None  # 3-D friction: (nc, 3) the fixed axis e_S of each node's tangent basis
    #: a contact pair (:mod:`signorini.contact.mortar`): each slave node's patch of nodes
    patches: object = None

    @property
    def lam_dofs(self) -> np.ndarray:
        return self.dofs[:, self.dofs.shape[1] - self.n_mult:]

    @property
    def has_history(self) -> bool:
        return self.tangential is not None

    @property
    def history_data(self) -> tuple:
        """The per-node constants that follow the history value in a friction node's
        ``hist``: (tangential,) in 2-D, (e_S, tangential) in 3-D."""
        if self.axes is None:
            return (self.tangential,)
        return (self.axes, self.tangential)


class DofLayout:
    """Unknowns, prescribed and free DOFs, contact surfaces of a problem."""

    def __init__(self, problem):
        mesh = problem.mesh
        self.n_nodes = mesh.n_nodes
        self.dim = d = int(mesh.nodes.shape[1])  # displacement components per node
        self.conn = mesh.cells
        self.edofs = (d * self.conn[:, :, None] + np.arange(d)).reshape(len(self.conn), -1)
        used = np.zeros(mesh.n_nodes, bool)
        used[self.conn.ravel()] = True
        if not used.all():
            lone = np.nonzero(~used)[0]
            raise InputError(
                f"{lone.size} node(s) belong to no cell (first: node {int(lone[0])} at "
                f"{mesh.nodes[lone[0]].round(6).tolist()}); their displacements would be "
                "undetermined. Remove unused nodes from the mesh (e.g. geometry points of a gmsh "
                "file) and renumber the cells")
        self._prescribe(problem)
        self._surfaces(problem)
        self._check_bodies(mesh)
        mask = np.ones(self.n_dof, bool)
        mask[self.prescribed] = False
        self.free = np.nonzero(mask)[0]

    def _prescribe(self, problem):
        pres, seen = [], {}
        for f in problem.fixed:
            if f.component not in range(self.dim):
                raise InputError(f"Fixed({f.node_set!r}): component must be one of "
                                 f"{list(range(self.dim))}, got {f.component}")
            for n in problem.mesh.node_set(f.node_set):
                d = self.dim * int(n) + f.component
                if d in seen:
                    raise InputError(
                        f"inconsistent boundary sets: DOF {f.component} of node {n} is prescribed "
                        f"by both {seen[d]!r} and {f.node_set!r}; prescribe each DOF once")
                seen[d] = f.node_set
                pres.append((d, f))
        self.prescribed = np.array([d for d, _ in pres], dtype=np.int64)
        self.prescribed_fixed = [f for _, f in pres]

    def _surfaces(self, problem):
        mesh = problem.mesh
        d = self.dim
        off = d * self.n_nodes
        surfaces = []
        pres = set(self.prescribed.tolist())
        for c in problem.contact:
            if d == 3:  # a face set
                edges = mesh.face_set(c.edges)
                if not len(edges):
                    raise InputError(f"contact face set {c.edges!r} is empty")
                c = replace(c, method=disc(c.method))  # Coulomb: the Coulomb disc
            else:
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
            both = np.array([all(d * n + k in pres for k in range(d)) for n in nodes])
            if both.any():
                raise InputError(
                    f"inconsistent boundary sets: contact node {int(nodes[np.argmax(both)])} of "
                    f"{c.edges!r} has every displacement component prescribed, so contact there "
                    "is meaningless; remove it from the contact set or free one component")
            m = c.method.n_multipliers
            lam = off + np.arange(len(nodes) * m).reshape(len(nodes), m)
            patches = None
            if is_mortar(c):
                patches = self._pair_patches(mesh, c, edges, nodes)
                xdofs = (d * patches.nodes[:, :, None] + np.arange(d)).reshape(len(nodes), -1)
            else:
                xdofs = d * nodes[:, None] + np.arange(d)
            dofs = np.concatenate([xdofs, lam], axis=1)
            if d == 3:
                tang, axes = self._tangential_mask_3d(c, mesh.nodes, edges, nodes, pres, problem.params)
            else:
                tang, axes = self._tangential_mask(c, mesh.nodes, edges, nodes, pres), None
            surfaces.append(Surface(c, edges, nodes, off, m, dofs, tang, axes, patches))
            off += len(nodes) * m
        self.surfaces = tuple(surfaces)
        self.n_dof = off

    def _check_bodies(self, mesh):
        """Every body (connected part of the mesh) must be held somewhere: by a
        prescribed displacement or by a contact (its nodes on a contact surface,
        or the master surface of a pair); otherwise its rigid motion is free and
        the first tangent singular."""
        bodies = parts(mesh)
        if len(bodies) == 1:
            return
        held = np.zeros(self.n_nodes, bool)
        held[self.prescribed // self.dim] = True
        for s in self.surfaces:
            held[s.nodes] = True
            if s.patches is not None:  # the master segments or faces that face a slave node
                held[s.patches.master_nodes()] = True
        for name, nodes, _ in bodies:
            if not held[nodes].any():
                node = int(nodes[0])
                what = f"body {name!r}" if name in mesh.node_sets else f"the body of node {node}"
                raise InputError(
                    f"{what} (at {mesh.nodes[node].round(6).tolist()}) has no support and no contact: "
                    "nothing holds its rigid motion. Prescribe some of its displacements (Fixed) or put "
                    "it in contact (a Contact on its boundary, or a contact pair with another body)")

    def _pair_patches(self, mesh, c, edges, nodes):
        """The patches of a contact pair's slave nodes (:func:`signorini.contact.mortar.build_patches`)."""
        name = f"{c.edges}/{c.obstacle.master}"
        if self.dim == 3:
            master = mesh.face_set(c.obstacle.master)
            if not len(master):
                raise InputError(f"contact pair {name}: the master face set {c.obstacle.master!r} is empty")
            patches = mortar3d.build_patches(np.asarray(mesh.nodes, dtype=float), edges, nodes, master,
                                             c.obstacle.search, name, c.obstacle.slide)
        else:
            master = mesh.edge_set(c.obstacle.master)
            check_edges(master, c.obstacle.master)
            patches = build_patches(np.asarray(mesh.nodes, dtype=float), edges, nodes, master,
                                    c.obstacle.search, name, c.obstacle.slide)
        if not patches.has_candidates():
            what = ("face", "face", "face sets") if self.dim == 3 else ("segment", "segment", "edge sets")
            raise InputError(
                f"contact pair {c.edges!r}/{c.obstacle.master!r}: no master {what[0]} faces any slave "
                f"{what[1]} within the search distance; check that the two {what[2]} face each other "
                "(outward normals opposite) and that search (the normal distance of candidates) is "
                "large enough")
        return patches

    @staticmethod
    def _tangential_mask(contact, X, edges, nodes, pres):
        """(nc,) 1.0 where a history (friction) node carries lam_T, 0.0 where its
        tangential displacement is prescribed (symmetry line or axis: g_T would be
        identically 0 and the stick row of lam_T zero, docs/theory.md §3.6); None
        for methods without history. "Tangential" = the prescribed component is
        closer to the body's reference tangent than to its normal."""
        if not contact.method.has_history:
            return None
        N = np.asarray(nodal_normals(X, edges, nodes))
        mask = np.ones(len(nodes))
        for k, n in enumerate(nodes):
            for c in (0, 1):
                if 2 * int(n) + c in pres and abs(N[k, 1 - c]) >= abs(N[k, c]):
                    mask[k] = 0.0  # |T_c| = |N_{1-c}|: prescribed component is tangential
        return mask

    @staticmethod
    def _tangential_mask_3d(contact, X, faces, nodes, pres, params):
        """(mask (nc, 2), e_S (nc, 3)) of a 3-D friction surface, or (None, None).

        Directions are judged against the obstacle's normal n0 at each node's
        reference position at t = 0 and the problem's parameter values (not the
        body's normal: a lateral face may fold onto a die). A prescribed
        component c of a node is tangential when the axis e_c is closer to the
        tangent plane than to n0 (|n0_c| < 1/sqrt(2)). With none, e_S is the axis
        least aligned with n0 and the node carries both multipliers; with one (a
        symmetry plane), e_S = e_c, so that t2 (the projection of e_c on the
        tangent plane) is the prescribed direction and lam_T2 is dropped; with two
        or more (an axis), both are dropped (docs/theory.md §12.4). e_S is a
        property of the mesh and the nominal problem: it does not move with a
        perturbed parameter."""
        if not contact.method.has_history:
            return None, None
        try:
            geo = contact.obstacle.geometry(params, 0.0)
            n0 = np.asarray(jax.vmap(lambda x: contact.obstacle.normal(x, geo))(
                jnp.asarray(X[nodes], dtype=float)))
            if not np.all(np.isfinite(n0)):
                raise ValueError
        except Exception:  # noqa: BLE001  (bad names or values: the model's checks say which)
            n0 = -np.asarray(nodal_normals(X, faces, nodes))
        mask = np.ones((len(nodes), 2))
        axes = np.zeros((len(nodes), 3))
        for k, n in enumerate(nodes):
            held = [c for c in range(3) if 3 * int(n) + c in pres and abs(n0[k, c]) < 2 ** -0.5]
            axes[k] = reference_axis(n0[k])
            if len(held) == 1:
                axes[k] = np.eye(3)[held[0]]
                mask[k, 1] = 0.0
            elif held:
                mask[k] = 0.0
        return mask, axes

    def split(self, w):
        """w -> (u (n_nodes, dim), [lam_s (nc_s, m_s) per surface])."""
        u = w[: self.dim * self.n_nodes].reshape(-1, self.dim)
        lams = [w[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(s.nodes.size, s.n_mult)
                for s in self.surfaces]
        return u, lams

    def block_dofs(self) -> list[np.ndarray]:
        """DOF maps of the element blocks and of each surface's contact blocks."""
        return [self.edofs] + [s.dofs for s in self.surfaces]
