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


def test_auto_start_only_for_large_3d_problems():
    small = hertz3d_problem(n_fine=4)
    sol = sg.solve(small)
    assert sol.coarse_start is None  # below AUTO_NODES: from rest
    m = sol.model
    assert not ca.wanted(m, NewtonOptions()) and ca.wanted(m, NewtonOptions(start="coarse"))
    assert not ca.wanted(m, NewtonOptions(start="rest"))
    assert m.n_nodes < ca.AUTO_NODES
    from signorini.algorithms.stepping import model_for
    from signorini.problems.spheres import spheres_problem
    pair = model_for(spheres_problem(n_fine=12))  # 3-D, frictionless pair, >= AUTO_NODES
    assert pair.n_nodes >= ca.AUTO_NODES and ca.wanted(pair, NewtonOptions())
    rough = model_for(spheres_problem({"mu": 0.3}, n_fine=12))  # a frictional pair too
    assert ca.wanted(rough, NewtonOptions()) and not ca.wanted(rough, NewtonOptions(start="rest"))


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


def test_a_frictionless_pair_starts_at_its_contact_zone():
    """Two elastic spheres (a mortar pair, 13.5k DOFs, one increment). The coarse
    space's aggregates follow the bodies' own graph: a pair's contact couplings,
    stored also where the bodies are apart, joined aggregates across the two
    bodies, whose relative motion the coarse problem must find (it then found 6
    closed nodes of the zone). Its tangent P^T (K + C) P holds the couplings between
    coarse functions on either side, which no single node carries (the zone stage
    converged linearly without them: 36 iterations here, 40 and abandoned at n_fine
    12). With both, the coarse stages converge in a few iterations each and the fine
    Newton needs 1 (8 from rest), to the state from rest."""
    from signorini.problems.spheres import spheres_problem

    pb = spheres_problem(n_fine=8)
    sol = sg.solve(pb, steps=1, options=NewtonOptions(start="coarse"))
    info = sol.coarse_start
    assert info["converged"] and "zone_abandoned" not in info, info
    assert info["iterations"] <= 8 and info["zone_iterations"] <= 8, info
    ref = sg.solve(pb, steps=1, options=NewtonOptions(start="rest"))
    assert sol.newton_iterations[0] <= 2 and ref.newton_iterations[0] >= 6
    w, w_ref = sol.increments[0].w, ref.increments[0].w
    assert np.abs(w - w_ref).max() <= 1e-12 * np.abs(w_ref).max()


def test_a_frictional_pair_starts_at_its_contact_zone():
    """The spheres with friction (mu = 0.3, one increment). With the multipliers
    held at zero the coarse problem is a penalty friction problem, whose full
    Newton steps cycled between two iterates in the zone stage (residual 2.30e-3,
    2.37e-3, 2.30e-3, ... for 40 iterations, abandoned): a step that does not
    lower the residual is halved, and one halving ends the cycle. The fine Newton
    then needs at most 4 iterations (10 from rest), to the state from rest."""
    from signorini.problems.spheres import spheres_problem

    pb = spheres_problem({"mu": 0.3}, n_fine=8)
    sol = sg.solve(pb, steps=1, options=NewtonOptions(start="coarse"))
    info = sol.coarse_start
    assert info["converged"] and "zone_abandoned" not in info, info
    assert info["zone_halved_steps"] >= 1 and info["zone_iterations"] <= 10, info
    ref = sg.solve(pb, steps=1, options=NewtonOptions(start="rest"))
    assert sol.newton_iterations[0] <= 4 and ref.newton_iterations[0] >= 8
    w, w_ref = sol.increments[0].w, ref.increments[0].w
    assert np.abs(w - w_ref).max() <= 1e-12 * np.abs(w_ref).max()


def test_a_coarse_tangent_outside_its_pattern_abandons_the_stage():
    """An entry of a coarse tangent outside the pattern analysed for it abandons
    the stage with that reason (it is never dropped or written elsewhere)."""
    import scipy.sparse as sp

    P = sp.identity(3, format="csr")
    bulk = sp.diags([1.0, 2.0, 3.0], format="csr")
    no_contact = (np.array([], dtype=int), sp.csr_matrix((0, 0)))
    stage = ca._Stage(P, bulk, no_contact, solver=None)
    inside = stage._on_template(sp.diags([4.0, 5.0, 6.0]))
    assert np.allclose(inside.toarray(), np.diag([4.0, 5.0, 6.0]))
    with pytest.raises(ca.OutsidePattern, match="outside the coarse pattern"):
        stage._on_template(sp.csr_matrix(np.array([[1.0, 0, 0], [0, 1, 0], [0.5, 0, 1]])))


def test_a_stage_whose_tangent_leaves_its_pattern_is_abandoned(monkeypatch):
    """Inside Newton's first increment (the spheres pair, its coarse pattern made
    without the contact couplings, which join coarse functions of the two bodies
    that the bulk does not): the start is abandoned with that reason and Newton
    converges from rest to the same state."""
    import scipy.sparse as sp

    from signorini.problems.spheres import spheres_problem

    def narrow(self, n_u):  # no contact coupling in the pattern
        return np.array([], dtype=int), sp.csr_matrix((0, 0))
    monkeypatch.setattr(ca.AlgebraicStart, "_coupling", narrow)
    pb = spheres_problem(n_fine=8)
    sol = sg.solve(pb, steps=1, options=NewtonOptions(start="coarse"))
    assert "outside the coarse pattern" in sol.coarse_start["abandoned"], sol.coarse_start
    ref = sg.solve(pb, steps=1, options=NewtonOptions(start="rest"))
    assert sol.newton_iterations == ref.newton_iterations
    assert np.abs(sol.increments[0].w - ref.increments[0].w).max() <= 1e-12 * np.abs(
        ref.increments[0].w).max()
