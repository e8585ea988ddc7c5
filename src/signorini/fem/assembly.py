"""Sparse assembly: the one place where JAX block arrays become SciPy matrices.

The sparsity pattern is computed once per model from the DOF maps of all
blocks (elements and contact nodes); every Newton iteration only scatters the
block values into the fixed CSR data array (``np.bincount`` with a precomputed
map) and picks the free-free part by a precomputed index; a read-only element
block array passed again is not scattered again.
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.sparse as sp


class SparsityPattern:
    """Fixed CSR pattern of the free-free tangent.

    Args:
        block_dofs: list of (n_blocks, k) DOF maps (row/column DOFs of each block).
        n_dof: total number of DOFs.
        free: (n_free,) sorted free DOFs (the rows/columns kept).
    """

    def __init__(self, block_dofs: list[np.ndarray], n_dof: int, free: np.ndarray):
        free = np.asarray(free)
        if np.any(np.diff(free) <= 0):
            raise ValueError("the free DOFs must be sorted and distinct")
        self.n = n = int(free.size)
        # The pattern is the sorted set of (row, column) pairs of free DOFs over all block
        # entries, and _map says which pair each kept entry adds to. Sorting the keys of
        # all entries (np.unique: 15 million for 27k Q1 hexahedra) takes most of a second;
        # instead each group of blocks gives its own pattern as a canonical CSR matrix
        # whose data are ids of the group's pairs (``_group_pattern``: sorting node pairs
        # where the DOFs come in nodes, b*b times fewer), and SciPy's C++ merge of sorted
        # rows takes their union, keeping every group's pairs in order.
        groups = [_group_pattern(np.asarray(d), n_dof, free) for d in block_dofs]
        union, positions = _union([g for g, _ in groups], n)
        self.nnz = int(union.nnz)
        # the pattern position of every block entry (-1: not kept), written group by
        # group into one array so that the groups' masks and positions are views of
        # _keep and _map
        ends = np.cumsum([0] + [np.asarray(d).size * np.asarray(d).shape[1] for d in block_dofs])
        at = np.empty(ends[-1], dtype=np.int64)
        for (g, spread), pos, (a, b) in zip(groups, positions, itertools.pairwise(ends)):
            spread(g.data, pos, at[a:b])
        self._keep = at >= 0
        self._map = at[self._keep]
        # per block group: (mask of its kept entries, their CSR positions)
        spans = list(itertools.pairwise(ends))
        kept = np.cumsum([0] + [np.count_nonzero(self._keep[a:b]) for a, b in spans])
        self._groups = [(self._keep[a:b], self._map[ka:kb])
                        for (a, b), (ka, kb) in zip(spans, itertools.pairwise(kept))]
        self._first = (None, None)  # (block array, its CSR contribution): reused while unchanged
        self.indices = union.indices.astype(np.int32, copy=False)
        self.indptr = union.indptr.astype(np.int32 if self.nnz < 2**31 else np.int64, copy=False)
        self.diagonal_positions = _diagonal_positions(self.indices, self.indptr)

    def assemble(self, blocks: list[np.ndarray]) -> sp.csr_matrix:
        """CSR matrix (n_free, n_free) from block values in the order of ``block_dofs``.

        A read-only first group (the elements) is scattered once and its
        contribution kept while the same array is passed again: a linear body's
        element stiffness is one read-only array per parameter values
        (``Model.element_stiffness``), so an iteration then scatters only the
        contact blocks, not the far more numerous element entries. Writable arrays are
        scattered every time (they could change in place)."""
        first, kept = blocks[0], self._first
        if isinstance(first, np.ndarray) and not first.flags.writeable:
            if kept[0] is not first:  # a read-only array cannot change under the cache
                m, pos = self._groups[0]
                kept = self._first = (first, np.bincount(pos, weights=first.reshape(-1)[m],
                                                         minlength=self.nnz))
            data = kept[1].copy()
            for b, (m, pos) in zip(blocks[1:], self._groups[1:]):
                np.add.at(data, pos, np.asarray(b).reshape(-1)[m])
        else:
            vals = np.concatenate([np.asarray(b).reshape(-1) for b in blocks])[self._keep]
            data = np.bincount(self._map, weights=vals, minlength=self.nnz)
        K = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
        # the pattern's own index arrays (SciPy keeps a view of the indices), so that a
        # solver recognises the pattern by identity instead of comparing every index
        K.indices, K.indptr = self.indices, self.indptr
        # the pattern is the sorted distinct (row, column) pairs: rows ascending, columns
        # sorted and unique in each row. Saying so spares a solver SciPy's test, a pass over the
        # indices on every factorisation
        K.has_sorted_indices = True
        K.has_canonical_format = True
        # read by linsolve.diagonal: the diagonal as a take of known positions, where
        # K.diagonal() searches every row for its diagonal entry
        K.diagonal_positions = self.diagonal_positions
        return K


def _group_pattern(d: np.ndarray, n_dof: int, free: np.ndarray):
    """Pattern of the (n_blocks, k) blocks of DOF map ``d`` on the free DOFs.

    Returns a canonical CSR matrix (n_free, n_free) whose data are distinct ids of
    its pairs, and ``spread(ids, positions, out)`` writing, for each block entry
    (n_blocks * k * k, row-major blocks), the position of its pair (the pair of id
    ``ids[i]`` is at ``positions[i]``) or -1 if a DOF of the entry is not free.
    If the map comes in nodes (runs of b consecutive DOFs from a multiple of b),
    the node pairs are sorted instead of the DOF pairs: see ``_node_pattern``.
    """
    nb, k = d.shape
    for b in range(min(k, 8), 1, -1):  # the largest node size, fewest node pairs
        if k % b == 0 and nb:
            q = d.reshape(nb, k // b, b)
            first = q[:, :, :1]
            if np.all(first % b == 0) and np.all(q == first + np.arange(b)):
                return _node_pattern(first[:, :, 0] // b, b, n_dof, free)
    n = free.size
    loc = -np.ones(n_dof, dtype=np.int64)
    loc[free] = np.arange(n)
    r = np.repeat(loc[d], k, axis=1).ravel()  # (n_blocks*k*k,) row-major block entries
    c = np.tile(loc[d], (1, k)).ravel()
    kept = (r >= 0) & (c >= 0)
    keys, inverse = np.unique(r[kept] * n + c[kept], return_inverse=True)
    rows, cols = np.divmod(keys, n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    indptr[1:] = np.cumsum(np.bincount(rows, minlength=n))
    pattern = sp.csr_matrix((np.arange(keys.size), cols, indptr), shape=(n, n))

    def spread(ids, positions, out):
        # ids are the pairs' ranks here: the data were given in order
        out[:] = -1
        out[kept] = positions[inverse]

    return pattern, spread


def _node_pattern(nodes: np.ndarray, b: int, n_dof: int, free: np.ndarray):
    """``_group_pattern`` of blocks of whole nodes: (n_blocks, q) node numbers, DOFs
    ``b * node + i`` (i < b).

    The distinct node pairs are sorted (np.unique, b*b times fewer than the DOF
    pairs) into a node-level CSR pattern; SciPy makes the DOF-level one, each node
    pair a dense b x b block (BSR to CSR), and keeps the free rows and columns, in C++
    and in order. The data carry the id p*b*b + i*b + j of DOF pair (i, j) of node pair p.
    """
    nb, q = nodes.shape
    n_nodes = n_dof // b + 1
    nodes = nodes.astype(np.int64)
    keys = (nodes[:, :, None] * n_nodes + nodes[:, None, :]).ravel()
    # (int32 keys when they fit sort faster)
    pair_keys, inverse = np.unique(keys.astype(np.int32) if n_nodes**2 < 2**31 else keys,
                                   return_inverse=True)
    pair_keys = pair_keys.astype(np.int64)
    A, B = np.divmod(pair_keys, n_nodes)
    indptr = np.zeros(n_nodes + 1, dtype=np.int64)
    indptr[1:] = np.cumsum(np.bincount(A, minlength=n_nodes))
    # (int32 ids when they fit: less memory to fill in each copy SciPy makes)
    ids = np.arange(A.size * b * b, dtype=np.int32 if A.size * b * b < 2**31 else np.int64)
    full = sp.bsr_matrix((ids.reshape(-1, b, b), B, indptr), shape=(n_nodes * b,) * 2).tocsr()
    pattern = full[free][:, free]
    # row i of the node pair of entry (e, a1, a2) for every (e, a1, i, a2): the entry
    # rows, each the b DOFs j of node a2, in row-major block order (one gather of
    # b-long rows, no reordering of the entries)
    i = np.arange(b)
    rows = (inverse.reshape(nb, q, 1, q) * b + i[:, None]).ravel()

    def spread(ids, positions, out):
        at = np.full(A.size * b * b, -1, dtype=np.int64)
        at[ids] = positions
        # indices valid by construction: 'clip' spares take its buffered output
        np.take(at.reshape(-1, b), rows, axis=0, out=out.reshape(-1, b), mode="clip")

    return pattern, spread


def _union(patterns: list[sp.csr_matrix], n: int):
    """Union of canonical CSR patterns (n, n) and the positions of each one's pairs in
    it (in the order of its data).

    Two patterns at a time, the union so far tagged 1 and the next one 2: their sum
    (SciPy's merge of sorted rows, canonical) is 1, 2 or 3 where a pair is in the
    first only, the second only or both, so the pairs of each are where the sum is not
    2, not 1, in order. The largest pattern is merged last, its positions found once."""
    if not patterns:
        return sp.csr_matrix((n, n)), []
    def tag(m, t):
        return sp.csr_matrix((np.full(m.nnz, t, dtype=np.int8), m.indices, m.indptr),
                             shape=(n, n))

    order = sorted(range(len(patterns)), key=lambda g: patterns[g].nnz)
    union, positions = patterns[order[0]], {order[0]: np.arange(patterns[order[0]].nnz)}
    for g in order[1:]:
        union = tag(union, 1) + tag(patterns[g], 2)
        was = np.flatnonzero(union.data != 2)
        positions = {h: was[pos] for h, pos in positions.items()}
        positions[g] = np.flatnonzero(union.data >= 2)
    return union, [positions[g] for g in range(len(patterns))]


def _diagonal_positions(indices: np.ndarray, indptr: np.ndarray):
    """Position of each row's diagonal entry in sorted CSR indices, or None if a row
    has none: a binary search in every row at once (log2 of the longest row steps over
    the rows, no array of the size of the pattern)."""
    n = indptr.size - 1
    if not indices.size:
        return None
    row = np.arange(n)
    lo, hi = indptr[:-1].astype(np.int64), indptr[1:].astype(np.int64)
    while True:  # lo: first entry of the row with column >= row
        active = lo < hi
        if not active.any():
            break
        mid = (lo + hi) // 2
        less = indices[np.minimum(mid, indices.size - 1)] < row
        lo = np.where(active & less, mid + 1, lo)
        hi = np.where(active & ~less, mid, hi)
    found = (lo < indptr[1:]) & (indices[np.minimum(lo, indices.size - 1)] == row)
    return lo if found.all() else None
