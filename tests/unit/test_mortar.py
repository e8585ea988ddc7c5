"""Two deformable bodies in contact: the mortar pair (docs/theory.md §13).

The contact patch test, DDM = FD and adjoint = DDM through frictional two-body
contact, the pair against a rigid obstacle, swapping the surfaces, bad input."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import signorini as sg
from signorini.contact.mortar import pair
from signorini.errors import InputError
from signorini.fem.loads import Fixed, Pressure, Traction
from signorini.fem.mesh import merge, rectangle
from signorini.materials import Bodies, LinearElastic, NeoHooke
from signorini.problems.cylinders import cylinders_problem

P, Q = 1.0, 0.2


def patch_problem(n_low, n_up, friction=False, swap=False, kinematics="auto", material=None):
    """Two blocks on a flat interface y = 0.5 with n_low and n_up cells along it,
    under a uniform pressure (and with friction a uniform shear Q < mu P, with the
    side tractions of the uniform stress state)."""
    low = rectangle(np.linspace(0, 1, n_low + 1), np.linspace(0, 0.5, 4))
    up = rectangle(np.linspace(0, 1, n_up + 1), np.linspace(0.5, 1.0, 4))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "p": P, "mu": 0.5, "eps_t": 100.0, "q": Q, "mq": -Q}
    slave, master = ("low.top", "up.bottom") if swap else ("up.bottom", "low.top")
    if friction:
        mesh = dataclasses.replace(mesh, node_sets={**mesh.node_sets, "corner": [0]})
        fixed = [Fixed("low.bottom", 1), Fixed("corner", 0)]
        loads = [Pressure("up.top", "p"), Traction("up.top", ("q", 0.0)), Traction("low.bottom", ("mq", 0.0)),
                 Traction("up.right", (0.0, "q")), Traction("up.left", (0.0, "mq")),
                 Traction("low.right", (0.0, "q")), Traction("low.left", (0.0, "mq"))]
        method = sg.Coulomb()
    else:
        fixed = [Fixed("low.bottom", 1), Fixed("low.left", 0), Fixed("up.left", 0)]
        loads = [Pressure("up.top", "p")]
        method = sg.AugmentedLagrangian()
    return sg.Problem(mesh, material or LinearElastic(), params, fixed=fixed, loads=loads,
                      contact=[pair(slave, master, method, kinematics)])


@pytest.mark.parametrize("friction", [False, True], ids=["frictionless", "friction"])
@pytest.mark.parametrize("ratio", [(1, 1), (2, 3), (1, 3), (3, 1)], ids=["1:1", "2:3", "1:3", "3:1"])
def test_patch_test_uniform_stress(ratio, friction):
    """Non-matching meshes on a flat interface transmit a uniform pressure (and a
    uniform shear in stick) exactly: every cell's stress is the uniform one to
    round-off, the multipliers are the tractions, no node slips."""
    pb = patch_problem(2 * ratio[0], 2 * ratio[1], friction)
    sol = sg.solve(pb, steps=2 if friction else 1)
    S = np.asarray(sol.stress()[0])
    assert np.abs(S[:, 1, 1] + P).max() <= 1e-10 * P
    assert np.abs(S[:, 0, 0]).max() <= 1e-10 * P
    assert np.abs(S[:, 0, 1] - (Q if friction else 0.0)).max() <= 1e-10 * P
    c = sol.contact()
    assert np.allclose(c["p_N"], P, rtol=0, atol=1e-10)
    if friction:
        assert np.allclose(np.abs(c["p_T"]), Q, rtol=0, atol=1e-10)
        assert set(c["status"]) == {"stick"}


def test_patch_test_finite_strain():
    """With finite kinematics (neo-Hooke bodies, current normals and overlaps) the
    frictionless patch test holds too: a uniform Cauchy stress."""
    pb = patch_problem(2, 6, kinematics="finite", material=NeoHooke())
    S = np.asarray(sg.solve(pb, steps=2).stress()[0])
    for a, b in ((0, 0), (1, 1), (0, 1)):
        assert np.ptp(S[:, a, b]) <= 1e-10 * P
    assert abs(S[0, 1, 1] + P) < 1e-2  # nominal pressure P, Cauchy within the strain


def test_swapping_the_surfaces():
    """Slave and master exchanged: the same (exact) solution of the patch test,
    displacements included."""
    u = [sg.solve(patch_problem(4, 6, True, swap=s), steps=2).displacement() for s in (False, True)]
    assert np.abs(u[0] - u[1]).max() <= 1e-10 * np.abs(u[0]).max()


def test_bodies_materials_per_body():
    """Bodies: each body its own E; frictionless patch test with E2 = 30 E1 stays
    uniform, and each body's strain follows its own modulus."""
    pb = patch_problem(4, 6)
    pb = dataclasses.replace(pb, material=Bodies({"low": LinearElastic(E="E1"), "up": LinearElastic(E="E2")}),
                             params={**pb.params, "E1": 100.0, "E2": 3000.0})
    sol = sg.solve(pb)
    S = np.asarray(sol.stress()[0])
    assert np.abs(S[:, 1, 1] + P).max() <= 1e-10
    u = sol.displacement()
    top_low = pb.mesh.node_sets["low.top"]
    top_up = pb.mesh.node_sets["up.top"]
    # plane-strain compression of each 0.5-high block: (1 - nu^2) P h / E
    d_low = -u[top_low, 1].mean()
    d_up = -(u[top_up, 1].mean() - u[pb.mesh.node_sets["up.bottom"], 1].mean())
    assert d_low == pytest.approx(0.91 * P * 0.5 / 100.0, rel=1e-9)
    assert d_up == pytest.approx(0.91 * P * 0.5 / 3000.0, rel=1e-9)


def test_bodies_of_several_laws_patch_test():
    """An elastic (neo-Hooke) block on a plastic (J2) one, each law's kernels on its
    own cells, under a nominal pressure beyond the yield stress: a uniform Cauchy
    stress in each block, sigma_yy times its current width the nominal force
    (the plastic block widens more), plastic strain in the J2 block only, F-bar
    there and the standard element in the elastic one."""
    from signorini.fem.element import FBar, Standard
    from signorini.materials import J2Plasticity

    pb = patch_problem(4, 6, kinematics="linear",
                       material=Bodies({"low": J2Plasticity(), "up": NeoHooke()}))
    pb = dataclasses.replace(pb, params={**pb.params, "sigma_y": 0.6, "H": 10.0})
    sol = sg.solve(pb, steps=2)
    m = sol.model
    assert [(type(g.law).__name__, type(g.form)) for g in m.groups] == [
        ("J2Plasticity", FBar), ("NeoHooke", Standard)]
    S = np.asarray(sol.stress()[0])
    u = sol.displacement()
    assert np.abs(S[:, [0, 0], [0, 1]]).max() <= 1e-10 * P
    for g in m.groups:
        body = "low" if type(g.law) is J2Plasticity else "up"
        assert np.ptp(S[g.idx, 1, 1]) <= 1e-10 * P
        width = np.ptp(pb.mesh.nodes[pb.mesh.node_sets[body], 0] + u[pb.mesh.node_sets[body], 0])
        assert S[g.idx[0], 1, 1] * width == pytest.approx(-P, rel=1e-10)
    alpha = m.gauss_mean(np.asarray(sol.state_after(1)[2])[..., 9])
    low = m.groups[0].idx
    assert alpha[low].min() > 1e-3 and np.ptp(alpha[low]) <= 1e-10 * alpha.max()
    assert not np.any(np.delete(alpha, low))


@pytest.mark.slow  # two J2 models to compile; the grouping by law in CI: the patch test above
def test_a_law_in_two_groups_is_the_same_law():
    """Bodies of two laws that are one law (a subclass of J2Plasticity changes the
    grouping, not the physics): the same path, displacements and sensitivities as
    one law on the whole mesh, to round-off; through plasticity and frictional
    contact, DDM = central FD of the groups' own solution."""
    from signorini.materials import J2Plasticity

    @dataclasses.dataclass(frozen=True)
    class J2Again(J2Plasticity):
        pass

    def problem(upper):
        pb = _punch_problem("linear")
        return dataclasses.replace(
            pb, material=Bodies({"low": J2Plasticity(), "up": upper(E="E2")}),
            params={**pb.params, "E2": 300.0, "sigma_y": 1.0, "H": 20.0, "d": 0.03})

    names = ["E", "sigma_y", "mu"]
    one, two = (sg.solve(problem(c), steps=3, wrt=names) for c in (J2Plasticity, J2Again))
    assert len(one.model.groups) == 1 and len(two.model.groups) == 2
    assert sum(len(i.switches["elastic_plastic"]) for i in two.increments) < len(two.model.conn)
    u = one.displacement()
    assert np.abs(two.displacement() - u).max() <= 1e-10 * np.abs(u).max()
    for n in names:
        du = one.displacement_sensitivity(n)
        assert np.abs(two.displacement_sensitivity(n) - du).max() <= 1e-9 * np.abs(du).max(), n
    plastic = np.asarray(two.state_after(2)[2])[..., 9]
    assert plastic.max() > 1e-3  # the lower block yields
    pb, h = problem(J2Again), 1e-6
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    f = [sg.solve(pb.with_params(sigma_y=1.0 + s * h), steps=3, options=tight).contact() for s in (1, -1)]
    c = two.contact()
    fd = (f[0]["p_N"] - f[1]["p_N"]) / (2 * h)
    assert np.abs(c["dp_N_dsigma_y"] - fd).max() <= 1e-6 * np.abs(c["dp_N_dsigma_y"]).max()


@pytest.fixture(scope="module")
def cylinders():
    """The frictional two-cylinder problem, small mesh: P then Q = mu P / 2."""
    pb = cylinders_problem({"mu": 0.3, "Q": 0.015, "E2": 150.0}, n_fine=6)
    names = ["R1", "R2", "E1", "E2", "P", "mu", "Q"]
    return pb, names, sg.solve(pb, steps=4, wrt=names)


def test_cylinders_ddm_equals_fd(cylinders):
    """DDM = central FD of p_N and p_T for the shape of either body, the moduli of
    both, the loads and mu, through the frictional path (stick and slip nodes)."""
    pb, names, sol = cylinders
    c = sol.contact()
    st = set(c["status"][c["p_N"] > 0])
    assert {"stick", "slip"} <= st
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    for n in names:
        h = 1e-4 * abs(pb.params[n])
        f = [sg.solve(pb.with_params(**{n: pb.params[n] + s * h}), steps=4, options=tight).contact()
             for s in (1, -1)]
        for k in ("p_N", "p_T"):
            fd = (f[0][k] - f[1][k]) / (2 * h)
            ddm = c[f"d{k}_d{n}"]
            assert np.abs(ddm - fd).max() <= 1e-6 * np.abs(c["dp_N_d" + n]).max(), (n, k)


def test_patch_adjoint_equals_ddm():
    """The adjoint gradient of a response of the tractions = the DDM's through a
    frictional pair (the 2:3 patch, load and friction parameters), and projected
    on a design velocity, the adjoint with respect to every nodal coordinate."""
    pb = patch_problem(4, 6, friction=True)
    V = np.zeros_like(pb.mesh.nodes)
    V[:, 1] = pb.mesh.nodes[:, 1] * pb.mesh.nodes[:, 0]
    pb = dataclasses.replace(pb, shape={"s": V}, shape_nominal={"s": 0.0}, params={**pb.params, "s": 0.0})
    names = ["E", "p", "q", "s"]

    def response(model):
        def f(w, p, t):
            c = model.contact_fields(w, p, t, 0)
            return jnp.sum(c["area"] * (c["p_N"] ** 2 + c["p_T"] * c["p_N"]))
        return f
    ga = sg.gradient(pb, response, wrt=names + ["nodes"], steps=2, method=sg.Adjoint())
    gd = sg.gradient(pb, response, wrt=names, steps=2, method=sg.DDM())
    for n in names:
        assert ga[n] == pytest.approx(gd[n], rel=1e-10, abs=1e-12 * abs(gd["p"]))
    assert np.sum(np.asarray(ga["nodes"]) * V) == pytest.approx(gd["s"], rel=1e-10)


def test_cylinders_adjoint_equals_ddm(cylinders):
    """The adjoint gradient of a response of the tractions = the DDM's, for every
    parameter and (projected on a design velocity) every nodal coordinate."""
    pb, names, _ = cylinders

    def response(model):
        def f(w, p, t):
            c = model.contact_fields(w, p, t, 0)
            return jnp.sum(c["area"] * (c["p_N"] ** 2 + c["p_T"] * c["p_N"]))
        return f
    ga = sg.gradient(pb, response, wrt=names + ["nodes"], steps=4, method=sg.Adjoint())  # one pass
    gd = sg.gradient(pb, response, wrt=names, steps=4, method=sg.DDM())
    for n in names:
        assert ga[n] == pytest.approx(gd[n], rel=1e-10)
    for n in ("R1", "R2"):
        assert np.sum(np.asarray(ga["nodes"]) * pb.shape[n]) == pytest.approx(gd[n], rel=1e-10)


def test_cylinders_against_hertz():
    """Frictionless cylinders of different radii and moduli: p0 within 1 % and the
    contact half-width within one cell of Hertz's."""
    from signorini.problems.cylinders import analytical
    v = {"R1": 1.0, "R2": 1.5, "E1": 100.0, "E2": 200.0}
    pb = cylinders_problem(v, n_fine=16)
    c = sg.solve(pb).contact()
    h = analytical(**{k: pb.params[k] for k in ("P", "R1", "R2", "E1", "E2", "nu1", "nu2")})
    assert c["p_N"].max() == pytest.approx(h["p0"], rel=1e-2)
    x = c["x_ref"][:, 0]
    closed = x[c["p_N"] > 0]
    cell = 1.5 * h["b"] / 16 * 1.5  # the fine cells (grid sized by the nominal b0, not this b)
    assert abs(closed.max() - h["b"]) < cell and abs(-closed.min() - h["b"]) < cell


def test_stiff_body_reproduces_rigid_die():
    """A very stiff flat block pressed (displacement-controlled, sticking friction)
    on a block = the rigid flat die of the library: the block's displacements, its
    support reactions and their sensitivities to E and nu within the stiffness
    ratio. (The multipliers themselves differ by design: the pair's are the nodal
    values of the traction field, the rigid obstacle's nodal forces over areas.)"""
    low = rectangle(np.linspace(0, 1, 9), np.linspace(0, 0.5, 5))
    up = rectangle(np.linspace(0, 1, 6), np.linspace(0.5, 0.7, 3))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "Es": 1e8, "eps": 200.0, "eps_t": 200.0, "mu": 5.0, "d": -0.01}
    fixed = [Fixed("low.bottom", 0), Fixed("low.bottom", 1)]
    method = sg.Coulomb()
    stiff = sg.Problem(mesh, Bodies({"low": LinearElastic(), "up": LinearElastic(E="Es")}), params,
                       fixed=fixed + [Fixed("up.top", 0), Fixed("up.top", 1, "d")],
                       contact=[pair("low.top", "up.bottom", method)])
    rigid = sg.Problem(low, LinearElastic(), params, fixed=[Fixed("bottom", 0), Fixed("bottom", 1)],
                       contact=[sg.Contact(sg.Line((0.0, 0.5), (0.0, -1.0), (0.0, "d")), "top", method)])
    names = ["E", "nu"]
    a = sg.solve(stiff, steps=2, wrt=names)
    b = sg.solve(rigid, steps=2, wrt=names)
    assert set(a.contact()["status"]) == {"stick"} and set(b.contact()["status"]) == {"stick"}
    n = low.n_nodes
    ua, ub = a.displacement()[:n], b.displacement()
    assert np.abs(ub[:, 0]).max() > 0.05 * np.abs(ub[:, 1]).max()  # friction holds the expansion
    assert np.abs(ua - ub).max() <= 1e-5 * np.abs(ub).max()
    da, db = a.displacement_sensitivity("nu")[:n], b.displacement_sensitivity("nu")
    assert np.abs(da - db).max() <= 1e-5 * np.abs(db).max()  # (u does not depend on E here)
    bottom = low.node_sets["bottom"]

    def at_bottom(r, m):
        return np.asarray(r)[: 2 * m].reshape(-1, 2)[bottom]
    for r, s in ((a.reactions(), b.reactions()),) + tuple(
            (a.reaction_sensitivity(k), b.reaction_sensitivity(k)) for k in names):
        ra, rb = at_bottom(r, n), at_bottom(s, n)
        assert np.abs(ra - rb).max() <= 1e-5 * np.abs(rb).max()


def test_bad_pairs():
    low = rectangle(np.linspace(0, 1, 3), np.linspace(0, 0.5, 3))
    up = rectangle(np.linspace(0, 1, 4), np.linspace(0.5, 1.0, 3))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "p": 1.0}
    fixed = [Fixed("low.bottom", 1), Fixed("low.left", 0), Fixed("up.left", 0)]
    with pytest.raises(InputError, match="both 'low.top'"):
        pair("low.top", "low.top")
    with pytest.raises(InputError, match="faces any slave"):  # the two tops never face each other
        sg.solve(sg.Problem(mesh, LinearElastic(), params, fixed=fixed,
                            contact=[pair("up.top", "low.top")]))
    with pytest.raises(InputError, match="body 'up'.*no support and no contact"):
        sg.solve(sg.Problem(mesh, LinearElastic(), params, fixed=fixed[:2],
                            loads=[Pressure("up.top", "p")]))
    with pytest.raises(InputError, match="no node set 'upper'"):
        sg.solve(sg.Problem(mesh, Bodies({"low": LinearElastic(), "upper": LinearElastic()}), params,
                            fixed=fixed, contact=[pair("up.bottom", "low.top")]))
    with pytest.raises(InputError, match="formulation is for finite-strain.*LinearElastic"):
        sg.solve(dataclasses.replace(patch_problem(2, 3), formulation=sg.FBar(),
                                     material=Bodies({"low": LinearElastic(), "up": NeoHooke()})))


@pytest.mark.parametrize("friction", [False, True], ids=["frictionless", "friction"])
def test_axisymmetric_patch_test(friction):
    """Axisymmetry: two coaxial cylinders meeting on a plane with non-matching
    meshes (2:3) under a uniform pressure: the integrals weighted by 2 pi R give
    the uniform stress (sigma_zz = -p, the others 0) to round-off, the
    multipliers equal p; with friction every node sticks without shear."""
    low = rectangle(np.linspace(0, 1, 5), np.linspace(0, 0.5, 4))
    up = rectangle(np.linspace(0, 1, 7), np.linspace(0.5, 1.0, 4))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "p": P, "mu": 0.5, "eps_t": 100.0}
    pb = sg.Problem(mesh, LinearElastic(), params, kinematics=sg.Axisymmetric(),
                    fixed=[Fixed("low.bottom", 1), Fixed("low.left", 0), Fixed("up.left", 0)],
                    loads=[Pressure("up.top", "p")],
                    contact=[pair("up.bottom", "low.top", sg.Coulomb() if friction else None)])
    sol = sg.solve(pb, steps=2 if friction else 1)
    S = np.asarray(sol.stress()[0])
    assert np.abs(S[:, 1, 1] + P).max() <= 1e-10 * P
    for a, b in ((0, 0), (0, 1), (2, 2)):
        assert np.abs(S[:, a, b]).max() <= 1e-10 * P
    c = sol.contact()
    assert np.allclose(c["p_N"], P, rtol=0, atol=1e-10)
    if friction:
        assert set(c["status"]) == {"stick"} and np.abs(c["p_T"]).max() <= 1e-10


def _punch_problem(kin, Q=None, c=(0.0, 0.0)):
    """A narrow block (3 cells over 0.5) pushed by (v, -d) t into a wider one
    (4 cells over 1: non-matching) with Coulomb friction, the lower bottom
    clamped; with Q and c the whole problem moved rigidly (x -> Q x + c): every
    prescribed displacement is a vector rotated by Q."""
    low = rectangle(np.linspace(0, 1, 9), np.linspace(0, 0.5, 4))
    up = rectangle(np.linspace(0.25, 0.75, 7), np.linspace(0.5, 0.8, 4))
    mesh = merge({"low": low, "up": up})
    top = (lambda p: p["v"], lambda p: -p["d"])
    if Q is not None:
        mesh = dataclasses.replace(mesh, nodes=mesh.nodes @ Q.T + np.asarray(c))
        top = tuple((lambda i: lambda p: Q[i, 0] * p["v"] - Q[i, 1] * p["d"])(i) for i in (0, 1))
    material = LinearElastic() if kin == "linear" else NeoHooke()
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "mu": 0.3, "eps_t": 100.0, "d": 0.01, "v": 0.003}
    return sg.Problem(mesh, material, params,
                      fixed=[Fixed("low.bottom", 0), Fixed("low.bottom", 1),
                             Fixed("up.top", 0, top[0]), Fixed("up.top", 1, top[1])],
                      contact=[pair("up.bottom", "low.top", sg.Coulomb(), kin)])


@pytest.mark.parametrize("kin", ["linear", "finite"])
def test_rigid_motion_of_a_pair_changes_nothing(kin):
    """Rotating (0.7 rad) and translating the whole two-body problem rotates the
    displacements and leaves the tractions, the stick/slip status and their
    sensitivities (E, mu, d, v) unchanged, to round-off; the path has stick and slip."""
    th = 0.7
    Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    names = ["E", "mu", "d", "v"]
    ref = sg.solve(_punch_problem(kin), steps=3, wrt=names)
    rot = sg.solve(_punch_problem(kin, Q, (2.0, -1.0)), steps=3, wrt=names)
    assert [i.t for i in rot.increments] == [i.t for i in ref.increments]
    cr, co = ref.contact(), rot.contact()
    assert (cr["status"] == "stick").sum() >= 1 and (cr["status"] == "slip").sum() >= 1, cr["status"]
    np.testing.assert_array_equal(co["status"], cr["status"])
    scale = np.abs(cr["p_N"]).max()
    assert scale > 0
    for k in ("p_N", "p_T"):
        np.testing.assert_allclose(co[k], cr[k], rtol=0, atol=1e-10 * scale, err_msg=k)
        for n in names:
            key = f"d{k}_d{n}"
            s = np.abs(cr[key]).max() + scale / abs(ref.params[n])
            np.testing.assert_allclose(co[key], cr[key], rtol=0, atol=1e-9 * s, err_msg=key)
    u = ref.displacement()
    np.testing.assert_allclose(rot.displacement(), u @ Q.T, rtol=0, atol=1e-10 * np.abs(u).max())
    for n in names:
        du = ref.displacement_sensitivity(n)
        np.testing.assert_allclose(rot.displacement_sensitivity(n), du @ Q.T, rtol=0,
                                   atol=1e-9 * np.abs(u).max() / abs(ref.params[n]), err_msg=n)


def test_partner_distances_computed_once_per_increment(monkeypatch):
    """A finite-sliding pair: the increment checks (lost partners, two reaches) and
    the switch detector (partner changes) share one computation of the partner
    distances per converged increment; partners() is the distances within reach."""
    from signorini.contact import mortar
    from signorini.problems.ironing import ironing_problem

    pb = ironing_problem(cells=24, params={"s": 0.3})
    master = pb.mesh.edge_set(pb.contact[0].obstacle.master)
    nc = np.unique(pb.mesh.edge_set(pb.contact[0].edges)).size
    calls = []
    real = mortar._projections
    # the projections of both segments of every slave node (nc of them) on the master
    # surface (the candidates' search on the nominal mesh projects the nc - 1 slave
    # segments, and only when the model is built, not when a worker has it already)
    monkeypatch.setattr(mortar, "_projections", lambda seg, x, edges: calls.append(
        len(edges) == len(master) and len(seg) == nc) or real(seg, x, edges))
    sol = sg.solve(pb, steps=4)
    assert not [w for w in sol.warnings if "candidate partners" in w], sol.warnings
    assert sum(calls) == 2 * len(sol.increments)  # once per increment
    surf = sol.model.surfaces[0]
    x = np.asarray(sol.reference()) + sol.displacement()
    d = mortar.partner_distances(x, surf.patches, master)
    assert np.isfinite(d).any() and np.all(d[np.isfinite(d)] >= 0)
    for reach in (0.5, 1.0):
        assert np.array_equal(mortar.partners(x, surf.patches, master, reach), d <= reach)


def test_predictor_restarts_where_the_load_path_turns(monkeypatch):
    """P over the first half of the path, then Q: the increment after the turn
    starts from the last converged state (extrapolating would continue P), every
    other increment from the extrapolation; the converged path is the same."""
    from signorini.algorithms import stepping

    pb = cylinders_problem({"mu": 0.3, "Q": 0.015}, n_fine=12)
    seen = []
    real = stepping._LoadPath._smooth_path
    monkeypatch.setattr(stepping._LoadPath, "_smooth_path",
                        lambda self, t_new: seen.append((round(t_new, 9), r := real(self, t_new))) or r)
    sol = sg.solve(pb, steps=10)
    assert [t for t, smooth in seen if not smooth] == [0.6]  # P ends at t = 0.5
    assert [t for t, _ in seen] == [round(0.1 * k, 9) for k in range(2, 11)]  # from the second on
    plain = sg.solve(pb, steps=10, options=sg.NewtonOptions(predictor="none"))
    assert sol.newton_iterations[5] == plain.newton_iterations[5]  # the same start after the turn
    assert np.allclose(sol.increments[-1].w, plain.increments[-1].w, rtol=0, atol=1e-10 * np.abs(plain.increments[-1].w).max())


def test_coarse_to_fine_start_of_two_bodies():
    """A coarser two-body mesh guides the load path of a finer one: the same
    solution in fewer Newton iterations; the interpolation keeps to each body (a
    fine node next to the other body takes none of its values)."""
    from signorini.algorithms.coarse_to_fine import solve_coarse_to_fine
    from signorini.algorithms.prolongation import Prolongation
    from signorini.algorithms.stepping import model_for

    coarse, fine = (cylinders_problem({"mu": 0.3, "Q": 0.015}, n_fine=n) for n in (12, 24))
    direct = sg.solve(fine, steps=10)
    guided, levels = solve_coarse_to_fine([coarse, fine], steps=10)
    w, w0 = guided.increments[-1].w, direct.increments[-1].w
    assert np.abs(w - w0).max() <= 1e-10 * np.abs(w0).max()
    assert sum(levels[-1]["newton_iterations"]) < 0.8 * sum(direct.newton_iterations)  # measured 25 vs 36
    P = Prolongation.between(model_for(coarse), model_for(fine)).matrix
    mc, mf = coarse.mesh, fine.mesh
    dim = 2
    for body in ("lower", "upper"):
        other = "upper" if body == "lower" else "lower"
        rows = np.ravel(np.column_stack([dim * mf.node_sets[body] + k for k in range(dim)]))
        cols = np.ravel(np.column_stack([dim * mc.node_sets[other] + k for k in range(dim)]))
        assert P[rows][:, cols].nnz == 0
        rows_c = np.ravel(np.column_stack([dim * mc.node_sets[body] + k for k in range(dim)]))
        assert np.allclose(np.asarray(P[rows][:, rows_c].sum(axis=1)).ravel(), 1.0)  # partition of unity


def test_cylinders_cli_coarse_start(tmp_path, monkeypatch):
    """The cylinders command starts a large run from coarser meshes (here forced on
    the default mesh): summary.json lists the level, Newton needs fewer iterations
    on the fine mesh, and the contact tractions are those of a run without it."""
    import csv
    import json

    from signorini.app.cli import main
    from signorini.app.commands import cylinders as command

    monkeypatch.setattr(command, "MIN_GUIDED_DOFS", 0)
    args = ["cylinders", "--set", "mu=0.3", "--set", "Q=0.015", "--steps", "4", "--no-fd", "-q"]
    assert main(args + ["--out", str(tmp_path / "g")]) == 0
    assert main(args + ["--out", str(tmp_path / "u"), "--no-coarse-start"]) == 0
    g, u = (json.loads((tmp_path / k / "summary.json").read_text()) for k in ("g", "u"))
    assert [lv["dofs"] for lv in g["coarse_start"]] == [4764] and u["coarse_start"] == "off"
    assert sum(g["newton_iterations"]) < sum(u["newton_iterations"])

    def read(k):
        with open(tmp_path / k / "contact.csv") as f:
            rows = list(csv.DictReader(f))
        return np.array([[float(r["p_N"]), float(r["p_T"])] for r in rows])
    assert np.abs(read("g") - read("u")).max() <= 1e-9 * np.abs(read("u")).max()


def test_rigid_die_and_pair_in_one_problem():
    """A rigid flat die (frictionless, moved down by d) presses two stacked blocks
    whose interface is a mortar pair (non-matching, 2:3): both contacts in one
    Newton. The stress is uniform in both blocks, the pair's pressure is the
    die's, the die's force is the bottom's reaction, and the DDM of the reaction
    to d and E equals central differences."""
    low = rectangle(np.linspace(0, 1, 5), np.linspace(0, 0.5, 4))
    up = rectangle(np.linspace(0, 1, 4), np.linspace(0.5, 1.0, 4))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "d": 0.01}
    die = sg.Contact(sg.Line((0.0, 1.0), (0.0, -1.0), (0.0, lambda p: -p["d"])), "up.top",
                     sg.AugmentedLagrangian())
    pb = sg.Problem(mesh, LinearElastic(), params,
                    fixed=[Fixed("low.bottom", 1), Fixed("low.left", 0), Fixed("up.left", 0)],
                    contact=[die, pair("up.bottom", "low.top", sg.AugmentedLagrangian())])
    sol = sg.solve(pb, steps=2, wrt=["d", "E"])
    stress, _ = sol.stress()
    syy = stress[..., 1, 1]
    assert np.abs(syy - syy.mean()).max() <= 1e-10 * np.abs(syy).max() and syy.mean() < 0
    top, interface = sol.contact(-1, 0), sol.contact(-1, 1)
    assert np.all(top["p_N"] > 0) and np.allclose(interface["p_N"], -syy.mean(), rtol=1e-10)
    bottom = np.asarray(mesh.node_sets["low.bottom"])
    R = np.asarray(sol.reactions())[: 2 * mesh.n_nodes].reshape(-1, 2)
    assert float(R[bottom, 1].sum()) == pytest.approx(-syy.mean() * 1.0, rel=1e-10)  # upward

    def force(s):
        return np.array([np.asarray(s.reactions())[: 2 * mesh.n_nodes].reshape(-1, 2)[bottom, 1].sum()])
    for name in ("d", "E"):
        ddm = np.asarray(sol.reaction_sensitivity(name))[: 2 * mesh.n_nodes].reshape(-1, 2)[bottom, 1].sum()
        fd = sg.finite_difference(pb, name, force, steps=2, rel_step=1e-5)[0]
        assert ddm == pytest.approx(fd, rel=1e-7), name
