"""SciPy's SuperLU: present everywhere, the fallback."""

from __future__ import annotations

import numpy as np

import logging

from ..errors import SingularTangentError

log = logging.getLogger("signorini")

from .base import LinearSolver
from .factor import Factor


class SuperLU(LinearSolver):
    """SciPy's SuperLU (the fallback present everywhere).

    Unsymmetric tangents: COLAMD ordering and partial pivoting; symmetric ones:
    minimum degree on A + A^T with diagonal pivoting preferred (SuperLU's
    symmetric mode), the faster ordering for the symmetric saddle-point tangents
    of frictionless contact.
    """

    name = "superlu"

    def factorize(self, K, symmetric=False):
        # scipy.sparse.linalg and the scipy.linalg it loads take 77 ms to import, which
        # a run by PARDISO need not wait for
        import scipy.sparse.linalg as spla  # noqa: PLC0415  (lazy: only where SuperLU runs)
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
        # the elimination's operations: column j of L times row j of U, outer products
        col = np.diff(lu.L.indptr) - 1
        row = np.bincount(lu.U.indices, minlength=A.shape[0]) - 1
        f.flops = float(2 * np.dot(col.astype(float), row.astype(float)) + col.sum())
        return f
