"""Meshes of 3-D cells (8-node hexahedra, 4-node tetrahedra, or both in bodies
of their own) with named node sets and boundary-face sets.

Conventions: ``nodes`` (n_nodes, 3) reference coordinates; ``cells`` (n_cells, 8)
or (n_cells, 4) in VTK/gmsh node order with a positive volume; a face set is
(n_faces, 4) quadrilaterals or (n_faces, 3) triangles, each numbered
counter-clockwise seen from outside the body, so that the outward normal
follows by the right hand (the orientation of the face in the cell that owns it).

A *mixed* mesh holds hexahedra and tetrahedra, each body (connected part) of one
kind (a conforming mesh of both in one body needs pyramids, which signorini
does not have): ``cells`` is (n_cells, 8), a tetrahedron's row its four nodes
followed by ``-1`` four times (given) or by its first node four times (as
stored: every row then indexes nodes, and a tetrahedron adds nothing at its
repeated node). :meth:`Mesh3D.groups` gives the cells of each kind. Such meshes
come from :func:`signorini.fem.mesh.merge` of a hexahedral and a tetrahedral
body, or from a gmsh file with both.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, InvertedElementError
from .mesh import Cells, named
from .solid import CellType, cell_type


@dataclass(frozen=True)
class Mesh3D(Cells):
    """A 3-D mesh of hexahedra, tetrahedra or both (the 2-D one, for plane
    strain and axisymmetry, is :class:`~signorini.fem.mesh.Mesh`). Made by
    :func:`box` and :func:`tetrahedra`, joined by
    :func:`~signorini.fem.mesh.merge`, or read from a file by
    :func:`signorini.read_mesh`; a :class:`~signorini.model.problem.Problem` on it
    is 3-D, without kinematics.

    Attributes:
        nodes: (n_nodes, 3) reference coordinates.
        cells: (n_cells, 8) hexahedra, (n_cells, 4) tetrahedra, or (n_cells, 8)
            both: a tetrahedron's row is its four nodes then -1 (or its first
            node) four times; each body of one kind (see the module's docstring).
        node_sets: name -> sorted node indices.
        face_sets: name -> (n_faces, 4 or 3) boundary faces, outward; each set
            all quadrilaterals or all triangles.
    """

    nodes: np.ndarray
    cells: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    face_sets: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        nodes = np.asarray(self.nodes, dtype=float)
        cells = np.asarray(self.cells)
        if nodes.ndim != 2 or nodes.shape[1] != 3:
            hint = (" (a 2-D mesh: use signorini.Mesh with PlaneStrain or Axisymmetric, or give "
                    "three coordinates per node)" if nodes.ndim == 2 and nodes.shape[1] == 2 else "")
            raise InputError(f"nodes of a 3-D mesh must have shape (n_nodes, 3), got "
                             f"{nodes.shape}{hint}")
        if cells.ndim != 2 or cells.shape[1] not in (8, 4):
            raise InputError(f"cells of a 3-D mesh must be (n_cells, 8) hexahedra or (n_cells, 4) "
                             f"tetrahedra (both: (n_cells, 8), a tetrahedron's row padded with -1); "
                             f"got shape {cells.shape}")
        if len(cells) == 0:
            raise InputError("the mesh has no cells; a body needs at least one cell")
        if not np.issubdtype(cells.dtype, np.integer):
            raise InputError(f"cells must be node indices (integers), got {cells.dtype}")
        cells = _stored(cells)
        if cells.min() < 0 or cells.max() >= len(nodes):
            raise InputError(f"cells refer to node indices outside 0..{len(nodes) - 1}")
        if not np.all(np.isfinite(nodes)):
            bad = int(np.nonzero(~np.all(np.isfinite(nodes), axis=1))[0][0])
            raise InputError(f"node coordinates must be finite numbers: node {bad} is at "
                             f"{nodes[bad].tolist()}")
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        object.__setattr__(self, "nodes", np.ascontiguousarray(nodes))
        object.__setattr__(self, "cells", cells)
        ns = {}
        for k, v in self.node_sets.items():
            v = np.unique(np.asarray(v, dtype=np.int64))
            if v.size and (v.min() < 0 or v.max() >= len(nodes)):
                raise InputError(f"node set {k!r} refers to nodes outside 0..{len(nodes) - 1}")
            ns[k] = v
        object.__setattr__(self, "node_sets", ns)
        check_cells(self.nodes, cells)
        if self.mixed:
            _check_kinds_apart(cells)
        boundary = {face_key(f): tuple(f) for f in self.boundary_faces()} if self.face_sets else {}
        fs = {}
        for k, v in self.face_sets.items():
            a = np.asarray(v)
            if a.ndim != 2 or a.shape[1] not in self._face_sizes() or (
                    a.size and not np.issubdtype(a.dtype, np.integer)):
                kinds = " or ".join(f"(n_faces, {n}) array of node indices for {c} cells"
                                    for n, c in self._face_sizes().items())
                raise InputError(f"face set {k!r} must be an {kinds}, got shape {a.shape}"
                                 + (" (a face set is all triangles or all quadrilaterals: give "
                                    "one set per kind)" if self.mixed else ""))
            for f in a:
                own = boundary.get(face_key(f))
                if own is None:
                    raise InputError(f"face set {k!r}: face {f.tolist()} is not on the boundary "
                                     "of the mesh; loads and contact need boundary faces")
                if not _same_cycle(tuple(int(i) for i in f), own):
                    raise InputError(f"face set {k!r}: face {f.tolist()} is numbered inward; "
                                     "number boundary faces counter-clockwise seen from outside "
                                     f"(e.g. {list(own)})")
            fs[k] = a.astype(np.int64)
        object.__setattr__(self, "face_sets", fs)

    @property
    def mixed(self) -> bool:
        """Whether the mesh holds hexahedra and tetrahedra."""
        return bool(self.cells.shape[1] == 8 and np.any(_tetra_rows(self.cells)))

    @property
    def cell(self) -> CellType:
        """The kind of every cell (hexahedron or tetrahedron); a mixed mesh has
        none: :meth:`groups`."""
        if self.mixed:
            raise InputError("this mesh holds hexahedra and tetrahedra: it has no one kind of "
                             "cell (Mesh3D.groups() gives the cells of each kind)")
        return cell_type(self.cells.shape[1])

    def groups(self) -> list[tuple[CellType, np.ndarray]]:
        """[(kind, indices of its cells)], hexahedra first: one entry for a mesh of
        one kind; a tetrahedron's nodes are the first four of its row."""
        return cell_groups(self.cells)

    def _face_sizes(self) -> dict:
        return {c.faces.shape[1]: c.name for c, _ in self.groups()}

    def boundary_faces(self) -> list | np.ndarray:
        """Faces that belong to exactly one cell, in that cell's (outward) numbering:
        (n, k) of the mesh's kind; for a mixed mesh a list of (n, 4) quadrilaterals
        and (n, 3) triangles."""
        out = []
        for cell, idx in self.groups():
            f = self.cells[idx][:, cell.faces].reshape(-1, cell.faces.shape[1])
            out.append(f[rows_once(np.sort(f, axis=1))])
        return out[0] if len(out) == 1 else [f for part in out for f in part]

    def face_set(self, name: str) -> np.ndarray:
        return named(self.face_sets, "face", name)


def rows_once(rows: np.ndarray) -> np.ndarray:
    """Mask of the rows of an integer array (n, k) that occur once (``np.unique`` over
    rows sorts a row view, several times slower than this lexicographic sort): with
    each face's or edge's nodes sorted, the boundary of a set of cells or faces."""
    order = np.lexsort(rows.T[::-1])
    s = rows[order]
    first = np.ones(len(s), dtype=bool)
    first[1:] = np.any(s[1:] != s[:-1], axis=1)
    group = np.cumsum(first) - 1
    once = np.empty(len(rows), dtype=bool)
    once[order] = np.bincount(group)[group] == 1
    return once


def face_key(face) -> tuple:
    """The face's nodes, sorted: the same for a face however it is numbered."""
    return tuple(sorted(int(i) for i in face))


def _same_cycle(a: tuple, b: tuple) -> bool:
    """Whether ``a`` is ``b`` up to a cyclic shift (same orientation)."""
    k = b.index(a[0]) if a[0] in b else -1
    return k >= 0 and b[k:] + b[:k] == a


def _tetra_rows(cells: np.ndarray) -> np.ndarray:
    """(n,) True for the rows of an (n, 8) array that are tetrahedra (padded)."""
    if cells.shape[1] != 8:
        return np.ones(len(cells), bool)
    return np.all(cells[:, 4:] == cells[:, :1], axis=1)


def _stored(cells: np.ndarray) -> np.ndarray:
    """The cells as stored: a tetrahedron padded with -1 gets its first node instead."""
    if cells.shape[1] != 8:
        return cells
    pad = np.all(cells[:, 4:] == -1, axis=1)
    if not pad.any():
        return cells
    if np.any(cells[pad, :4] < 0):
        raise InputError("cells: a tetrahedron padded with -1 needs four node indices first")
    cells = np.array(cells)
    cells[pad, 4:] = cells[pad, :1]
    return cells


def cell_groups(cells: np.ndarray) -> list[tuple[CellType, np.ndarray]]:
    """[(kind, indices of its cells)] of a cell array (see :meth:`Mesh3D.groups`)."""
    if cells.shape[1] == 4:
        return [(cell_type(4), np.arange(len(cells)))]
    tet = _tetra_rows(cells)
    return [(cell_type(k), np.nonzero(m)[0]) for k, m in ((8, ~tet), (4, tet)) if m.any()]


def _check_kinds_apart(cells: np.ndarray) -> None:
    """A mixed mesh: no node in cells of both kinds (a conforming hexahedron-to-
    tetrahedron interface needs pyramids)."""
    tet = _tetra_rows(cells)
    both = np.intersect1d(cells[~tet].ravel(), cells[tet, :4].ravel())
    if both.size:
        raise InputError(
            f"the mesh joins hexahedra and tetrahedra at {both.size} node(s) (first: node "
            f"{int(both[0])}); a conforming mesh of both needs pyramids, which signorini does "
            "not have: mesh each body with one kind of cell (bodies of different kinds may touch "
            "through a contact pair)")


def cell_jacobians(nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """det(dX/dxi) (n_cells, n_check) at the corners of each cell (hexahedra; the
    trilinear map is one-to-one if these are positive for a cell with planar or
    mildly warped faces) or its constant value (tetrahedra; in a mixed mesh
    repeated in the eight columns)."""
    det = np.zeros((len(cells), 8 if cells.shape[1] == 8 else 1))
    for cell, idx in cell_groups(cells):
        X = nodes[cells[idx][:, :cell.n_nodes]]  # (c, n, 3)
        dN = np.stack([cell.gradient(p) for p in cell.corners]) if cell.n_nodes == 8 else cell.dN
        J = np.tensordot(X, dN, axes=([1], [1]))  # (c, 3, g, 3): J[c, j, g, i] = dX_j/dxi_i
        d = (J[:, 0, :, 0] * (J[:, 1, :, 1] * J[:, 2, :, 2] - J[:, 1, :, 2] * J[:, 2, :, 1])
             - J[:, 0, :, 1] * (J[:, 1, :, 0] * J[:, 2, :, 2] - J[:, 1, :, 2] * J[:, 2, :, 0])
             + J[:, 0, :, 2] * (J[:, 1, :, 0] * J[:, 2, :, 1] - J[:, 1, :, 1] * J[:, 2, :, 0]))
        det[idx] = d if d.shape[1] == det.shape[1] else np.repeat(d, det.shape[1], axis=1)
    return det


def check_cells(nodes: np.ndarray, cells: np.ndarray, what: str = "mesh") -> None:
    """Raise :class:`InvertedElementError` naming the first cell with a
    non-positive Jacobian (inverted, degenerate or numbered the wrong way)."""
    det = cell_jacobians(nodes, cells)
    scale = np.ptp(nodes, axis=0).max() ** 3 or 1.0
    bad = np.nonzero(det.min(axis=1) <= 1e-14 * scale)[0]
    if bad.size:
        c = int(bad[0])
        kind = cell_type(8 if cells.shape[1] == 8 and not _tetra_rows(cells[c:c + 1])[0] else 4)
        nodes_c = cells[c, :kind.n_nodes]
        raise InvertedElementError(
            f"{what}: {bad.size} inverted or degenerate cell(s), first is cell {c} with nodes "
            f"{nodes_c.tolist()} at {nodes[nodes_c].round(6).tolist()} (Jacobians "
            f"{np.unique(det[c]).round(8).tolist() if kind.n_nodes == 4 else det[c].round(8).tolist()}). "
            f"Number the nodes of each {kind.name} in VTK/gmsh order with a positive volume.")


def box(xs, ys, zs) -> Mesh3D:
    """Structured hexahedral mesh on the tensor grid ``xs`` x ``ys`` x ``zs``
    (each increasing; graded grids from :func:`signorini.fem.mesh.graded_coordinates`;
    the 2-D counterpart is :func:`signorini.fem.mesh.rectangle`).

    Node and face sets: ``x0``, ``x1``, ``y0``, ``y1``, ``z0``, ``z1`` (the
    faces at the smallest and largest x, y, z) and the node set ``all``.
    """
    grids = [np.asarray(g, dtype=float) for g in (xs, ys, zs)]
    for name, g in zip("xyz", grids):
        if g.ndim != 1 or len(g) < 2:
            raise InputError(f"box needs at least two {name} coordinates")
        if np.any(np.diff(g) <= 0):
            raise InputError(f"box {name} coordinates must be strictly increasing")
    nx, ny, nz = (len(g) for g in grids)
    Z, Y, X = np.meshgrid(grids[2], grids[1], grids[0], indexing="ij")  # (nz, ny, nx)
    nodes = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    idx = np.arange(nx * ny * nz).reshape(nz, ny, nx)
    c = idx[:-1, :-1, :-1]
    corners = [c, c + 1, c + 1 + nx, c + nx]
    cells = np.stack(corners + [k + nx * ny for k in corners], axis=-1).reshape(-1, 8)
    return with_box_sets(Mesh3D(nodes, cells))


def with_box_sets(mesh: Mesh3D) -> Mesh3D:
    """``mesh`` (of a box-shaped body) with the node and face sets ``x0``, ``x1``,
    ``y0``, ``y1``, ``z0``, ``z1`` (its boundary faces and nodes on the planes of the
    smallest and largest x, y, z) and the node set ``all``."""
    nodes = mesh.nodes
    faces = mesh.boundary_faces()
    centre = nodes[faces].mean(axis=1)
    lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    tol = 1e-9 * (hi - lo).max()
    node_sets, face_sets = {"all": np.arange(len(nodes))}, {}
    for d, name in enumerate("xyz"):
        for side, value in (("0", lo[d]), ("1", hi[d])):
            face_sets[name + side] = faces[np.abs(centre[:, d] - value) <= tol]
            node_sets[name + side] = np.nonzero(np.abs(nodes[:, d] - value) <= tol)[0]
    return Mesh3D(nodes, mesh.cells, node_sets, face_sets)


#: each hexahedron as six tetrahedra around its diagonal 0-6 (VTK order): conforming
#: between neighbours of a structured mesh, every tetrahedron of positive volume
_HEX_TO_TETS = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6],
                         [0, 5, 1, 6]])


def tetrahedra(mesh: Mesh3D) -> Mesh3D:
    """The hexahedral ``mesh`` with every cell split into six tetrahedra (same
    nodes and node sets; each quadrilateral face set split into triangles)."""
    if mesh.cells.shape[1] != 8 or mesh.mixed:
        raise InputError("tetrahedra() splits hexahedra; this mesh has tetrahedra already")
    cells = mesh.cells[:, _HEX_TO_TETS].reshape(-1, 4)
    tets = Mesh3D(mesh.nodes, cells)
    tri = tets.boundary_faces()
    by_key = {face_key(f): f for f in tri}
    face_sets = {}
    for name, quads in mesh.face_sets.items():
        out = []
        for q in quads:
            for f in ((q[0], q[1], q[2]), (q[0], q[2], q[3]), (q[1], q[2], q[3]), (q[0], q[1], q[3])):
                t = by_key.get(face_key(f))
                if t is not None and set(int(i) for i in t) <= set(int(i) for i in q):
                    out.append(t)
        face_sets[name] = np.unique(np.array(out), axis=0)
    return Mesh3D(mesh.nodes, cells, mesh.node_sets, face_sets)
