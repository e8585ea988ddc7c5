"""The multigrid V-cycle of the iterative solver (docs/theory.md §12.7): pyamg's
smoothed-aggregation hierarchy (its operators A_l, P_l, R_l and coarse solve),
cycled with Chebyshev smoothing, every sparse product on all the cores.

A Gauss-Seidel sweep is sequential, and pyamg's holds Python's lock: on a
283k-DOF displacement block its symmetric block sweep costs as much as eight
products with A, on one core. A Chebyshev smoother of degree k is k products
with A and with the inverse of A's nodal diagonal blocks, which SciPy computes
without Python's lock, so that they split by rows over threads. Degree 3 before
and after the coarse correction needs as many Krylov iterations as the
symmetric block Gauss-Seidel sweeps (34 against 33 on that block) at 0.17 s a
cycle against 0.41 s on two cores; degree 2 on the coarser levels, denser than
the finest, brings the cycle to 0.10 s for 37 iterations.

The smoother is the Chebyshev iteration (Saad, *Iterative Methods for Sparse
Linear Systems*, Algorithm 12.1) for D^-1 A on [lambda_max / RATIO, 1.1
lambda_max], D the nodal diagonal blocks, lambda_max from a few Arnoldi steps:
it damps the upper part of the spectrum, the part the coarse levels do not
represent. From a zero initial guess the whole cycle is a fixed linear map of
its right-hand side.
"""

from __future__ import annotations

import contextlib
import copy
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

#: the smoother's polynomial degree, before and after the coarse correction, on the
#: finest level and on the coarser ones (denser: level 1 of the 283k-DOF block has
#: 1.5 times the finest level's nonzeros)
DEGREE = 3
COARSE_DEGREE = 2
#: the smoothed part of the spectrum: [lambda_max / RATIO, 1.1 lambda_max]
RATIO = 30.0
#: Arnoldi steps of the estimate of lambda_max(D^-1 A)
ARNOLDI_STEPS = 12
#: rows below which a product is not split (a thread's start costs more)
SPLIT_ROWS = 20_000

_THREADS = [max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                else (os.cpu_count() or 1))]
_POOL: list = []


@contextlib.contextmanager
def product_threads(n: int):
    """Split the V-cycle's and the Krylov method's sparse products over ``n``
    threads for the duration (the sweep's worker processes run on one each)."""
    old = _THREADS[0]
    _THREADS[0] = max(1, int(n))
    try:
        yield
    finally:
        _THREADS[0] = old


def _pool() -> ThreadPoolExecutor:
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max(2, _THREADS[0]), thread_name_prefix="signorini-spmv"))
    return _POOL[0]


class RowSplit:
    """y = M x with M's rows split in as many parts as there are threads.

    The parts are views of M's arrays (no copy); each thread writes its rows of
    y. SciPy's CSR and BSR products release Python's lock, so the parts run at
    once. ``shape`` and ``@`` make it a stand-in for M in products."""

    def __init__(self, M):
        self.M = M
        self.shape = M.shape
        self.dtype = M.dtype
        self._parts: dict = {}

    def parts(self, n: int) -> list:
        """(first row, end row, the rows' matrix) of ``n`` parts of equal nonzeros."""
        if n not in self._parts:
            M = self.M
            bsr = M.format == "bsr"
            r = M.blocksize[0] if bsr else 1
            cuts = np.searchsorted(M.indptr, np.linspace(0, M.indptr[-1], n + 1)[1:-1])
            bounds = [0, *sorted(set(int(c) for c in cuts)), len(M.indptr) - 1]
            out = []
            for a, b in zip(bounds[:-1], bounds[1:]):
                if b <= a:
                    continue
                s, e = M.indptr[a], M.indptr[b]
                arrays = (M.data[s:e], M.indices[s:e], M.indptr[a:b + 1] - s)
                shape = ((b - a) * r, M.shape[1])
                part = (sp.bsr_matrix(arrays, shape=shape, blocksize=M.blocksize, copy=False)
                        if bsr else sp.csr_matrix(arrays, shape=shape, copy=False))
                out.append((a * r, b * r, part))
            self._parts[n] = out
        return self._parts[n]

    def __matmul__(self, x):
        """M x for a vector x, or M X for a block X (n, k) of vectors (one pass
        over M for the k of them)."""
        n = _THREADS[0]
        if n == 1 or self.shape[0] < SPLIT_ROWS or x.ndim > 2:
            return self.M @ x
        y = np.empty((self.shape[0],) + x.shape[1:], dtype=np.result_type(self.dtype, x.dtype))

        def rows(part):
            a, b, Mp = part
            y[a:b] = Mp @ x
        list(_pool().map(rows, self.parts(n)))
        return y

    def matvec(self, x):
        return self @ x


def _lambda_max(A, Dinv, n: int) -> float:
    """An estimate of the largest |eigenvalue| of D^-1 A: the largest Ritz value of
    ``ARNOLDI_STEPS`` Arnoldi steps from a fixed start (reproducible)."""
    m = min(ARNOLDI_STEPS, n)
    V = np.zeros((n, m + 1))
    H = np.zeros((m + 1, m))
    v = np.random.default_rng(0).standard_normal(n)
    V[:, 0] = v / np.linalg.norm(v)
    k = m
    for j in range(m):
        w = Dinv @ (A @ V[:, j])
        for i in range(j + 1):
            H[i, j] = V[:, i] @ w
            w -= H[i, j] * V[:, i]
        H[j + 1, j] = np.linalg.norm(w)
        if H[j + 1, j] <= 1e-12 * abs(H[j, j]):
            k = j + 1
            break
        V[:, j + 1] = w / H[j + 1, j]
    return float(np.max(np.abs(np.linalg.eigvals(H[:k, :k]))))


class _Level:
    """One level: A, the inverse of its nodal diagonal blocks, P, R and the
    Chebyshev interval."""

    def __init__(self, A, P, R, degree: int, blocksize: int = 1):
        self.A, self.Dinv = RowSplit(A), RowSplit(nodal_inverse(A, blocksize))
        self.P, self.R = (RowSplit(M if M.format == "bsr" else M.tocsr()) for M in (P, R))
        lam = _lambda_max(self.A, self.Dinv, A.shape[0])
        self.hi, self.lo = 1.1 * lam, lam / RATIO
        self.degree = degree

    def smooth(self, b, x=None):
        """``degree`` Chebyshev steps on A x = b from x (zero)."""
        theta, delta = 0.5 * (self.hi + self.lo), 0.5 * (self.hi - self.lo)
        sigma = theta / delta
        rho = 1.0 / sigma
        if x is None:
            x = np.zeros_like(b)
            r = b.copy()
        else:
            x = x.copy()
            r = b - self.A @ x
        d = (self.Dinv @ r) / theta
        for k in range(self.degree):
            x += d
            if k == self.degree - 1:
                break
            r -= self.A @ d
            rho_new = 1.0 / (2.0 * sigma - rho)
            d *= rho_new * rho
            d += (2.0 * rho_new / delta) * (self.Dinv @ r)
            rho = rho_new
        return x


class ChebyshevCycle:
    """x = V(b): one V-cycle of pyamg's hierarchy ``ml`` with Chebyshev smoothing
    (the module's text); a level in BSR format is smoothed with its nodal blocks.
    ``b`` is a vector, or a block (n, k) of vectors cycled together (each column's
    result that of its own cycle): every product then reads a level's matrix once
    for the k of them."""

    #: the cycle takes blocks of vectors
    blocks = True

    def __init__(self, ml):
        self.levels = [_Level(lv.A, lv.P, lv.R, COARSE_DEGREE if i else DEGREE,
                              lv.A.blocksize[0] if lv.A.format == "bsr" else 1)
                       for i, lv in enumerate(ml.levels[:-1])]
        coarse = ml.levels[-1].A
        solve = ml.coarse_solver
        self._coarse = lambda b: solve(coarse, b)  # noqa: E731

    def with_finest(self, A, blocksize: int) -> ChebyshevCycle:
        """This cycle with its finest operator replaced by ``A`` (its smoother's
        nodal blocks and interval made anew; the prolongators and the coarser
        levels kept): the cycle of a tangent that differs from the one the
        hierarchy was built for in a few rows (docs/theory.md §12.7). The
        smoothed interval is kept: the largest eigenvalue of D^-1 A is a bound of
        its rows, which a few changed rows hardly move."""
        first = copy.copy(self.levels[0])
        first.A, first.Dinv = RowSplit(A), RowSplit(nodal_inverse(A, blocksize))
        new = copy.copy(self)
        new.levels = [first] + self.levels[1:]
        return new

    def __call__(self, b, i: int = 0):
        if i == 0:
            b = np.asarray(b, dtype=float)
        if i == len(self.levels):
            if b.ndim == 2:  # the coarse solve a column at a time (pyamg's takes vectors)
                return np.column_stack([np.asarray(self._coarse(np.ascontiguousarray(c))).ravel()
                                        for c in b.T])
            return np.asarray(self._coarse(b)).ravel()
        lv = self.levels[i]
        x = lv.smooth(b)
        x += lv.P @ self(lv.R @ (b - lv.A @ x), i + 1)
        return lv.smooth(b, x)


def nodal_inverse(A, blocksize: int):
    """The inverse of the diagonal blocks of ``blocksize`` x ``blocksize`` of A
    (a node's DOFs; ``blocksize`` 1: the diagonal), a block-diagonal BSR matrix
    (CSR with blocks of 1). A zero diagonal entry (a row of 1) is left out."""
    n = A.shape[0]
    if blocksize == 1:
        d = A.diagonal()
        return sp.diags(np.where(d != 0, 1.0 / np.where(d != 0, d, 1.0), 0.0)).tocsr()
    nb = n // blocksize
    if A.format == "bsr" and A.blocksize == (blocksize, blocksize):
        from pyamg.util.utils import get_block_diag  # noqa: PLC0415  (lazy: pyamg)
        D = get_block_diag(A, blocksize=blocksize, inv_flag=True)
    else:  # CSR: the entries within a node's block, gathered, then inverted
        A = sp.csr_matrix(A)
        A.sum_duplicates()  # one entry per position (a no-op on a canonical matrix)
        rows = np.repeat(np.arange(n), np.diff(A.indptr))
        inside = rows // blocksize == A.indices // blocksize
        r, c = rows[inside], A.indices[inside]
        D = np.zeros((nb, blocksize, blocksize))
        D[r // blocksize, r % blocksize, c % blocksize] = A.data[inside]
        try:
            D = np.linalg.inv(D)
        except np.linalg.LinAlgError:  # a singular block: its pseudo-inverse, as pyamg's
            D = np.linalg.pinv(D)
    return sp.bsr_matrix((D, np.arange(nb, dtype=np.int32), np.arange(nb + 1, dtype=np.int32)),
                         shape=A.shape)
