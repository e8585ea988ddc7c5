"""Meshes of 4-node quadrilaterals with named node and boundary-edge sets.

Conventions: ``nodes`` (n_nodes, 2) reference coordinates; ``cells`` (n_cells, 4)
node indices counter-clockwise; an edge set is (n_edges, 2) node pairs ordered
so that the body lies on the left when walking from the first node to the
second (the orientation of the cell that owns the edge). Then the outward
normal of edge (a, b) is ``(dy, -dx) / L``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, InvertedElementError


class Cells:
    """What every mesh has: ``nodes``, ``cells`` and named ``node_sets``."""

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    def node_set(self, name: str) -> np.ndarray:
        return named(self.node_sets, "node", name)


@dataclass(frozen=True)
class Mesh(Cells):
    """A 2-D mesh of Q4 cells.

    Attributes:
        nodes: (n_nodes, 2) reference coordinates.
        cells: (n_cells, 4) node indices, counter-clockwise.
        node_sets: name -> sorted node indices.
        edge_sets: name -> (n_edges, 2) boundary edges (body on the left).
    """

    nodes: np.ndarray
    cells: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    edge_sets: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        nodes = np.ascontiguousarray(self.nodes, dtype=float)
        cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        if nodes.ndim != 2 or nodes.shape[1] != 2:
            raise InputError(f"nodes must have shape (n_nodes, 2), got {nodes.shape}")
        if cells.ndim != 2 or cells.shape[1] != 4:
            raise InputError(f"cells must have shape (n_cells, 4) (Q4), got {cells.shape}")
        if not np.all(np.isfinite(nodes)):
            bad = int(np.nonzero(~np.all(np.isfinite(nodes), axis=1))[0][0])
            raise InputError(f"node coordinates must be finite numbers: node {bad} is at "
                             f"{nodes[bad].tolist()}; fix the mesh (NaN or inf in the coordinates)")
        if len(cells) == 0:
            raise InputError("the mesh has no cells; a body needs at least one Q4 cell")
        if cells.size and (cells.min() < 0 or cells.max() >= len(nodes)):
            raise InputError("cells refer to node indices outside 0..n_nodes-1")
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "cells", cells)
        ns = {k: np.unique(np.asarray(v, dtype=np.int64)) for k, v in self.node_sets.items()}
        for k, v in ns.items():
            if v.size and (v.min() < 0 or v.max() >= len(nodes)):
                raise InputError(f"node set {k!r} refers to nodes outside 0..{len(nodes)-1}")
        object.__setattr__(self, "node_sets", ns)
        es = {}
        for k, v in self.edge_sets.items():
            a = np.asarray(v)
            if a.ndim != 2 or a.shape[1] != 2 or (a.size and not np.issubdtype(a.dtype, np.integer)):
                raise InputError(f"edge set {k!r} must be an (n_edges, 2) array of node indices "
                                 f"(one row per edge: first node, second node), got shape {a.shape} "
                                 f"of {a.dtype}")
            if a.size and (a.min() < 0 or a.max() >= len(nodes)):
                raise InputError(f"edge set {k!r} refers to nodes outside 0..{len(nodes)-1}")
            es[k] = a.astype(np.int64)
        object.__setattr__(self, "edge_sets", es)
        check_orientation(nodes, cells)
        boundary = {tuple(e) for e in self.boundary_edges()}
        for k, edges in es.items():
            for a, b in edges:
                if (a, b) not in boundary:
                    if (b, a) in boundary:
                        raise InputError(
                            f"edge set {k!r}: edge ({a}, {b}) is reversed; order boundary "
                            "edges so that the body lies on the left (counter-clockwise)"
                        )
                    raise InputError(
                        f"edge set {k!r}: edge ({a}, {b}) is not on the boundary of the "
                        "mesh; loads and contact need boundary edges"
                    )

    def boundary_edges(self) -> np.ndarray:
        """(n, 2) edges that belong to exactly one cell, in that cell's orientation."""
        e = np.stack([self.cells, np.roll(self.cells, -1, axis=1)], axis=-1).reshape(-1, 2)
        # one integer per undirected edge: a 1-D unique, 8x faster than rows of two
        key = np.minimum(e[:, 0], e[:, 1]) * len(self.nodes) + np.maximum(e[:, 0], e[:, 1])
        _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
        return e[counts[inv] == 1]

    def edge_set(self, name: str) -> np.ndarray:
        return named(self.edge_sets, "edge", name)

    def min_edge_length(self, name: str) -> float:
        e = self.edge_set(name)
        return float(np.linalg.norm(self.nodes[e[:, 1]] - self.nodes[e[:, 0]], axis=1).min())


def named(sets: Mapping, kind: str, name: str) -> np.ndarray:
    """``sets[name]``, or an InputError listing the mesh's sets of that kind."""
    try:
        return sets[name]
    except KeyError:
        raise InputError(f"unknown {kind} set {name!r}; mesh has {sorted(sets)}") from None


def signed_jacobians(nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """det(dX/dxi) at the 4 corners of every cell, (n_cells, 4).

    For a bilinear quad the Jacobian is positive everywhere inside iff it is
    positive at the four corners.
    """
    x = nodes[cells]  # (n_cells, 4, 2)
    nxt = np.roll(x, -1, axis=1) - x
    prv = np.roll(x, 1, axis=1) - x
    return nxt[..., 0] * prv[..., 1] - nxt[..., 1] * prv[..., 0]


def check_orientation(nodes: np.ndarray, cells: np.ndarray, what: str = "mesh") -> None:
    """Raise :class:`InvertedElementError` for cells with non-positive Jacobian."""
    if not len(cells):
        return
    det = signed_jacobians(nodes, cells)
    bad = np.nonzero(det.min(axis=1) <= 0.0)[0]
    if bad.size:
        c = int(bad[0])
        raise InvertedElementError(
            f"{what}: {bad.size} inverted or degenerate element(s), first is cell {c} with "
            f"nodes {cells[c].tolist()} at {nodes[cells[c]].round(6).tolist()} "
            f"(corner Jacobians {det[c].round(8).tolist()}). Cells must be convex and "
            "numbered counter-clockwise; check the node order or the shape parameters."
        )


def graded_coordinates(length: float, fine_length: float, n_fine: int, growth: float) -> np.ndarray:
    """1-D grid on [0, length]: n_fine uniform cells on [0, fine_length], then
    cells growing geometrically by ``growth`` up to ``length``.

    The graded part is scaled so it ends exactly at ``length``.
    """
    if not (0 < fine_length <= length) or n_fine < 1 or growth < 1.0:
        raise InputError(
            f"grading needs 0 < fine_length <= length, n_fine >= 1, growth >= 1 "
            f"(got length={length}, fine_length={fine_length}, n_fine={n_fine}, growth={growth})"
        )
    fine = np.linspace(0.0, fine_length, n_fine + 1)
    rest = length - fine_length
    if rest <= 1e-14 * length:
        return fine
    h = fine_length / n_fine
    sizes, total = [], 0.0
    while total < rest:
        h = h * growth
        sizes.append(h)
        total += h
    if len(sizes) > 1 and sum(sizes) - rest > 0.5 * sizes[-1]:
        sizes.pop()
    sizes = np.asarray(sizes) * rest / sum(sizes)
    return np.concatenate([fine, fine_length + np.cumsum(sizes)])


def rectangle(xs, ys) -> Mesh:
    """Structured Q4 mesh on the tensor grid ``xs`` x ``ys`` (both increasing).

    Node sets: ``left``, ``right``, ``bottom``, ``top`` and ``all``; edge sets with
    the same side names (counter-clockwise).
    """
    xs = np.asarray(xs, dtype=float)
    ys = np.asarray(ys, dtype=float)
    if xs.ndim != 1 or ys.ndim != 1 or len(xs) < 2 or len(ys) < 2:
        raise InputError("rectangle needs at least two x and two y coordinates")
    if np.any(np.diff(xs) <= 0) or np.any(np.diff(ys) <= 0):
        raise InputError("rectangle coordinates must be strictly increasing")
    nx, ny = len(xs), len(ys)
    X, Y = np.meshgrid(xs, ys, indexing="xy")  # (ny, nx)
    nodes = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange(nx * ny).reshape(ny, nx)
    cells = np.column_stack(
        [idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()]
    )
    bottom, top, left, right = idx[0, :], idx[-1, :], idx[:, 0], idx[:, -1]
    edge_sets = {
        "bottom": np.column_stack([bottom[:-1], bottom[1:]]),
        "right": np.column_stack([right[:-1], right[1:]]),
        "top": np.column_stack([top[1:], top[:-1]])[::-1],
        "left": np.column_stack([left[1:], left[:-1]])[::-1],
    }
    node_sets = {"bottom": bottom, "top": top, "left": left, "right": right,
                 "all": np.arange(nx * ny)}
    return Mesh(nodes, cells, node_sets, edge_sets)


def merge(bodies: Mapping[str, Mesh]) -> Mesh:
    """One mesh of several bodies (disconnected: no node is shared).

    ``bodies``: name -> mesh, all 2-D (:class:`Mesh`) or all 3-D
    (:class:`~signorini.fem.mesh3d.Mesh3D`; hexahedral and tetrahedral bodies
    together make a mixed mesh, see :mod:`signorini.fem.mesh3d`). Each body's node
    and edge (2-D) or face (3-D) sets keep their names prefixed by the body's,
    ``"<body>.<set>"``; the node set ``"<body>"`` holds all its nodes. Node and
    cell numbers follow the order of ``bodies``.
    """
    if not bodies:
        raise InputError("merge needs at least one body")
    dims = {int(m.nodes.shape[1]) for m in bodies.values()}
    if len(dims) > 1:
        raise InputError("merge takes meshes of one dimension: all 2-D or all 3-D; got "
                         + ", ".join(f"{k!r} {m.nodes.shape[1]}-D" for k, m in bodies.items()))
    dim = dims.pop()
    # 3-D bodies of both kinds: a mixed mesh, each tetrahedron padded to 8 columns
    width = max(m.cells.shape[1] for m in bodies.values())
    nodes, cells, node_sets, boundary_sets = [], [], {}, {}
    off = 0
    for name, m in bodies.items():
        if "." in name:
            raise InputError(f"body name {name!r}: a body name may not contain '.'")
        nodes.append(m.nodes)
        c = m.cells + off
        if c.shape[1] < width:  # tetrahedra among hexahedra: (Mesh3D's padding)
            c = np.concatenate([c, np.repeat(c[:, :1], width - c.shape[1], axis=1)], axis=1)
        cells.append(c)
        node_sets[name] = off + np.arange(m.n_nodes)
        for k, v in m.node_sets.items():
            node_sets[f"{name}.{k}"] = v + off
        for k, v in (m.face_sets if dim == 3 else m.edge_sets).items():
            boundary_sets[f"{name}.{k}"] = v + off
        off += m.n_nodes
    kind = type(next(iter(bodies.values())))  # Mesh, or Mesh3D (its boundary sets: faces)
    return kind(np.concatenate(nodes), np.concatenate(cells), node_sets, boundary_sets)


def _components(cells: np.ndarray, n: int) -> np.ndarray:
    """(n,) the connected part of every node, labelled by its smallest node (a node
    in no cell is a part of its own). Each round links the parts of the two ends
    of every edge (the first node of a cell to its others) and follows the links
    to their ends; a mesh needs two or three rounds (3 ms at 28k nodes, where
    scipy.sparse.csgraph's import alone takes 50-100 ms)."""
    k = cells.shape[1]
    a = np.repeat(cells[:, :1], k - 1, axis=1).ravel()
    b = cells[:, 1:].ravel()
    label = np.arange(n)
    while True:
        la, lb = label[a], label[b]
        low = np.minimum(la, lb)
        new = label.copy()
        np.minimum.at(new, la, low)
        np.minimum.at(new, lb, low)
        while True:  # every node to the end of its chain of links
            further = new[new]
            if np.array_equal(further, new):
                break
            new = further
        if np.array_equal(new, label):
            return label
        label = new


def parts(mesh) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The bodies of a mesh: its connected parts as (name, nodes, cells), in the
    order of their first node. A part is named by a node set holding exactly its
    nodes (the body sets of :func:`merge`, a gmsh physical surface), else
    ``"body<k>"``; nodes in no cell are left out."""
    c = np.asarray(mesh.cells)
    n = len(mesh.nodes)
    label = _components(c, n)
    used = np.zeros(n, bool)
    used[c.ravel()] = True
    out = []
    for part in dict.fromkeys(label[np.nonzero(used)[0]]):  # first appearance order
        nodes = np.nonzero((label == part) & used)[0]
        names = [name for name, v in mesh.node_sets.items()
                 if v.size == nodes.size and np.array_equal(np.sort(v), nodes)]
        cells = np.nonzero(label[c[:, 0]] == part)[0]
        out.append((names[0] if names else f"body{len(out) + 1}", nodes, cells))
    return out
