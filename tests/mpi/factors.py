"""Factorise one tangent ten times with solver="petsc", each factor dropped as the
next is made (as Newton does), and print the peak resident memory of this process
after each, in GB, one line per rank (tests/mpi/test_petsc_mpi.py)."""

import resource
import sys

import numpy as np
import scipy.sparse as sp

from signorini.linsolve.petsc import PetscSolver


def main() -> None:
    n = 30  # a 7-point operator on a 30^3 grid: 27,000 unknowns, MUMPS's factors ~75 MB
    one = sp.identity(n)
    t = sp.diags([-1.0, 2.2, -1.1], [-1, 0, 1], shape=(n, n))
    K = (sp.kron(sp.kron(t, one), one) + sp.kron(sp.kron(one, t), one)
         + sp.kron(sp.kron(one, one), t)).tocsr()
    solver = PetscSolver()
    kb = 1024.0 if sys.platform != "darwin" else 1.0  # ru_maxrss: kB on Linux, bytes on macOS
    rss = []
    factor = None
    for _ in range(10):
        factor = solver.factorize(K)
        x = factor.solve(np.ones(K.shape[0]))
        assert np.allclose(K @ x, 1.0)
        rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * kb / 2**30)
    print(solver.rank, " ".join(f"{r:.4f}" for r in rss), flush=True)


if __name__ == "__main__":
    main()
