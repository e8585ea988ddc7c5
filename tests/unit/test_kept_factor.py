"""Tangents solved by Krylov on a kept factorisation (linsolve.kept): the solves
equal a fresh factorisation's, the refactorisation rule fires where it must,
and Newton with a kept factor converges to the same state and sensitivities
with fewer factorisations."""

import numpy as np
import pytest

import signorini as sg
from signorini.algorithms.newton import NewtonOptions
from signorini.algorithms.stepping import model_for
from signorini.errors import InputError
from signorini.linsolve import get_solver
from signorini.linsolve.kept import (
    MIN_BUDGET,
    KeptFactor,
    Krylov,
    budget_of,
    is_kept_solve,
)
from signorini.problems.hertz3d import hertz3d_problem


@pytest.fixture(scope="module")
def tangents():
    """Free-free tangents of a frictional 3-D Hertz block at rest (one contact node
    closed) and at its converged state (the contact disc closed, stick and slip):
    they differ in the rows of every node that closed."""
    pb = hertz3d_problem({"mu": 0.3}, n_fine=4)
    sol = sg.solve(pb, steps=2)
    m = model_for(pb)
    p = sol.jax_params
    w0 = np.zeros(m.n_dof)
    _, b0 = m.local_tangents(w0, p, 0.5, m.initial_state(w0, p))
    inc = sol.increments[-1]
    _, b1 = m.local_tangents(inc.w, p, inc.t, sol.state_before(len(sol.increments) - 1)[0])
    K0, K1 = m.pattern.assemble(b0).copy(), m.pattern.assemble(b1).copy()
    return K0, K1


def _direct(K, b):
    return get_solver("superlu").factorize(K).solve(b)


def test_krylov_on_kept_factor_equals_a_fresh_solve(tangents):
    K0, K1 = tangents
    changed = np.flatnonzero(np.abs(K1 - K0).max(axis=1).toarray().ravel())
    assert changed.size > 10  # the rows of the closed nodes, and only a fraction of all
    assert changed.size < K0.shape[0] / 4
    kept = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K), reuse="always",
                      budget=200)
    kept.fresh(K0)
    fac = kept.factor(K1)
    assert is_kept_solve(fac)
    rng = np.random.default_rng(0)
    B = rng.standard_normal((K1.shape[0], 3))
    X = fac.solve(B)
    assert is_kept_solve(fac) and kept.factorizations == 1  # no fallback
    ref = _direct(K1, B)
    assert np.abs(X - ref).max() <= 1e-9 * np.abs(ref).max()
    assert fac.backward_error <= 1e-14
    # a changed row is a rank-one perturbation: the first column converges in about as
    # many iterations as rows changed, the others reuse its space and need far fewer
    assert kept.krylov_iterations <= changed.size + 3 * 5


def _backward_error(K, x, b) -> float:
    """Normwise: ||K x - b|| / (||K|| ||x|| + ||b||), infinity norms."""
    norm = float(np.abs(K).sum(axis=1).max())
    return float(np.abs(K @ x - b).max() / (norm * np.abs(x).max() + np.abs(b).max()))


def test_the_kept_space_serves_later_right_hand_sides(tangents):
    K0, K1 = tangents
    inv0 = get_solver("superlu").factorize(K0)
    space = Krylov(K1, inv0._solve)
    rng = np.random.default_rng(1)
    b = rng.standard_normal(K1.shape[0])
    x, first, ok = space.solve(b, 1e-13, 200)
    assert ok and first > 5 and _backward_error(K1, x, b) <= 1e-15
    # another right-hand side in the rows that changed: the space found them already
    b2 = K1 @ x + 1e-3 * (K1 - K0) @ rng.standard_normal(K1.shape[0])
    x2, second, ok2 = space.solve(b2, 1e-13, 200)
    assert ok2 and second <= first // 4 and _backward_error(K1, x2, b2) <= 1e-15


def test_a_tangent_far_from_the_kept_one_is_factorised(tangents):
    """The rule: a solve that exceeds what is left of the budget is abandoned and
    the tangent factorised ("cap"); a spent budget factorises the next tangent
    ("budget"); the results are a fresh solve's either way."""
    K0, K1 = tangents
    kept = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K), reuse="always",
                      budget=3)
    kept.fresh(K0)
    b = np.ones(K1.shape[0])
    fac = kept.factor(K1)
    x = fac.solve(b)
    assert kept.reasons == ["first", "cap"]
    assert not is_kept_solve(fac) and fac.fresh is not None
    assert np.abs(x - _direct(K1, b)).max() <= 1e-9 * np.abs(x).max()
    # the inexact solve of a Newton correction falls back the same way
    kept.fresh(K0)
    fac = kept.factor(K1)
    y = fac.solve_to(b, 1e-12)
    assert kept.reasons[-1] == "cap" and np.abs(y - x).max() <= 1e-9 * np.abs(x).max()
    # a factor whose budget is spent is not reused
    kept = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K), reuse="always",
                      budget=MIN_BUDGET)
    kept.fresh(K0)
    kept.factor(K0).solve(b)  # its own matrix: one iteration
    kept._spent = kept.budget
    assert not is_kept_solve(kept.factor(K1)) and kept.reasons[-1] == "budget"


def test_reuse_never_and_small_factors():
    K = np.diag([2.0, 3.0, 4.0])
    import scipy.sparse as sp
    K = sp.csr_matrix(K)
    never = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K), reuse="never")
    never.fresh(K)
    never.factor(K)
    assert never.reasons == ["first", "never"]
    auto = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K))
    f = auto.fresh(K)
    assert budget_of(f) < MIN_BUDGET  # a factorisation of three pivots costs nothing
    auto.factor(K)
    assert auto.reasons == ["first", "small"]
    with pytest.raises(InputError, match="reuse"):
        KeptFactor(lambda K, blocks: None, reuse="sometimes")
    with pytest.raises(InputError, match="reuse_factor"):
        NewtonOptions(reuse_factor="sometimes")


@pytest.mark.parametrize("solver", ["superlu", "pardiso"])
def test_newton_on_a_kept_factor_converges_to_the_same_state(solver):
    """A frictional 3-D path with every factor reused ("always") against every
    tangent factorised ("never"): the same displacements, multipliers and DDM
    sensitivities (to Newton's tolerance), with fewer factorisations."""
    if solver not in sg.linsolve.available():
        pytest.skip(f"{solver} is not installed")
    pb = hertz3d_problem({"mu": 0.3}, n_fine=4)
    runs = {}
    for reuse in ("never", "always"):
        runs[reuse] = sg.solve(pb, steps=3, wrt=["R", "mu"], solver=solver,
                               options=NewtonOptions(rtol=1e-10, reuse_factor=reuse))
    a, b = runs["never"], runs["always"]
    for ia, ib in zip(a.increments, b.increments):
        scale = np.abs(ia.w).max()
        assert np.abs(ib.w - ia.w).max() <= 1e-9 * scale
        for n in ("R", "mu"):
            s = np.abs(ia.sens[n]).max()
            assert np.abs(ib.sens[n] - ia.sens[n]).max() <= 1e-8 * s
    fa = sum(inc.newton.factorizations for inc in a.increments)
    fb = sum(inc.newton.factorizations for inc in b.increments)
    assert fa == sum(inc.newton.iterations for inc in a.increments) + len(a.increments)
    assert fb <= 0.6 * fa  # measured: 5 (SuperLU) and 7 (PARDISO) against 15
    assert sum(inc.newton.krylov_iterations for inc in b.increments) > 0
    assert all(r for inc in b.increments for r in inc.newton.refactorizations)


def test_a_factor_on_the_kept_one_is_freed_when_dropped(tangents):
    """No reference cycle: a Newton iteration's factor, its tangent and its Krylov
    space are freed as soon as Newton drops them, not when the cyclic collector
    runs (with the cycle, the 89k-DOF run's traced peak was 1,134 MB, not 462)."""
    import gc
    import weakref

    K0, K1 = tangents
    kept = KeptFactor(lambda K, blocks: get_solver("superlu").factorize(K), reuse="always",
                      budget=200)
    kept.fresh(K0)
    fac = kept.factor(K1)
    fac.solve(np.ones(K1.shape[0]))
    alive = weakref.ref(fac)
    gc.disable()
    try:
        del fac
        assert alive() is None
    finally:
        gc.enable()
