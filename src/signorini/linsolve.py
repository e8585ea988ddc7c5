"""Direct linear solvers behind one small interface.

``get_solver(name).factorize(K, symmetric=...)`` returns a factor with
``solve(b)`` (b of shape (n,) or (n, k)); the same factorisation serves Newton
and all DDM right-hand sides. Every solve is checked against K (one sparse
product) and refined by a few back-substitutions if its row-wise backward error is
above ``REFINE_TOL``, so a solver's pivot perturbation never reaches Newton or
the sensitivities.

Backends (``solver=`` of :func:`signorini.solve`, ``--solver`` of the CLI):

* ``pardiso`` -- Intel MKL PARDISO (the library comes with ``pypardiso``, a
  dependency on x86-64). Our own driver: the fill-reducing ordering and
  symbolic factorisation (phase 11) are done once per sparsity pattern and kept;
  each Newton iteration does only the numeric factorisation (phase 22).
  Symmetric tangents (frictionless contact, hyperelastic bodies) use the
  symmetric indefinite factorisation (upper triangle, Bunch-Kaufman pivoting),
  unsymmetric ones (friction, plasticity) the general LU.
* ``superlu`` -- SciPy's SuperLU, present everywhere: the fallback. SciPy does
  not expose a reusable symbolic factorisation; symmetric tangents use the
  symmetric-mode ordering of A + A^T.
* ``umfpack`` -- through ``scikit-umfpack``, if installed.
* ``auto`` (the default) -- the fastest one installed: pardiso, else superlu.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import time
from collections import OrderedDict, deque

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._memo import ObjectMemo
from .errors import InputError, SingularTangentError

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
                 transposable: bool = False, residual=None):
        self._solve = solve
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

    def row_scale(self) -> None:
        """Compute now the row scale the check of a solve will use (it is kept)."""
        self._row_scale(False, False)

    def _row_scale(self, transpose: bool, exact: bool) -> np.ndarray:
        """max_j |K_ij| of every row (of K^T: every column), or with ``exact=False``
        a lower bound that costs a quarter: |K_ii|, and the exact maximum only in
        the rows whose diagonal is zero (the multipliers of closed contact nodes).
        A lower bound overstates the backward error, so it can only ask for the
        exact value, never hide a residual (1.0 against 0.09 ms at 56k DOFs)."""
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
            # short last axis are slow (3 columns at 225k DOFs: 7.2 -> 0.8 ms)
            return max((self._backward_error(r[:, j], x[:, j], b[:, j], transpose)
                        for j in range(x.shape[1])), default=0.0)
        # two scratch vectors kept for every column and solve of this factor: no fresh
        # temporaries, which page-fault whenever the C library has given freed memory
        # back (one column at 56k DOFs then cost 0.48 ms, 300 page faults, against
        # 0.09 ms; in the DDM's solve they did not fault: three columns 0.4-0.5 ms
        # either way)
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
            if eta <= REFINE_TOL:
                break
        return eta

    def solve(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        """x with K x = b (``transpose``: K^T x = b); b (n,) or (n, k)."""
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
        x = self._solve_refined(b, transpose)
        if self.backward_error > REFINE_TOL and self._refactor is not None:
            self._solve, self._refactor = self._refactor(), None
            x = self._solve_refined(b, transpose)
        return x

    def _solve_refined(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        K = self.K.T if transpose else self.K
        step = (lambda v: self._solve(v, True)) if transpose else self._solve
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
            if eta <= REFINE_TOL:
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
    product is faster than its several-vector one: 6 against 8 ms for 3 columns
    at 225k DOFs)."""
    if x.ndim == 1:
        return b - K @ x
    r = np.empty_like(b, dtype=float)
    for j in range(x.shape[1]):
        r[:, j] = b[:, j] - K @ x[:, j]
    return r


class _MatrixDescr(ctypes.Structure):
    """MKL's ``struct matrix_descr``: type, fill mode, diagonal type."""
    _fields_ = [("type", ctypes.c_int), ("mode", ctypes.c_int), ("diag", ctypes.c_int)]


def _sparse_blas(lib):
    """MKL's sparse BLAS entry points (inspector-executor API), typed once."""
    if not hasattr(lib, "_signorini_sparse"):
        vp, i32, d = ctypes.c_void_p, ctypes.c_int32, ctypes.c_double
        create = lib.mkl_sparse_d_create_csr
        create.argtypes = [ctypes.POINTER(vp), ctypes.c_int, i32, i32, vp, vp, vp, vp]
        mv = lib.mkl_sparse_d_mv
        mv.argtypes = [ctypes.c_int, d, vp, _MatrixDescr, vp, d, vp]
        mm = lib.mkl_sparse_d_mm
        mm.argtypes = [ctypes.c_int, d, vp, _MatrixDescr, ctypes.c_int, vp, i32, i32, d, vp, i32]
        destroy = lib.mkl_sparse_destroy
        destroy.argtypes = [vp]
        for f in (create, mv, mm, destroy):
            f.restype = ctypes.c_int  # sparse_status_t, 0 = success
        lib._signorini_sparse = (create, mv, mm, destroy)
    return lib._signorini_sparse


class _MklProduct:
    """b - A x (``transpose``: b - A^T x) by MKL's sparse BLAS, for the check of a
    PARDISO solve.

    It runs on MKL's OpenMP threads, like PARDISO: on two cores 2.5x SciPy's
    one-thread product (3 columns at 56k DOFs: 0.37 against 1.03 ms; one column
    0.14 against 0.34 ms). The handle refers to A's arrays without copying them;
    it is made on the first product (0.02 ms) and destroyed with this object.
    Returns None where it cannot serve (64-bit indices, an MKL without the
    routines, a failed call): the caller then uses SciPy's product."""

    _GENERAL = _MatrixDescr(20, 40, 50)  # general matrix (fill mode, diagonal unused)

    def __init__(self, lib, A: sp.csr_matrix):
        self._lib, self._h, self._n = lib, None, A.shape[0]
        # the arrays themselves: the handle points into them, whatever becomes of A
        self._arrays = (A.indptr, A.indices, A.data)
        self.ok = (A.shape[0] == A.shape[1] and A.indptr.dtype == np.int32
                   and A.indices.dtype == np.int32 and A.data.dtype == np.float64
                   and A.data.flags.c_contiguous and A.indices.flags.c_contiguous
                   and A.indptr.flags.c_contiguous)

    def _handle(self):
        """MKL's handle of the matrix, made on first use; None once a call failed."""
        if not self.ok:
            return None
        if self._h is None:
            try:
                create = _sparse_blas(self._lib)[0]
            except AttributeError:  # an MKL without the inspector-executor API
                self.ok = False
                return None
            (indptr, indices, data), h, n = self._arrays, ctypes.c_void_p(), self._n
            if create(ctypes.byref(h), 0, n, n, indptr.ctypes.data, indptr.ctypes.data + 4,
                      indices.ctypes.data, data.ctypes.data) != 0:
                self.ok = False
                return None
            self._h = h
        return self._h

    def __call__(self, x, b, transpose=False):
        if x.ndim == 2 and x.shape[1] == 0:
            return np.array(b, dtype=float, order="F")
        h = self._handle()
        if h is None:
            return None
        _, mv, mm, _ = _sparse_blas(self._lib)
        op = 11 if transpose else 10  # SPARSE_OPERATION_TRANSPOSE / _NON_TRANSPOSE
        n = self._n
        if x.ndim == 1:
            x = np.ascontiguousarray(x, dtype=float)
            r = np.array(b, dtype=float, order="C")
            status = mv(op, -1.0, h, self._GENERAL, x.ctypes.data, 1.0, r.ctypes.data)
        else:  # columns contiguous (PARDISO's layout): SPARSE_LAYOUT_COLUMN_MAJOR
            x = np.asfortranarray(x, dtype=float)
            r = np.array(b, dtype=float, order="F")
            status = mm(op, -1.0, h, self._GENERAL, 102, x.ctypes.data, x.shape[1], n, 1.0,
                        r.ctypes.data, n)
        if status != 0:
            self.ok = False
            return None
        return r

    def __del__(self):
        if self._h is not None:
            try:
                _sparse_blas(self._lib)[3](self._h)
            except Exception:  # noqa: BLE001 - interpreter shutdown
                pass
            self._h = None


class LinearSolver:
    """Base class: ``factorize(K, symmetric=False) -> Factor``."""

    name = "?"

    def factorize(self, K: sp.spmatrix, symmetric: bool = False) -> Factor:
        raise NotImplementedError

    def describe(self) -> str:
        return self.name


class SuperLU(LinearSolver):
    """SciPy's SuperLU (the fallback present everywhere).

    Unsymmetric tangents: COLAMD ordering and partial pivoting; symmetric ones:
    minimum degree on A + A^T with diagonal pivoting preferred (SuperLU's
    symmetric mode), measured faster on our saddle-point tangents.
    """

    name = "superlu"

    def factorize(self, K, symmetric=False):
        A = K.tocsc()
        try:
            if symmetric:
                lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                               options={"SymmetricMode": True})
            else:
                lu = spla.splu(A, permc_spec="COLAMD")
        except RuntimeError as e:  # "Factor is exactly singular"
            raise SingularTangentError(f"SuperLU could not factorise the tangent: {e}") from None
        f = Factor(lambda b, transpose=False: lu.solve(b, trans="T" if transpose else "N"), K,
                   transposable=True)
        f.nbytes = 12 * (lu.L.nnz + lu.U.nnz) + 8 * A.shape[0]  # values + row indices, permutations
        return f


class Umfpack(LinearSolver):
    """UMFPACK through scikit-umfpack (optional)."""

    name = "umfpack"

    def __init__(self):
        try:
            import scikits.umfpack  # noqa: F401
        except (ImportError, OSError) as e:
            raise InputError(f"solver 'umfpack' is not installed: `pip install scikit-umfpack` "
                             f"(import failed: {e})") from None

    def factorize(self, K, symmetric=False):
        import scikits.umfpack as um

        try:
            lu = um.splu(K.tocsc())
        except Exception as e:  # noqa: BLE001 - umfpack raises generic errors
            raise SingularTangentError(f"UMFPACK could not factorise the tangent: {e}") from None
        def solve(b):
            return np.column_stack([lu.solve(c) for c in b.T]) if b.ndim == 2 else lu.solve(b)
        return Factor(solve, K, transpose_factor=lambda: self.factorize(K.T.tocsr()))


def _mkl_rt_path() -> str | None:
    """MKL's runtime library where pip installs it (``PYPARDISO_MKL_RT`` if set,
    else the ``lib`` folder of this environment or of the user site; the newest
    version if several), or None.

    A direct look costs under a millisecond; importing pypardiso and letting it
    search (``find_library`` runs ``ldconfig``, then a recursive glob of the
    environment) cost 0.7 s of every CLI start (0.43 s import, 0.26 s search)."""
    env = os.environ.get("PYPARDISO_MKL_RT")
    if env:
        return env
    import glob
    import re
    import site
    import sys

    def version(path):  # libmkl_rt.so.2 -> (2,): the newest of several installed
        return tuple(int(v) for v in re.findall(r"\d+", os.path.basename(path)))

    for base in (sys.prefix, site.USER_BASE):
        for pattern in ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll"):
            hits = glob.glob(os.path.join(base, pattern))
            if hits:
                return max(hits, key=version)
    return None


def _load_mkl():
    """The ``pardiso`` entry point of MKL's runtime library (:func:`_mkl_rt_path`,
    else found by pypardiso)."""
    # MKL's OpenMP threads wait this long (ms) for more work after a PARDISO call:
    # long enough to span the gap between a factorisation and its back-substitution,
    # short enough not to hold a core during the JAX kernels that follow (the default,
    # 200 ms, spread the solves at 5k DOFs over 0.064-0.20 s). 0 put the threads to
    # sleep after every call: at 5k DOFs a back-substitution then took 0.57 instead
    # of 0.20 ms and a factorisation 2.0 instead of 1.7 ms (the frictional Hertz, 10
    # increments: 0.56 -> 0.50 s; no change at 56k). A value the user set is kept;
    # read when MKL is loaded.
    os.environ.setdefault("KMP_BLOCKTIME", "1")
    lib = None
    path = _mkl_rt_path()
    if path is not None:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            lib = None
    if lib is None:  # elsewhere: pypardiso's own search
        try:
            import pypardiso
            lib = pypardiso.PyPardisoSolver().libmkl
        except (ImportError, OSError) as e:  # OSError: MKL's shared library not found
            raise InputError(f"solver 'pardiso' is not installed: `python3 -m pip install pypardiso` "
                             f"(x86-64 only; it brings Intel MKL) (import failed: {e})") from None
    f = lib.pardiso
    i32 = ctypes.POINTER(ctypes.c_int32)
    vp = ctypes.c_void_p
    f.argtypes = [ctypes.POINTER(ctypes.c_int64), i32, i32, i32, i32, i32, vp, vp, vp, vp, i32,
                  i32, i32, vp, vp, i32]
    f.restype = None
    f.lib = lib
    return f


_MKL = None

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


_BLAS = None


@contextlib.contextmanager
def openblas_single_thread():
    """NumPy's and SciPy's OpenBLAS on one thread for the duration.

    Their idle threads spin after every BLAS call (even a vector norm) and took
    one of two cores from the PARDISO factorisation that followed: measured 0.085
    s instead of 0.043 s per numeric factorisation at 56k DOFs. signorini's own
    BLAS work is vectors only, so one thread costs nothing."""
    global _BLAS
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a dependency; tolerate its absence
        yield
        return
    if _BLAS is None:
        _BLAS = ThreadpoolController()
    with _BLAS.select(internal_api="openblas").limit(limits=1):
        yield


def _mkl():
    global _MKL
    if _MKL is None:
        _MKL = _load_mkl()
    return _MKL


@contextlib.contextmanager
def mkl_threads(n: int):
    """Run PARDISO with ``n`` OpenMP threads for the duration (no-op without MKL).

    MKL's results are bitwise reproducible only for a fixed thread count; the
    sweep runs every point with one thread, in worker processes and in the
    sequential mode alike, so both give the same bits."""
    try:
        lib = _mkl().lib
    except InputError:
        yield
        return
    old = int(lib.MKL_Get_Max_Threads())
    lib.MKL_Set_Num_Threads(ctypes.c_int(int(n)))
    try:
        yield
    finally:
        lib.MKL_Set_Num_Threads(ctypes.c_int(old))


def mkl_max_threads(f) -> int:
    """The number of OpenMP threads MKL's PARDISO would use now (``f``: :func:`_mkl`'s
    entry point): its domain's count follows ``MKL_Set_Num_Threads``, threadpoolctl's
    limits and a limit of the PARDISO domain alone (MKL_DOMAIN_PARDISO = 4), which
    ``MKL_Get_Max_Threads`` does not see."""
    lib = f.lib
    try:
        return int(lib.MKL_Domain_Get_Max_Threads(ctypes.c_int(4)))
    except AttributeError:  # an MKL without domains
        return int(lib.MKL_Get_Max_Threads())


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
        columns one by one if k single solves would now beat the block. Which is
        faster depends on the machine's state, not on the factor: on the 2-core
        test machine, at 56k DOFs, for the same factor, three columns took
        7.4-7.9 ms as a block and 4.0-4.5 ms each alone in some processes,
        10.4-11.3 ms and 2.9-3.3 ms in others (theory §10.2). Both give the same
        solution to round-off, and every solve is checked (:class:`Factor`)."""
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
        ip[12] = 1  # weighted matching (needed for the zero diagonal of active multipliers)
        ip[17] = -1  # report the factor's non-zeros
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
        (comparing them cost 0.15 ms per factorisation at 56k DOFs)."""
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
        # SciPy's own test of an unknown matrix costs 0.26 ms at 56k DOFs
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
            # one column, which no single active set suits (measured: as many perturbed
            # pivots, ~50 per factorisation on the frictional Hertz at 60k, either way)
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
            # does not, analyse these values afresh (docs/theory.md §10).
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
        # the check's row scale now, while K's values are in cache (the upper triangle
        # was just taken from them): after the factorisation, which streams the factor
        # through the cache, it cost 0.30-0.34 instead of 0.24 ms at 56k DOFs
        factor.row_scale()
        h.a = a
        h.call(22, a)
        self.factorizations += 1
        self.perturbed_pivots += int(h.iparm[13])
        h.generation += 1
        factor.owner = self  # keeps this solver, and so its PARDISO handles, alive
        factor.nbytes = 8 * abs(int(h.iparm[17]))  # iparm(18): non-zeros of the factors
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


SOLVERS = {"superlu": SuperLU, "umfpack": Umfpack, "pardiso": Pardiso}

#: the order in which ``auto`` tries the backends (fastest first)
AUTO_ORDER = ("pardiso", "superlu")


class _Foreign(LinearSolver):
    """A user object with ``factorize(K)``: the symmetry flag is not passed on."""

    def __init__(self, obj):
        self._obj = obj
        self.name = getattr(obj, "name", type(obj).__name__)

    def factorize(self, K, symmetric=False):
        f = self._obj.factorize(K)
        if isinstance(f, Factor):
            return f
        return Factor(f.solve, K, transpose_factor=lambda: self.factorize(K.T.tocsr()))


def available() -> list[str]:
    """Names of the backends that can be used on this machine."""
    out = []
    for name, cls in SOLVERS.items():
        try:
            cls()
            out.append(name)
        except InputError:
            pass
    return out


def get_solver(name_or_solver="auto") -> LinearSolver:
    """A solver instance from its name (``auto``, ``pardiso``, ``superlu``,
    ``umfpack``) or a user object with a ``factorize(K)`` method.

    ``auto`` picks the fastest backend installed (PARDISO, else SuperLU); a named
    backend that is not installed raises :class:`InputError` saying how to install it.
    """
    if isinstance(name_or_solver, LinearSolver):
        return name_or_solver
    if not isinstance(name_or_solver, str):
        if not callable(getattr(name_or_solver, "factorize", None)):
            raise InputError(f"solver must be 'auto', one of {sorted(SOLVERS)} or an object with a "
                             f"factorize(K) method, got {name_or_solver!r}")
        return _Foreign(name_or_solver)
    if name_or_solver == "auto":
        for name in AUTO_ORDER:
            try:
                return SOLVERS[name]()
            except InputError as e:
                log.debug("auto solver: %s unavailable (%s)", name, e)
        raise AssertionError("SuperLU is always available")
    try:
        cls = SOLVERS[name_or_solver]
    except KeyError:
        raise InputError(f"unknown linear solver {name_or_solver!r}; choose from "
                         f"{['auto'] + sorted(SOLVERS)}") from None
    return cls()


#: ||K - K^T||_max / ||K||_max below which a tangent is taken as symmetric
SYMMETRY_TOL = 1e-12


def is_symmetric(K: sp.spmatrix, tol: float = SYMMETRY_TOL) -> bool:
    """True if K equals its transpose to ``tol`` relative (max norm)."""
    scale = abs(K).max()
    return scale == 0 or abs(K - K.T).max() <= tol * scale


#: (max |b|, max |b - b^T|) of the read-only block arrays tested last, kept while
#: each lives (a kept figure must not keep a model's stiffness alive)
_BLOCK_STATS = ObjectMemo(4)


def _block_stats(b: np.ndarray) -> tuple[float, float]:
    """(max |b|, max |b - b^T|) of a block array (n, k, k). A read-only array (a
    linear body's element stiffness, one per parameter values) cannot change, so
    its figures are kept while it is passed again (4.7 ms per solve at 56k DOFs)."""
    frozen = not b.flags.writeable
    stats = _BLOCK_STATS.get(b) if frozen else None
    if stats is None:
        stats = (float(np.max(np.abs(b))), float(np.max(np.abs(b - np.swapaxes(b, -1, -2)))))
        if frozen:
            _BLOCK_STATS.put(b, stats)
    return stats


def blocks_symmetric(blocks, tol: float = SYMMETRY_TOL) -> bool:
    """True if every local block (n, k, k) equals its transpose to ``tol`` relative
    to the largest entry of all: then so does their assembly, and every square
    submatrix of it on the same rows and columns. A sufficient test (blocks
    whose asymmetries cancel in the sum would say False), a tenth of the cost
    of comparing the assembled K with its transpose (2 ms against 21 ms at 56k
    DOFs)."""
    stats = [_block_stats(np.asarray(b)) for b in blocks if np.size(b)]
    scale = max((m for m, _ in stats), default=0.0)
    return scale == 0 or all(a <= tol * scale for _, a in stats)


class TangentSolver:
    """The solver of one load path: picks the symmetric factorisation once.

    A model without history (no friction, no plasticity) has a symmetric exact
    tangent (the Hessian of its augmented Lagrangian); this is verified on the
    first tangent factorised, and that choice is kept for the whole path.
    """

    def __init__(self, solver: LinearSolver, symmetric_candidate: bool, analysis=None):
        self.solver = solver
        self._candidate = symmetric_candidate
        self.symmetric: bool | None = None
        self._analysis = analysis  # () -> tangent to analyse the pattern with (PARDISO)

    def factorize(self, K: sp.spmatrix, blocks=None) -> Factor:
        """Factorise K; ``blocks`` (the local blocks K was assembled from), if
        given, let the first call decide symmetry on them (:func:`blocks_symmetric`)."""
        if self.symmetric is None:
            self.symmetric = bool(self._candidate and (
                (blocks is not None and blocks_symmetric(blocks)) or is_symmetric(K)))
            log.debug("tangent factorised as %s by %s",
                      "symmetric" if self.symmetric else "unsymmetric", self.solver.describe())
        if self._analysis is not None and isinstance(self.solver, Pardiso):
            return self.solver.factorize(K, symmetric=self.symmetric, analysis=self._analysis)
        return self.solver.factorize(K, symmetric=self.symmetric)
