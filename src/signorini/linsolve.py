"""Direct linear solvers behind one small interface.

``factorize(K)`` returns an object with ``solve(b)`` (b of shape (n,) or
(n, k)); the same factorisation serves Newton and all DDM right-hand sides.
Matrices may be unsymmetric (friction). SciPy's SuperLU is the embedded
default; UMFPACK (``scikit-umfpack``) and PARDISO (``pypardiso``) are used
when installed and asked for.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import InputError, SingularTangentError


class _Factor:
    def __init__(self, solve, n):
        self._solve = solve
        self.n = n

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._solve(b)
        if not np.all(np.isfinite(x)):
            raise SingularTangentError("the linear solve returned non-finite values (singular tangent)")
        return x


class SuperLU:
    """SciPy's SuperLU with COLAMD ordering (the default)."""

    name = "superlu"

    def __init__(self, permc_spec: str = "COLAMD"):
        self.permc_spec = permc_spec

    def factorize(self, K: sp.spmatrix) -> _Factor:
        try:
            lu = spla.splu(K.tocsc(), permc_spec=self.permc_spec)
        except RuntimeError as e:  # "Factor is exactly singular"
            raise SingularTangentError(f"SuperLU could not factorise the tangent: {e}") from None
        return _Factor(lu.solve, K.shape[0])


class Umfpack:
    """UMFPACK through scikit-umfpack (optional)."""

    name = "umfpack"

    def __init__(self):
        try:
            import scikits.umfpack  # noqa: F401
        except (ImportError, OSError) as e:
            raise InputError(f"solver 'umfpack' needs `pip install scikit-umfpack` (import failed: {e})") from None

    def factorize(self, K):
        import scikits.umfpack as um

        try:
            lu = um.splu(K.tocsc())
        except Exception as e:  # noqa: BLE001 - umfpack raises generic errors
            raise SingularTangentError(f"UMFPACK could not factorise the tangent: {e}") from None
        return _Factor(lambda b: np.column_stack([lu.solve(c) for c in b.T]) if b.ndim == 2
                       else lu.solve(b), K.shape[0])


class Pardiso:
    """Intel MKL PARDISO through pypardiso (optional).

    One MKL solver handle per ``Pardiso`` object: each ``factorize`` releases the
    previous factorisation's memory first (a new handle per call leaked the MKL
    workspace: 24 GB after one 225k-DOF solve). A factor is therefore valid until
    the next ``factorize`` of the same object, which is how Newton and the DDM
    use it.
    """

    name = "pardiso"

    def __init__(self):
        try:
            import pypardiso
        except (ImportError, OSError) as e:  # OSError: MKL's shared library not found
            raise InputError(f"solver 'pardiso' needs `pip install pypardiso` (import failed: {e})") from None
        self._solver = pypardiso.PyPardisoSolver()  # mtype 11: real unsymmetric
        self._generation = 0

    def factorize(self, K):
        solver = self._solver
        if self._generation:
            solver.free_memory(everything=False)
        A = K.tocsr()
        A.sort_indices()
        try:
            solver.factorize(A)
        except Exception as e:  # noqa: BLE001
            raise SingularTangentError(f"PARDISO could not factorise the tangent: {e}") from None
        self._generation += 1
        generation = self._generation

        def solve(b):
            if generation != self._generation:
                raise InputError("this PARDISO factorisation was replaced by a newer one")
            return solver.solve(A, np.asarray(b))

        return _Factor(solve, K.shape[0])

    def __del__(self):
        try:
            if self._generation:
                self._solver.free_memory(everything=True)
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


SOLVERS = {"superlu": SuperLU, "umfpack": Umfpack, "pardiso": Pardiso}


def get_solver(name_or_solver="superlu"):
    """A solver instance from its name (``superlu``, ``umfpack``, ``pardiso``)."""
    if not isinstance(name_or_solver, str):
        if not callable(getattr(name_or_solver, "factorize", None)):
            raise InputError(f"solver must be one of {sorted(SOLVERS)} or an object with a "
                             f"factorize(K) method, got {name_or_solver!r}")
        return name_or_solver
    try:
        return SOLVERS[name_or_solver]()
    except KeyError:
        raise InputError(f"unknown linear solver {name_or_solver!r}; choose from {sorted(SOLVERS)}") from None
