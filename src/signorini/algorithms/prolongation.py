"""Interpolation of a solution from a coarser mesh of the same body to a finer
one (:class:`Prolongation`): bilinear inside the coarse cells, along the
surface for the contact multipliers. Used by the coarse-to-fine start."""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..fem.mesh import parts

#: the thread that builds prolongations ahead of their use (Prolongation.prepare)
_BUILDER: list = []


def _grid_of(Xc: np.ndarray):
    """(axes, node) if the points Xc are exactly the tensor product of their
    coordinate values (a structured box mesh): axes[k] the sorted values along
    axis k, node the point at each grid position (C order); else None."""
    axes = [np.unique(Xc[:, k]) for k in range(Xc.shape[1])]
    shape = tuple(a.size for a in axes)
    if int(np.prod(shape)) != len(Xc) or min(shape) < 2:
        return None
    flat = np.ravel_multi_index([np.searchsorted(a, Xc[:, k]) for k, a in enumerate(axes)], shape)
    node = np.full(len(Xc), -1)
    node[flat] = np.arange(len(Xc))
    return (axes, node) if np.all(node >= 0) else None


def _grid_weights(axes, node, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) trilinear (bilinear) interpolation on a tensor grid: in the grid
    cell of each point (by a binary search per axis), extrapolated linearly from
    the nearest cell for a point outside the grid."""
    nf, d = Xf.shape
    shape = tuple(a.size for a in axes)
    lo, t = [], []
    for k, a in enumerate(axes):
        i = np.clip(np.searchsorted(a, Xf[:, k], side="right") - 1, 0, a.size - 2)
        lo.append(i)
        t.append((Xf[:, k] - a[i]) / (a[i + 1] - a[i]))
    rows, cols, vals = [], [], []
    for corner in range(2**d):
        bits = [(corner >> k) & 1 for k in range(d)]
        w = np.ones(nf)
        for k in range(d):
            w *= t[k] if bits[k] else 1.0 - t[k]
        rows.append(np.arange(nf))
        cols.append(node[np.ravel_multi_index([lo[k] + bits[k] for k in range(d)], shape)])
        vals.append(w)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(nf, len(node)))


def _linear_weights(Xc: np.ndarray, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) interpolation matrix: piecewise linear on the Delaunay triangulation
    (tetrahedralisation in 3-D) of the coarse points Xc; a point outside it is
    extrapolated linearly from a simplex at its nearest coarse point. In 3-D, coarse
    points that form a tensor grid (a structured box of hexahedra) are interpolated
    trilinearly in their cells instead (:func:`_grid_weights`): the coarse solution
    itself, where a tetrahedralisation of a grid's cospherical points is slow and
    degenerate (measured: 3.6 s for 47,652 fine nodes in 5,776 coarse ones, against
    0.02 s)."""
    nf, nc = len(Xf), len(Xc)
    if Xc.shape[1] == 3:
        grid = _grid_of(Xc)
        if grid is not None:
            return _grid_weights(*grid, Xf)
    from scipy.spatial import Delaunay, cKDTree  # lazy: heavy (scipy.special), coarse starts only

    d = Xc.shape[1]
    tri = Delaunay(Xc)
    simplex = tri.find_simplex(Xf)
    inside = simplex >= 0
    rows, cols, vals = [], [], []
    if inside.any():
        s = simplex[inside]
        T = tri.transform[s]  # (m, d + 1, d): inverse affine map and the offset
        b = np.einsum("mij,mj->mi", T[:, :d], Xf[inside] - T[:, d])
        bary = np.column_stack([b, 1.0 - b.sum(axis=1)])
        rows.append(np.repeat(np.nonzero(inside)[0], d + 1))
        cols.append(tri.simplices[s].ravel())
        vals.append(bary.ravel())
    if (~inside).any():
        # outside the triangulation (a curved boundary: the coarse chords cut inside
        # the fine nodes): extrapolated linearly from the simplex, among those of the
        # nearest coarse point, whose barycentric coordinates there are least negative
        # (a nearest-point value instead made the surface's gaps wrong by a cell's
        # slope: a guided two-body start then needed more iterations than one from rest)
        out = np.nonzero(~inside)[0]
        _, near = cKDTree(Xc).query(Xf[out])
        flat = tri.simplices.ravel()
        order = np.argsort(flat, kind="stable")
        first = np.searchsorted(flat[order], np.arange(nc + 1))
        for i, k in zip(out, near):
            cand = order[first[k]:first[k + 1]] // (d + 1)  # the simplices of point k
            if not cand.size:  # a point the triangulation left out: its value
                rows.append([i])
                cols.append([k])
                vals.append([1.0])
                continue
            T = tri.transform[cand]
            b = np.einsum("mij,mj->mi", T[:, :d], Xf[i] - T[:, d])
            bary = np.column_stack([b, 1.0 - b.sum(axis=1)])
            best = int(np.argmax(bary.min(axis=1)))
            rows.append(np.full(d + 1, i))
            cols.append(tri.simplices[cand[best]])
            vals.append(bary[best])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(nf, nc))


def _along_surface(Xc: np.ndarray, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) matrix taking values at coarse surface nodes Xc to points Xf on the
    same curve: linear between the two nearest coarse nodes (clamped to the segment);
    on a 3-D surface the inverse-distance mean of the four nearest (a start only)."""
    nf, nc = len(Xf), len(Xc)
    if nc == 1:
        return sp.csr_matrix((np.ones(nf), (np.arange(nf), np.zeros(nf, dtype=int))), shape=(nf, 1))
    from scipy.spatial import cKDTree  # lazy: heavy (scipy.special), coarse starts only

    if Xc.shape[1] == 3:  # a surface: the inverse-distance mean of the 4 nearest coarse nodes
        k = min(4, nc)
        dist, idx = cKDTree(Xc).query(Xf, k=k)
        w = 1.0 / np.maximum(dist, 1e-12 * max(float(np.ptp(Xc)), 1e-300))
        w /= w.sum(axis=1, keepdims=True)
        return sp.csr_matrix((w.ravel(), (np.repeat(np.arange(nf), k), idx.ravel())), shape=(nf, nc))
    _, idx = cKDTree(Xc).query(Xf, k=2)
    a, b = Xc[idx[:, 0]], Xc[idx[:, 1]]
    d = b - a
    s = np.clip(np.einsum("ij,ij->i", Xf - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    rows = np.repeat(np.arange(nf), 2)
    return sp.csr_matrix((np.column_stack([1.0 - s, s]).ravel(), (rows, idx.ravel())), shape=(nf, nc))


def _bodywise_weights(mc, mf, Xc: np.ndarray, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) node interpolation body by body (:func:`signorini.fem.mesh.parts`,
    matched by name): a node of one body near another (two bodies in contact)
    takes values of its own body only. One body: :func:`_linear_weights`."""
    pc, pf = parts(mc), parts(mf)
    if len(pc) == 1 and len(pf) == 1:
        return _linear_weights(Xc, Xf)
    coarse = {name: nodes for name, nodes, _ in pc}
    if sorted(coarse) != sorted(name for name, _, _ in pf):
        raise InputError(f"prolong: the coarse and fine meshes have other bodies "
                         f"({sorted(coarse)} and {sorted(n for n, _, _ in pf)})")
    rows, cols, vals = [], [], []
    for name, nf, _ in pf:
        nc = coarse[name]
        B = _linear_weights(Xc[nc], Xf[nf]).tocoo()
        rows.append(nf[B.row])
        cols.append(nc[B.col])
        vals.append(B.data)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(len(Xf), len(Xc)))


class Prolongation:
    """The interpolation of unknowns from a coarse model to a fine one, built once
    as a sparse matrix (it is linear in the coarse unknowns).

    Displacements: piecewise linear on a triangulation of the coarse nodes
    (nearest node outside it); contact multipliers (nominal tractions): linear
    along each contact surface, surface k of the coarse model to surface k of
    the fine one.
    """

    def __init__(self, coarse_model, fine_model):
        cm, fm = coarse_model, fine_model
        if len(cm.surfaces) != len(fm.surfaces) or any(
                a.n_mult != b.n_mult for a, b in zip(cm.surfaces, fm.surfaces)):
            raise InputError("prolong: the coarse and fine problems must have the same contact "
                             "surfaces (in the same order, with the same multipliers per node)")
        Xc, Xf = np.asarray(cm.reference_nodes), np.asarray(fm.reference_nodes)
        self.coarse_model, self.fine_model = cm, fm
        if cm.n_dof == fm.n_dof and Xc.shape == Xf.shape and np.array_equal(Xc, Xf) and all(
                np.array_equal(a.nodes, b.nodes) and a.lam_offset == b.lam_offset
                for a, b in zip(cm.surfaces, fm.surfaces)):
            self.matrix = sp.identity(fm.n_dof, format="csr")  # the same mesh (other parameters)
            return
        blocks = []
        Pu = _bodywise_weights(cm.problem.mesh, fm.problem.mesh, Xc, Xf)  # nodes -> nodes;
        # DOFs interleave (x, y[, z]) per node
        blocks.append((sp.kron(Pu, sp.identity(Xf.shape[1])), 0, 0))
        for sc, sf in zip(cm.surfaces, fm.surfaces):
            Ps = _along_surface(Xc[sc.nodes], Xf[sf.nodes])
            blocks.append((sp.kron(Ps, sp.identity(sf.n_mult)), sf.lam_offset, sc.lam_offset))
        rows, cols, vals = [], [], []
        for B, r0, c0 in blocks:
            B = B.tocoo()
            rows.append(B.row + r0)
            cols.append(B.col + c0)
            vals.append(B.data)
        self.matrix = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                    shape=(fm.n_dof, cm.n_dof))

    @classmethod
    def between(cls, coarse_model, fine_model) -> "Prolongation":
        """The prolongation of these two models, built once and kept by the fine
        model: it depends only on their meshes, not on parameter values, and
        rebuilt in every solve it would be a large share of a coarse-to-fine solve
        (docs/theory.md §10.3). One being built (:meth:`prepare`) is waited for."""
        key = ("prolongation", id(coarse_model))
        kept = fine_model.cache.get(key)
        if isinstance(kept, Future):
            kept = fine_model.cache[key] = kept.result()
        if kept is None or kept.coarse_model is not coarse_model:
            kept = fine_model.cache[key] = cls(coarse_model, fine_model)
        return kept

    @classmethod
    def prepare(cls, coarse_model, fine_model) -> None:
        """Start building :meth:`between` on a thread of its own, while the coarse
        model is solved: its triangulation and point location run outside Python's
        lock (and the first one imports scipy.spatial meanwhile)."""
        key = ("prolongation", id(coarse_model))
        kept = fine_model.cache.get(key)
        if kept is None or (not isinstance(kept, Future) and kept.coarse_model is not coarse_model):
            if not _BUILDER:
                _BUILDER.append(ThreadPoolExecutor(1, thread_name_prefix="signorini-prolongation"))
            fine_model.cache[key] = _BUILDER[0].submit(cls, coarse_model, fine_model)

    def __call__(self, w_coarse) -> np.ndarray:
        """(fine n_dof,) interpolation of coarse unknowns (coarse n_dof,)."""
        return self.matrix @ np.asarray(w_coarse, dtype=float)


