"""Intel MKL PARDISO, with our own driver: the ordering and symbolic
factorisation once per sparsity pattern, the numeric factorisation per
Newton iteration, symmetric indefinite or general LU."""

from __future__ import annotations

import ctypes
import logging
import time
from collections import OrderedDict, deque

import numpy as np

from ..errors import InputError, SingularTangentError

log = logging.getLogger("signorini")

from .base import LinearSolver
from .factor import Factor
from .mkl import _MklProduct, _mkl, mkl_max_threads

#: PARDISO error codes (MKL reference)
_PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
                   -4: "zero pivot, numerical factorization or iterative refinement problem",
                   -5: "unclassified (internal) error", -6: "reordering failed",
                   -7: "diagonal matrix is singular", -8: "32-bit integer overflow problem",
                   -9: "not enough memory for out-of-core solver",
                   -10: "error opening out-of-core files", -11: "read/write error with OOC files",
                   -12: "pardiso_64 called from 32-bit library",
                   -13: "interrupted by the mkl_progress function",
                   -15: "reordering failed (matrix types 11 and 13 only)"}


class _Handle:
    """One PARDISO instance: its internal pointer, parameters and analysed pattern."""

    def __init__(self, f, mtype: int, n: int, indptr: np.ndarray, indices: np.ndarray):
        self._f = f
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.mtype, self.n = mtype, n
        self.indptr = np.ascontiguousarray(indptr, dtype=np.int32)
        self.indices = np.ascontiguousarray(indices, dtype=np.int32)
        self.analysed = False
        # weighted matching (and its scaling) in the analysis: until an analysis with it
        # has failed a tangent (general LU only; see Pardiso.factorize's refactor)
        self.matching = True
        self.threads = 0  # MKL's thread count when the pattern was analysed
        self.generation = 0
        self.a = None  # values of the current factorisation (kept alive while it is used)
        # seconds of recent back-substitutions: one column, and k columns at once
        self.single: deque = deque(maxlen=8)
        self.blocks: dict[int, deque] = {}
        self.by_columns: dict[int, deque] = {}  # k columns one by one
        self.multi_solves = 0  # solves of several columns so far
        self.column_solves = 0  # of them, those done column by column

    def matches(self, mtype, n, indptr, indices) -> bool:
        return (self.mtype == mtype and self.n == n and self.indices.size == indices.size
                and (self.indptr is indptr or np.array_equal(self.indptr, indptr))
                and (self.indices is indices or np.array_equal(self.indices, indices)))

    def call(self, phase: int, a=None, b=None) -> np.ndarray | None:
        nrhs = 1 if b is None or b.ndim == 1 else b.shape[1]
        x = None if b is None else np.zeros_like(b)
        err = ctypes.c_int32(0)
        c = ctypes.c_int32
        ptr = lambda arr: None if arr is None else arr.ctypes.data  # noqa: E731
        self._f(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(c(1)),
                ctypes.byref(c(1)), ctypes.byref(c(self.mtype)), ctypes.byref(c(phase)),
                ctypes.byref(c(self.n)), ptr(a), ptr(self.indptr), ptr(self.indices), None,
                ctypes.byref(c(nrhs)), self.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
                ctypes.byref(c(0)), ptr(b), ptr(x), ctypes.byref(err))
        if err.value != 0:
            msg = _PARDISO_ERRORS.get(err.value, "unknown error")
            raise SingularTangentError(f"PARDISO phase {phase} failed: error {err.value} ({msg})")
        return x

    #: the time of k columns one by one, until measured, is taken as k single solves
    #: times this margin
    COLUMNS_MARGIN = 1.05
    #: time the other way again every this many solves of several columns
    PROBE_EVERY = 4

    def solve(self, a, b: np.ndarray) -> np.ndarray:
        """Back-substitution (phase 33) of b (n,) or (n, k), columns contiguous.

        Several columns go to PARDISO as one block, or one by one when recent
        solves of this handle timed that faster: the fastest of the last block
        solves (at least two, the first of a process is often slow) against the
        fastest of the last column-by-column solves, or, before there is one, k
        single solves (x :attr:`COLUMNS_MARGIN`). Every :attr:`PROBE_EVERY`-th
        solve of several columns times the other way again: a block, or the
        columns one by one if k single solves would beat the block. Which is
        faster depends on the machine's state, not on the factor: for the same
        factor, the block wins in some processes and the columns in others
        (docs/theory.md §10.2), hence a choice by timing that keeps probing the
        other way. Both give the same solution to round-off, and every solve is
        checked (:class:`Factor`)."""
        k = 1 if b.ndim == 1 else b.shape[1]
        if k == 1:
            t0 = time.perf_counter()
            x = self.call(33, a, b)
            self.single.append(time.perf_counter() - t0)
            return x
        self.multi_solves += 1
        block = self.blocks.setdefault(k, deque(maxlen=4))
        cols = self.by_columns.setdefault(k, deque(maxlen=4))
        if len(block) >= 2 and (cols or self.single):
            guess = self.COLUMNS_MARGIN * k * min(self.single) if self.single else np.inf
            faster = (min(cols) if cols else guess) < min(block)
            if self.multi_solves % self.PROBE_EVERY == 0:  # time the other way again,
                # columns only where single solves say they may now be the faster
                faster = not faster and guess < min(block)
            if faster:
                self.column_solves += 1
                t0 = time.perf_counter()
                x = np.empty_like(b, order="F")
                for j in range(k):
                    x[:, j] = self.call(33, a, b[:, j])
                cols.append(time.perf_counter() - t0)
                return x
        t0 = time.perf_counter()
        x = self.call(33, a, b)
        block.append(time.perf_counter() - t0)
        return x

    def analyse(self, a) -> None:
        """Ordering and symbolic factorisation (phase 11) with the values ``a``
        (PARDISO's scaling and matching use them)."""
        self.release()
        ip = self.iparm
        ip[:] = 0
        ip[0] = 1  # we supply the parameters
        ip[1] = 2  # METIS nested dissection
        ip[7] = 0  # iterative refinement: MKL's default (2 steps when pivots were perturbed)
        ip[9] = 13 if self.mtype == 11 else 8  # pivot perturbation 1e-13 / 1e-8
        ip[10] = 1  # scaling
        ip[12] = 1 if self.matching else 0  # weighted matching (zero diagonals of multipliers)
        ip[17] = -1  # report the factor's non-zeros
        ip[18] = -1  # report the factorisation's floating-point operations (millions)
        ip[20] = 1  # Bunch-Kaufman pivoting (symmetric indefinite)
        ip[34] = 1  # zero-based indices
        self.threads = mkl_max_threads(self._f)
        # a new analysis invalidates every factor of the old one, also where the
        # numeric factorisation that follows fails (a solve of an analysed but
        # unfactorised handle crashes MKL)
        self.generation += 1
        self.call(11, a)
        self.analysed = True

    def release(self) -> None:
        if self.analysed:
            try:
                self.call(-1)
            finally:
                self.analysed = False
                self.pt[:] = 0
                self.a = None


class Pardiso(LinearSolver):
    """Intel MKL PARDISO with symbolic reuse (our own ctypes driver of MKL).

    One PARDISO handle per sparsity pattern (up to :attr:`MAX_PATTERNS`, the
    least recently used released first): ``factorize`` runs the analysis
    (ordering + symbolic factorisation, phase 11) only for a pattern it has not
    seen, then the numeric factorisation (phase 22). A factor is valid until the
    next ``factorize`` of the same pattern, which is how Newton and the DDM use
    it. ``analyses``, ``reanalyses`` and ``factorizations`` count the phases.
    """

    name = "pardiso"
    #: patterns kept analysed at once (the levels of a coarse-to-fine start)
    MAX_PATTERNS = 4

    def __init__(self):
        self._f = _mkl()
        self._handles: OrderedDict = OrderedDict()
        self._upper: OrderedDict = OrderedDict()  # CSR pattern -> its upper triangle
        self.analyses = 0  # symbolic analyses (phase 11), including re-analyses
        self.reanalyses = 0  # analyses redone because refinement could not repair a kept one
        self.factorizations = 0
        self.perturbed_pivots = 0  # summed over the numeric factorisations (iparm(14))

    @property
    def _iparm(self) -> np.ndarray:
        """Parameters (and reports) of the most recently used handle."""
        return next(reversed(self._handles.values())).iparm

    def _upper_triangle(self, A):
        """(positions, indptr, indices) of the upper triangle of the CSR pattern of A:
        its values are ``A.data.take(positions)``. Kept per pattern; an assembled
        tangent passes the same index arrays every iteration, found by identity
        (a comparison would read every index on every factorisation)."""
        key = (A.shape[0], A.nnz)
        up = self._upper.get(key)
        if up is None or not ((up[0] is A.indices or np.array_equal(up[0], A.indices))
                              and (up[1] is A.indptr or np.array_equal(up[1], A.indptr))):
            n = A.shape[0]
            rows = np.repeat(np.arange(n), np.diff(A.indptr))
            mask = A.indices >= rows
            indptr = np.concatenate([[0], np.cumsum(np.bincount(rows[mask], minlength=n))])
            up = (A.indices, A.indptr, np.flatnonzero(mask), indptr.astype(np.int32),
                  A.indices[mask].astype(np.int32))
            self._upper[key] = up
            while len(self._upper) > self.MAX_PATTERNS:
                self._upper.popitem(last=False)
        else:
            self._upper.move_to_end(key)
        return up[2], up[3], up[4]

    @staticmethod
    def _csr(K):
        A = K.tocsr()
        # an assembled tangent says its indices are sorted (SparsityPattern.assemble);
        # SciPy's own test of an unknown matrix would cost a pass over its indices on
        # every factorisation
        return A if A.has_sorted_indices else A.sorted_indices()

    def _handle(self, mtype, n, indptr, indices, values) -> tuple[_Handle, bool]:
        for key, h in self._handles.items():
            if h.matches(mtype, n, indptr, indices):
                self._handles.move_to_end(key)
                return h, False
        h = _Handle(self._f, mtype, n, indptr, indices)
        h.analyse(values())
        self.analyses += 1
        self._handles[id(h)] = h
        while len(self._handles) > self.MAX_PATTERNS:
            self._handles.popitem(last=False)[1].release()
        return h, True

    def factorize(self, K, symmetric=False, analysis=None):
        """Numeric factorisation of K; the first one of a pattern also analyses it.

        ``analysis``: optional ``() -> matrix`` of the same pattern whose values a
        symmetric analysis uses instead of K's (its scaling and weighted matching
        are kept for every later factorisation of the pattern). The model passes
        its tangent with every contact node closed (``Model.analysis_tangent``):
        the 2x2 pivots chosen for it suit every active set, whereas an analysis
        of the first tangent perturbs one pivot per node that changes state
        later (docs/theory.md §10.1)."""
        A = self._csr(K)
        n = A.shape[0]
        if symmetric:
            upper, indptr, indices = self._upper_triangle(A)
            a, mtype = A.data.take(upper), -2
        else:
            a, indptr, indices, mtype = np.ascontiguousarray(A.data), A.indptr, A.indices, 11
        if np.any(np.diff(indptr) == 0):
            raise SingularTangentError("the tangent has an empty row (singular)")

        other = []  # set when the analysis used other values than K's

        def analysis_values():
            # symmetric only: the general LU's matching pairs each multiplier row with
            # one column, which no single active set suits (analysed with every node
            # closed or with its first tangent, the frictional Hertz has as many
            # perturbed pivots; docs/theory.md §10.1)
            B = None if analysis is None or not symmetric else analysis()
            if B is None:
                return a
            B = self._csr(B)
            if not (np.array_equal(B.indptr, A.indptr) and np.array_equal(B.indices, A.indices)):
                return a  # not the same pattern: analyse with K's own values
            other.append(True)
            return B.data.take(upper)

        h, fresh = self._handle(mtype, n, indptr, indices, analysis_values)
        threads = mkl_max_threads(self._f)
        if h.threads != threads:
            # PARDISO's numeric factorisation with fewer OpenMP threads than its analysis
            # had crashes the process (a segmentation fault, MKL 2026.2 on x86-64: analysis
            # with 2 threads, factorisation under threadpoolctl's or mkl_threads' limit
            # of 1): analyse the pattern again with the threads there are now
            log.debug("pardiso: MKL's thread count changed from %d to %d since the analysis; "
                      "analysing the pattern again", h.threads, threads)
            h.analyse(analysis_values())
            self.analyses += 1
            fresh = True
        fresh = fresh and not other  # an analysis of other values may still need K's own

        def solver_of(generation):
            def solve(b, transpose=False):
                if generation != h.generation or not h.analysed:
                    raise InputError("this PARDISO factorisation was replaced by a newer one")
                # iparm(12) = 2: solve with A^T (a symmetric factor is its own transpose)
                h.iparm[11] = 2 if transpose and mtype == 11 else 0
                try:
                    # columns contiguous in and out (PARDISO's layout): the check's
                    # products and reductions then run over contiguous columns
                    return h.solve(a, np.asfortranarray(b))
                finally:
                    h.iparm[11] = 0
            return solve

        def refactor():
            # The kept analysis carries the scaling and matching of older values; pivots
            # it no longer suits are perturbed, which refinement normally repairs. When it
            # does not, analyse these values afresh (docs/theory.md §10.1); a general LU
            # without the weighted matching, whose row permutation suits one active set
            # only: its static pivot order, from the pattern alone, perturbs the pivot of
            # every closed multiplier, and one refinement step repairs that whatever the
            # active set, where a matching of these values would fail again later
            if mtype == 11:
                h.matching = False
            h.analyse(a)
            h.a = a
            h.call(22, a)
            self.analyses += 1
            self.reanalyses += 1
            h.generation += 1
            return solver_of(h.generation)

        # the factor of the numeric factorisation below (generation + 1)
        factor = Factor(solver_of(h.generation + 1), A, None if fresh else refactor,
                        transposable=True, residual=_MklProduct(self._f.lib, A))
        # the check's row scale here, while K's values are in cache (the upper triangle
        # has just been taken from them): after the factorisation, which streams the
        # factor through the cache, they would be read from memory again
        factor.row_scale()
        h.a = a
        h.call(22, a)
        self.factorizations += 1
        self.perturbed_pivots += int(h.iparm[13])
        h.generation += 1
        factor.owner = self  # keeps this solver, and so its PARDISO handles, alive
        factor.nbytes = 8 * abs(int(h.iparm[17]))  # iparm(18): non-zeros of the factors
        factor.flops = 1e6 * abs(float(h.iparm[18]))  # iparm(19): MFLOP of the factorisation
        return factor

    def describe(self) -> str:
        return "pardiso (Intel MKL PARDISO)"

    def release(self) -> None:
        """Free every factorisation and analysis of this solver."""
        while self._handles:
            self._handles.popitem()[1].release()

    def __del__(self):
        try:
            self.release()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass
