"""The iterative solver (AMG-preconditioned flexible GMRES): the same solutions and
sensitivities as a direct solver, frictionless and with friction (unsymmetric),
adjoint (transposed solves), 2-D and 3-D, and its errors."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini.errors import InputError, SolverError
from signorini.linsolve import AMGKrylov, get_solver
from test_model3d import block, hertz3d, hertz3d_friction


def same(a, b, fields, tol=1e-8):
    for f in fields:
        scale = np.abs(a[f]).max()
        assert np.max(np.abs(a[f] - b[f])) <= tol * scale, f


@pytest.mark.parametrize("friction", [False, True])
def test_amg_gives_the_direct_solution_and_sensitivities(friction):
    pb = hertz3d_friction(block(n=5)) if friction else hertz3d(block(n=5))
    steps = 2 if friction else 1
    d = sg.solve(pb, steps=steps, wrt=["R", "E"], solver="superlu").contact()
    lin = AMGKrylov()
    it = sg.solve(pb, steps=steps, wrt=["R", "E"], solver=lin).contact()
    same(d, it, ["p_N", "dp_N_dR", "dp_N_dE"] + (["p_T", "dp_T_dR"] if friction else []))
    assert lin.iterations and max(lin.iterations) < 200  # preconditioned: tens, not thousands


def test_amg_adjoint_and_2d():
    """The adjoint's transposed solves, and a plane-strain problem (rigid modes in 2-D)."""
    from signorini._jax import jnp
    pb = hertz3d_friction(block(n=4))
    n_u = 3 * pb.mesh.n_nodes
    response = lambda w, p, t: jnp.sum(w[:n_u] ** 2)  # noqa: E731
    a = sg.gradient(pb, response, ["R", "mu"], method=sg.Adjoint(), steps=2, solver="amg")
    b = sg.gradient(pb, response, ["R", "mu"], method=sg.Adjoint(), steps=2, solver="superlu")
    for k in ("R", "mu"):
        assert a.grad[k] == pytest.approx(b.grad[k], rel=1e-8)
    from signorini.problems.hertz import hertz_problem
    p2 = hertz_problem(n_fine=12)
    same(sg.solve(p2, wrt=["R"], solver="superlu").contact(),
         sg.solve(p2, wrt=["R"], solver="amg").contact(), ["p_N", "dp_N_dR"])


def test_amg_errors_are_named():
    lin = get_solver("amg")
    with pytest.raises(InputError, match="needs the tangent's structure"):
        lin.factorize(sp.identity(4, format="csr"))
    with pytest.raises(SolverError, match="did not reach the relative residual .* use a direct solver"):
        sg.solve(hertz3d(block(n=3)), solver=AMGKrylov(restart=2, max_iterations=2))
