"""The linear-solver interface: every available backend gives the same Newton
solution and DDM sensitivities, on symmetric (frictionless) and unsymmetric
(friction) tangents."""

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini.linsolve import SOLVERS, get_solver
from signorini.problems import hertz



def _why_not(name):
    """None if the backend can be used, else the reason (its own import message)."""
    try:
        get_solver(name)
        return None
    except sg.InputError as e:  # optional backend not installed (or its library not loadable)
        return str(e)


AVAILABLE = [n for n in ("superlu", "pardiso", "umfpack") if _why_not(n) is None]
OPTIONAL = ("pardiso", "umfpack")


@pytest.mark.parametrize("name", AVAILABLE)
def test_factorisation_solves_unsymmetric_multi_rhs(name):
    rng = np.random.default_rng(0)
    A = sp.random(60, 60, density=0.1, random_state=1) + sp.eye(60) * 5.0  # unsymmetric
    B = rng.normal(size=(60, 3))
    X = get_solver(name).factorize(A.tocsr()).solve(B)
    assert np.allclose(A @ X, B, atol=1e-12)


@pytest.mark.parametrize("name", OPTIONAL)
def test_optional_solver_matches_superlu_in_hertz(name):
    """Runs for every optional backend that is installed; for one that is not, the
    skip reason says which package to install (the default install has SuperLU only)."""
    reason = _why_not(name)
    if reason is not None:
        pytest.skip(f"optional solver {name!r} is not installed on this machine: {reason}")
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
