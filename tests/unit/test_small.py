"""Small determinants and inverses in plain arithmetic (signorini._small): equal to
LAPACK's to round-off, with their derivatives, and no LAPACK call in the element
and contact kernels (two such batched calls at once can hold every worker of XLA's
thread pool on a 2-core machine and never return)."""

import numpy as np
import pytest

from signorini import _small
from signorini._jax import jax, jnp
from signorini.contact import clip3d
from signorini.fem import solid


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_det_adjugate_and_inverse_equal_lapack(n):
    rng = np.random.default_rng(n)
    A = rng.normal(size=(9, n, n))
    d, adj, inv = (np.asarray(f(jnp.asarray(A))) for f in (_small.det, _small.adjugate, _small.inv))
    np.testing.assert_allclose(d, np.linalg.det(A), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(np.einsum("bij,bjk->bik", A, adj),
                               d[:, None, None] * np.eye(n), atol=1e-13)
    np.testing.assert_allclose(inv, np.linalg.inv(A), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_spd_inverse_equals_lapack_also_when_ill_conditioned(n):
    rng = np.random.default_rng(10 + n)
    B = rng.normal(size=(6, n, n))
    for scale in (1.0, 1e-6):  # condition numbers about 1e1 and 1e13
        S = B @ B.transpose(0, 2, 1) * scale + np.eye(n) * (1e-1 * scale**2)
        got = np.asarray(_small.spd_inv(jnp.asarray(S)))
        # backward stable: S X = I to round-off relative to |S| |X|
        r = np.einsum("bij,bjk->bik", S, got) - np.eye(n)
        scale_r = np.einsum("bij,bjk->bik", np.abs(S), np.abs(got))
        assert np.max(np.abs(r) / scale_r.max(axis=(1, 2), keepdims=True)) < 1e-14
        np.testing.assert_allclose(got, np.linalg.inv(S), rtol=1e-14 * np.linalg.cond(S).max())


def test_derivatives_equal_the_analytical_ones():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    # d det / dA = det(A) A^-T;  d (A^-1) / dA_kl = -A^-1 e_k e_l^T A^-1
    g = np.asarray(jax.grad(_small.det)(jnp.asarray(A)))
    np.testing.assert_allclose(g, np.linalg.det(A) * np.linalg.inv(A).T, rtol=1e-12)
    J = np.asarray(jax.jacfwd(_small.inv)(jnp.asarray(A)))
    Ai = np.linalg.inv(A)
    np.testing.assert_allclose(J, -np.einsum("ik,lj->ijkl", Ai, Ai), rtol=1e-11, atol=1e-13)


def test_element_and_dual_basis_kernels_call_no_lapack():
    dN = jnp.asarray(np.random.default_rng(0).normal(size=(8, 8, 3)))
    Xe = jnp.asarray(np.random.default_rng(1).normal(size=(8, 3)))
    text = jax.jit(jax.vmap(solid.physical_gradients, (None, 0))).lower(dN, jnp.stack([Xe] * 4)).as_text()
    assert "lapack" not in text and "custom_call" not in text
    N = jnp.asarray(np.random.default_rng(2).uniform(size=(7, 4)))
    w = jnp.full(7, 0.1)
    text = jax.jit(jax.vmap(lambda N: clip3d.dual_functions(N, w))).lower(jnp.stack([N] * 3)).as_text()
    assert "lapack" not in text and "custom_call" not in text
