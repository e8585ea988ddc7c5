"""The algebraic coarse start (algorithms.coarse_algebraic): on meshes without
coarser ones, the fine Newton's iteration count does not grow with the mesh,
and the converged state is the one from rest."""

import numpy as np
import pytest

import signorini as sg
from signorini.algorithms import coarse_algebraic as ca
from signorini.algorithms.newton import NewtonOptions
from signorini.fem.mesh3d import Mesh3D
from signorini.problems.hertz3d import hertz3d_problem, tetrahedral_block


def unstructured_block(n_fine: int) -> Mesh3D:
    return tetrahedral_block(n_fine=n_fine)


def _iterations(pb, start: str):
    sol = sg.solve(pb, options=NewtonOptions(rtol=1e-10, start=start))
    return sol, sol.newton_iterations[0]


@pytest.mark.parametrize("kind", ["graded hexahedra", "unstructured tetrahedra"])
def test_fine_iterations_do_not_grow_with_the_mesh(kind):
    """Two meshes, the second with 1.5 times the cells across the contact zone
    (3.4x the unknowns): from rest Newton's iterations grow with the nodes across
    the zone; from the algebraic coarse start they stay within a fixed bound, and
    the solution is the same."""
    counts = {}
    for n in (6, 9):
        pb = hertz3d_problem(n_fine=n)
        if kind != "graded hexahedra":
            pb = sg.Problem(mesh=unstructured_block(n), material=pb.material, params=pb.params,
                            fixed=pb.fixed, loads=pb.loads, contact=pb.contact)
        coarse, k_coarse = _iterations(pb, "coarse")
        rest, k_rest = _iterations(pb, "rest")
        info = coarse.coarse_start
        assert info["converged"] and info["coarse_unknowns"] < sol_dofs(coarse) / 4
        scale = np.abs(rest.increments[0].w).max()
        assert np.abs(coarse.increments[0].w - rest.increments[0].w).max() <= 1e-8 * scale
        counts[n] = (k_rest, k_coarse)
    (rest6, coarse6), (rest9, coarse9) = counts[6], counts[9]
    assert rest9 > rest6  # from rest: one ring of nodes per iteration
    assert coarse6 <= 5 and coarse9 <= 5, counts
    assert coarse9 <= coarse6 + 1, counts


def sol_dofs(sol) -> int:
    return int(sol.model.n_dof)


def test_auto_start_only_for_large_3d_obstacle_problems():
    small = hertz3d_problem(n_fine=4)
    sol = sg.solve(small)
    assert sol.coarse_start is None  # below AUTO_NODES: from rest
    m = sol.model
    assert not ca.wanted(m, NewtonOptions()) and ca.wanted(m, NewtonOptions(start="coarse"))
    assert not ca.wanted(m, NewtonOptions(start="rest"))
    assert m.n_nodes < ca.AUTO_NODES


def test_a_coarse_problem_that_fails_is_abandoned(monkeypatch):
    """No convergence within the budget: Newton starts from rest, says why, and
    converges to the same state."""
    monkeypatch.setattr(ca, "MAX_ITERATIONS", 1)
    pb = hertz3d_problem(n_fine=4)
    sol = sg.solve(pb, options=NewtonOptions(start="coarse"))
    assert "no convergence" in sol.coarse_start["abandoned"]
    ref = sg.solve(pb, options=NewtonOptions(start="rest"))
    assert sol.newton_iterations == ref.newton_iterations
    assert np.abs(sol.increments[0].w - ref.increments[0].w).max() <= 1e-12 * np.abs(
        ref.increments[0].w).max()
