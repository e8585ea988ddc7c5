"""Sparse assembly: the one place where JAX block arrays become SciPy matrices.

The sparsity pattern is computed once per model from the DOF maps of all
blocks (elements and contact nodes); every Newton iteration only scatters the
block values into the fixed CSR data array (``np.bincount`` with a precomputed
map) and picks the free-free part by a precomputed index; a read-only element
block array passed again is not scattered again.
"""

from __future__ import annotations

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
        loc = -np.ones(n_dof, dtype=np.int64)
        loc[free] = np.arange(free.size)
        self.n = int(free.size)
        rows, cols, keep = [], [], []
        for d in block_dofs:
            k = d.shape[1]
            r = np.repeat(loc[d], k, axis=1).ravel()  # (n_blocks*k*k,) row-major block entries
            c = np.tile(loc[d], (1, k)).ravel()
            m = (r >= 0) & (c >= 0)
            rows.append(r[m])
            cols.append(c[m])
            keep.append(m)
        sizes = [int(m.sum()) for m in keep]
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        self._keep = np.concatenate(keep)
        key = rows * self.n + cols
        uniq, self._map = np.unique(key, return_inverse=True)
        # per block group: (mask of its kept entries, their CSR positions)
        ends = np.cumsum(sizes)
        self._groups = [(m, self._map[e - k: e]) for m, k, e in zip(keep, sizes, ends)]
        self._first = (None, None)  # (block array, its CSR contribution): reused while unchanged
        self.nnz = int(uniq.size)
        r, c = np.divmod(uniq, self.n)
        self.indices = c.astype(np.int32)
        self.indptr = np.zeros(self.n + 1, dtype=np.int64)
        np.add.at(self.indptr, r + 1, 1)
        self.indptr = np.cumsum(self.indptr).astype(np.int32 if self.nnz < 2**31 else np.int64)
        # where each row's diagonal entry is in the data (None if one is not in the pattern)
        diag = np.arange(self.n, dtype=np.int64) * (self.n + 1)
        pos = np.minimum(np.searchsorted(uniq, diag), max(uniq.size - 1, 0))
        self.diagonal_positions = pos if uniq.size and np.all(uniq[pos] == diag) else None

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
        # the pattern is np.unique's sorted keys: rows ascending, columns sorted and
        # unique in each row. Saying so spares a solver SciPy's test, a pass over the
        # indices on every factorisation
        K.has_sorted_indices = True
        K.has_canonical_format = True
        # read by linsolve.diagonal: the diagonal as a take of known positions, where
        # K.diagonal() searches every row for its diagonal entry
        K.diagonal_positions = self.diagonal_positions
        return K
