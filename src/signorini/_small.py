"""Determinants and inverses of small matrices (n <= 4) in plain arithmetic.

``jnp.linalg.det`` and ``jnp.linalg.inv`` call LAPACK (an LU and triangular
solves) through custom calls which, batched over cells or faces, split their
batch over XLA's intra-op thread pool and wait for the parts inside a worker of
that same pool. Two such calls running at once (XLA runs independent
operations of a program side by side) can then hold every worker of a small
pool while their parts wait in its queue: measured, a 3-D J2 forging on a
2-core machine (8,000 hexahedra) stopped for good inside the Jacobians'
``inv`` (docs/theory.md §10.2). The functions here are fused element-wise
arithmetic, with no custom call (and cheaper to trace and differentiate than
an LU of a 3x3 matrix).

Every function takes (..., n, n) arrays of a static n <= 4.
"""

from __future__ import annotations

from ._jax import jnp

MAX_N = 4


def _n(A) -> int:
    n = A.shape[-1]
    if A.shape[-2] != n or not 1 <= n <= MAX_N:
        raise ValueError(f"small matrices are square with n <= {MAX_N}, got shape {A.shape}")
    return n


def _det(A, rows: tuple, cols: tuple):
    """det of A's submatrix (rows, cols), by cofactors along its first row: indices
    only, no array built (the 2x2 and 3x3 cases are the products written out)."""
    if len(rows) == 1:
        return A[..., rows[0], cols[0]]
    if len(rows) == 2:
        (r, s), (c, d) = rows, cols
        return A[..., r, c] * A[..., s, d] - A[..., r, d] * A[..., s, c]
    return sum((-1) ** k * A[..., rows[0], c] * _det(A, rows[1:], cols[:k] + cols[k + 1:])
               for k, c in enumerate(cols))


def det(A):
    """det A (...,) by cofactors."""
    n = _n(A)
    return _det(A, tuple(range(n)), tuple(range(n)))


def adjugate(A):
    """adj A (..., n, n): A adj(A) = adj(A) A = det(A) I."""
    n = _n(A)
    if n == 1:
        return jnp.ones_like(A)
    idx = tuple(range(n))
    without = lambda k: idx[:k] + idx[k + 1:]
    # adj(A)_ij = (-1)^(i+j) det(A without row j and column i)
    return jnp.stack([jnp.stack([(-1) ** (i + j) * _det(A, without(j), without(i)) for j in range(n)], -1)
                      for i in range(n)], -2)


def inv(A):
    """A^-1 = adj(A) / det(A): for well-conditioned matrices (element Jacobians)."""
    return adjugate(A) / det(A)[..., None, None]


def spd_inv(A):
    """A^-1 of a symmetric positive definite A by an LDL^T factorisation written
    out (no pivoting, which elimination on an SPD matrix does not need to be
    backward stable: what LAPACK's pivoted LU gave, to round-off, also on the
    ill-conditioned dual mass matrices of nearly uncovered faces)."""
    n = _n(A)
    L = [[None] * n for _ in range(n)]
    D = [None] * n
    for j in range(n):
        D[j] = A[..., j, j] - sum(L[j][k] * L[j][k] * D[k] for k in range(j))
        for i in range(j + 1, n):
            L[i][j] = (A[..., i, j] - sum(L[i][k] * L[j][k] * D[k] for k in range(j))) / D[j]
    # columns of the inverse: L y = e_c, D z = y, L^T x = z
    cols = []
    for c in range(n):
        y = [None] * n
        for i in range(n):
            e = jnp.ones_like(D[0]) if i == c else jnp.zeros_like(D[0])
            y[i] = e - sum(L[i][k] * y[k] for k in range(i))
        x = [None] * n
        for i in reversed(range(n)):
            x[i] = y[i] / D[i] - sum(L[k][i] * x[k] for k in range(i + 1, n))
        cols.append(jnp.stack(x, -1))
    return jnp.stack(cols, -1)


__all__ = ["MAX_N", "adjugate", "det", "inv", "spd_inv"]
