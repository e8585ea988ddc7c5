"""The iterative solver's V-cycle (Chebyshev smoothing) and its row-split products."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.linsolve import multigrid, product_threads
from signorini.linsolve.multigrid import ChebyshevCycle, RowSplit, _lambda_max


def elasticity(n=24):
    """A plane-strain elastic square, fixed on one side (pyamg's gallery), as BSR 2x2."""
    from pyamg.gallery import linear_elasticity
    A, B = linear_elasticity((n, n), format="bsr")
    return sp.bsr_matrix(A), B


@pytest.mark.parametrize("fmt", ["csr", "bsr"])
def test_row_split_products_are_the_whole_products_to_the_bit(monkeypatch, fmt):
    monkeypatch.setattr(multigrid, "SPLIT_ROWS", 0)  # split even a small matrix
    A, _ = elasticity(16)
    M = A.tocsr() if fmt == "csr" else A
    x = np.random.default_rng(1).standard_normal(M.shape[1])
    split = RowSplit(M)
    for n in (1, 2, 3, 7):
        with product_threads(n):
            y = split @ x
        assert np.array_equal(y, M @ x), n
        if n > 1:
            parts = split.parts(n)
            assert 1 < len(parts) <= n and parts[0][0] == 0 and parts[-1][1] == M.shape[0]


@pytest.mark.parametrize("fmt", ["csr", "bsr"])
def test_row_split_products_of_a_block_of_vectors_are_its_columns_products(monkeypatch, fmt):
    """A block X (n, k) in one product, split by rows over the threads: each column
    of M X is M times that column."""
    monkeypatch.setattr(multigrid, "SPLIT_ROWS", 0)
    A, _ = elasticity(16)
    M = A.tocsr() if fmt == "csr" else A
    X = np.random.default_rng(3).standard_normal((M.shape[1], 3))
    for n in (1, 2, 3):
        with product_threads(n):
            Y = RowSplit(M) @ X
        assert Y.shape == X.shape
        for j in range(3):
            assert np.allclose(Y[:, j], M @ X[:, j], rtol=0, atol=1e-13 * np.abs(Y).max()), (n, j)


def test_a_cycle_of_a_block_of_vectors_is_the_cycle_of_each():
    """V(B) for a block B (n, k): column j is V(B[:, j]), the coarse level included."""
    import pyamg
    A, B = elasticity(40)
    V = ChebyshevCycle(pyamg.smoothed_aggregation_solver(A, B=B, max_coarse=50))
    assert V.blocks
    X = np.random.default_rng(4).standard_normal((A.shape[0], 3))
    Y = V(X)
    for j in range(3):
        assert np.allclose(Y[:, j], V(X[:, j]), rtol=0, atol=1e-12 * np.abs(Y).max()), j


def test_lambda_max_estimate_bounds_the_spectrum():
    """1.1 times the Arnoldi estimate lies above the largest eigenvalue of D^-1 A (else
    the smoother amplifies the top of the spectrum), the estimate itself below it."""
    A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(300, 300)).tocsr()
    A = A + sp.diags(np.linspace(0.0, 3.0, 300))  # a diagonal that varies
    Dinv = sp.diags(1.0 / A.diagonal()).tocsr()
    exact = np.max(np.linalg.eigvals((Dinv @ A).toarray()).real)
    est = _lambda_max(A, Dinv, A.shape[0])
    assert 0.9 * exact <= est <= exact * (1 + 1e-12)
    assert 1.1 * est >= exact


def test_chebyshev_cycle_is_a_linear_contraction():
    """The cycle from a zero start is a fixed linear map, and as a stationary iteration
    x <- x + V(b - A x) it converges fast (a V-cycle, not a smoother alone)."""
    import pyamg
    A, B = elasticity(40)
    ml = pyamg.smoothed_aggregation_solver(A, B=B, max_coarse=50)
    assert len(ml.levels) >= 3
    V = ChebyshevCycle(ml)
    rng = np.random.default_rng(2)
    b1, b2 = rng.standard_normal((2, A.shape[0]))
    assert np.allclose(V(2.0 * b1 + b2), 2.0 * V(b1) + V(b2), rtol=0, atol=1e-12 * np.abs(V(b1)).max())
    x = np.zeros_like(b1)
    r0 = np.linalg.norm(b1)
    rates = []
    for _ in range(8):
        r = np.linalg.norm(b1 - A @ x)
        x += V(b1 - A @ x)
        rates.append(np.linalg.norm(b1 - A @ x) / r)
    assert max(rates[2:]) < 0.5, rates
    assert np.linalg.norm(b1 - A @ x) < 1e-3 * r0
