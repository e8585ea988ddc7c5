"""Three-dimensional cells (signorini.fem.solid, signorini.fem.mesh3d): patch
tests (a uniform stress reproduced to round-off on distorted meshes), rigid
rotations, tangents equal to forward-mode Jacobians, the plane-strain element
recovered by a slab, and bad 3-D meshes."""

from __future__ import annotations

import numpy as np
import pytest

from signorini import FBar, InputError, InvertedElementError, J2Plasticity, LinearElastic, NeoHooke, Standard
from signorini._jax import jax, jnp
from signorini.fem import element as q4
from signorini.fem import solid
from signorini.fem.mesh3d import Mesh3D, box, tetrahedra

ELASTIC = LinearElastic(E=100.0, nu=0.3)
NEO = NeoHooke(E=100.0, nu=0.3)
J2 = J2Plasticity(E=200.0, nu=0.3, sigma_y=0.5, H=2.0)


def distorted_box(kind: str, seed: int = 0) -> Mesh3D:
    """A 3x3x3 box with its interior nodes moved at random (the patch)."""
    g = np.linspace(0.0, 1.0, 4)
    m = box(g, 1.2 * g, 0.8 * g)
    X = m.nodes.copy()
    inner = np.all((X > 1e-9) & (X < X.max(axis=0) - 1e-9), axis=1)
    X[inner] += np.random.default_rng(seed).uniform(-0.08, 0.08, (inner.sum(), 3))
    m = Mesh3D(X, m.cells, m.node_sets, m.face_sets)
    return m if kind == "hexahedron" else tetrahedra(m)


def assemble(mesh, u, material, mp, formulation=Standard()):
    """Global internal forces and dense tangent of a small mesh."""
    cell = mesh.cell
    kernel = jax.vmap(lambda ue, Xe: solid.element_residual_tangent(ue, Xe, material, mp, None, cell,
                                                                    formulation)[:2])
    r, K = kernel(jnp.asarray(u[mesh.cells]), jnp.asarray(mesh.nodes[mesh.cells]))
    dofs = (3 * mesh.cells[:, :, None] + np.arange(3)).reshape(len(mesh.cells), -1)
    n = 3 * mesh.n_nodes
    R = np.zeros(n)
    np.add.at(R, dofs, np.asarray(r))
    KK = np.zeros((n, n))
    np.add.at(KK, (dofs[:, :, None], dofs[:, None, :]), np.asarray(K))
    return R, KK


A = np.array([[0.010, -0.004, 0.002], [0.003, -0.006, 0.005], [-0.002, 0.001, 0.008]])


@pytest.mark.parametrize("kind", ["hexahedron", "tetra"])
def test_patch_test_linear_field_is_reproduced(kind):
    """u = A X on the boundary, the interior solved: u = A X everywhere and the
    stress uniform, to round-off, on a distorted mesh."""
    mesh = distorted_box(kind)
    mp = ELASTIC.values({})
    X = mesh.nodes
    exact = X @ A.T
    lo, hi = X.min(axis=0), X.max(axis=0)
    bnd = np.any((np.abs(X - lo) < 1e-12) | (np.abs(X - hi) < 1e-12), axis=1)
    fixed = (3 * np.nonzero(bnd)[0][:, None] + np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(3 * mesh.n_nodes), fixed)
    assert free.size > 0
    u = np.zeros(3 * mesh.n_nodes)
    u[fixed] = exact.ravel()[fixed]
    R, K = assemble(mesh, u.reshape(-1, 3), ELASTIC, mp)
    u[free] -= np.linalg.solve(K[np.ix_(free, free)], R[free])
    assert np.max(np.abs(u - exact.ravel())) < 1e-13
    sig = jax.vmap(lambda ue, Xe: solid.element_stress(ue, Xe, ELASTIC, mp, None, mesh.cell))(
        jnp.asarray(u.reshape(-1, 3)[mesh.cells]), jnp.asarray(X[mesh.cells]))
    eps = 0.5 * (A + A.T)
    mu, lam = ELASTIC.lame(mp)
    exact_sig = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
    assert np.max(np.abs(np.asarray(sig) - exact_sig)) < 1e-12 * np.abs(exact_sig).max() * 100


@pytest.mark.parametrize("kind,material,formulation", [
    ("hexahedron", NEO, Standard()), ("hexahedron", NEO, FBar()), ("tetra", NEO, Standard()),
    ("hexahedron", J2, FBar())])
def test_rigid_rotation_gives_no_force(kind, material, formulation):
    """Finite strain: u = (Q - I) X for a rotation Q of 60 degrees strains nothing."""
    mesh = distorted_box(kind, seed=1)
    c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    Q = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    u = mesh.nodes @ (Q - np.eye(3)).T
    mp = material.values({})
    hn = jnp.broadcast_to(material.initial_state(), (mesh.cell.n_gauss, material.n_state))
    r = jax.vmap(lambda ue, Xe: solid.element_residual(ue, Xe, material, mp, hn, mesh.cell,
                                                       formulation))(
        jnp.asarray(u[mesh.cells]), jnp.asarray(mesh.nodes[mesh.cells]))
    assert float(jnp.max(jnp.abs(r))) < 1e-12 * material.values({})["E"]


@pytest.mark.parametrize("kind,material,formulation", [
    ("hexahedron", ELASTIC, Standard()), ("hexahedron", NEO, Standard()), ("hexahedron", NEO, FBar()),
    ("tetra", NEO, Standard()), ("hexahedron", J2, Standard()), ("hexahedron", J2, FBar())])
def test_tangent_is_the_jacobian_of_the_residual(kind, material, formulation):
    """K = d r / d u_e (jacfwd of the residual), also on the plastic branch of J2
    (a deformation large enough to yield, from a history with plastic strain)."""
    mesh = distorted_box(kind, seed=2)
    cell = mesh.cell
    Xe = jnp.asarray(mesh.nodes[mesh.cells[13 if kind == "hexahedron" else 40]])
    rng = np.random.default_rng(3)
    ue = jnp.asarray(0.05 * rng.standard_normal((cell.n_nodes, 3)))
    mp = material.values({})
    hn = jnp.broadcast_to(material.initial_state(), (cell.n_gauss, material.n_state))
    if material.n_state:  # a history with plastic flow: one update from a first deformation
        hn = solid.element_update(0.5 * ue, Xe, material, mp, hn, cell, formulation)[1]
        assert float(jnp.max(jnp.abs(hn - material.initial_state()))) > 1e-4
    r, K, _ = solid.element_residual_tangent(ue, Xe, material, mp, hn, cell, formulation)
    fwd = jax.jacfwd(lambda u: solid.element_residual(u.reshape(-1, 3), Xe, material, mp, hn, cell,
                                                      formulation).reshape(-1))(ue.reshape(-1))
    assert np.allclose(r, solid.element_residual(ue, Xe, material, mp, hn, cell, formulation).reshape(-1),
                       rtol=1e-13, atol=1e-13)
    assert float(jnp.max(jnp.abs(K - fwd))) < 1e-10 * float(jnp.max(jnp.abs(fwd)))
    if material.n_state:
        ratio = jax.vmap(lambda h, hs: material.yield_ratio(h, hs, mp))(
            *solid.gauss_gradients(ue, Xe, cell, formulation)[:1], hn)
        assert float(jnp.max(ratio)) > 1.0  # the plastic branch is the one tested


@pytest.mark.parametrize("material,formulation", [(ELASTIC, Standard()), (NEO, Standard()),
                                                  (J2, FBar())])
def test_a_slab_with_no_out_of_plane_motion_is_the_plane_strain_element(material, formulation):
    """A hexahedron of thickness t extruded from a quadrilateral, with u_z = 0 and
    the quadrilateral's in-plane displacements on both layers: the in-plane nodal
    forces are t/2 of the plane-strain element's at each layer, and the z-forces
    of the two layers (the stress sigma_zz that holds u_z = 0) cancel node by node."""
    X2 = np.array([[0.0, 0.0], [1.1, 0.1], [1.0, 0.9], [-0.1, 1.2]])
    u2 = 0.04 * np.random.default_rng(4).standard_normal((4, 2))
    t = 0.3
    Xe = np.vstack([np.column_stack([X2, np.zeros(4)]), np.column_stack([X2, np.full(4, t)])])
    ue = np.vstack([np.column_stack([u2, np.zeros(4)])] * 2)
    mp = material.values({})
    h2 = jnp.broadcast_to(material.initial_state(), (4, material.n_state))
    h3 = jnp.broadcast_to(material.initial_state(), (8, material.n_state))
    r2 = q4.element_residual(jnp.asarray(u2), jnp.asarray(X2), material, mp, h2, formulation=formulation)
    r3 = solid.element_residual(jnp.asarray(ue), jnp.asarray(Xe), material, mp, h3, formulation=formulation)
    scale = float(jnp.max(jnp.abs(r2)))
    assert float(jnp.max(jnp.abs(r3[:4, :2] - 0.5 * t * r2))) < 1e-12 * scale
    assert float(jnp.max(jnp.abs(r3[4:, :2] - 0.5 * t * r2))) < 1e-12 * scale
    assert float(jnp.max(jnp.abs(r3[:4, 2] + r3[4:, 2]))) < 1e-12 * scale
    assert float(jnp.max(jnp.abs(r3[:, 2]))) > 1e-3 * scale  # sigma_zz is there


def test_box_sets_and_tetrahedra():
    m = box(np.linspace(0, 2, 5), np.linspace(0, 1, 3), np.linspace(0, 1, 4))
    assert (m.n_nodes, m.n_cells) == (5 * 3 * 4, 4 * 2 * 3)
    assert len(m.face_sets["x1"]) == 2 * 3 and len(m.face_sets["z0"]) == 4 * 2
    assert np.allclose(m.nodes[m.node_sets["y1"], 1], 1.0) and len(m.node_sets["y1"]) == 5 * 4
    assert len(m.boundary_faces()) == 2 * (4 * 2 + 4 * 3 + 2 * 3)
    t = tetrahedra(m)
    assert t.n_cells == 6 * m.n_cells
    assert len(t.boundary_faces()) == 2 * len(m.boundary_faces())  # conforming: no inner face left open
    for name, quads in m.face_sets.items():
        assert len(t.face_sets[name]) == 2 * len(quads)
    vol = lambda mesh: sum(float(jnp.sum(solid.gauss_gradients(jnp.zeros((mesh.cell.n_nodes, 3)),
                                                               jnp.asarray(mesh.nodes[c]), mesh.cell)[1]))
                           for c in mesh.cells)
    assert vol(m) == pytest.approx(2.0, rel=1e-13) and vol(t) == pytest.approx(2.0, rel=1e-13)


def test_bad_3d_meshes_are_named():
    m = box([0, 1, 2], [0, 1], [0, 1])
    with pytest.raises(InputError, match=r"\(n_nodes, 3\).*2-D mesh"):
        Mesh3D(m.nodes[:, :2], m.cells)
    with pytest.raises(InputError, match=r"\(n_cells, 4\) tetrahedra"):
        Mesh3D(m.nodes, m.cells[:, :6])
    flipped = m.cells.copy()
    flipped[1] = flipped[1][[4, 5, 6, 7, 0, 1, 2, 3]]
    with pytest.raises(InvertedElementError, match="cell 1 "):
        Mesh3D(m.nodes, flipped)
    flat = m.nodes.copy()
    flat[m.cells[0, 4:], 2] = 0.0  # cell 0 squashed to zero height
    with pytest.raises(InvertedElementError, match="cell 0 "):
        Mesh3D(flat, m.cells)
    with pytest.raises(InputError, match="not on the boundary"):
        Mesh3D(m.nodes, m.cells, face_sets={"mid": [[1, 4, 10, 7]]})
    with pytest.raises(InputError, match="numbered inward"):
        Mesh3D(m.nodes, m.cells, face_sets={"bottom": m.face_sets["z0"][:, ::-1]})
    with pytest.raises(InputError, match="F-bar"):
        t = tetrahedra(m)
        solid.element_residual(jnp.zeros((4, 3)), jnp.asarray(t.nodes[t.cells[0]]), NEO,
                               NEO.values({}), None, t.cell, FBar())
