"""Assembly of the sparse tangent (signorini.fem.assembly): an unchanged element
block is not scattered again, and the assembled CSR matrix states only true
index properties (sorted, canonical, the pattern's own index arrays, the
positions of its diagonal)."""

import numpy as np
import scipy.sparse as sp

from signorini import linsolve
from signorini.params import as_jax
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for


def test_assembly_reuses_an_unchanged_element_block():
    """A read-only element array passed again is not scattered again; a new or a
    writable one is."""
    pb = hertz.hertz_problem(n_fine=8, size=8)
    m, p = model_for(pb), as_jax(pb.params)
    w = np.zeros(m.n_dof)
    _, blocks = m.local_tangents(w, p, 1.0)
    fresh = lambda bl: sp.csr_matrix(  # noqa: E731 - the assembly without any cache
        (np.bincount(m.pattern._map, weights=np.concatenate([b.reshape(-1) for b in bl])
                     [m.pattern._keep], minlength=m.pattern.nnz), m.pattern.indices,
         m.pattern.indptr), shape=(m.pattern.n,) * 2)
    K1 = m.pattern.assemble(blocks)
    contact = [b * 3.0 for b in blocks[1:]]
    K2 = m.pattern.assemble([blocks[0]] + contact)  # same element array: kept part
    assert not blocks[0].flags.writeable and m.pattern._first[0] is blocks[0]
    K3 = m.pattern.assemble([blocks[0] * 2.0] + contact)  # a new one
    for K, bl in ((K1, blocks), (K2, [blocks[0]] + contact), (K3, [blocks[0] * 2.0] + contact)):
        assert abs(K - fresh(bl)).max() <= 1e-12 * abs(K).max()


def test_assembled_tangent_states_only_true_index_properties():
    """The assembly says its CSR indices are sorted and canonical (a solver then
    skips SciPy's test of them), passes the pattern's own index arrays and where
    the diagonal entries are: all must be true of the matrix, as SciPy's own
    tests of a copy find."""
    for pb in (hertz.hertz_problem(n_fine=8, size=8), hertz_friction_problem(refine=0)):
        m, p = model_for(pb), as_jax(pb.params)
        _, blocks = m.local_tangents(np.zeros(m.n_dof), p, 1.0, m.initial_state(np.zeros(m.n_dof), p))
        K = m.pattern.assemble(blocks)
        assert K.has_sorted_indices and K.has_canonical_format
        assert K.indices is m.pattern.indices and K.indptr is m.pattern.indptr
        copy = sp.csr_matrix((K.data.copy(), K.indices.copy(), K.indptr.copy()), shape=K.shape)
        assert copy.has_sorted_indices and copy.has_canonical_format  # SciPy's own test
        assert np.array_equal(K.toarray(), copy.toarray())
        # the diagonal from the positions the assembly carries is SciPy's diagonal
        assert K.diagonal_positions is not None and not hasattr(copy, "diagonal_positions")
        assert np.array_equal(linsolve.diagonal(K), copy.diagonal())
        assert np.array_equal(linsolve.diagonal(copy), copy.diagonal())
