"""The algebraic coarse start (algorithms.coarse_algebraic): on meshes without
coarser ones, the fine Newton's iteration count does not grow with the mesh,
and the converged state is the one from rest."""

import numpy as np
import pytest

import signorini as sg
from signorini.algorithms import coarse_algebraic as ca
from signorini.algorithms.newton import NewtonOptions
from signorini.fem.mesh3d import Mesh3D
from signorini.problems.hertz3d import grid, hertz3d_problem


def unstructured_block(n_fine: int, seed: int = 0) -> Mesh3D:
    """The graded block of ``hertz3d`` as an unstructured tetrahedral mesh: its grid
    points moved at random by up to a fifth of the local spacing (not across the
    box's faces), then tetrahedralised by Delaunay."""
    from scipy.spatial import Delaunay

    xs, zs, _ = grid(n_fine=n_fine)
    Z, Y, X = np.meshgrid(zs, xs, xs, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    lo, hi = P.min(axis=0), P.max(axis=0)

    def spacing(g, v):
        i = np.clip(np.searchsorted(g, v), 1, len(g) - 1)
        return g[i] - g[i - 1]

    h = np.column_stack([spacing(xs, P[:, 0]), spacing(xs, P[:, 1]), spacing(zs, P[:, 2])])
    J = np.random.default_rng(seed).uniform(-0.2, 0.2, P.shape) * h.min(axis=1)[:, None]
    J[np.isclose(P, lo) | np.isclose(P, hi)] = 0.0
    P = P + J
    cells = Delaunay(P).simplices
    e = P[cells[:, 1:]] - P[cells[:, :1]]
    flip = np.einsum("ij,ij->i", np.cross(e[:, 0], e[:, 1]), e[:, 2]) < 0
    cells[flip] = cells[flip][:, [0, 2, 1, 3]]
    mesh = Mesh3D(P, cells)
    faces = mesh.boundary_faces()
    centre = P[faces].mean(axis=1)
    tol = 1e-9 * float((hi - lo).max())
    node_sets, face_sets = {"all": np.arange(len(P))}, {}
    for d, name in enumerate("xyz"):
        for side, value in (("0", lo[d]), ("1", hi[d])):
            face_sets[name + side] = faces[np.abs(centre[:, d] - value) <= tol]
            node_sets[name + side] = np.nonzero(np.abs(P[:, d] - value) <= tol)[0]
    return Mesh3D(P, cells, node_sets, face_sets)


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
