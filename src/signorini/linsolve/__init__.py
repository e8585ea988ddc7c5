"""Linear solvers behind one small interface.

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
* ``amg`` -- iterative: flexible GMRES preconditioned by algebraic multigrid
  (pyamg's hierarchy, Chebyshev-smoothed V-cycles on all the cores,
  :mod:`signorini.linsolve.multigrid`) on the displacements, the contact
  multipliers condensed node by node (:mod:`signorini.linsolve.iterative`), for
  large 3-D problems.
* ``petsc``, ``petsc-amg`` -- MUMPS, or ``amg`` with its cycle run by PETSc, over
  MPI ranks (:mod:`signorini.linsolve.petsc`; an optional install, docs/parallel.md).
* ``auto`` (the default) -- the fastest direct one installed: pardiso, else superlu.
"""

from .base import LinearSolver
from .factor import REFINE_STEPS, REFINE_TOL, Factor, diagonal
from .memory import GB, available_memory, check_size, estimated_peak_memory
from .mkl import mkl_max_threads, mkl_threads, openblas_single_thread
from .pardiso import Pardiso
from .iterative import AMGKrylov
from .multigrid import product_threads
from .petsc import PetscAMG, PetscSolver
from .select import (
    AUTO_ORDER, SOLVERS, SYMMETRY_TOL, TangentSolver, available, blocks_symmetric, for_model,
    get_solver, is_symmetric)
from .superlu import SuperLU
from .umfpack import Umfpack

__all__ = [
    "AMGKrylov", "AUTO_ORDER", "GB", "REFINE_STEPS", "REFINE_TOL", "SOLVERS", "SYMMETRY_TOL", "Factor",
    "LinearSolver", "Pardiso", "PetscAMG", "PetscSolver", "SuperLU", "TangentSolver", "Umfpack", "available",
    "available_memory", "blocks_symmetric", "check_size", "diagonal", "estimated_peak_memory",
    "for_model", "get_solver", "is_symmetric", "mkl_max_threads", "mkl_threads", "openblas_single_thread",
    "product_threads",
]
