"""A factorisation with a checked solve: every solve is checked against K
(one sparse product) and refined by a few back-substitutions when its
row-wise backward error is above :data:`REFINE_TOL`."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, SingularTangentError

log = logging.getLogger("signorini")


#: row-wise backward error max_i |K x - b|_i / (max_j |K_ij| ||x|| + |b_i|) above
#: which a solve is refined; round-off of a stable factorisation is ~1e-16
REFINE_TOL = 1e-14
#: at most this many refinement steps (each one back-substitution)
REFINE_STEPS = 3


class Factor:
    """A factorisation of K: ``solve(b)`` (or of K^T: ``solve(b, transpose=True)``)
    with a backward-error check and refinement.

    ``solve`` is the backend's ``solve(b)``; with ``transposable=True`` it is
    ``solve(b, transpose)``. A backend without a transposed solve may pass
    ``transpose_factor``, a function returning a :class:`Factor` of K^T
    (factorised once, on first use)."""

    def __init__(self, solve, K: sp.spmatrix, refactor=None, transpose_factor=None,
                 transposable: bool = False, residual=None, solve_to=None, solve_from=None):
        self._solve = solve
        # (b, x0) -> x: the solve started from the guess x0, for a backend whose solves are
        # iterative and cost less from a good guess (:meth:`solve`'s ``guess``); None: no use
        self._solve_from = solve_from
        # (b, rtol) -> x with ||K x - b|| <= rtol ||b||, for a backend whose solves are
        # iterative and cost less at a looser tolerance (:meth:`solve_to`); None: exact
        self._solve_to = solve_to
        # (x, b, transpose) -> b - K x (K^T x), or None if it cannot; default SciPy's product
        self._residual_of = residual
        self._transposable = transposable
        self._refactor = refactor  # () -> a more accurate solve function, if the solver has one
        self._transpose_factor = transpose_factor
        self._transposed = None
        self.K = K
        self.n = K.shape[0]
        self._norm = {}
        self._scratch = None  # (2, n) work vectors of the backward error
        self.refinements = 0  # refinement back-substitutions done so far
        self.backward_error = 0.0  # of the last solve (worst column)
        self.relative_residual = 0.0  # max over columns of ||K x - b|| / ||b|| of the last solve
        self.nbytes: int | None = None  # memory of the factors, where the solver reports it
        self.flops: float | None = None  # operations of the factorisation, where it reports them
        #: backward error below which a solve is not refined (an iterative backend's is
        #: its own tolerance's, not round-off)
        self.refine_tol = REFINE_TOL

    def row_scale(self) -> None:
        """Compute now the row scale the check of a solve will use (it is kept)."""
        self._row_scale(False, False)

    def _row_scale(self, transpose: bool, exact: bool) -> np.ndarray:
        """max_j |K_ij| of every row (of K^T: every column), or with ``exact=False``
        a lower bound that costs a quarter: |K_ii|, and the exact maximum only in
        the rows whose diagonal is zero (the multipliers of closed contact nodes).
        A lower bound overstates the backward error, so it can only ask for the
        exact value, never hide a residual; it reads the diagonal (and the few
        rows without one) where the exact value reads every entry of K."""
        for key in ((transpose, exact), (transpose, True)):  # the exact values serve as a bound
            if key in self._norm:
                return self._norm[key]
        key = (transpose, exact)
        # the rows of K^T are the columns of K: the compressed rows of its CSC layout
        K = sp.csc_matrix(self.K) if transpose else (
            self.K if getattr(self.K, "format", None) == "csr" else sp.csr_matrix(self.K))
        if exact:
            rn = np.zeros(K.shape[0])
            filled = np.diff(K.indptr) > 0
            if K.nnz:
                rn[filled] = np.maximum.reduceat(np.abs(K.data), K.indptr[:-1][filled])
        else:
            rn = np.abs(diagonal(self.K))
            zero = np.flatnonzero(rn == 0.0)
            if zero.size:  # rows (K^T: columns) without a diagonal: their exact maximum
                start = K.indptr[zero]
                lens = K.indptr[zero + 1] - start
                full = lens > 0
                if full.any():
                    start, lens = start[full], lens[full]
                    first = np.cumsum(lens) - lens  # where each row starts in `pos`
                    pos = np.arange(int(lens.sum())) + np.repeat(start - first, lens)
                    rn[zero[full]] = np.maximum.reduceat(np.abs(K.data[pos]), first)
        self._norm[key] = rn
        return rn

    def _backward_error(self, r, x, b, transpose=False) -> float:
        """Row-wise normwise backward error max_i |r_i| / (max_j |K_ij| ||x|| + |b_i|).

        Row by row, because the rows of a contact tangent differ in scale by the
        augmentation eps: a norm over all rows is dominated by the multiplier rows
        and hides a residual in the force rows (measured: a frictional solve with
        perturbed pivots had a backward error of 1e-16 over all rows, 2e-7 row-wise,
        and a forward error of 2e-7).

        First with the cheap lower bound of max_j |K_ij| (:meth:`_row_scale`): an
        upper bound of the error. Only if that exceeds ``REFINE_TOL`` is the exact
        row maximum computed, so the value returned is the exact backward error
        or an upper bound of it that is below the tolerance."""
        if x.ndim == 2:  # column by column: NumPy's reductions and broadcasts over a
            # short last axis are slow, a contiguous column is one fast pass
            return max((self._backward_error(r[:, j], x[:, j], b[:, j], transpose)
                        for j in range(x.shape[1])), default=0.0)
        # two scratch vectors kept for every column and solve of this factor: no fresh
        # temporaries, which page-fault whenever the C library has given freed memory
        # back, and then cost several times the arithmetic on them (docs/theory.md §10.1)
        if self._scratch is None:
            self._scratch = np.empty((2, self.n))
        den, ratio = self._scratch
        xmax = max(float(x.max(initial=0.0)), -float(x.min(initial=0.0)))
        eta = 0.0
        for exact in (False, True):
            np.multiply(self._row_scale(transpose, exact), xmax, out=den)
            den += np.abs(b, out=ratio)
            # den_i = 0 only where b_i = 0 and (row i of K is zero or x = 0): then r_i = 0,
            # and r_i / tiny = 0. A NaN (a non-finite refinement step, a NaN in K) stays
            # NaN, so that the step is rejected and the error is not called small
            np.maximum(den, 1e-300, out=den)
            np.abs(r, out=ratio)
            ratio /= den
            eta = float(np.max(ratio, initial=0.0))
            if eta <= self.refine_tol:
                break
        return eta

    def solve(self, b: np.ndarray, transpose: bool = False, guess=None) -> np.ndarray:
        """x with K x = b (``transpose``: K^T x = b); b (n,) or (n, k).

        ``guess``, shaped as b: an estimate of x an iterative backend starts from
        (:attr:`takes_guess`); the result is checked and refined as any other, so the
        guess decides the cost, not the accuracy. A direct backend ignores it."""
        b = np.asarray(b, dtype=float)
        if transpose and not self._transposable:
            if self._transpose_factor is None:
                raise InputError("this factorisation has no transposed solve (K^T x = b), which "
                                 "the adjoint needs: use solver 'pardiso' or 'superlu', or return a "
                                 "signorini.linsolve.Factor with transposable=True or "
                                 "transpose_factor=")
            if self._transposed is None:
                self._transposed = self._transpose_factor()
            x = self._transposed.solve(b)
            self.backward_error = self._transposed.backward_error
            self.relative_residual = self._transposed.relative_residual
            return x
        x = self._solve_refined(b, transpose, None if transpose else guess)
        if self.backward_error > self.refine_tol and self._refactor is not None:
            self._solve, self._refactor = self._refactor(), None
            x = self._solve_refined(b, transpose)
        return x

    @property
    def takes_guess(self) -> bool:
        """Whether :meth:`solve` starts from a ``guess`` (an iterative backend)."""
        return self._solve_from is not None

    @property
    def inexact(self) -> bool:
        """Whether :meth:`solve_to` costs less at a looser tolerance (an iterative backend)."""
        return self._solve_to is not None

    def solve_to(self, b: np.ndarray, rtol: float) -> np.ndarray:
        """x with ||K x - b|| <= rtol ||b|| (b one vector): the inexact solve of a
        Newton correction (docs/theory.md §12.7). A direct factorisation solves to
        round-off as :meth:`solve` does; an iterative backend stops at ``rtol``, and
        the solve is neither checked for its backward error nor refined."""
        if self._solve_to is None:
            return self.solve(b)
        b = np.asarray(b, dtype=float)
        x = self._solve_to(b, rtol)
        if not np.all(np.isfinite(x)):
            raise SingularTangentError("the linear solve returned non-finite values (singular tangent)")
        r = _residual(self.K, x, b)
        self.relative_residual = float(np.linalg.norm(r) / max(np.linalg.norm(b), 1e-300))
        self.backward_error = self.relative_residual  # not the row-wise one: not checked
        return x

    def _solve_refined(self, b: np.ndarray, transpose: bool = False, guess=None) -> np.ndarray:
        K = self.K.T if transpose else self.K
        step = (lambda v: self._solve(v, True)) if transpose else self._solve
        if guess is not None and self._solve_from is not None:
            x = self._solve_from(b, np.asarray(guess, dtype=float).reshape(b.shape))
        else:
            x = step(b)
        if not np.all(np.isfinite(x)):
            raise SingularTangentError("the linear solve returned non-finite values (singular tangent)")
        res = self._residual_of

        def residual(x):
            r = None if res is None else res(x, b, transpose)
            return _residual(K, x, b) if r is None else r

        r = residual(x)
        eta = self._backward_error(r, x, b, transpose)
        for _ in range(REFINE_STEPS):
            if eta <= self.refine_tol:
                break
            x_new = x + step(r)
            self.refinements += 1
            r_new = residual(x_new)
            eta_new = self._backward_error(r_new, x_new, b, transpose)
            if eta_new < eta:
                x, r = x_new, r_new
            stalled = not eta_new < 0.5 * eta
            eta = min(eta, eta_new)
            if stalled:
                break
        self.backward_error = eta
        r2, b2 = r.reshape(r.shape[0], -1), b.reshape(b.shape[0], -1)
        nr = np.array([np.dot(r2[:, j], r2[:, j]) for j in range(r2.shape[1])])
        nb = np.array([np.dot(b2[:, j], b2[:, j]) for j in range(b2.shape[1])])
        self.relative_residual = float(np.sqrt(np.max(nr / np.maximum(nb, 1e-300))))
        return x

    def refined_for(self, K: sp.spmatrix) -> "Factor":
        """This factorisation used for a nearby matrix K: solves of K by iterative
        refinement (this factor as the preconditioner), checked by K's backward error."""
        def transposed():
            base = self._transposed if self._transposed is not None else self._transpose_factor()
            return base.refined_for(K.T.tocsr())
        keep = not self._transposable and self._transpose_factor is not None
        return Factor(self._solve, K, transpose_factor=transposed if keep else None,
                      transposable=self._transposable)


def diagonal(K) -> np.ndarray:
    """The diagonal of K: a ``take`` of the positions an assembled tangent carries
    (``SparsityPattern.assemble`` sets ``K.diagonal_positions``), else SciPy's."""
    pos = getattr(K, "diagonal_positions", None)
    if pos is not None and getattr(K, "format", None) == "csr" and pos.size == K.shape[0] \
            and pos.size and int(pos[-1]) < K.data.size:
        return K.data.take(pos)
    return K.diagonal()


def _residual(K, x, b):
    """b - K x, column by column for several right-hand sides (SciPy's one-vector
    product, repeated, is faster than its several-vector one on a few columns)."""
    if x.ndim == 1:
        return b - K @ x
    r = np.empty_like(b, dtype=float)
    for j in range(x.shape[1]):
        r[:, j] = b[:, j] - K @ x[:, j]
    return r
