"""Tangents solved on a kept factorisation (docs/theory.md §10.8).

Newton's tangents within an increment, and from one increment to the next,
differ mostly in the rows of the contact nodes that close, open, stick or
slip. A change of k rows is a rank-k perturbation of the factorised matrix:
GMRES (here its twin GCR) preconditioned by the kept factorisation converges
in at most about k + 1 iterations, each one back-substitution and one
product with K. In 3-D,
where a factorisation costs some fifty back-substitutions, that is cheaper
than factorising again as long as few rows changed; :class:`KeptFactor`
solves so while it pays and factorises afresh when it stops paying:

* a factorisation serves Krylov iterations worth one factorisation in all
  (its budget B); the tangent after that is factorised (reason ``"budget"``),
  and so is one whose solve exceeds what is left of B (reason ``"cap"``);
* B is the factorisation's cost in back-substitutions, estimated from the
  factor itself: its floating-point operations over :data:`FLOPS_PER_ITERATION`
  times its non-zeros (a back-substitution reads every non-zero once; the
  factorisation runs at a higher rate, in dense blocks). Measured with PARDISO
  on two cores: 20, 40 and 63 back-substitutions per factorisation for 3-D
  tangents of 17k, 36k and 67k unknowns (estimates 23, 36, 52), 5.5 for a 2-D
  one of 56k (estimate 6);
* several right-hand sides solved to round-off (the sensitivities) on a
  tangent that differs from the kept one in more rows than what is left of B
  are solved by a fresh factorisation at once (reason ``"rows"``): a change of
  k rows takes up to about k + 1 iterations to resolve to round-off;
* a factor whose B is below :data:`MIN_BUDGET` is not reused (reason
  ``"small"``): 2-D tangents and small 3-D ones, whose factorisation costs
  little more than the Krylov iterations would.

Which tangents are factorised then depends on the matrices only, never on
timings: a run repeats itself iteration for iteration.
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError
from .factor import Factor

log = logging.getLogger("signorini")

#: a factorisation's operations per non-zero of its factor that cost as much as one
#: Krylov iteration (back-substitution and product) on it: measured, PARDISO, 2 cores
FLOPS_PER_ITERATION = 30.0
#: the least budget (Krylov iterations per factorisation) for which a factor is reused
MIN_BUDGET = 12
#: the largest budget
MAX_BUDGET = 400
#: relative residual of a Krylov solve that replaces an exact one (a DDM solve, a
#: Newton correction of a direct solver without a forcing term); the factor's
#: backward-error check then refines it like any other solve
KRYLOV_RTOL = 1e-13
REUSE = ("auto", "always", "never")


class Krylov:
    """Right-preconditioned GCR on one matrix K, its search space kept across
    right-hand sides: the directions z_i (preconditioned residuals) and their
    images c_i = K z_i, orthonormalised. A new right-hand side is first projected
    on the kept images (the error of a nearby factor lies in the few directions
    of the rows that changed, which an earlier solve of the same K has already
    found), then the space grows until the residual is small enough. In exact
    arithmetic each solve is GMRES's (minimal residual over the space).

    ``precondition(v)`` applies the inverse of the kept factor."""

    def __init__(self, K, precondition):
        self.K, self.precondition = K, precondition
        self.Z: list[np.ndarray] = []
        self.C: list[np.ndarray] = []
        self._norm: float | None = None  # ||K||_inf

    def _floor(self, x) -> float:
        """The residual norm below which round-off hides progress: 1e-15 ||K|| ||x||
        (a body held only by its contact has a solution far larger than b / ||K||,
        and ||r|| / ||b|| cannot then go below about that)."""
        if self._norm is None:
            K = self.K
            self._norm = float(np.max(np.add.reduceat(np.abs(K.data), K.indptr[:-1]),
                                      initial=0.0)) if K.nnz else 0.0
        return 1e-15 * self._norm * float(np.abs(x).max(initial=0.0))

    def solve(self, b: np.ndarray, rtol: float, cap: int, exact: bool = True):
        """(x, iterations, converged): ||b - K x|| <= rtol ||b||, or at the round-off
        floor of K's products, once converged, with at most ``cap`` new directions
        The residual is GCR's updated one: an inexact solve (``exact=False``, a
        Newton correction to its forcing term) stops at ``rtol`` only, confirmed by
        the true residual; an exact one also at the round-off floor, and its
        caller's backward-error test checks it."""
        nb = float(np.linalg.norm(b))
        if nb == 0.0:
            return np.zeros_like(b), 0, True
        target = rtol * nb
        x = np.zeros_like(b)
        r = b.copy()
        for z, c in zip(self.Z, self.C):  # the kept space first
            beta = float(np.dot(c, r))
            x += beta * z
            r -= beta * c
        its = 0
        while True:
            nr = float(np.linalg.norm(r))
            if nr <= target or (exact and nr <= self._floor(x)):
                if not exact:  # drift of the updated residual: the true one decides
                    return x, its, float(np.linalg.norm(b - self.K @ x)) <= 2 * target
                return x, its, True
            if its >= cap:
                return x, its, False
            z = self.precondition(r)
            c = self.K @ z
            for _ in range(2):  # twice is enough (Kahan): C stays orthonormal to round-off
                for zi, ci in zip(self.Z, self.C):
                    alpha = float(np.dot(ci, c))
                    c -= alpha * ci
                    z -= alpha * zi
            nc = float(np.linalg.norm(c))
            its += 1
            if not nc > 1e-14 * float(np.linalg.norm(z)) * (self._norm or 1.0):
                return x, its, False  # K z lies in the space already: no progress possible
            c /= nc
            z /= nc
            self.Z.append(z)
            self.C.append(c)
            beta = float(np.dot(c, r))
            x += beta * z
            r -= beta * c


def budget_of(fac: Factor) -> int:
    """The Krylov iterations a factorisation is worth: its operations over
    :data:`FLOPS_PER_ITERATION` times its non-zeros (0 where the backend reports
    neither), at most :data:`MAX_BUDGET`."""
    flops, nbytes = getattr(fac, "flops", None), getattr(fac, "nbytes", None)
    if not flops or not nbytes:
        return 0
    return int(min(MAX_BUDGET, flops / (FLOPS_PER_ITERATION * nbytes / 8)))


class KeptFactor:
    """The factorisations of one load path, each kept to solve the tangents near it.

    Args:
        factorize: ``(K, blocks) -> Factor``, a fresh factorisation.
        reuse: ``"auto"`` (a factor whose budget is at least :data:`MIN_BUDGET`),
            ``"always"`` (every factor, with at least that budget) or ``"never"``
            (every tangent factorised).
        budget: a fixed budget instead of the estimate (:func:`budget_of`).

    Counters (the whole path): :attr:`factorizations`, :attr:`krylov_iterations`,
    :attr:`reasons` (why each factorisation was made: ``"first"``, ``"cap"``,
    ``"budget"``, ``"rows"``, ``"accuracy"``, ``"transpose"``, ``"small"`` for a
    factor too small to reuse, ``"never"``, ``"direct"`` for one asked for).
    """

    def __init__(self, factorize, reuse: str = "auto", budget: int | None = None):
        if reuse not in REUSE:
            raise InputError(f"reuse must be one of {REUSE}, got {reuse!r}")
        self._factorize = factorize
        self.reuse = reuse
        self._fixed = budget
        self.budget = 0  # of the kept factor
        self._kept: Factor | None = None
        self._spent = 0  # Krylov iterations on the kept factor so far
        self.factorizations = 0
        self.krylov_iterations = 0
        self.reasons: list[str] = []

    def _reusable(self, fac: Factor | None) -> str:
        """'' if ``fac`` may precondition the next tangent, else why not."""
        if fac is None:
            return "first"
        if self.reuse == "never":
            return "never"
        if self.budget < MIN_BUDGET and self.reuse == "auto":
            return "small"
        if self._spent >= self.budget:
            return "budget"
        return ""

    def fresh(self, K, blocks=None, reason: str = "first") -> Factor:
        """Factorise K, keep the factor and count it."""
        fac = self._factorize(K, blocks)
        self._kept, self._spent = fac, 0
        self.budget = self._fixed if self._fixed is not None else budget_of(fac)
        if self.reuse == "always":
            self.budget = max(self.budget, MIN_BUDGET)
        self.factorizations += 1
        self.reasons.append(reason)
        return fac

    def factor(self, K, blocks=None) -> Factor:
        """A :class:`Factor` of K: Krylov on the kept factorisation while that pays
        (:class:`Krylov`), else a fresh factorisation (kept)."""
        why = self._reusable(self._kept)
        if why:
            return self.fresh(K, blocks, why)
        return _OnKept(self, self._kept, K, blocks)


class _Solves:
    """What an :class:`_OnKept` factor solves with: GCR on the kept factorisation,
    or the fresh one it fell back to. Held by the factor, never holding it: the
    factor's solve functions are this object's methods, so that a factor (its K,
    its Krylov space) is freed as soon as Newton drops it, not when the cyclic
    garbage collector runs (a factor holding its own bound methods kept every
    iteration's K and space alive: 89k DOFs, 670 MB more at the peak)."""

    def __init__(self, owner: KeptFactor, kept: Factor, K, blocks):
        self.owner, self.kept, self.K, self.blocks = owner, kept, K, blocks
        self.fresh: Factor | None = None
        self.space = Krylov(K, kept._solve)
        self.krylov_iterations = 0

    def fallback(self, reason: str) -> Factor:
        if self.fresh is None:
            log.debug("kept factor: Krylov stopped (%s); factorising the tangent", reason)
            self.fresh = self.owner.fresh(self.K, self.blocks, reason)
        return self.fresh

    def refactor(self):
        return self.fallback("accuracy").solve

    def krylov(self, b, rtol, exact):
        own = self.owner
        cap = max(own.budget - own._spent, 1)
        x, its, ok = self.space.solve(b, rtol, cap, exact)
        log.debug("kept factor: Krylov %s in %d iterations (rtol %.0e, %d kept directions)",
                  "converged" if ok else "stopped", its, rtol, len(self.space.Z))
        own._spent += its
        own.krylov_iterations += its
        self.krylov_iterations += its
        return x if ok else None

    def one(self, b, rtol, transpose=False, exact=True):
        # a fresh factorisation's solves are checked and refined as its own (a raw
        # back-substitution with perturbed pivots can be far from round-off)
        if self.fresh is not None:
            return self.fresh.solve(b, transpose=transpose)
        if transpose:  # the adjoint's: factorised
            return self.fallback("transpose").solve(b, transpose=True)
        x = self.krylov(b, rtol, exact)
        if x is None:
            x = self.fallback("cap").solve(b)
        return x

    def changed_rows(self) -> int:
        """Rows in which K differs from the kept factor's matrix: K is a rank-k
        change of it, solved in at most about k + 1 Krylov iterations."""
        A, B = self.K, self.kept.K
        if (A.shape == B.shape and A.nnz == B.nnz and getattr(B, "format", "") == "csr"
                and (A.indices is B.indices or np.array_equal(A.indices, B.indices))
                and np.array_equal(A.indptr, B.indptr)):
            diff = A.data != B.data
            if not diff.any():
                return 0
            return int(np.count_nonzero(np.logical_or.reduceat(diff, A.indptr[:-1])
                                        & (np.diff(A.indptr) > 0)))
        D = (A - B).tocsr()
        D.eliminate_zeros()
        return int(np.count_nonzero(np.diff(D.indptr)))

    def exact(self, b, transpose=False):
        b = np.asarray(b, dtype=float)
        if b.ndim == 2 and self.fresh is None and not transpose:
            # several right-hand sides solved to round-off (the sensitivities): the
            # space grows by about the rank of the change for the first and by a few
            # for each further one; where that exceeds what is left of the budget, the
            # tangent is factorised at once rather than after the Krylov iterations
            own = self.owner
            if self.changed_rows() + b.shape[1] > own.budget - own._spent:
                self.fallback("rows")
        if b.ndim == 1:
            return self.one(b, KRYLOV_RTOL, transpose)
        return np.column_stack([self.one(np.ascontiguousarray(b[:, j]), KRYLOV_RTOL, transpose)
                                for j in range(b.shape[1])])

    def to(self, b, rtol):
        return self.one(np.asarray(b, dtype=float), rtol, exact=False)


class _OnKept(Factor):
    """K solved by GMRES preconditioned by a kept factorisation of a nearby matrix;
    a solve that exceeds the cap factorises K (through the owner, who keeps it) and
    finishes on that. Inexact: Newton's corrections stop at their forcing term."""

    def __init__(self, owner: KeptFactor, kept: Factor, K, blocks):
        self._solves = st = _Solves(owner, kept, K, blocks)
        super().__init__(st.exact, K, solve_to=st.to, transposable=True, refactor=st.refactor)
        self.refine_tol = kept.refine_tol
        self.nbytes = kept.nbytes

    @property
    def fresh(self) -> Factor | None:
        """The factorisation of K this solve fell back to, if it did."""
        return self._solves.fresh

    @property
    def krylov_iterations(self) -> int:
        """Krylov iterations of this factor's solves."""
        return self._solves.krylov_iterations

    @property
    def inexact(self) -> bool:
        return self._solves.fresh is None


def is_kept_solve(fac) -> bool:
    """Whether ``fac`` solves by Krylov on a kept factor (not a factorisation of its K)."""
    return isinstance(fac, _OnKept) and fac.fresh is None


