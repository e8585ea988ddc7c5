"""Intel MKL loaded from the ``mkl`` wheel that ``pypardiso`` brings: the
library handle, its thread count, and its sparse matrix-vector product
(used to check PARDISO's solves)."""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os

import numpy as np
import scipy.sparse as sp

import glob
import re
import site
import sys
from ..errors import InputError

log = logging.getLogger("signorini")


def _mkl_rt_path() -> str | None:
    """MKL's runtime library where pip installs it (``PYPARDISO_MKL_RT`` if set,
    else the ``lib`` folder of this environment or of the user site; the newest
    version if several), or None.

    A direct look is a few globs of known folders; importing pypardiso and letting
    it search (``find_library`` runs ``ldconfig``, then a recursive glob of the
    environment) is a large part of every CLI start (docs/theory.md §10.5)."""
    env = os.environ.get("PYPARDISO_MKL_RT")
    if env:
        return env

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
    # short enough not to hold a core during the JAX kernels that follow (MKL's
    # default, 200 ms, spins through them and takes a core from them). 0 would put
    # the threads to sleep after every call, and on small meshes waking them costs
    # more than the work; on large meshes the value hardly matters (docs/theory.md
    # §10.1). A value the user set is kept; read when MKL is loaded.
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
            import pypardiso  # optional: brings MKL on x86-64 only
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

    It runs on MKL's OpenMP threads, like PARDISO, where SciPy's product runs on
    one thread, and takes several columns in one call. The handle refers to A's
    arrays without copying them; it is made on the first product (cheap next to
    the product) and destroyed with this object.
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


_BLAS = None


@contextlib.contextmanager
def openblas_single_thread():
    """NumPy's and SciPy's OpenBLAS on one thread for the duration.

    Their idle threads spin after every BLAS call (even a vector norm) and take
    cores from the PARDISO factorisation that follows, slowing it down where the
    cores are few (docs/theory.md §10.1). signorini's own BLAS work is vectors
    only, so one thread costs nothing."""
    global _BLAS
    try:
        from threadpoolctl import ThreadpoolController  # optional at run time: tolerated if absent
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
