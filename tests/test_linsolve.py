"""The linear-solver interface: every available backend gives the same Newton
solution and DDM sensitivities, on symmetric (frictionless) and unsymmetric
(friction) tangents."""

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini.linsolve import SOLVERS, get_solver
from signorini.problems import hertz



def _usable(name):
    try:
        get_solver(name)
        return True
    except sg.InputError:  # optional backend not installed (or its library not loadable)
        return False


AVAILABLE = [n for n in ("superlu", "pardiso", "umfpack") if _usable(n)]


@pytest.mark.parametrize("name", AVAILABLE)
def test_factorisation_solves_unsymmetric_multi_rhs(name):
    rng = np.random.default_rng(0)
    A = sp.random(60, 60, density=0.1, random_state=1) + sp.eye(60) * 5.0  # unsymmetric
    B = rng.normal(size=(60, 3))
    X = get_solver(name).factorize(A.tocsr()).solve(B)
    assert np.allclose(A @ X, B, atol=1e-12)


@pytest.mark.parametrize("name", [n for n in AVAILABLE if n != "superlu"])
def test_optional_solver_matches_superlu_in_hertz(name):
    pb = hertz.hertz_problem(n_fine=8, size=8)
    a = sg.solve(pb, sensitivities=["R"])
    b = sg.solve(pb, sensitivities=["R"], solver=name)
    assert np.allclose(a.increments[-1].w, b.increments[-1].w, rtol=0, atol=1e-10)
    ra, rb = a.w_sensitivity("R"), b.w_sensitivity("R")
    assert np.max(np.abs(ra - rb)) <= 1e-8 * np.max(np.abs(ra))


def test_singular_matrix_is_reported():
    A = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    with pytest.raises(sg.SingularTangentError):
        get_solver("superlu").factorize(A)


def test_solver_names():
    assert set(SOLVERS) == {"superlu", "umfpack", "pardiso"}
    with pytest.raises(sg.InputError, match="unknown linear solver"):
        get_solver("mumps")
