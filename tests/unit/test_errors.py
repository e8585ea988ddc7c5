"""Bad input produces one of signorini's own errors, with a message that names
the problem (never a raw JAX / NumPy / SciPy exception)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import signorini as sg
from signorini._jax import jnp
from signorini.errors import (
    ConvergenceError, InputError, InvertedElementError, SignoriniError, UnknownParameterError)
from signorini.problems.hertz import hertz_problem


@pytest.fixture(scope="module")
def problem():
    """Small Hertz half model (121 nodes); its compiled model is cached by solve."""
    return hertz_problem(n_fine=4, size=6)


def assert_ours(excinfo):
    """The exception is a signorini error with a readable message, not a traceback."""
    err = excinfo.value
    assert isinstance(err, SignoriniError)
    assert type(err).__module__ == "signorini.errors"
    msg = str(err)
    assert msg and "Traceback" not in msg and "jax" not in msg.lower()
    assert not msg.startswith(("'", '"'))  # UnknownParameterError is a KeyError: no quoting


# ------------------------------------------------------------------- mesh
def test_clockwise_cell_is_inverted():
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    sg.Mesh(nodes, [[0, 1, 2, 3]])  # counter-clockwise: accepted
    with pytest.raises(InvertedElementError, match=r"inverted.*cell 0.*counter-clockwise") as e:
        sg.Mesh(nodes, [[0, 3, 2, 1]])
    assert_ours(e)


def test_inverted_cell_is_reported_by_index():
    base = sg.rectangle([0.0, 1.0, 2.0], [0.0, 1.0])
    cells = base.cells.copy()
    cells[1] = cells[1][::-1]  # second cell numbered clockwise
    with pytest.raises(InvertedElementError, match=r"1 inverted.*first is cell 1") as e:
        sg.Mesh(base.nodes, cells)
    assert_ours(e)


def test_interior_contact_edge_is_rejected():
    base = sg.rectangle([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])  # nodes 0..8, node 4 in the middle
    # edge 1-4 is shared by cells 0 and 1
    with pytest.raises(InputError, match=r"edge set 'c': edge \(1, 4\) is not on the boundary") as e:
        sg.Mesh(base.nodes, base.cells, edge_sets={"c": [[1, 4]]})
    assert_ours(e)


def test_reversed_boundary_edge_is_rejected():
    base = sg.rectangle([0.0, 1.0, 2.0], [0.0, 1.0])
    with pytest.raises(InputError, match=r"edge \(1, 0\) is reversed") as e:
        sg.Mesh(base.nodes, base.cells, edge_sets={"c": [[1, 0]]})
    assert_ours(e)


# ------------------------------------------------------------- parameters
def test_with_params_unknown_name(problem):
    with pytest.raises(UnknownParameterError, match=r"unknown parameter 'Q'") as e:
        problem.with_params(Q=1)
    assert_ours(e)


def test_solve_unknown_sensitivity(problem):
    with pytest.raises(UnknownParameterError, match=r"unknown parameter 'Q' in wrt") as e:
        sg.solve(problem, wrt=["Q"])
    assert_ours(e)


def test_material_names_undefined_parameter(problem):
    bad = dataclasses.replace(problem, material=sg.LinearElastic(E="Young"))
    with pytest.raises(UnknownParameterError, match=r"unknown parameter 'Young'") as e:
        sg.solve(bad)
    assert_ours(e)


# a typo inside a parameter expression (lambda) is reported before any JAX tracing
def test_callable_material_spec_names_undefined_parameter(problem):
    bad = dataclasses.replace(problem, material=sg.LinearElastic(E=lambda p: p["Young"]))
    with pytest.raises(UnknownParameterError, match=r"'Young'") as e:
        sg.solve(bad)
    assert_ours(e)


def test_callable_obstacle_spec_names_undefined_parameter(problem):
    circle = sg.Circle(radius="R", centre=(0.0, lambda p: p["Rr"]))
    bad = dataclasses.replace(problem, contact=(sg.Contact(circle, "top", sg.AugmentedLagrangian("eps")),))
    with pytest.raises(UnknownParameterError, match=r"'Rr'") as e:
        sg.solve(bad)
    assert_ours(e)


@pytest.mark.parametrize("values, pattern", [
    ({"R": -1.0}, r"radius must be positive, got -1"),
    ({"E": -5.0}, r"Young's modulus must be positive, got E=-5"),
    ({"nu": 0.6}, r"Poisson's ratio must lie in \(-1, 0\.5\), got nu=0\.6"),
    ({"eps": 0.0}, r"parameter must be positive, got eps=0"),
    ({"eps": -3.0}, r"parameter must be positive, got eps=-3"),
], ids=["R<0", "E<0", "nu=0.6", "eps=0", "eps<0"])
def test_invalid_parameter_values(problem, values, pattern):
    with pytest.raises(InputError, match=pattern) as e:
        sg.solve(problem.with_params(**values))
    assert_ours(e)


# --------------------------------------------------------- boundary sets
def test_same_dof_prescribed_twice(problem):
    # "left" is a subset of "all": u_x of the left nodes would be prescribed twice
    bad = dataclasses.replace(problem, fixed=(sg.Fixed("left", 0), sg.Fixed("all", 0)))
    with pytest.raises(InputError, match=r"inconsistent boundary sets: DOF 0 of node \d+ is "
                                         r"prescribed by both 'left' and 'all'") as e:
        sg.solve(bad)
    assert_ours(e)


def test_unknown_linear_solver(problem):
    with pytest.raises(InputError, match=r"unknown linear solver 'mumps'; choose from") as e:
        sg.solve(problem, solver="mumps")
    assert_ours(e)


# ------------------------------------------------------------ convergence
def test_obstacle_not_touching_under_force_control(problem):
    # cylinder raised by 0.05: initial gap 0.05 everywhere at the top, body held by nothing
    circle = sg.Circle(radius="R", centre=(0.0, lambda p: p["R"] + 0.05))
    bad = dataclasses.replace(problem, contact=(sg.Contact(circle, "top", sg.AugmentedLagrangian("eps")),))
    with pytest.raises(ConvergenceError, match=r"(?s)smallest gap 0\.05 .*must touch the obstacle") as e:
        sg.solve(bad)
    assert_ours(e)
    partial = e.value.partial
    assert isinstance(partial, sg.Solution)
    assert partial.status == "failed"
    assert len(partial.increments) == 0


def test_newton_failure_after_cuts(problem):
    # the Hertz problem needs ~4 Newton iterations (contact set changes): 1 is not enough
    with pytest.raises(ConvergenceError, match=r"after 1 step cuts \(no convergence in 1 iterations \(last") as e:
        sg.solve(problem, options=sg.NewtonOptions(max_iter=1, max_cuts=1))
    assert_ours(e)
    partial = e.value.partial
    assert isinstance(partial, sg.Solution)
    assert partial.status == "failed"
    assert len(partial.increments) == 0
    # t = 1 tried, then t = 0.5 after the one cut
    assert [round(log.t, 12) for log in partial.log] == [1.0, 0.5]
    assert not any(log.converged for log in partial.log)


def test_partial_keeps_converged_increments(problem):
    # load switched on only for t > 0.5: the increment to t = 0.5 converges at once
    # (zero residual), the loaded one needs more than 1 Newton iteration and fails
    late = sg.Pressure("bottom", lambda p: 0.5 * p["P"], resultant=True,
                       ramp=lambda t: jnp.maximum(0.0, 2.0 * t - 1.0))
    bad = dataclasses.replace(problem, loads=(late,))
    with pytest.raises(ConvergenceError, match=r"after 1 step cuts .*1 increments converged") as e:
        sg.solve(bad, steps=2, options=sg.NewtonOptions(max_iter=1, max_cuts=1))
    assert_ours(e)
    partial = e.value.partial
    assert partial.status == "failed"
    assert [inc.t for inc in partial.increments] == [0.5]
    np.testing.assert_array_equal(partial.displacement(), 0.0)  # nothing loaded yet at t = 0.5
    # the same problem solves with enough iterations, so the failure is the iteration limit
    sol = sg.solve(bad, steps=2)
    assert sol.status == "converged" and max(sol.newton_iterations) > 1


def test_max_cuts_is_per_increment(problem):
    # predictor="none": the measured precondition below is a path from the last state
    options = sg.NewtonOptions(max_iter=1, max_cuts=1, predictor="none")
    try:
        log = sg.solve(problem, steps=8, options=options).log
    except ConvergenceError as e:
        log = e.partial.log
    attempts = [(round(entry.t, 12), round(entry.dt, 12), entry.converged) for entry in log]
    # precondition (measured with this mesh): t = 0.125 fails, its half converges, and the
    # next full-size increment to t = 0.1875 fails again, without having been cut yet
    if attempts[:3] != [(0.125, 0.125, False), (0.0625, 0.0625, True), (0.1875, 0.125, False)]:
        pytest.fail(f"precondition changed: {attempts[:3]}")
    # max_cuts=1 per increment: the failed increment from t = 0.0625 is halved once more
    assert len(attempts) > 3 and attempts[3][:2] == (0.125, 0.0625)
