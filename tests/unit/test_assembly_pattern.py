"""The sparsity pattern of the tangent (signorini.fem.assembly.SparsityPattern)
equals the straightforward one, the sorted distinct (row, column) pairs of all
block entries on the free DOFs (np.unique of their keys, kept here as the
reference), for models (2-D, 3-D, frictional, two bodies) and random block maps
(DOFs in nodes or not, repeated, prescribed); its assembly of random blocks is
SciPy's COO sum restricted to the free DOFs."""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.algorithms.stepping import model_for
from signorini.fem.assembly import SparsityPattern
from signorini.problems.cylinders import cylinders_problem
from signorini.problems.hertz import hertz_problem
from signorini.problems.hertz3d import hertz3d_problem
from signorini.problems.spheres import spheres_problem


def reference(block_dofs, n_dof, free):
    """(indices, indptr, keep, map, diagonal positions) by np.unique of every
    entry's key row * n + col."""
    loc = -np.ones(n_dof, dtype=np.int64)
    loc[free] = np.arange(free.size)
    n = free.size
    rows, cols, keep = [], [], []
    for d in block_dofs:
        k = d.shape[1]
        r = np.repeat(loc[d], k, axis=1).ravel()  # row-major block entries
        c = np.tile(loc[d], (1, k)).ravel()
        m = (r >= 0) & (c >= 0)
        rows.append(r[m])
        cols.append(c[m])
        keep.append(m)
    key = np.concatenate(rows) * n + np.concatenate(cols)
    uniq, inverse = np.unique(key, return_inverse=True)
    r, c = np.divmod(uniq, n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, r + 1, 1)
    indptr = np.cumsum(indptr).astype(np.int32 if uniq.size < 2**31 else np.int64)
    diag = np.arange(n, dtype=np.int64) * (n + 1)
    pos = np.minimum(np.searchsorted(uniq, diag), max(uniq.size - 1, 0))
    diagonal = pos if uniq.size and np.all(uniq[pos] == diag) else None
    return c.astype(np.int32), indptr, np.concatenate(keep), inverse, diagonal


def check(block_dofs, n_dof, free, rng):
    block_dofs = [np.asarray(d) for d in block_dofs]
    p = SparsityPattern(block_dofs, n_dof, free)
    indices, indptr, keep, inverse, diagonal = reference(block_dofs, n_dof, free)
    assert p.n == free.size and p.nnz == indices.size
    assert p.indices.dtype == indices.dtype and np.array_equal(p.indices, indices)
    assert p.indptr.dtype == indptr.dtype and np.array_equal(p.indptr, indptr)
    assert np.array_equal(p._keep, keep)
    assert p._map.dtype == inverse.dtype and np.array_equal(p._map, inverse)
    if diagonal is None:
        assert p.diagonal_positions is None
    else:
        assert p.diagonal_positions.dtype == diagonal.dtype
        assert np.array_equal(p.diagonal_positions, diagonal)
    # each group's (mask, positions) are its part of _keep and _map
    sizes = [d.size * d.shape[1] for d in block_dofs]
    kept = np.cumsum([0] + [int(m.sum()) for m, _ in p._groups])
    for (m, pos), a, b, ka, kb in zip(p._groups, np.cumsum([0] + sizes), np.cumsum(sizes),
                                      kept, kept[1:]):
        assert np.array_equal(m, keep[a:b]) and np.array_equal(pos, inverse[ka:kb])

    # assembly of random blocks: the COO sum of all entries, free rows and columns
    blocks = [rng.standard_normal((d.shape[0], d.shape[1], d.shape[1])) for d in block_dofs]
    rows = np.concatenate([np.repeat(d, d.shape[1], axis=1).ravel() for d in block_dofs])
    cols = np.concatenate([np.tile(d, (1, d.shape[1])).ravel() for d in block_dofs])
    full = sp.coo_matrix((np.concatenate([b.ravel() for b in blocks]), (rows, cols)),
                         shape=(n_dof, n_dof)).tocsr()
    expected = full[free][:, free].toarray()
    K = p.assemble(blocks)
    assert np.allclose(K.toarray(), expected, rtol=0, atol=1e-12)
    if p.diagonal_positions is not None:
        assert np.array_equal(K.data[p.diagonal_positions], K.diagonal())
    blocks[0].flags.writeable = False  # the path that keeps the element contribution
    assert np.allclose(p.assemble(blocks).toarray(), expected, rtol=0, atol=1e-12)
    return p


@pytest.mark.parametrize("build", [
    lambda: hertz_problem(n_fine=8, size=8),
    lambda: hertz3d_problem(n_fine=4),
    lambda: hertz3d_problem({"mu": 0.3}, n_fine=4),
    lambda: cylinders_problem(n_fine=6),
    lambda: spheres_problem(n_fine=4),
], ids=["hertz", "hertz3d", "hertz3d-friction", "cylinders", "spheres"])
def test_model_pattern_equals_the_unique_pairs(build):
    m = model_for(build())
    check(m.layout.block_dofs(), m.layout.n_dof, m.layout.free, np.random.default_rng(0))


def node_blocks(rng, n_nodes, n_blocks, q, b):
    """(n_blocks, q*b) maps of q random nodes each (repeats allowed), DOFs b*node + i."""
    nodes = rng.integers(0, n_nodes, size=(n_blocks, q))
    return (b * nodes[:, :, None] + np.arange(b)).reshape(n_blocks, q * b)


@pytest.mark.parametrize("seed", range(6))
def test_random_block_maps(seed):
    """Node-blocked maps (b = 2, 3) with repeated nodes, maps of arbitrary DOFs
    with repeated DOFs, an empty group, prescribed DOFs (none, some, most)."""
    rng = np.random.default_rng(seed)
    b = 2 + seed % 2
    n_nodes = int(rng.integers(5, 40))
    n_dof = b * n_nodes + int(rng.integers(0, 6))  # some DOFs outside the nodes
    groups = [node_blocks(rng, n_nodes, int(rng.integers(1, 60)), int(rng.integers(1, 5)), b),
              rng.integers(0, n_dof, size=(int(rng.integers(1, 20)), int(rng.integers(1, 6)))),
              np.zeros((0, 3), dtype=np.int64),
              node_blocks(rng, n_nodes, int(rng.integers(1, 10)), 2, b)]
    for fraction in (1.0, 0.8, 0.2):
        free = np.flatnonzero(rng.random(n_dof) < fraction)
        check(groups, n_dof, free, rng)
        check(groups[:1], n_dof, free, rng)  # one group
        check(groups[1:2], n_dof, free, rng)  # no node structure


def test_edge_cases():
    rng = np.random.default_rng(1)
    d = np.array([[0, 1, 2, 3, 4, 5], [3, 4, 5, 6, 7, 8], [6, 7, 8, 6, 7, 8]])  # nodes 0-2
    p = check([d], 18, np.arange(18), rng)  # every DOF free
    assert p.diagonal_positions is None  # the DOFs 9-17 of no block: empty rows
    assert check([d], 9, np.arange(9), rng).diagonal_positions is not None
    check([d], 18, np.zeros(0, dtype=np.int64), rng)  # none free
    check([d[:, :3]], 18, np.array([0, 2, 5]), rng)
    check([d.astype(np.int32)], 18, np.arange(0, 18, 2), rng)
    with pytest.raises(ValueError, match="sorted"):
        SparsityPattern([d], 18, np.array([3, 1, 2]))
