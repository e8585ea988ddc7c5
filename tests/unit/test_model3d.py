"""Three-dimensional problems through the one Newton in (U, Lambda): a rigid sphere
pressed into a block (Hertz), the plane-strain problem recovered by a slab, a rigid
translation of everything, DDM = FD, and what 3-D does not take yet."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini._jax import jnp
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


def test_bad_3d_input_is_named():
    mesh = block(n=3)
    with pytest.raises(sg.InputError, match="kinematics need a 2-D mesh"):
        sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, kinematics=sg.Axisymmetric())
    with pytest.raises(sg.InputError, match="component must be one of \\[0, 1, 2\\]"):
        sg.solve(sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, fixed=[sg.Fixed("z0", 3)]))
    with pytest.raises(sg.InputError, match="unknown face set 'top'"):
        sg.solve(sg.Problem(mesh, sg.LinearElastic(E=1.0, nu=0.3), {}, fixed=[sg.Fixed("z0", 2)],
                            loads=[sg.Pressure("top", 1.0)]))


MU = 0.1


def hertz3d_friction(mesh, R=1.0, E=100.0, mu=MU, shift=(0.0, 0.0, 0.0), rotation=None,
                     fixed=None, spin=None):
    """The sphere pressed into the block with Coulomb friction (the 2-D law given:
    a 3-D surface takes it as the Coulomb disc); ``rotation`` (3, 3) turns the
    mesh, the sphere and its motion together; ``spin`` (radians) turns the sphere
    about its vertical axis as it presses."""
    Q = np.eye(3) if rotation is None else np.asarray(rotation)
    mesh = Mesh3D(mesh.nodes @ Q.T, mesh.cells, mesh.node_sets, mesh.face_sets)
    centre = lambda p: (jnp.asarray(shift) + jnp.asarray(Q) @ jnp.array([0.0, 0.0, p["R"] + 1.0]))
    c = tuple((lambda p, k=k: centre(p)[k]) for k in range(3))
    motion = tuple(float(v) for v in Q @ np.array([0.0, 0.0, -D]))
    turn = None if spin is None else tuple(float(v) for v in Q @ np.array([0.0, 0.0, spin]))
    sphere = Sphere(radius="R", centre=c, motion=motion, rotation=turn)
    mesh = Mesh3D(mesh.nodes + np.asarray(shift), mesh.cells, mesh.node_sets, mesh.face_sets)
    if fixed is None:
        fixed = [sg.Fixed("z0", 2), sg.Fixed("x0", 0), sg.Fixed("y0", 1)]
    return sg.Problem(mesh, sg.LinearElastic(E="E", nu=0.3),
                      {"E": E, "R": R, "mu": mu, "eps": E, "eps_t": E}, fixed=fixed,
                      contact=[sg.Contact(sphere, "z1", sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps_t"))])


def test_friction_ddm_equals_fd_through_the_path():
    """Coulomb friction in 3-D (the disc, two tangential multipliers, the closest
    point as history): with stick and slip nodes at the end of four increments,
    DDM = central FD of p_N and of both tangential tractions for R and mu, and the
    supports balance the contact force."""
    mesh = block(n=6)
    pb = hertz3d_friction(mesh)
    sol = sg.solve(pb, steps=4, wrt=["R", "mu"])
    c = sol.contact()
    status = set(c["status"][c["p_N"] > 0])
    assert status == {"stick", "slip"} and c["p_T"].shape == (mesh.n_nodes and len(c["p_N"]), 2)
    # symmetry planes: a node on x = 0 or y = 0 carries no traction across it, one on
    # the axis none at all
    on_axis = np.all(np.abs(c["x_ref"][:, :2]) < 1e-12, axis=1)
    assert np.all(c["p_T"][on_axis] == 0.0)
    # the supports hold the contact force: in z the base, in x and y the symmetry planes
    force = np.sum(c["area"][:, None] * c["traction"], axis=0)
    assert force[2] < -0.03 and abs(force[0]) > 1e-4 * abs(force[2])
    assert np.allclose(sol.reactions().sum(axis=0), -force, rtol=1e-9, atol=0)
    for name, h in (("R", 1e-5), ("mu", 1e-4)):
        val = {"R": 1.0, "mu": MU}[name]
        # the same problem at other values (its compiled model: hertz3d_friction built
        # again would be a new model, its sphere's centre being known by identity only)
        cs = [sg.solve(pb.with_params(**{name: val + s * h}), steps=4).contact() for s in (1, -1)]
        for q in ("p_N", "p_T"):
            fd = (cs[0][q] - cs[1][q]) / (2 * h)
            ddm = c[f"d{q}_d{name}"]
            assert np.max(np.abs(fd - ddm)) < 1e-6 * np.max(np.abs(ddm)), (name, q)


def test_friction_on_a_slab_is_the_plane_strain_problem():
    """A one-cell slab with u_z = 0 against a cylinder along z, with Coulomb
    friction over three increments: the pressures, the tangential tractions and
    their sensitivities to R and mu are the plane-strain problem's at both layers
    (u_z prescribed: each node carries only the in-plane tangential multiplier)."""
    xs = graded_coordinates(1.0, 0.3, 8, 1.3)
    ys = 1.0 - graded_coordinates(1.0, 0.3, 6, 1.3)[::-1]
    t = 0.25
    law = sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps_t")
    params = {"E": 100.0, "R": 1.0, "mu": 0.2, "eps": 100.0, "eps_t": 100.0}
    p2 = sg.Problem(sg.rectangle(xs, ys), sg.LinearElastic(E="E", nu=0.3), params,
                    fixed=[sg.Fixed("bottom", 1), sg.Fixed("left", 0)],
                    contact=[sg.Contact(sg.Circle(radius="R", centre=(0.0, lambda p: p["R"] + 1.0),
                                                  motion=(0.0, -2 * D)), "top", law)])
    p3 = sg.Problem(box(xs, ys, [0.0, t]), sg.LinearElastic(E="E", nu=0.3), params,
                    fixed=[sg.Fixed("y0", 1), sg.Fixed("x0", 0), sg.Fixed("all", 2)],
                    contact=[sg.Contact(Cylinder(radius="R", centre=(0.0, lambda p: p["R"] + 1.0, 0.0),
                                                 axis=(0.0, 0.0, 1.0), motion=(0.0, -2 * D, 0.0)),
                                        "y1", law)])
    c2 = sg.solve(p2, steps=3, wrt=["R", "mu"]).contact()
    c3 = sg.solve(p3, steps=3, wrt=["R", "mu"]).contact()
    assert set(c2["status"][c2["p_N"] > 0]) == {"stick", "slip"}
    for layer in (0.0, t):
        on = np.abs(c3["x_ref"][:, 2] - layer) < 1e-12
        order = np.argsort(c3["x_ref"][on, 0])
        assert list(c3["status"][on][order]) == list(c2["status"])
        assert np.all(c3["p_T"][on][:, 1] == 0.0)  # the out-of-plane multiplier
        for f in ("p_N", "dp_N_dR", "dp_N_dmu", "p_T", "dp_T_dR", "dp_T_dmu"):
            a, b = c2[f], c3[f][on][order]
            if f.startswith(("p_T", "dp_T")):
                b = b[:, 0] * np.sign(np.sum(a * b[:, 0]))  # t1 = +-T
            assert np.allclose(a, b, rtol=0, atol=1e-9 * np.abs(a).max()), (f, layer)


def test_friction_rigid_motion_changes_nothing():
    """The whole frictional problem (a full block, its base held, so no symmetry
    planes) turned by a rotation and moved by a translation, the sphere spinning
    about its (turned) vertical axis as it presses: the same pressures, the same
    magnitudes of the tangential tractions, the same stick/slip zones and the same
    sensitivities (the tangent bases differ: e_S is a property of the mesh)."""
    g = graded_coordinates(1.0, 0.25, 3, 1.5)
    full = np.concatenate([-g[::-1], g[1:]])
    mesh = box(full, full, 1.0 - g[::-1])
    fixed = [sg.Fixed("z0", k) for k in range(3)]
    a = sg.solve(hertz3d_friction(mesh, fixed=fixed, spin=0.02), steps=3, wrt=["R"]).contact()
    angle = 0.7
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    Q = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    b = sg.solve(hertz3d_friction(mesh, fixed=[sg.Fixed("z0", k) for k in range(3)], rotation=Q,
                                  shift=(0.4, -1.1, 0.3), spin=0.02), steps=3, wrt=["R"]).contact()
    assert set(a["status"][a["p_N"] > 0]) == {"stick", "slip"}
    assert list(a["status"]) == list(b["status"])
    scale = a["p_N"].max()
    for f in ("p_N", "dp_N_dR"):
        assert np.allclose(a[f], b[f], rtol=0, atol=1e-10 * np.abs(a[f]).max()), f
    norm = lambda v: np.linalg.norm(v, axis=1)
    assert np.allclose(norm(a["p_T"]), norm(b["p_T"]), rtol=0, atol=1e-10 * scale)


def test_the_kind_programs_give_the_whole_mesh_solution(monkeypatch):
    """Large 3-D meshes run through the cells' kind programs (one chunk after the
    other): the same solution and sensitivities as the whole-mesh programs."""
    from signorini.algorithms import stepping
    from signorini.model.kernels import Model

    for pb, steps in ((hertz3d(block(n=4)), 1), (hertz3d_friction(block(n=4)), 2)):
        a = sg.solve(pb, steps=steps, wrt=["R", "E"])
        with monkeypatch.context() as mp:
            mp.setattr(Model, "WHOLE_MESH_UP_TO", 0)
            mp.setattr(stepping, "_MODELS", type(stepping._MODELS)())
            b = sg.solve(pb, steps=steps, wrt=["R", "E"])
        assert b.model.by_kind and not a.model.by_kind
        ca, cb = a.contact(), b.contact()
        for f in ("p_N", "dp_N_dR", "dp_N_dE", "p_T", "dp_T_dR", "traction"):
            assert np.allclose(ca[f], cb[f], rtol=0, atol=1e-9 * np.abs(ca[f]).max()), f


def test_adjoint_equals_ddm_in_3d():
    """Frictionless and with Coulomb friction through three increments: the
    adjoint gradient of a response equals the DDM's for R, E (and mu), and its
    gradient with respect to every nodal coordinate, projected on a design
    velocity, equals the DDM sensitivity to that shape parameter."""
    from signorini._jax import jnp

    mesh = block(n=3)
    X = mesh.nodes
    V = 0.05 * X * (1.0 - X) * np.array([1.0, -0.5, 0.7])  # vanishes on the supports' planes
    n_u = 3 * mesh.n_nodes
    response = lambda w, p, t: jnp.sum(w[:n_u] ** 2) + jnp.sum(w[n_u:]) * 1e-2
    for pb, steps, names in ((hertz3d(mesh), 1, ["R", "E"]),
                             (hertz3d_friction(mesh), 3, ["R", "E", "mu"])):
        pb = sg.Problem(pb.mesh, pb.material, {**pb.params, "s": 0.0}, fixed=pb.fixed,
                        contact=pb.contact, shape={"s": V})
        ddm = sg.gradient(pb, response, wrt=names + ["s"], method=sg.DDM(), steps=steps)
        adj = sg.gradient(pb, response, wrt=names + ["nodes"], method=sg.Adjoint(), steps=steps)
        for k in names:
            assert adj.grad[k] == pytest.approx(ddm.grad[k], rel=1e-9), k
        assert adj.grad["nodes"].shape == (mesh.n_nodes, 3)
        assert np.sum(adj.grad["nodes"] * V) == pytest.approx(ddm.grad["s"], rel=1e-8)


@pytest.mark.parametrize("tets", [False, True])
def test_face_loads_give_the_uniform_stress(tets):
    """A pressure q on the top of a graded block (held by its symmetry planes and
    base) and a traction on a side: the uniform stress sigma_zz = -q, sigma_xz =
    tau to round-off, and the loads' resultants are the given ones."""
    g = graded_coordinates(1.0, 0.3, 3, 1.4)
    m = box(g, 0.5 * g, 2.0 * g)
    if tets:
        m = tetrahedra(m)
    q = 3.0
    pb = sg.Problem(m, sg.LinearElastic(E=100.0, nu=0.3), {"q": q},
                    fixed=[sg.Fixed("z0", 2), sg.Fixed("x0", 0), sg.Fixed("y0", 1)],
                    loads=[sg.Pressure("z1", "q")])
    sol = sg.solve(pb)
    s, _ = sol.stress()
    expect = np.zeros((3, 3))
    expect[2, 2] = -q
    assert np.allclose(s, expect, rtol=0, atol=1e-12 * q)
    assert sol.reactions()[:, 2].sum() == pytest.approx(q * 1.0 * 0.5, rel=1e-12)
    # a resultant: the force over the face's reference area
    pb = sg.Problem(m, sg.LinearElastic(E=100.0, nu=0.3), {"F": 0.2},
                    fixed=[sg.Fixed("z0", k) for k in range(3)],
                    loads=[sg.Traction("z1", (0.0, "F", 0.0), resultant=True)])
    assert sg.solve(pb).reactions()[:, 1].sum() == pytest.approx(-0.2, rel=1e-12)
    with pytest.raises(sg.InputError, match="3-D body needs 3 components"):
        sg.solve(sg.Problem(m, sg.LinearElastic(E=1.0, nu=0.3), {},
                            fixed=[sg.Fixed("z0", k) for k in range(3)],
                            loads=[sg.Traction("z1", (0.0, 1.0))]))


def test_an_implicit_sphere_is_the_sphere():
    """The sphere given as a signed-distance function (Implicit, normal and curvature
    by autodiff) gives the analytic Sphere's pressures and sensitivities to round-off."""
    from signorini.contact.obstacles3d import Implicit
    mesh = block(n=4)
    a = sg.solve(hertz3d(mesh), wrt=["R", "E"]).contact()
    pb = hertz3d(mesh)
    ball = Implicit(lambda y, p: jnp.sqrt(y @ y) - p["R"], {"R": "R"},
                    origin=(0.0, 0.0, lambda p: p["R"] + 1.0), motion=(0.0, 0.0, -D))
    pb = sg.Problem(pb.mesh, pb.material, pb.params, fixed=pb.fixed,
                    contact=[sg.Contact(ball, "z1", sg.AugmentedLagrangian(eps="E"))])
    b = sg.solve(pb, wrt=["R", "E"]).contact()
    for f in ("p_N", "dp_N_dR", "dp_N_dE", "gap"):
        assert np.allclose(a[f], b[f], rtol=0, atol=1e-11 * np.abs(a[f]).max()), f


def test_hertz3d_peak_pressure_converges_to_hertz():
    """The force-controlled sphere on the graded block: p0's error against Hertz
    falls under refinement of the fine zone, below 1 % on the finer mesh."""
    from signorini.problems.hertz3d import DEFAULTS, analytical, hertz3d_problem
    p0 = analytical(DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])["p0"]
    err = [abs(sg.solve(hertz3d_problem(n_fine=n, size=6.0)).contact()["p_N"].max() / p0 - 1)
           for n in (4, 8)]
    assert err[1] < err[0] and err[1] < 0.01, err
