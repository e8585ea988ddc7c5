"""The public responses (signorini.responses) in plane strain, axisymmetry and 3-D,
with a rigid obstacle and with a pair of bodies: each equals what it measures
(equilibrium: the contact force is the applied load), and its DDM sensitivity
equals central differences of its own value and the adjoint's gradient."""

from pathlib import Path

import numpy as np
import pytest

import signorini as sg
from signorini import responses as rs
from signorini.problems.cylinders import cylinders_problem
from signorini.problems.hertz import hertz_problem
from signorini.problems.hertz3d import hertz3d_problem

TIGHT = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)


def plane_strain():
    pb = hertz_problem(n_fine=8, size=8.0)
    rsp = [rs.contact_force(component=1), rs.displacement("bottom", 1), rs.contact_force(), rs.contact_area(), rs.max_pressure(), rs.pressure_norm(),
           rs.contact_work()]
    return pb, 1, ["R", "E", "P"], rsp, (rs.contact_force(component=1), 0.5 * pb.params["P"])


def axisymmetric():
    pb = hertz3d_problem({"mu": 0.3}, n_fine=8, size=6.0, axisymmetric=True)
    rsp = [rs.contact_force(component=1), rs.displacement(0, 1), rs.pressure_norm(order=4),
           rs.contact_work(), rs.stick_area()]
    return pb, 3, ["R", "E", "mu"], rsp, (rs.contact_force(component=1), pb.params["P"])


def three_d():
    pb = hertz3d_problem({"mu": 0.3}, n_fine=4, size=6.0)
    rsp = [rs.contact_force(component=2), rs.pressure_norm(), rs.contact_force(component=0),
           rs.displacement("z0", 2), rs.contact_area(), rs.stick_area()]
    return pb, 3, ["R", "E", "mu"], rsp, (rs.contact_force(component=2), 0.25 * pb.params["P"])


def pair():
    pb = cylinders_problem({"mu": 0.3, "Q": 0.015}, n_fine=6)
    rsp = [rs.reaction("lower.bottom", 1), rs.contact_force(component=0), rs.pressure_norm(),
           rs.contact_force(component=1), rs.stick_area()]
    return pb, 4, ["R1", "E2", "mu"], rsp, (rs.reaction("lower.bottom", 1), pb.params["P"])


def own_gmsh_mesh():
    """A user's own 3-D mesh from a gmsh file: a tetrahedral die (physical volume
    "die") pressed by P on a hexahedral base ("base", on its "floor"), the faces
    "base_top", "die_face" and "load" named by physical surfaces: a mixed mesh and
    a mortar pair, each body its own modulus."""
    import tempfile

    import meshio

    base = sg.box(np.linspace(0, 1, 6), np.linspace(0, 1, 6), np.linspace(0, 0.4, 3))
    die = sg.tetrahedra(sg.box(np.linspace(0.3, 0.7, 4), np.linspace(0.3, 0.7, 4), np.linspace(0.4, 0.6, 2)))
    off = base.n_nodes
    blocks = [("hexahedron", base.cells, 1), ("tetra", die.cells + off, 2),
              ("quad", base.face_sets["z0"], 3), ("quad", base.face_sets["z1"], 4),
              ("triangle", die.face_sets["z0"] + off, 5), ("triangle", die.face_sets["z1"] + off, 6)]
    path = Path(tempfile.mkdtemp()) / "own.msh"
    meshio.Mesh(np.vstack([base.nodes, die.nodes]), [(k, c) for k, c, _ in blocks],
                cell_data={"gmsh:physical": [np.full(len(c), t) for _, c, t in blocks],
                           "gmsh:geometrical": [np.full(len(c), t) for _, c, t in blocks]},
                field_data={"base": np.array([1, 3]), "die": np.array([2, 3]), "floor": np.array([3, 2]),
                            "base_top": np.array([4, 2]), "die_face": np.array([5, 2]),
                            "load": np.array([6, 2])}).write(path, file_format="gmsh22", binary=False)
    mesh = sg.read_mesh(path)
    assert mesh.mixed
    pb = sg.Problem(mesh, sg.Bodies({"base": sg.LinearElastic(E="E1"), "die": sg.LinearElastic(E="E2")}),
                    {"E1": 100.0, "E2": 300.0, "nu": 0.3, "P": 0.2, "eps": 1000.0},
                    fixed=[sg.Fixed("floor", k) for k in range(3)] + [sg.Fixed("load", 0), sg.Fixed("load", 1)],
                    loads=[sg.Pressure("load", "P", resultant=True)],
                    contact=[sg.pair("die_face", "base_top", sg.AugmentedLagrangian(eps="eps"))])
    rsp = [rs.pressure_norm(), rs.reaction("floor", 2), rs.contact_force(component=2),
           rs.displacement("load", 2), rs.contact_area()]
    return pb, 1, ["E1", "E2", "P"], rsp, (rs.reaction("floor", 2), pb.params["P"])


@pytest.mark.parametrize("case", [plane_strain, axisymmetric, three_d, pair, own_gmsh_mesh],
                         ids=["plane strain", "axisymmetric, friction", "3-D, friction", "2-D pair, friction",
                              "own 3-D gmsh mesh, mixed, pair"])
def test_responses_and_their_sensitivities(case):
    """DDM (Response.of) = central FD of the response's value to 1e-6, the adjoint
    gradient = the DDM to 1e-10 (the first responses; all of them outside CI), and
    the contact force on the body balances the applied load."""
    import os

    pb, steps, names, responses, balance = case()
    sol = sg.solve(pb, steps=steps, wrt=names, options=TIGHT)
    if balance is not None:
        force, load = balance
        assert abs(force(sol)) == pytest.approx(load, rel=1e-9)
    moved = {}
    for n in names:
        h = 1e-5 * abs(pb.params[n])
        moved[n] = (h, [sg.solve(pb.with_params(**{n: pb.params[n] + s * h}), steps=steps, options=TIGHT)
                        for s in (1, -1)])
    ci = os.environ.get("CI", "").lower() in ("1", "true", "yes")
    # a response that vanishes by symmetry (the x force of a quarter model with linearised
    # kinematics) is compared with the size of the first response's sensitivity
    typical = {n: abs(responses[0].of(sol)[1][n]) for n in names}
    for k, r in enumerate(responses):
        value, ddm = r.of(sol)
        scale = {n: max(abs(ddm[n]), abs(value) / abs(pb.params[n]), 1e-9 * typical[n]) for n in names}
        for n in names:
            h, (plus, minus) = moved[n]
            fd = (r(plus) - r(minus)) / (2 * h)
            assert abs(ddm[n] - fd) <= 1e-6 * scale[n], (r, n, ddm[n], fd)
        if ci and k >= 2:
            continue
        ga = sg.gradient(pb, r, wrt=names, steps=steps, method=sg.Adjoint(), solution=sol)
        for n in names:
            assert abs(ga[n] - ddm[n]) <= 1e-10 * scale[n], (r, n, ga[n], ddm[n])


def test_a_history_over_the_path():
    """Response.path lists the value at every increment; gradient(increments="all")
    is the sum of the increments' DDM sensitivities."""
    pb = hertz3d_problem({"mu": 0.3}, n_fine=8, size=6.0, axisymmetric=True)
    sol = sg.solve(pb, steps=3, wrt=["mu", "E"])
    r = rs.contact_force(component=1)
    path = r.path(sol)
    assert path == pytest.approx([-pb.params["P"] * t for t in (1 / 3, 2 / 3, 1.0)], rel=1e-9)  # on the block
    g = sg.gradient(pb, r, wrt=["mu", "E"], steps=3, increments="all", method=sg.DDM())
    for n in ("mu", "E"):
        assert g[n] == pytest.approx(sum(r.of(sol, i)[1][n] for i in range(3)), rel=1e-10, abs=1e-14)


def test_bad_responses():
    pb = hertz_problem(n_fine=8, size=8.0)
    sol = sg.solve(pb)
    with pytest.raises(sg.InputError, match="surface 1 does not exist"):
        rs.contact_force(surface=1)(sol)
    with pytest.raises(sg.InputError, match="component must be 0..1"):
        rs.contact_force(component=2)(sol)
    with pytest.raises(sg.InputError, match="not held by a support"):
        rs.reaction("left", 1)(sol)
    with pytest.raises(sg.InputError, match="no friction"):
        rs.stick_area()(sol)
    with pytest.raises(sg.InputError, match="order must be at least 1"):
        rs.pressure_norm(order=0.5)


def test_traction_vectors_sensitivities_and_switch_points():
    """3-D: Solution.contact() gives the traction vectors' sensitivities (= central
    FD of the traction vectors), their sum times the areas is the contact force;
    switch_points() lists the path's switch points by increment, kind and surface."""
    pb = hertz3d_problem({"mu": 0.3}, n_fine=4, size=6.0)
    sol = sg.solve(pb, steps=3, wrt=["mu"], options=TIGHT)
    c = sol.contact()
    assert np.sum(c["traction"] * c["area"][:, None], axis=0) == pytest.approx(
        [rs.contact_force(component=k)(sol) for k in range(3)], rel=1e-12, abs=1e-15)
    h = 1e-5 * pb.params["mu"]
    f = [sg.solve(pb.with_params(mu=pb.params["mu"] + s * h), steps=3, options=TIGHT).contact()["traction"]
         for s in (1, -1)]
    d = c["dtraction_dmu"]
    assert np.abs(d - (f[0] - f[1]) / (2 * h)).max() <= 1e-6 * np.abs(d).max()
    rows = sol.switch_points()
    for r in rows:
        assert set(r) == {"increment", "t", "kind", "surface", "nodes"} and r["nodes"]
        assert r["nodes"] == sol.increments[r["increment"]].switches[r["kind"]][r["surface"]]
    assert len(rows) == sum(len(n) > 0 for inc in sol.increments for k, v in inc.switches.items()
                            if k != "elastic_plastic" for n in v)


def test_a_fit_to_a_measured_history():
    """Objective over the path: the block's modulus and Poisson's ratio
    (axisymmetric sphere, with friction), fitted by Objective(increments="all")
    and minimize to a synthetic history of the block's displacement (three
    increments), come back to the true values; the gradient of a misfit of two
    histories (displacement and contact work): DDM = adjoint = central
    differences of the objective."""
    pb = hertz3d_problem({"mu": 0.3}, n_fine=8, size=6.0, axisymmetric=True)
    true = np.array([pb.params["E"], pb.params["nu"]])
    u, work = rs.displacement(0, 1), rs.contact_work()
    sol = sg.solve(pb, steps=3, options=TIGHT)
    times = [1 / 3, 2 / 3, 1.0]
    u_m, w_m = u.path(sol), work.path(sol)
    fit_u = rs.misfit(u, times, u_m, weights=1 / u_m ** 2)  # relative misfits
    fit_w = rs.misfit(work, times, w_m, weights=1 / w_m ** 2)
    assert fit_u(sol) == 0.0
    x = np.array([80.0, 0.25])
    start = pb.with_params(E=x[0], nu=x[1])

    class Both(rs.Response):  # the two misfits, one objective
        def __init__(self):
            super().__init__("both", lambda m: (lambda w, p, t, s: fit_u(m)(w, p, t, s) + fit_w(m)(w, p, t, s)))

    objs = {k: sg.Objective(start, ["E", "nu"], Both(), steps=3, increments="all", options=TIGHT, method=meth)
            for k, meth in (("ddm", sg.DDM()), ("adjoint", sg.Adjoint()))}
    g_ddm, g_adj = objs["ddm"].jac(x), objs["adjoint"].jac(x)
    assert g_adj == pytest.approx(g_ddm, rel=1e-10)
    for k, h in enumerate((1e-4, 1e-6)):
        e = np.zeros(2)
        e[k] = h
        fd = (objs["ddm"].fun(x + e) - objs["ddm"].fun(x - e)) / (2 * h)
        assert fd == pytest.approx(g_ddm[k], rel=1e-6)
    res = sg.minimize(sg.Objective(start, ["E", "nu"], fit_u, steps=3, increments="all", options=TIGHT),
                      x, method="BFGS", gtol=1e-10)
    assert res.x == pytest.approx(true, rel=1e-6), res.message
