"""Two deformable 3-D bodies in contact: the mortar pair on faces (docs/theory.md §13.10).

The 3-D contact patch test (hexahedra on hexahedra at cell ratios 1:1, 2:3, 1:3,
tetrahedra on tetrahedra; frictionless, with friction under a uniform shear,
and with finite kinematics), exchanging slave and master, DDM = FD and adjoint
= DDM through a frictional path with a curved body, invariance under a rigid
motion of the whole problem, and bad input."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import signorini as sg
from signorini.contact.friction import STATUS_NAMES
from signorini.contact.mortar import pair
from signorini.errors import InputError
from signorini.fem.loads import Fixed, Pressure, Traction
from signorini.fem.mesh import merge
from signorini.fem.mesh3d import Mesh3D, box, tetrahedra
from signorini.materials import Bodies, LinearElastic, NeoHooke

P, Q = 1.0, 0.2


def blocks(n_low, n_up, tets=False):
    """Two unit-square blocks meeting on z = 0.5, n_low and n_up cells across;
    ``tets``: True (both blocks tetrahedra), "low" or "up" (that one: a mixed mesh)."""
    low = box(np.linspace(0, 1, n_low + 1), np.linspace(0, 1, n_low + 1), np.linspace(0, 0.5, 3))
    up = box(np.linspace(0, 1, n_up + 1), np.linspace(0, 1, n_up + 1), np.linspace(0.5, 1.0, 3))
    if tets in (True, "low"):
        low = tetrahedra(low)
    if tets in (True, "up"):
        up = tetrahedra(up)
    return merge({"low": low, "up": up})


def patch_problem(n_low, n_up, friction=False, tets=False, swap=False, kinematics="auto",
                  material=None):
    """The blocks under a uniform pressure P on top; with friction also a uniform
    shear Q < mu P (sigma_xz = Q), the tractions of that uniform state applied on
    the bottom and on the x faces."""
    mesh = blocks(n_low, n_up, tets)
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "p": P, "mu": 0.5, "eps_t": 100.0, "q": Q, "mq": -Q}
    slave, master = ("low.z1", "up.z0") if swap else ("up.z0", "low.z1")
    if friction:
        mesh = dataclasses.replace(mesh, node_sets={**mesh.node_sets, "corner": [0]})
        fixed = [Fixed("low.z0", 2), Fixed("corner", 0), Fixed("low.y0", 1), Fixed("up.y0", 1)]
        loads = [Pressure("up.z1", "p"), Traction("up.z1", ("q", 0.0, 0.0)),
                 Traction("low.z0", ("mq", 0.0, 0.0))]
        loads += [Traction(f"{b}.x1", (0.0, 0.0, "q")) for b in ("low", "up")]
        loads += [Traction(f"{b}.x0", (0.0, 0.0, "mq")) for b in ("low", "up")]
        method = sg.Coulomb()
    else:
        fixed = [Fixed("low.z0", 2)] + [Fixed(f"{b}.{s}0", k) for b in ("low", "up") for k, s in ((0, "x"), (1, "y"))]
        loads = [Pressure("up.z1", "p")]
        method = sg.AugmentedLagrangian()
    return sg.Problem(mesh, material or LinearElastic(), params, fixed=fixed, loads=loads,
                      contact=[pair(slave, master, method, kinematics)])


def check_uniform(sol, friction):
    S = np.asarray(sol.stress()[0]).reshape(-1, 3, 3)
    expect = np.zeros((3, 3))
    expect[2, 2] = -P
    if friction:
        expect[0, 2] = expect[2, 0] = Q
    assert np.abs(S - expect).max() <= 1e-10 * P
    c = sol.contact()
    assert np.abs(c["p_N"] - P).max() <= 1e-10 * P
    if friction:
        assert np.abs(np.linalg.norm(c["p_T"], axis=1) - Q).max() <= 1e-10 * P
        assert set(c["status"]) == {"stick"}


@pytest.mark.parametrize("ratio", [pytest.param((1, 1), marks=pytest.mark.slow),
                                   pytest.param((2, 3), marks=pytest.mark.slow), (1, 3)],
                         ids=["1:1", "2:3", "1:3"])
def test_patch_test_hexahedra(ratio):
    """Non-matching hexahedral meshes on a flat interface transmit a uniform
    pressure exactly: every Gauss point's stress is the uniform one to round-off,
    every multiplier the pressure."""
    check_uniform(sg.solve(patch_problem(2 * ratio[0], 2 * ratio[1])), False)


@pytest.mark.parametrize("ratio", [pytest.param((1, 1), marks=pytest.mark.slow),
                                   pytest.param((2, 3), marks=pytest.mark.slow), (1, 3)],
                         ids=["1:1", "2:3", "1:3"])
def test_patch_test_hexahedra_with_friction(ratio):
    """With friction and a uniform shear below mu P: the uniform stress, every node
    sticking, every tangential multiplier of size Q."""
    check_uniform(sg.solve(patch_problem(2 * ratio[0], 2 * ratio[1], friction=True), steps=2), True)


@pytest.mark.parametrize("friction", [False, pytest.param(True, marks=pytest.mark.slow)],
                         ids=["frictionless", "friction"])
def test_patch_test_tetrahedra(friction):
    """Triangles on triangles (tetrahedral meshes, 2:3): the same uniform state."""
    check_uniform(sg.solve(patch_problem(2, 3, friction=friction, tets=True), steps=2 if friction else 1),
                  friction)


@pytest.mark.parametrize("tets, friction", [
    ("up", False), ("up", True), ("low", False),
    pytest.param("low", True, marks=pytest.mark.slow)],  # in CI: friction with one slave kind
    ids=["tetrahedra on hexahedra", "tetrahedra on hexahedra, friction", "hexahedra on tetrahedra",
         "hexahedra on tetrahedra, friction"])
def test_patch_test_mixed_mesh(tets, friction, tmp_path):
    """A tetrahedral block on a hexahedral one (a mixed mesh, 2:3, triangles
    against quadrilaterals, either slave): the same uniform state in every cell
    of both kinds, written as one VTU file of both kinds."""
    import meshio

    from signorini.post.files import write_vtu

    mesh = blocks(2, 3, tets)
    assert mesh.mixed and [c.name for c, _ in mesh.groups()] == ["hexahedron", "tetra"]
    sol = sg.solve(patch_problem(2, 3, friction=friction, tets=tets), steps=2 if friction else 1)
    check_uniform(sol, friction)
    write_vtu(sol, tmp_path / "both.vtu")
    vtu = meshio.read(tmp_path / "both.vtu")
    kinds = {b.type: len(b.data) for b in vtu.cells}
    assert kinds == {"hexahedron": 8 if tets == "up" else 18, "tetra": 108 if tets == "up" else 48}
    sz = np.concatenate(vtu.cell_data["cauchy_stress"])[:, 8]
    assert np.abs(sz + P).max() <= 1e-10 * P


def test_patch_test_finite_kinematics():
    """Finite kinematics (neo-Hooke blocks, current normals and overlaps): a uniform
    Cauchy stress."""
    sol = sg.solve(patch_problem(2, 3, kinematics="finite", material=NeoHooke()), steps=2)
    S = np.asarray(sol.stress()[0]).reshape(-1, 3, 3)
    assert np.ptp(S, axis=0).max() <= 1e-10 * P
    assert abs(S[0, 2, 2] + P) < 2e-2  # the nominal pressure P, Cauchy within the strain


@pytest.mark.slow
def test_swapping_the_surfaces():
    """Slave and master exchanged: the same (exact) patch-test solution."""
    u = [sg.solve(patch_problem(2, 3, friction=True, swap=s), steps=2).displacement() for s in (False, True)]
    assert np.abs(u[0] - u[1]).max() <= 1e-10 * np.abs(u[0]).max()


@pytest.mark.parametrize("size", [(2, 3), pytest.param((8, 12), marks=pytest.mark.slow)],
                         ids=["one coarse level", "multigrid"])
def test_the_iterative_solver_handles_pair_rows(size):
    """solver="amg" (GMRES, the pair's multiplier rows through the block
    preconditioner's Schur complement): the patch test's uniform state, on a
    problem smaller than one coarse level (its exact solve is the preconditioner)
    and, with friction, on 2,757 unknowns (the multigrid hierarchy)."""
    friction = size == (8, 12)
    sol = sg.solve(patch_problem(*size, friction=friction), solver="amg", steps=2 if friction else 1)
    check_uniform(sol, friction)


def _ci():
    import os
    return os.environ.get("CI", "").lower() in ("1", "true", "yes")


# ------------------------------------------------------------ a curved contact
NAMES = ["E1", "E2", "p", "d", "mu", "c"]


def crown_problem():
    """A block whose bottom face is lifted by c (x^2 + y^2) (c a shape parameter,
    the design velocity fading to 0 at its top) pressed by p on a wider block
    with friction (its first touch at one node), then its top moved by d along x
    (partial slip); each block its own modulus. Non-matching meshes (cells 0.45
    and 0.5 across)."""
    low = box(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5), np.linspace(0, 0.5, 3))
    up = box(np.linspace(-0.9, 0.9, 5), np.linspace(-0.9, 0.9, 5), np.linspace(0.5, 0.9, 3))
    mesh = merge({"low": low, "up": up})
    X = mesh.nodes
    V = np.zeros_like(X)
    in_up = mesh.node_sets["up"]
    lift = (0.9 - X[in_up, 2]) / 0.4
    V[in_up, 2] = lift * (X[in_up, 0] ** 2 + X[in_up, 1] ** 2)
    params = {"E1": 100.0, "E2": 150.0, "nu": 0.3, "eps": 100.0, "eps_t": 100.0, "mu": 0.4,
              "p": 2.0, "d": 0.004, "c": 0.1}
    mesh = Mesh3D(X + 0.1 * V, mesh.cells, mesh.node_sets, mesh.face_sets)
    fixed = ([Fixed("low.z0", k) for k in range(3)] + [Fixed("up.z1", 1)]
             + [Fixed("up.z1", 0, "d", ramp=sg.Ramp(0.5, 1.0))])
    loads = [Pressure("up.z1", "p", ramp=sg.Ramp(0.0, 0.5))]
    return sg.Problem(mesh, Bodies({"low": LinearElastic(E="E1"), "up": LinearElastic(E="E2")}), params,
                      fixed=fixed, loads=loads, shape={"c": V}, shape_nominal={"c": 0.1},
                      contact=[pair("up.z0", "low.z1", sg.Coulomb())])


STEPS = 4


@pytest.fixture(scope="module")
def crown():
    pb = crown_problem()
    return pb, sg.solve(pb, steps=STEPS, wrt=NAMES)


def test_crown_ddm_equals_fd(crown):
    """DDM = central FD of the pressures and tangential tractions for the moduli
    of both bodies, the load, the slide, mu and the shape of the upper body,
    through a frictional path with stick and slip nodes."""
    pb, sol = crown
    c = sol.contact()
    closed = c["p_N"] > 0
    assert {"stick", "slip"} <= set(c["status"][closed])
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    for n in NAMES if not _ci() else ["E2", "mu", "c"]:  # in CI: one of each kind
        h = 1e-5 * abs(pb.params[n])
        f = [sg.solve(pb.with_params(**{n: pb.params[n] + s * h}), steps=STEPS, options=tight).contact()
             for s in (1, -1)]
        scale = np.abs(c["dp_N_d" + n]).max()
        for k in ("p_N", "p_T"):
            fd = (f[0][k] - f[1][k]) / (2 * h)
            assert np.abs(c[f"d{k}_d{n}"] - fd).max() <= 1e-6 * scale, (n, k)


def test_the_contact_table_equals_the_separate_functions(crown):
    """``Solution.contact`` computes a surface's values and their sensitivities in
    one program (the pair's clip once): they equal the model's separate pure
    functions (fields, status, frames and contact forces) and their own JVPs; a
    second call returns the kept result, which the caller cannot alter."""
    pb, sol = crown
    m, inc = sol.model, sol.increments[-1]
    st_n = sol.state_before(-1)[0]
    c = sol.contact()
    f = m.contact_fields(inc.w, sol.jax_params, inc.t, 0)
    status, slip = m.contact_status(inc.w, sol.jax_params, inc.t, st_n, 0)
    frames = m.contact_frames(inc.w, sol.jax_params, inc.t, st_n, 0)
    expected = {**f, "slip": slip, "normal": frames[0], "t1": frames[1], "t2": frames[2],
                "traction": frames[3]}
    scale = np.abs(c["p_N"]).max()
    for k, v in expected.items():
        assert np.abs(c[k] - np.asarray(v)).max() <= 1e-12 * max(scale, 1.0), k
    assert np.array_equal(c["status"], np.array([STATUS_NAMES[k] for k in np.asarray(status)]))
    _, d_fields = sol.response(lambda w, p, t: m.contact_fields(w, p, t, 0))
    _, d_traction = sol.history_response(lambda w, p, t, st: m.contact_frames(w, p, t, st, 0)[3])
    for n in NAMES:
        ref = np.abs(c["dp_N_d" + n]).max()
        for k in ("gap", "p_N", "p_T"):
            assert np.abs(c[f"d{k}_d{n}"] - np.asarray(d_fields[n][k])).max() <= 1e-12 * ref, (n, k)
        assert np.abs(c["dtraction_d" + n] - np.asarray(d_traction[n])).max() <= 1e-12 * ref, n
    pN = c["p_N"].copy()
    c["p_N"][:] = -1.0
    assert np.array_equal(sol.contact()["p_N"], pN)


def adjoint_equals_ddm(pb, names, steps):
    """The adjoint gradient of a response of the tractions = the DDM's for every
    parameter, and (projected on the design velocity) with respect to every nodal
    coordinate of both bodies."""
    def response(model):
        def f(w, p, t):
            c = model.contact_fields(w, p, t, 0)
            return jnp.sum(c["area"] * (c["p_N"] ** 2 + c["p_T"][:, 0] * c["p_N"]))
        return f
    ga = sg.gradient(pb, response, wrt=names + ["nodes"], steps=steps, method=sg.Adjoint())
    gd = sg.gradient(pb, response, wrt=names, steps=steps, method=sg.DDM())
    scale = max(abs(gd[n]) for n in names)
    for n in names:
        assert ga[n] == pytest.approx(gd[n], rel=1e-10, abs=1e-12 * scale), n
    assert np.sum(np.asarray(ga["nodes"]) * pb.shape["c"]) == pytest.approx(gd["c"], rel=1e-10)


@pytest.mark.slow  # the adjoint's machinery is the 2-D pairs' (test_mortar.py); the kernel is the DDM test's
def test_crown_adjoint_equals_ddm(crown):
    adjoint_equals_ddm(crown[0], NAMES, STEPS)


def test_a_rigid_motion_of_a_patch_changes_nothing():
    """Every slave node of the crown, its patch turned by an arbitrary rotation and
    moved: the weighted gap is the same, the slip point and the normal turn with
    it (finite kinematics, displaced positions), to 1e-12."""
    from signorini.model import Model
    pb = crown_problem()
    m = Model(dataclasses.replace(pb, contact=[pair("up.z0", "low.z1", sg.Coulomb(), "finite")]))
    s = m.surfaces[0]
    X = np.asarray(pb.mesh.nodes)
    rng = np.random.default_rng(1)
    x = X + 0.01 * rng.standard_normal(X.shape) * np.isin(np.arange(len(X)), s.patches.nodes)[:, None]
    A = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    A *= np.sign(np.linalg.det(A))
    b = np.array([3.0, -2.0, 5.0])
    arrays = s.patches.arrays()

    @jax.jit
    def seen(Y, y, *arr):
        node = s.patches.node(Y, *arr, linear=False)
        return node.gap(y), node.closest(y), node.normal(y)

    for j in range(0, len(s.nodes), 3):
        pn = s.patches.nodes[j]
        row = [a[j] for a in arrays]
        (g0, y0, n0), (g1, y1, n1) = (
            [np.asarray(v) for v in seen(jnp.asarray(Y), jnp.asarray(y), *row)]
            for Y, y in ((X[pn], x[pn]), (X[pn] @ A.T + b, x[pn] @ A.T + b)))
        assert abs(float(g1) - float(g0)) <= 1e-12
        assert np.abs(y1 - y0 @ A.T).max() <= 1e-12
        assert np.abs(n1 - n0 @ A.T).max() <= 1e-12


@pytest.mark.slow  # two problems' programs to compile; the pair's code is the patch and crown tests'
def test_stiff_die_reproduces_the_rigid_plane():
    """A very stiff flat block (E 1e6 times the other's) pressed into a block by a
    displacement of its top, with sticking friction, through a 3-D pair = the
    rigid plane moving by the same amount: the block's displacements, its support
    reactions and their sensitivities to E and nu within the stiffness ratio."""
    low = box(np.linspace(0, 1, 5), np.linspace(0, 1, 5), np.linspace(0, 0.5, 3))
    up = box(np.linspace(-0.1, 1.1, 4), np.linspace(-0.1, 1.1, 4), np.linspace(0.5, 0.7, 2))
    mesh = merge({"low": low, "up": up})
    params = {"E": 100.0, "nu": 0.3, "Es": 1e8, "eps": 200.0, "eps_t": 200.0, "mu": 5.0, "d": -0.01}
    fixed = [Fixed("low.z0", k) for k in range(3)]
    method = sg.Coulomb()
    stiff = sg.Problem(mesh, Bodies({"low": LinearElastic(), "up": LinearElastic(E="Es")}), params,
                       fixed=fixed + [Fixed("up.z1", 0), Fixed("up.z1", 1), Fixed("up.z1", 2, "d")],
                       contact=[pair("low.z1", "up.z0", method)])
    rigid = sg.Problem(low, LinearElastic(), params, fixed=[Fixed("z0", k) for k in range(3)],
                       contact=[sg.Contact(sg.Plane((0.0, 0.0, 0.5), (0.0, 0.0, -1.0), (0.0, 0.0, "d")),
                                           "z1", method)])
    names = ["E", "nu"]
    a = sg.solve(stiff, steps=2, wrt=names)
    b = sg.solve(rigid, steps=2, wrt=names)
    assert set(a.contact()["status"]) == {"stick"} and set(b.contact()["status"]) == {"stick"}
    n = low.n_nodes
    ua, ub = a.displacement()[:n], b.displacement()
    assert np.abs(ub[:, :2]).max() > 0.02 * np.abs(ub[:, 2]).max()  # friction holds the expansion
    assert np.abs(ua - ub).max() <= 1e-5 * np.abs(ub).max()
    da, db = a.displacement_sensitivity("nu")[:n], b.displacement_sensitivity("nu")
    assert np.abs(da - db).max() <= 1e-5 * np.abs(db).max()
    bottom = low.node_sets["z0"]

    def at_bottom(r, m):
        return np.asarray(r)[: 3 * m].reshape(-1, 3)[bottom]
    for r, q in ((a.reactions(), b.reactions()),) + tuple(
            (a.reaction_sensitivity(k), b.reaction_sensitivity(k)) for k in names):
        ra, rb = at_bottom(r, n), at_bottom(q, n)
        assert np.abs(ra - rb).max() <= 1e-5 * np.abs(rb).max()


def test_the_master_boundary_over_a_slave_node_is_a_switch():
    """Hand-made flat surfaces: a slave grid of 3 x 3 squares (z = 0, facing up)
    under a master grid facing down whose boundary edge x = 1 passes exactly over
    the slave nodes at x = 1 (the master reaching beyond the slave elsewhere).
    The nodes with a face vertex on that line (x = 0, 1, 2) are at a switch, not
    those at x = 3; moved by 1e-3 along x, none is; and the partner matrices
    follow the overlaps."""
    from signorini.contact import mortar3d
    slave = box(np.arange(4.0), np.arange(4.0), [-1.0, 0.0])
    master = box(np.linspace(-1, 1, 3), np.linspace(-1, 4, 6), [0.0, 1.0])
    X = np.vstack([slave.nodes, master.nodes])
    sf = slave.face_set("z1")
    mf = master.face_set("z0") + slave.n_nodes
    nodes = np.unique(sf)
    patches = mortar3d.build_patches(X, sf, nodes, mf, None, "t")
    on = mortar3d.boundary_switches(X, patches, mf, 1e-6)
    assert set(np.round(X[nodes[on], 0], 9)) == {0.0, 1.0, 2.0}
    assert not on[np.isclose(X[nodes, 0], 3.0)].any()
    moved = X.copy()
    moved[slave.n_nodes:, 0] += 1e-3
    assert not mortar3d.boundary_switches(moved, patches, mf, 1e-6).any()
    now = mortar3d.partners(moved, sf, nodes, mf)
    covered = np.asarray(now.sum(axis=1)).ravel() > 0  # nodes with a face under the master
    assert set(np.round(X[nodes[covered], 0], 9)) == {0.0, 1.0, 2.0}
    assert not mortar3d.outside(now, mortar3d.candidates(patches, len(mf))).any()
    assert mortar3d.changed(now, mortar3d.partners(X, sf, nodes, mf)).any()


def test_bad_pairs():
    mesh = blocks(2, 3)
    params = {"E": 100.0, "nu": 0.3, "eps": 100.0, "p": 1.0}
    fixed = [Fixed("low.z0", 2)] + [Fixed(f"{b}.{s}0", k) for b in ("low", "up") for k, s in ((0, "x"), (1, "y"))]
    with pytest.raises(InputError, match="both 'low.z1'"):
        pair("low.z1", "low.z1")
    with pytest.raises(InputError, match="no master face faces any slave face"):  # two tops
        sg.solve(sg.Problem(mesh, LinearElastic(), params, fixed=fixed, contact=[pair("up.z1", "low.z1")]))
    with pytest.raises(InputError, match="body 'up'.*no support and no contact"):
        sg.solve(sg.Problem(mesh, LinearElastic(), params, fixed=fixed[:3], loads=[Pressure("up.z1", "p")]))
    with pytest.raises(InputError, match="one dimension"):
        from signorini.fem.mesh import rectangle
        merge({"a": blocks(1, 1), "b": rectangle(np.linspace(0, 1, 2), np.linspace(0, 1, 2))})
    low = box(np.linspace(0, 1, 2), np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    tet = tetrahedra(box(np.linspace(1, 2, 2), np.linspace(0, 1, 2), np.linspace(0, 1, 2)))
    joined = np.concatenate([tet.cells + 8, -np.ones((len(tet.cells), 4), int)], axis=1)
    joined[:, :4] = np.where(np.isin(joined[:, :4] - 8, [0, 2, 4, 6]), joined[:, :4] - 7, joined[:, :4])
    with pytest.raises(InputError, match="joins hexahedra and tetrahedra"):  # no pyramids
        Mesh3D(np.vstack([low.nodes, tet.nodes]), np.vstack([low.cells, joined]))


@pytest.mark.parametrize("tets", [False, True], ids=["quadrilaterals", "triangles"])
def test_face_terms_are_the_dual_mortar_weights(tets):
    """The terms of linearised kinematics, one clip per face pair (mortar3d.face_terms):
    on a wholly covered slave face D_ab = ∫ Φ_a N_b is diagonal with ∫ N_a (the
    dual functions' biorthogonality), each row of M_ab = ∫ Φ_a N_b over the master
    vertices sums to ∫ N_a too (so a rigid translation of both surfaces changes no
    gap), and the gap and slip integrals of two coincident surfaces vanish to the
    round-off of the positions;
    the face areas add up to the slave surface's (its faces grown by the clip's
    band of CLIP_TOL x an edge's length on each side, docs/theory.md §13.9)."""
    from signorini.contact import clip3d
    from signorini.contact.mortar3d import build_patches, face_terms
    lower = box(np.linspace(0, 1, 5), np.linspace(0, 1, 5), [0.0, 0.5])
    upper = box(np.linspace(-0.1, 1.1, 8), np.linspace(-0.1, 1.1, 8), [0.5, 1.0])
    if tets:
        lower, upper = tetrahedra(lower), tetrahedra(upper)
    mesh = merge({"lower": lower, "upper": upper})
    sf, mf = mesh.face_sets["lower.z1"], mesh.face_sets["upper.z0"]
    nodes = np.unique(sf)
    pt = build_patches(mesh.nodes, sf, nodes, mf, None, "test")
    G, S, A, D, Mw, n = (np.asarray(a) for a in face_terms(jnp.asarray(mesh.nodes), pt))
    k = sf.shape[1]
    area = np.einsum("fa->f", A[:, :k])
    assert np.abs(area - area.mean()).max() <= 1e-13 and abs(area.sum() - 1.0) <= 10 * clip3d.CLIP_TOL
    for f in range(len(sf)):
        assert np.abs(D[f, :k, :k] - np.diag(A[f, :k])).max() <= 1e-13 * A[f, :k].max()
        assert np.abs(Mw[f, :k].sum(axis=(1, 2)) - A[f, :k]).max() <= 1e-13 * A[f, :k].max()
    assert np.abs(G).max() <= 1e-16 * A.max() and np.abs(S).max() <= 1e-16 * A.max()
    assert np.allclose(n, [0.0, 0.0, 1.0], atol=1e-15)


def test_finite_kinematics_tangent_by_batches_of_nodes(monkeypatch):
    """A finite-kinematics 3-D pair whose tangent would not fit at once is evaluated
    a batch of slave nodes at a time (Model._pair_batch, lax.map): here one node at
    a time, the same uniform Cauchy stress as the patch test."""
    from signorini.model.kernels import Model
    monkeypatch.setattr(Model, "PAIR_BATCH_BYTES", 1.0)
    pb = patch_problem(1, 2, kinematics="finite", material=NeoHooke())
    assert Model(pb)._pair_batch(0) == 1
    sol = sg.solve(pb, steps=1)
    S = np.asarray(sol.stress()[0]).reshape(-1, 3, 3)
    assert np.ptp(S, axis=0).max() <= 1e-10 * P


# ------------------------------------------- a mixed mesh, turned arbitrarily
HELD = ["E1", "E2", "d", "w", "mu", "c"]


def held_crown(R=np.eye(3), b=np.zeros(3)):
    """The crown's blocks, the upper one of tetrahedra (a mixed mesh: triangles
    against quadrilaterals), the lower block's bottom held and the upper block's
    top moved along t (d, 0, -w) (pressed and slid at once, partial slip); the
    whole problem (mesh, supports, design velocity) turned by R and moved by b:
    held in every component, the supports turn with it."""
    low = box(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5), np.linspace(0, 0.5, 3))
    up = tetrahedra(box(np.linspace(-0.9, 0.9, 5), np.linspace(-0.9, 0.9, 5), np.linspace(0.5, 0.9, 3)))
    mesh = merge({"low": low, "up": up})
    X = mesh.nodes
    V = np.zeros_like(X)
    in_up = mesh.node_sets["up"]
    V[in_up, 2] = (0.9 - X[in_up, 2]) / 0.4 * (X[in_up, 0] ** 2 + X[in_up, 1] ** 2)
    mesh = Mesh3D((X + 0.1 * V) @ R.T + b, mesh.cells, mesh.node_sets, mesh.face_sets)
    params = {"E1": 100.0, "E2": 150.0, "nu": 0.3, "eps": 100.0, "eps_t": 100.0, "mu": 0.4,
              "d": 0.01, "w": 0.05, "c": 0.1}
    fixed = [Fixed("low.z0", k) for k in range(3)] + [
        Fixed("up.z1", k, lambda p, k=k: R[k, 0] * p["d"] - R[k, 2] * p["w"]) for k in range(3)]
    return sg.Problem(mesh, Bodies({"low": LinearElastic(E="E1"), "up": LinearElastic(E="E2")}),
                      params, fixed=fixed, shape={"c": V @ R.T}, shape_nominal={"c": 0.1},
                      contact=[pair("up.z0", "low.z1", sg.Coulomb())])


@pytest.fixture(scope="module")
def held():
    pb = held_crown()
    return pb, sg.solve(pb, steps=2, wrt=HELD)


def test_mixed_mesh_ddm_equals_fd(held):
    """On the mixed mesh, through a frictional path with stick and slip: DDM =
    central FD of the pressures and tangential tractions (in CI: the tetrahedral
    body's modulus, mu and the shape)."""
    pb, sol = held
    c = sol.contact()
    assert {"stick", "slip"} <= set(c["status"][c["p_N"] > 0])
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    for n in HELD if not _ci() else ["E2", "mu", "c"]:
        h = 1e-5 * abs(pb.params[n])
        f = [sg.solve(pb.with_params(**{n: pb.params[n] + s * h}), steps=2, options=tight).contact()
             for s in (1, -1)]
        scale = np.abs(c["dp_N_d" + n]).max()
        for k in ("p_N", "p_T"):
            fd = (f[0][k] - f[1][k]) / (2 * h)
            assert np.abs(c[f"d{k}_d{n}"] - fd).max() <= 1e-6 * scale, (n, k)


@pytest.mark.slow  # a second model to compile; the kernel's invariance under any rotation: the patch test, in CI
def test_an_arbitrary_rigid_motion_of_the_whole_problem_changes_nothing(held):
    """The mixed problem turned by an arbitrary rotation and moved: pressures,
    status, the traction vectors (turned) and the sensitivities of the pressures
    to every parameter equal the original's to 1e-9."""
    pb, sol = held
    rng = np.random.default_rng(7)
    R = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    a, t = sol.contact(), sg.solve(held_crown(R, np.array([2.0, -3.0, 1.5])), steps=2, wrt=HELD).contact()
    scale = np.abs(a["p_N"]).max()
    assert np.array_equal(a["status"], t["status"])
    assert np.abs(a["p_N"] - t["p_N"]).max() <= 1e-9 * scale
    assert np.abs(a["traction"] @ R.T - t["traction"]).max() <= 1e-9 * scale
    for n in HELD:
        d = np.abs(a["dp_N_d" + n]).max()
        assert np.abs(a["dp_N_d" + n] - t["dp_N_d" + n]).max() <= 1e-9 * d, n


@pytest.mark.slow  # the adjoint's machinery: test_mortar.py; the mixed mesh's kernels: the DDM test
def test_mixed_mesh_adjoint_equals_ddm(held):
    """The adjoint = the DDM on the mixed mesh."""
    adjoint_equals_ddm(held[0], HELD, 2)


@pytest.mark.slow  # J2's programs to compile; history padding by law: test_mortar.py, the mixed VTU: the patch test
def test_mixed_mesh_with_plasticity_and_its_files(tmp_path):
    """J2 plasticity on the mixed patch (the tetrahedra's one Gauss point beside
    the hexahedra's eight in one history array): a uniform Cauchy stress and
    plastic strain in the cells of both kinds, the sensitivity to the yield
    stress through the history = central FD, and one VTU file holding both kinds
    of cell with their fields."""
    import meshio

    from signorini.fem.element import STANDARD
    from signorini.materials import J2Plasticity
    from signorini.post.files import write_vtu

    pb = dataclasses.replace(patch_problem(2, 3, tets="up", kinematics="linear", material=J2Plasticity()),
                             formulation=STANDARD)
    pb = dataclasses.replace(pb, params={**pb.params, "sigma_y": 0.6, "H": 10.0})
    sol = sg.solve(pb, steps=2, wrt=["sigma_y"])
    assert [inc.switches["elastic_plastic"] for inc in sol.increments] == [[], []]  # no padded point
    S = np.asarray(sol.stress()[0]).reshape(-1, 3, 3)
    assert np.ptp(S, axis=0).max() <= 1e-10 * P
    m = sol.model
    alpha = m.gauss_mean(np.asarray(sol.state_after(1)[2])[..., 9])
    assert alpha.min() > 1e-3 and np.ptp(alpha) <= 1e-10 * alpha.max()
    h = 1e-6
    u = [sg.solve(dataclasses.replace(pb, params={**pb.params, "sigma_y": 0.6 + s * h}), steps=2).displacement()
         for s in (1, -1)]
    d = np.asarray(sol.displacement_sensitivity("sigma_y"))
    assert np.abs(d - (u[0] - u[1]) / (2 * h)).max() <= 1e-6 * np.abs(d).max()
    write_vtu(sol, tmp_path / "both.vtu")
    vtu = meshio.read(tmp_path / "both.vtu")
    assert {b.type: len(b.data) for b in vtu.cells} == {"hexahedron": 8, "tetra": 108}
    eps = np.concatenate(vtu.cell_data["equivalent_plastic_strain"])
    assert np.ptp(eps) <= 1e-10 * eps.max()
