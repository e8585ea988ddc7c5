"""Three-dimensional problems through the one Newton in (U, Lambda): a rigid sphere
pressed into a block (Hertz), the plane-strain problem recovered by a slab, a rigid
translation of everything, DDM = FD, and what 3-D does not take yet."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.contact.friction3d import CoulombDisc
from signorini.contact.obstacles3d import Cylinder, Sphere
from signorini.fem.mesh import graded_coordinates
from signorini.fem.mesh3d import Mesh3D, box, tetrahedra

D = 0.01  # the sphere's travel


def block(n=5, shift=(0.0, 0.0, 0.0), tets=False):
    g = graded_coordinates(1.0, 0.2, n, 1.4)
    m = box(g, g, 1.0 - g[::-1])
    if tets:
        m = tetrahedra(m)
    return Mesh3D(m.nodes + np.asarray(shift), m.cells, m.node_sets, m.face_sets)


def hertz3d(mesh, R=1.0, E=100.0, shift=(0.0, 0.0, 0.0)):
    c = lambda k: (lambda p: p["R"] + 1.0 + shift[2]) if k == 2 else shift[k]
    sphere = Sphere(radius="R", centre=(c(0), c(1), c(2)), motion=(0.0, 0.0, -D))
    return sg.Problem(mesh, sg.LinearElastic(E="E", nu=0.3), {"E": E, "R": R},
                      fixed=[sg.Fixed("z0", 2), sg.Fixed("x0", 0), sg.Fixed("y0", 1)],
                      contact=[sg.Contact(sphere, "z1", sg.AugmentedLagrangian(eps="E"))])


@pytest.mark.parametrize("tets", [False, True])
def test_sphere_on_a_block_ddm_equals_fd_and_equilibrium(tets):
    """DDM = central FD of the pressures for R (the sphere kept touching) and E;
    the contact force balances the reactions of the supports."""
    mesh = block(tets=tets)
    sol = sg.solve(hertz3d(mesh), wrt=["R", "E"])
    c = sol.contact()
    assert (c["p_N"] > 0).sum() >= 4 and sol.model.dim == 3
    # the contact force on the body, p A n' (linearised kinematics: n' at the reference
    # position carried along with the sphere, Y = X - D e_z), balances the supports
    Y = c["x_ref"] - np.array([0.0, 0.0, D])
    n = Y - np.array([0.0, 0.0, 2.0 - D])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    force_z = np.sum(c["area"] * c["p_N"] * n[:, 2])
    assert sol.reactions()[:, 2].sum() == pytest.approx(-force_z, rel=1e-9)
    for name, h in (("R", 1e-5), ("E", 1e-3)):
        val = {"R": 1.0, "E": 100.0}[name]
        p = [sg.solve(hertz3d(mesh, **{name: val + s * h})).contact()["p_N"] for s in (1, -1)]
        fd = (p[0] - p[1]) / (2 * h)
        ddm = c[f"dp_N_d{name}"]
        assert np.max(np.abs(fd - ddm)) < 1e-6 * np.max(np.abs(ddm)), name


def test_a_rigid_translation_changes_nothing():
    """Mesh and sphere moved together by a vector: the same pressures and sensitivities."""
    a = sg.solve(hertz3d(block()), wrt=["R"]).contact()
    shift = (0.3, -1.7, 2.2)
    b = sg.solve(hertz3d(block(shift=shift), shift=shift), wrt=["R"]).contact()
    assert np.allclose(a["p_N"], b["p_N"], rtol=0, atol=1e-10 * a["p_N"].max())
    assert np.allclose(a["dp_N_dR"], b["dp_N_dR"], rtol=0, atol=1e-9 * np.abs(a["dp_N_dR"]).max())


def test_a_slab_is_the_plane_strain_problem():
    """A one-cell slab with u_z = 0 against a cylinder along z: the pressures and
    their sensitivity to R are the plane-strain problem's (a cylinder on a
    rectangle) at both layers."""
    xs = graded_coordinates(1.0, 0.3, 8, 1.3)
    ys = 1.0 - graded_coordinates(1.0, 0.3, 6, 1.3)[::-1]
    R, t = 1.0, 0.25
    law = sg.AugmentedLagrangian(eps="E")
    params = {"E": 100.0, "R": R}
    p2 = sg.Problem(sg.rectangle(xs, ys), sg.LinearElastic(E="E", nu=0.3), params,
                    fixed=[sg.Fixed("bottom", 1), sg.Fixed("left", 0)],
                    contact=[sg.Contact(sg.Circle(radius="R", centre=(0.0, lambda p: p["R"] + 1.0),
                                                  motion=(0.0, -D)), "top", law)])
    p3 = sg.Problem(box(xs, ys, [0.0, t]), sg.LinearElastic(E="E", nu=0.3), params,
                    fixed=[sg.Fixed("y0", 1), sg.Fixed("x0", 0), sg.Fixed("all", 2)],
                    contact=[sg.Contact(Cylinder(radius="R", centre=(0.0, lambda p: p["R"] + 1.0, 0.0),
                                                 axis=(0.0, 0.0, 1.0), motion=(0.0, -D, 0.0)),
                                        "y1", law)])
    c2 = sg.solve(p2, wrt=["R"]).contact()
    c3 = sg.solve(p3, wrt=["R"]).contact()
    assert (c2["p_N"] > 0).sum() >= 3
    for layer in (0.0, t):
        on = np.abs(c3["x_ref"][:, 2] - layer) < 1e-12
        order = np.argsort(c3["x_ref"][on, 0])
        for f in ("p_N", "dp_N_dR"):
            a, b = c2[f], c3[f][on][order]
            assert np.allclose(a, b, rtol=0, atol=1e-10 * np.abs(a).max()), (f, layer)


def test_a_3d_solution_writes_vtu(tmp_path):
    sol = sg.solve(hertz3d(block(n=3)), wrt=["R"])
    sg.write_vtu(sol, tmp_path / "s.vtu")
    m = meshio.read(tmp_path / "s.vtu")
    assert m.cells[0].type == "hexahedron" and m.points.shape == (sol.model.n_nodes, 3)
    assert m.point_data["displacement"].shape == (sol.model.n_nodes, 3)
    assert "dp_N_dR" in m.point_data and m.cell_data["cauchy_stress"][0].shape[1] == 9


def test_what_3d_does_not_take_yet_is_named():
    mesh = block(n=3)
    with pytest.raises(sg.InputError, match="kinematics need a 2-D mesh"):
        sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, kinematics=sg.Axisymmetric())
    with pytest.raises(sg.InputError, match="component must be one of \\[0, 1, 2\\]"):
        sg.solve(sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, fixed=[sg.Fixed("z0", 3)]))
    with pytest.raises(sg.InputError, match="friction in a 3-D problem is not available yet"):
        sg.solve(sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {"mu": 0.3, "eps": 1.0, "eps_t": 1.0},
                            fixed=[sg.Fixed("z0", 2)],
                            contact=[sg.Contact(Sphere(radius=1.0, centre=(0.0, 0.0, 2.0)), "z1",
                                                CoulombDisc())]))
    with pytest.raises(sg.InputError, match="boundary loads .* 3-D body are not available yet"):
        sg.solve(sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, fixed=[sg.Fixed("z0", 2)],
                            loads=[sg.Pressure("z1", 1.0)]))


def test_the_kind_programs_give_the_whole_mesh_solution(monkeypatch):
    """Large 3-D meshes run through the cells' kind programs (one chunk after the
    other): the same solution and sensitivities as the whole-mesh programs."""
    from signorini.algorithms import stepping
    from signorini.model.kernels import Model

    pb = hertz3d(block(n=4))
    a = sg.solve(pb, wrt=["R", "E"])
    monkeypatch.setattr(Model, "WHOLE_MESH_UP_TO", 0)
    monkeypatch.setattr(stepping, "_MODELS", type(stepping._MODELS)())
    b = sg.solve(pb, wrt=["R", "E"])
    assert b.model.by_kind and not a.model.by_kind
    ca, cb = a.contact(), b.contact()
    for f in ("p_N", "dp_N_dR", "dp_N_dE"):
        assert np.allclose(ca[f], cb[f], rtol=0, atol=1e-9 * np.abs(ca[f]).max()), f


def test_adjoint_equals_ddm_in_3d():
    """The adjoint gradient of a response equals the DDM's for R and E, and its
    gradient with respect to every nodal coordinate, projected on a design
    velocity, equals the DDM sensitivity to that shape parameter."""
    from signorini._jax import jnp

    mesh = block(n=3)
    X = mesh.nodes
    V = 0.05 * X * (1.0 - X) * np.array([1.0, -0.5, 0.7])  # vanishes on the supports' planes
    pb = hertz3d(mesh)
    pb = sg.Problem(pb.mesh, pb.material, {**pb.params, "s": 0.0}, fixed=pb.fixed,
                    contact=pb.contact, shape={"s": V})
    n_u = 3 * mesh.n_nodes
    response = lambda w, p, t: jnp.sum(w[:n_u] ** 2) + jnp.sum(w[n_u:]) * 1e-2
    ddm = sg.gradient(pb, response, wrt=["R", "E", "s"], method=sg.DDM())
    adj = sg.gradient(pb, response, wrt=["R", "E", "nodes"], method=sg.Adjoint())
    for k in ("R", "E"):
        assert adj.grad[k] == pytest.approx(ddm.grad[k], rel=1e-9)
    assert adj.grad["nodes"].shape == (mesh.n_nodes, 3)
    assert np.sum(adj.grad["nodes"] * V) == pytest.approx(ddm.grad["s"], rel=1e-8)
