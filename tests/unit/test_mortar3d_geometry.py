"""The geometry kernel of the 3-D mortar pairs (docs/theory.md §13.9,
``signorini.contact.clip3d``): clipped overlaps and their areas, the quadrature's
exactness, the dual functions' biorthogonality, the weighted gap of flat faces
(the geometric core of the contact patch test), exact derivatives, invariance
under a rigid motion, jit and vmap."""

import itertools
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from signorini.contact import clip3d

D = 0.1  # the distance between the flat faces


@pytest.fixture(autouse=True)
def exact_clip(request, monkeypatch):
    """The clip without its tolerance band (CLIP_TOL = 0): the exact overlap, which
    these tests compare with closed forms; the tests of the band set it back."""
    if "clip_tol" not in request.keywords or os.environ.get("NOBAND"):
        monkeypatch.setattr(clip3d, "CLIP_TOL", 0.0)


def square(x0, y0, h, z=0.0, facing_down=False):
    """A square face (4, 3) of side h at height z, counter-clockwise seen from +z
    (a slave below, outward normal +z) or, facing_down, from -z (a master above)."""
    v = np.array([[x0, y0, z], [x0 + h, y0, z], [x0 + h, y0 + h, z], [x0, y0 + h, z]])
    return v[::-1].copy() if facing_down else v


def pad(tri):
    return np.vstack([np.asarray(tri, float), np.zeros((1, 3))])


SLAVE_QUAD = square(0.0, 0.0, 1.0)
SLAVE_TRI = pad([[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def gauss01(n=12):
    t, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (t + 1), 0.5 * w


def polygon_integral(V, f):
    """int f dA over the counter-clockwise polygon V (k, 2), exact for polynomials
    f of degree <= 20: Green's theorem, int f dA = oint F dy with F(x, y) = int_0^x
    f(s, y) ds, both integrals by Gauss–Legendre."""
    t, w = gauss01()
    total = 0.0
    for i in range(len(V)):
        p, q = np.asarray(V[i], float), np.asarray(V[(i + 1) % len(V)], float)
        for tk, wk in zip(t, w):
            x, y = p + tk * (q - p)
            F = x * sum(ws * f(s * x, y) for s, ws in zip(t, w))
            total += wk * F * (q[1] - p[1])
    return total


def shoelace(V):
    V = np.asarray(V, float)
    return 0.5 * np.sum(V[:, 0] * np.roll(V[:, 1], -1) - V[:, 1] * np.roll(V[:, 0], -1))


def quad_N(x, y):
    """The unit square's bilinear shape functions at (x, y)."""
    return np.array([(1 - x) * (1 - y), x * (1 - y), x * y, (1 - x) * y])


def tri_N(x, y):
    return np.array([1 - x - y, x, y, 0.0 * x])


def rotated_square():
    """The unit square turned by 45 degrees about its centre, facing down."""
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    v = SLAVE_QUAD[:, :2] - 0.5
    v = v @ np.array([[c, s], [-s, c]]) + 0.5
    return np.column_stack([v, np.full(4, D)])[::-1].copy()


def octagon():
    """The overlap of the unit square and the rotated one: the regular octagon of
    inradius 1/2 about (1/2, 1/2), its vertices at angles pi/8 + k pi/4."""
    r = 0.5 / np.cos(np.pi / 8)
    a = np.pi / 8 + np.arange(8) * np.pi / 4
    return np.column_stack([0.5 + r * np.cos(a), 0.5 + r * np.sin(a)])


TRI_IN = np.array([[0.2, 0.1], [0.7, 0.3], [0.4, 0.8]])
#: (slave, n_slave, master, n_master, the overlap polygon counter-clockwise in x, y)
CASES = {
    "shifted": (SLAVE_QUAD, 4, square(0.3, 0.2, 1.0, D, True), 4,
                np.array([[0.3, 0.2], [1, 0.2], [1, 1], [0.3, 1]])),
    "triangle inside": (SLAVE_QUAD, 4, pad(np.column_stack([TRI_IN, np.full(3, D)])[::-1]), 3, TRI_IN),
    "identical": (SLAVE_QUAD, 4, square(0.0, 0.0, 1.0, D, True), 4, SLAVE_QUAD[:, :2]),
    "rotated 45": (SLAVE_QUAD, 4, rotated_square(), 4, octagon()),
    "square over triangle": (SLAVE_TRI, 3, square(0.25, -0.5, 1.0, D, True), 4,
                             np.array([[0.25, 0], [1, 0], [0.5, 0.5], [0.25, 0.5]])),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_overlap_area(case):
    slave, ns, master, nm, poly = CASES[case]
    q = clip3d.overlap_quadrature(slave, master, ns, nm)
    assert abs(float(jnp.sum(q.w)) - shoelace(poly)) <= 1e-14
    assert int(jnp.sum(q.polygon_mask)) == len(poly)
    if case == "shifted":
        assert abs(float(jnp.sum(q.w)) - 0.7 * 0.8) <= 1e-14
    if case == "rotated 45":
        assert abs(float(jnp.sum(q.w)) - 2 * (np.sqrt(2) - 1)) <= 1e-14
    # the polygon's vertices, in the plane's frame (centre (1/2, 1/2) or (1/3, 1/3), e1 = x)
    got = np.asarray(q.polygon)[np.asarray(q.polygon_mask)] + slave[:ns, :2].mean(axis=0)
    for v in poly:
        assert np.min(np.linalg.norm(got - v, axis=1)) <= 1e-14


def test_disjoint_faces_overlap_nothing():
    master = square(1.5, 0.2, 1.0, D, True)
    q = clip3d.overlap_quadrature(SLAVE_QUAD, master, 4, 4)
    assert not np.any(np.asarray(q.polygon_mask))
    assert np.all(np.asarray(q.w) == 0.0)
    r = clip3d.weighted_gaps(SLAVE_QUAD, 4, master[None], np.array([4]))
    for a in r:
        assert np.all(np.asarray(a) == 0.0)
    # its derivatives exist and are zero
    J = jax.jacfwd(lambda m: clip3d.weighted_gaps(SLAVE_QUAD, 4, m[None], np.array([4])).gap)(master)
    assert np.all(np.asarray(J) == 0.0)


def test_clip_polygon_in_the_plane():
    """A square clipped by a triangle (either orientation of each): the part of
    the triangle inside the square."""
    sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    tri = np.array([[0.5, -0.5], [1.5, 0.5], [0.5, 0.5], [0, 0]])
    expected = 0.5 * 0.5 * 0.5 + 0.5 * 0.5 * 0.5  # the triangle's part above y = 0, left of x = 1
    for s, t in itertools.product((sq, sq[::-1]), (tri[:3], tri[:3][::-1])):
        P, m = clip3d.clip_polygon(s, t, np.ones(4, bool))
        V = np.asarray(P)[np.asarray(m)]
        assert abs(abs(shoelace(V)) - expected) <= 1e-15
    # a subject's invalid rows are ignored wherever they are
    P, m = clip3d.clip_polygon(np.vstack([sq[:2], [[9.0, 9.0]], sq[2:]]), tri[:3],
                               np.array([1, 1, 0, 1, 1], bool))
    assert abs(abs(shoelace(np.asarray(P)[np.asarray(m)])) - expected) <= 1e-15


@pytest.mark.parametrize("case", ["shifted", "triangle inside", "rotated 45", "square over triangle"])
def test_quadrature_is_exact_to_degree_5(case):
    """int x^a y^b over the overlap, a + b <= 5, equals the analytic integral."""
    slave, ns, master, nm, poly = CASES[case]
    q = clip3d.overlap_quadrature(slave, master, ns, nm)
    x, y = np.asarray(q.x_slave[:, 0]), np.asarray(q.x_slave[:, 1])
    w = np.asarray(q.w)
    for a in range(6):
        for b in range(6 - a):
            exact = polygon_integral(poly, lambda s, t, a=a, b=b: s ** a * t ** b)
            assert abs(np.sum(w * x ** a * y ** b) - exact) <= 1e-14, (a, b)


def test_points_lie_on_both_faces_above_the_plane_point():
    """On a warped slave quadrilateral and a skew master: the slave point and the
    master point of every quadrature point are on the line along n through it
    (the Newton inversion of the bilinear maps converged)."""
    slave = np.array([[0, 0, 0.02], [1.1, 0.05, -0.03], [1.0, 0.9, 0.04], [-0.1, 1.0, -0.01]])
    master = np.array([[0.2, 1.2, 0.15], [1.3, 1.1, 0.05], [1.2, 0.1, 0.1], [0.3, -0.2, 0.2]])
    q = clip3d.overlap_quadrature(slave, master, 4, 4)
    c, n, e1, e2 = (np.asarray(a) for a in clip3d.face_frame(slave, 4))
    used = np.asarray(q.w) > 0
    E = np.stack([e1, e2], axis=1)
    for x in (np.asarray(q.x_slave), np.asarray(q.x_master)):
        assert np.abs((x[used] - c) @ E - np.asarray(q.plane)[used]).max() <= 1e-14
    between = np.asarray(q.x_master - q.x_slave)[used]
    assert np.abs(np.cross(between, n)).max() <= 1e-14
    assert np.abs(np.asarray(q.N_slave).sum(axis=1) - 1).max() <= 1e-14


def _joint(parts):
    """Concatenate the quadratures of several master faces of one slave face."""
    return (jnp.concatenate([p.N_slave for p in parts]), jnp.concatenate([p.w for p in parts]))


@pytest.mark.parametrize("kind", ["quad", "tri"])
def test_dual_functions_are_biorthogonal_on_a_partly_covered_face(kind):
    if kind == "quad":
        slave, ns = SLAVE_QUAD, 4
        masters = [square(0.35, -0.4, 0.8, D, True), square(0.35, 0.4, 0.8, D, True)]
    else:
        slave, ns = SLAVE_TRI, 3
        masters = [square(-0.3, 0.15, 0.6, D, True), square(0.3, 0.15, 0.6, D, True)]
    N, w = _joint([clip3d.overlap_quadrature(slave, m, ns, 4) for m in masters])
    mask = (np.arange(4) < ns).astype(float)
    phi = np.asarray(clip3d.dual_functions(N, w, mask))
    N, w = np.asarray(N), np.asarray(w)
    assert 0.2 < w.sum() < (0.9 if kind == "quad" else 0.45)  # partly covered
    G = (phi * w[:, None]).T @ N  # int Phi_j N_k
    d = w @ N
    assert np.abs(G - np.diag(d * mask)).max() <= 1e-12
    assert np.all(phi[:, ns:] == 0.0)
    # the dual functions sum to one where the face is covered
    assert np.abs(phi.sum(axis=1) - 1)[w > 0].max() <= 1e-12


def test_dual_functions_on_a_wholly_covered_face():
    """The closed forms: Phi_j = 3 N_j - N_k - N_l on a triangle, Phi_1 = 4 N_1 -
    2 N_2 + N_3 - 2 N_4 (and its rotations) on a parallelogram."""
    q = clip3d.overlap_quadrature(SLAVE_TRI, square(-0.5, -0.5, 2.0, D, True), 3, 4)
    N = np.asarray(q.N_slave)
    phi = np.asarray(clip3d.dual_functions(q.N_slave[:, :3], q.w))
    used = np.asarray(q.w) > 0
    expect = 4 * N[:, :3] - 1
    assert np.abs(phi - expect)[used].max() <= 1e-12
    para = np.array([[0, 0, 0], [1, 0.2, 0], [1.5, 1.2, 0], [0.5, 1.0, 0]])
    q = clip3d.overlap_quadrature(para, square(-1, -1, 4.0, D, True), 4, 4)
    N = np.asarray(q.N_slave)
    phi = np.asarray(clip3d.dual_functions(q.N_slave, q.w))
    used = np.asarray(q.w) > 0
    for j in range(4):
        r = [(j + i) % 4 for i in range(4)]
        expect = 4 * N[:, r[0]] - 2 * N[:, r[1]] + N[:, r[2]] - 2 * N[:, r[3]]
        assert np.abs(phi[:, j] - expect)[used].max() <= 1e-12


def master_grid(x0, y0, h, nx, ny, z=D):
    """A grid of nx x ny square master faces of side h from (x0, y0), facing down."""
    faces = [square(x0 + i * h, y0 + k * h, h, z, True) for i in range(nx) for k in range(ny)]
    return np.array(faces), np.full(len(faces), 4)


@pytest.mark.parametrize("ratio", [(1, 1), (2, 3), (1, 3)], ids=["1:1", "2:3", "1:3"])
def test_flat_parallel_faces_quad_on_quad(ratio):
    """Each slave node's weighted gap is D int N_j over the covered part, whatever
    the master cells' size and offset (the contact patch test's geometric core),
    and its weighted relative position -D n int N_j."""
    h = ratio[0] / ratio[1]
    nx, ny = {(1, 1): (1, 1), (2, 3): (2, 1), (1, 3): (4, 2)}[ratio]
    x0, y0 = -0.25, -0.1
    faces, nm = master_grid(x0, y0, h, nx, ny)
    r = clip3d.weighted_gaps(SLAVE_QUAD, 4, faces, nm)
    xe, ye = min(1.0, x0 + nx * h), min(1.0, y0 + ny * h)
    assert xe < 1.0 or ye < 1.0  # partly covered
    cover = [[0, 0], [xe, 0], [xe, ye], [0, ye]]
    A = np.array([polygon_integral(cover, lambda x, y, j=j: quad_N(x, y)[j]) for j in range(4)])
    assert np.abs(np.asarray(r.area) - A).max() <= 1e-14
    assert np.abs(np.asarray(r.gap) - D * A).max() <= 1e-14
    slip = np.asarray(r.slip)
    assert np.abs(slip[:, :2]).max() <= 1e-15
    assert np.abs(slip[:, 2] + D * A).max() <= 1e-14


def test_flat_parallel_faces_tri_on_quad_and_quad_on_tri():
    # a slave triangle under master squares of side 1/3 covering x <= 17/30
    faces, nm = master_grid(-0.1, -0.2, 1 / 3, 2, 4)
    r = clip3d.weighted_gaps(SLAVE_TRI, 3, faces, nm)
    xe = -0.1 + 2 / 3
    cover = [[0, 0], [xe, 0], [xe, 1 - xe], [0, 1]]
    A = np.array([polygon_integral(cover, lambda x, y, j=j: tri_N(x, y)[j]) for j in range(4)])
    assert np.abs(np.asarray(r.area) - A).max() <= 1e-14
    assert np.abs(np.asarray(r.gap) - D * A).max() <= 1e-14
    # a slave square under master triangles (each master square split in two) covering y <= 0.6
    tris = []
    for f in master_grid(-0.2, -0.4, 0.5, 3, 2)[0]:
        tris += [pad(f[[0, 1, 2]]), pad(f[[0, 2, 3]])]
    r = clip3d.weighted_gaps(SLAVE_QUAD, 4, np.array(tris), np.full(len(tris), 3))
    cover = [[0, 0], [1, 0], [1, 0.6], [0, 0.6]]
    A = np.array([polygon_integral(cover, lambda x, y, j=j: quad_N(x, y)[j]) for j in range(4)])
    assert np.abs(np.asarray(r.area) - A).max() <= 1e-14
    assert np.abs(np.asarray(r.gap) - D * A).max() <= 1e-14


@pytest.mark.parametrize("kind", ["quad", "tri"])
def test_a_linear_gap_weighs_to_its_nodal_value(kind):
    """With the dual weights, a gap that is linear over the face gives int Phi_j g
    = g(x_j) int N_j on a partly covered face (the nodes' constraints do not couple)."""
    slave, ns = (SLAVE_QUAD, 4) if kind == "quad" else (SLAVE_TRI, 3)
    faces, nm = master_grid(-0.15, 0.3, 0.4, 4, 3)
    gap = lambda x, y: D + 0.05 * x - 0.03 * y
    faces = faces.copy()
    faces[..., 2] = gap(faces[..., 0], faces[..., 1])
    r = clip3d.weighted_gaps(slave, ns, faces, nm)
    nodal = gap(slave[:, 0], slave[:, 1]) * (np.arange(4) < ns)
    area = np.asarray(r.area)
    assert 0 < area[0] < area.max()  # partly covered
    assert np.abs(np.asarray(r.gap) - nodal * area).max() <= 1e-14


GENERIC_SLAVE = np.array([[0.0, 0.0, 0.02], [1.1, 0.05, -0.03], [1.0, 0.9, 0.04], [-0.1, 1.0, -0.01]])
GENERIC_MASTERS = np.array([
    [[0.31, 0.47, 0.12], [0.93, -0.21, 0.17], [-0.17, -0.33, 0.09], [0.0, 0.0, 0.0]],   # triangle
    [[0.52, 1.31, 0.11], [1.27, 0.83, 0.16], [0.93, -0.21, 0.17], [0.31, 0.47, 0.12]],  # quadrilateral
])
GENERIC_NM = np.array([3, 4])


def _all_outputs(xs, xm, ns):
    r = clip3d.weighted_gaps(xs, ns, xm, GENERIC_NM)
    return jnp.concatenate([r.gap, r.slip.reshape(-1), r.area])


@pytest.mark.parametrize("ns", [4, 3], ids=["quad", "tri"])
def test_derivatives_equal_central_differences(ns):
    """jacfwd of the weighted gap, slip and area with respect to every vertex
    coordinate equals central differences at a generic configuration (a warped
    slave quadrilateral, or a triangle, under a skew master triangle and
    quadrilateral: no vertex on an edge)."""
    xs, xm = GENERIC_SLAVE.copy(), GENERIC_MASTERS.copy()
    if ns == 3:
        xs[3] = 0.0
    f = jax.jit(lambda a, b: _all_outputs(a, b, ns))
    k = int(jnp.sum(clip3d.overlap_quadrature(xs, xm[1], ns, 4).polygon_mask))
    assert k >= 5  # a clipped polygon, not a face
    Js, Jm = jax.jacfwd(f, argnums=(0, 1))(xs, xm)
    J = np.concatenate([np.asarray(Js).reshape(len(Js), -1), np.asarray(Jm).reshape(len(Jm), -1)], axis=1)
    h = 1e-6
    x = np.concatenate([xs.ravel(), xm.ravel()])
    F = np.zeros_like(J)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        fp = f((x + e)[:12].reshape(4, 3), (x + e)[12:].reshape(xm.shape))
        fm = f((x - e)[:12].reshape(4, 3), (x - e)[12:].reshape(xm.shape))
        F[:, i] = (np.asarray(fp) - np.asarray(fm)) / (2 * h)
    assert np.abs(J).max() > 0.1
    assert np.abs(J - F).max() <= 1e-7 * np.abs(J).max()
    if ns == 3:  # a triangle's fourth row is no vertex
        assert np.all(J[:, 9:12] == 0.0)


def test_a_rigid_motion_changes_nothing():
    rng = np.random.default_rng(5)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.linalg.det(Q))
    t = np.array([3.0, -2.0, 7.5])
    r0 = clip3d.weighted_gaps(GENERIC_SLAVE, 4, GENERIC_MASTERS, GENERIC_NM)
    r1 = clip3d.weighted_gaps(GENERIC_SLAVE @ Q.T + t, 4, GENERIC_MASTERS @ Q.T + t, GENERIC_NM)
    for a, b in ((r0.gap, r1.gap), (r0.area, r1.area)):
        a, b = np.asarray(a), np.asarray(b)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()
    s0, s1 = np.asarray(r0.slip), np.asarray(r1.slip)
    assert np.abs(s0 @ Q.T - s1).max() <= 1e-12 * np.abs(s0).max()


def test_jit_and_vmap_over_face_pairs():
    """A batch of pairs with triangles and quadrilaterals mixed (the vertex counts
    are data): the compiled, vectorised kernel gives each pair's values."""
    rng = np.random.default_rng(2)
    slaves, masters, ns, nms = [], [], [], []
    for b in range(6):
        s = GENERIC_SLAVE + 0.05 * rng.normal(size=(4, 3))
        m = GENERIC_MASTERS + 0.05 * rng.normal(size=(2, 4, 3))
        slaves.append(s)
        masters.append(m)
        ns.append(3 if b % 2 else 4)
        nms.append([3, 4] if b % 3 else [4, 3])
    slaves, masters, ns, nms = map(np.array, (slaves, masters, ns, nms))
    batched = jax.jit(jax.vmap(clip3d.weighted_gaps))(slaves, ns, masters, nms)
    for b in range(len(slaves)):
        one = clip3d.weighted_gaps(slaves[b], int(ns[b]), masters[b], nms[b])
        for x, y in zip(batched, one):
            assert np.abs(np.asarray(x[b]) - np.asarray(y)).max() <= 1e-14 * max(1.0, np.abs(np.asarray(y)).max())
        assert np.asarray(one.area).sum() > 0.1
    q = jax.jit(jax.vmap(clip3d.overlap_quadrature))(slaves, masters[:, 1], ns, nms[:, 1])
    assert q.w.shape == (len(slaves), clip3d.NQ)


@pytest.mark.clip_tol
def test_the_clip_keeps_a_band_of_clip_tol_outside_the_slave_face():
    """With its tolerance the clip is the exact clip by the slave polygon moved
    outward by CLIP_TOL x each edge's length: the shifted square's overlap is
    (0.7 + tol) x (0.8 + tol)."""
    tol = clip3d.CLIP_TOL
    assert tol > 0
    slave, ns, master, nm, _ = CASES["shifted"]
    q = clip3d.overlap_quadrature(slave, master, ns, nm)
    assert abs(float(jnp.sum(q.w)) - (0.7 + tol) * (0.8 + tol)) <= 1e-15


@pytest.mark.clip_tol
@pytest.mark.parametrize("noise", [(0.0, 0.0), (2.3e-16, -1.2e-16), (-1.2e-16, 2.3e-16), (1e-15, -1e-15)])
def test_master_faces_along_the_slave_edges_have_bounded_derivatives(noise):
    """Two master faces A (over the slave) and B (its neighbour) share the edge
    x = 1 that lies, to round-off, along the slave's edge (matching meshes,
    coincident boundaries: its two ends on either side of the slave's edge by
    ``noise``). The covered area summed over A and B does not change
    when the shared edge moves (its derivative is 0: what A loses, B gains), and
    the second derivatives of the weighted gap stay of the order of the geometry
    (without the band, round-off placed a crossing point anywhere along the edge
    and they reached 1e13)."""
    slave = SLAVE_QUAD

    def total(e):
        A = square(0.0, 0.0, 1.0, D, True)
        B = square(1.0, 0.0, 1.0, D, True)
        A = A.copy()
        B = B.copy()
        A[[1, 2], 0] = 1.0 + np.array(noise)  # facing down: A's rows 1, 2 and B's 0, 3 at x = 1
        B[[0, 3], 0] = 1.0 + np.array(noise)
        A = jnp.asarray(A).at[jnp.array([1, 2]), 0].add(e)
        B = jnp.asarray(B).at[jnp.array([0, 3]), 0].add(e)
        wg = clip3d.weighted_gaps(slave, 4, jnp.stack([A, B]), jnp.array([4, 4]))
        return jnp.sum(wg.area), wg.gap

    assert abs(float(jax.grad(lambda e: total(e)[0])(0.0))) <= 1e-9
    H = jax.jacfwd(jax.jacfwd(lambda e: total(e)[1]))(0.0)
    assert np.all(np.isfinite(H)) and np.abs(H).max() <= 10.0
