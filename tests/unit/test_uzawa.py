"""Uzawa's nested-loop AL as a comparator (THEORY section 4, paper section 3.3)."""

import dataclasses

import numpy as np
import pytest

import signorini as sg
from signorini.contact.uzawa import UzawaPenalty
from signorini.problems import hertz
from signorini.algorithms.uzawa import solve_uzawa

TIGHT = sg.NewtonOptions(rtol=1e-11)


@pytest.fixture(scope="module")
def pair():
    pb = hertz.hertz_problem(n_fine=8, size=8)
    c = pb.contact[0]
    pu = dataclasses.replace(pb, contact=(sg.Contact(c.obstacle, c.edges, UzawaPenalty("eps")),))
    al = sg.solve(pb, wrt=["R", "E"], options=TIGHT)
    uz = solve_uzawa(pu, wrt=["R", "E"], options=TIGHT, tol=1e-10)  # above the inner noise
    return pb, pu, al, uz


def test_same_saddle_point(pair):
    """Uzawa's fixed point is the AL solution (THEORY 4)."""
    _, _, al, uz = pair
    lam = al.multipliers()[:, 0]
    assert np.max(np.abs(uz.lam - lam)) <= 1e-9 * np.max(np.abs(lam))
    assert np.max(np.abs(uz.displacement() - al.displacement())) <= 1e-9 * np.max(np.abs(al.displacement()))


def test_sensitivity_iteration_converges_to_the_one_solve_ddm(pair):
    """The differentiated Uzawa algorithm is an iteration (one solve per outer
    iteration) whose limit is the AL sensitivity obtained in one solve; truncating it
    leaves an error (paper 3.3)."""
    _, _, al, uz = pair
    for name in ("R", "E"):
        ref = al.multiplier_sensitivity(name)[:, 0]
        errs = [np.max(np.abs(h - ref)) / np.max(np.abs(ref)) for h in uz.sens_history[name]]
        assert errs[-1] <= 1e-7, (name, errs[-1])
        assert errs[0] > 1e-3  # the first outer iterate is far from the exact sensitivity
        assert errs[len(errs) // 2] > errs[-1]
    # the cost: outer iterations x (inner Newton + a sensitivity solve) vs one AL Newton
    assert uz.outer_iterations[0] > 3
    assert uz.linear_solves > 2 * sum(al.newton_iterations)


def test_uzawa_law_is_rejected_by_the_single_newton_driver(pair):
    _, pu, _, _ = pair
    with pytest.raises(sg.InputError, match="solve_uzawa"):
        sg.solve(pu)


def test_non_differentiable_expression_is_a_convergence_error_with_the_partial_result(pair):
    """Uzawa's DDM inside the outer loop: a modulus 100 + sqrt(k) at k = 0 (NaN
    tangent) ends in a ConvergenceError naming it, carrying what was computed,
    not in a linear solver's "singular tangent"."""
    import jax.numpy as jnp

    pu = pair[1]
    mat = dataclasses.replace(pu.material, E=lambda p: 100.0 + jnp.sqrt(p["k"]))
    bad = dataclasses.replace(pu, material=mat, params={**pu.params, "k": 0.0})
    with pytest.raises(sg.ConvergenceError, match="sensitivities of 'k' are not finite") as e:
        solve_uzawa(bad, wrt=["k"], tol=1e-8)
    assert e.value.partial is not None
