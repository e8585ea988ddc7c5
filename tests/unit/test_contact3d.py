"""Contact in three dimensions: the rigid obstacles (signorini.contact.obstacles3d)
and the Coulomb-disc law (signorini.contact.friction3d)."""

from __future__ import annotations

import numpy as np
import pytest

from signorini import Coulomb, InputError, Line
from signorini._jax import jax, jnp
from signorini.contact.friction3d import CoulombDisc, reference_axis, tangent_basis
from signorini.contact.obstacles3d import Cylinder, Implicit, Plane, Sphere

P = {"R": 1.3, "mu": 0.3, "eps": 10.0, "eps_t": 7.0}
RNG = np.random.default_rng(0)
POINTS = jnp.asarray(RNG.uniform(-0.5, 0.5, (6, 3)) + np.array([0.2, -0.1, -0.4]))


def implicit_sphere():
    return Implicit(lambda y, p: jnp.sqrt(y @ y) - p["R"], {"R": "R"}, origin=(0.1, -0.2, "R"),
                    motion=(0.05, 0.0, -0.2))


def test_implicit_sphere_is_the_sphere_to_round_off():
    """Gap, normal, closest point and their derivatives with respect to the point
    and to R: the same for the signed distance of a sphere as for the Sphere."""
    s = Sphere(centre=(0.1, -0.2, "R"), motion=(0.05, 0.0, -0.2))
    i = implicit_sphere()
    for t in (0.0, 0.7):
        for x in POINTS:
            for f in ("gap", "normal", "closest"):
                a = lambda x_, R: getattr(s, f)(x_, s.geometry({**P, "R": R}, t))
                b = lambda x_, R: getattr(i, f)(x_, i.geometry({**P, "R": R}, t))
                for val in (lambda g: g(x, 1.3), lambda g: jax.jacfwd(g, argnums=(0, 1))(x, 1.3)):
                    va, vb = val(a), val(b)
                    for p, q in zip(jax.tree_util.tree_leaves(va), jax.tree_util.tree_leaves(vb)):
                        assert np.allclose(p, q, rtol=1e-14, atol=1e-14), f


@pytest.mark.parametrize("obstacle", [Plane(point=(0.1, 0.2, 0.3), normal_vector=(0.2, -0.3, -1.0),
                                            motion=(0.1, 0.0, -0.3)),
                                      Sphere(motion=(0.0, 0.1, -0.2)),
                                      Cylinder(axis=(0.3, 1.0, 0.1), motion=(0.1, 0.0, -0.2)),
                                      implicit_sphere()])
def test_obstacle_kinematics(obstacle):
    """n = grad g (unit); the closest point lies on the surface (g = 0) and x =
    c + y + g n; a point carried along with the obstacle keeps its closest point."""
    obstacle.check(P)
    for x in POINTS:
        geo = obstacle.geometry(P, 0.3)
        g, n, y = obstacle.gap(x, geo), obstacle.normal(x, geo), obstacle.closest(x, geo)
        assert np.allclose(jax.grad(obstacle.gap)(x, geo), n, atol=1e-14)
        assert abs(float(n @ n) - 1) < 1e-14
        assert abs(float(obstacle.gap(geo["c"] + y, geo))) < 1e-13
        assert np.allclose(geo["c"] + y + g * n, x, atol=1e-14)
        later = obstacle.geometry(P, 0.9)
        moved = x + later["shift"] - geo["shift"]
        assert np.allclose(obstacle.closest(moved, later), y, atol=1e-14)
        assert abs(float(obstacle.gap(moved, later) - g)) < 1e-14


def test_bad_obstacles_are_named():
    with pytest.raises(InputError, match="sphere's radius must be positive"):
        Sphere().check({"R": -1.0})
    with pytest.raises(InputError, match="cylinder's axis must be a non-zero"):
        Cylinder(axis=(0.0, 0.0, 0.0)).check(P)
    with pytest.raises(InputError, match="plane's normal"):
        Plane(normal_vector=(0.0, 0.0, 0.0)).check(P)
    with pytest.raises(InputError, match="must return a scalar"):
        Implicit(lambda y, p: y, origin=(0.0, 0.0, 0.0)).check(P)
    with pytest.raises(InputError, match="cannot be evaluated.*KeyError"):
        Implicit(lambda y, p: y @ y - p["r"], {"R": "R"}).check(P)


def test_tangent_basis_is_orthonormal_and_right_handed():
    for n in POINTS:
        n = n / jnp.linalg.norm(n)
        t1, t2 = tangent_basis(n, jnp.asarray(reference_axis(np.asarray(n))))
        B = jnp.stack([t1, t2, n])
        assert np.allclose(B @ B.T, np.eye(3), atol=1e-15) and float(jnp.linalg.det(B)) > 0


def plane_pair():
    """A 3-D plane and a 2-D line that are the same die in the x-y plane."""
    plane = Plane(point=(0.1, 0.05, 0.0), normal_vector=(0.1, -1.0, 0.0), motion=(0.2, -0.1, 0.0))
    line = Line(point=(0.1, 0.05), normal_vector=(0.1, -1.0), motion=(0.2, -0.1))
    return plane, line


@pytest.mark.parametrize("lam,g_shift,s_n", [
    ((-2.0, 0.3), 0.0, 0.02),    # closed, stick
    ((-2.0, 1.5), 0.0, -0.3),    # closed, slip
    ((-0.1, 0.05), 0.2, 0.0),    # open
])
def test_motion_in_a_plane_is_the_2d_law(lam, g_shift, s_n):
    """Plane strain inside 3-D: a node moving in the x-y plane against a plane
    whose normal lies in it, with lam_T2 = 0 and the history on the line, has
    the 2-D Coulomb residual and tangent; its out-of-plane rows vanish."""
    plane, line = plane_pair()
    law2, law3 = Coulomb(), CoulombDisc()
    cp = law2.values(P)
    t = 0.4
    g2, g3 = line.geometry(P, t), plane.geometry(P, t)
    x2 = jnp.array([0.3, -0.02 - g_shift])
    x3 = jnp.array([0.3, -0.02 - g_shift, 0.0])
    e = jnp.asarray(reference_axis(np.asarray(plane.geometry(P, 0.0)["n"])))
    t1, _ = tangent_basis(g3["n"], e)
    n2 = g2["n"]
    assert np.allclose(t1[:2], [-n2[1], n2[0]], atol=1e-15)  # the same tangent
    y_n = s_n * t1
    A = 0.7
    r2 = lambda x, l: law2.residual(x, l, A, g2, line, cp, (s_n, 1.0))
    r3 = lambda x, l: law3.residual(x, l, A, g3, plane, cp, (y_n, e, 1.0))
    l2, l3 = jnp.array(lam), jnp.array([*lam, 0.0])
    a, b = r2(x2, l2), r3(x3, l3)
    assert np.allclose(np.asarray(b)[[0, 1, 3, 4]], a, rtol=1e-13, atol=1e-13)
    assert abs(float(b[2])) < 1e-13 and abs(float(b[5])) < 1e-13
    K2 = jax.jacfwd(lambda v: r2(v[:2], v[2:]))(jnp.concatenate([x2, l2]))
    K3 = jax.jacfwd(lambda v: r3(v[:3], v[3:]))(jnp.concatenate([x3, l3]))
    keep = np.array([0, 1, 3, 4])
    assert np.allclose(np.asarray(K3)[np.ix_(keep, keep)], K2, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("eps", [1.0, 30.0])
def test_converged_states_satisfy_coulomb_for_any_eps(eps):
    """The multiplier rows vanish exactly on Coulomb's law, whatever eps: stick
    (g_T = 0, |lam_T| < mu |lam_N|) and slip in any direction of the plane
    (lam_T = mu |lam_N| e, g_T = gamma e, gamma > 0), closed (g_N = 0)."""
    law = CoulombDisc()
    cp = law.values({**P, "eps": eps, "eps_t": 2 * eps})
    plane = Plane(point=(0.0, 0.0, 0.0), normal_vector=(0.0, 0.0, -1.0))
    geo = plane.geometry(P, 0.0)
    e = jnp.array([1.0, 0.0, 0.0])
    t1, t2 = tangent_basis(geo["n"], e)
    x = jnp.array([0.2, -0.1, 0.0])  # on the plane: g_N = 0
    y = plane.closest(x, geo)
    lam_n = -2.0
    stick = jnp.array([lam_n, 0.2, -0.3])  # |lam_T| = 0.36 < 0.6
    r = law.residual(x, stick, 1.0, geo, plane, cp, (y, e, 1.0))
    assert np.allclose(r[3:], 0.0, atol=1e-14)
    assert int(law.status(x, stick, 1.0, geo, plane, cp, (y, e, 1.0))) == 1
    d = np.array([0.6, -0.8])
    slip = jnp.array([lam_n, *(P["mu"] * 2.0 * d)])
    y_n = y - 0.05 * (d[0] * t1 + d[1] * t2)  # slipped by 0.05 along d
    r = law.residual(x, slip, 1.0, geo, plane, cp, (y_n, e, 1.0))
    assert np.allclose(r[3:], 0.0, atol=1e-14)
    assert int(law.status(x, slip, 1.0, geo, plane, cp, (y_n, e, 1.0))) == 2
    # the force on the body: the pressure along n and the friction opposing the slip
    f = r[:3]
    assert np.allclose(f, lam_n * geo["n"] + slip[1] * t1 + slip[2] * t2, atol=1e-14)


def test_face_areas_are_consistent_nodal_loads():
    """On a graded flat grid each node gets int N_S dA (a quarter of each adjacent
    quadrilateral), triangles a third of each; on a curved (cylindrical) surface
    the areas add up to the area of the faces, and JAX and NumPy agree."""
    from signorini.contact.area import face_areas
    from signorini.fem.mesh3d import box, tetrahedra

    xs, ys = np.array([0.0, 0.1, 0.3, 0.7]), np.array([0.0, 0.2, 0.5])
    m = box(xs, ys, [0.0, 0.4])
    for mesh in (m, tetrahedra(m)):
        faces = mesh.face_sets["z1"]
        nodes = np.unique(faces)
        A = face_areas(mesh.nodes, faces, nodes)
        assert A.sum() == pytest.approx(0.7 * 0.5, rel=1e-14)
        assert np.allclose(A, face_areas(jnp.asarray(mesh.nodes), faces, nodes), rtol=1e-14)
    A = face_areas(m.nodes, m.face_sets["z1"])
    hx, hy = np.diff(xs), np.diff(ys)
    wx = np.concatenate([[hx[0]], hx[:-1] + hx[1:], [hx[-1]]]) / 2
    wy = np.concatenate([[hy[0]], hy[:-1] + hy[1:], [hy[-1]]]) / 2
    assert np.allclose(A, np.outer(wy, wx).ravel(), rtol=1e-14)  # nodes of z1 in y-major order
    bent = m.nodes.copy()
    theta = bent[:, 0] / 0.7 * (np.pi / 3)
    bent[:, 0], bent[:, 2] = (2 + bent[:, 2]) * np.sin(theta), (2 + bent[:, 2]) * np.cos(theta)
    A = face_areas(bent, m.face_sets["z1"])
    Xf = bent[m.face_sets["z1"]]
    from signorini.fem.element import DN_PARENT

    J = np.einsum("gak,fai->fgki", DN_PARENT, Xf)
    total = np.linalg.norm(np.cross(J[:, :, 0], J[:, :, 1]), axis=-1).sum()
    assert A.sum() == pytest.approx(total, rel=1e-14)
    chords = 2 * 2.4 * np.sin(np.diff(xs / 0.7 * (np.pi / 3)) / 2)  # the faces are flat strips
    assert A.sum() == pytest.approx(chords.sum() * 0.5, rel=1e-14)


def test_an_open_node_at_rest_has_its_tangential_rows():
    """An open node whose augmented tangential multiplier is zero (at rest: lam_T =
    0, no slip) has the rows lam_T / eps_T of every open node, -A/eps_T on the
    diagonal of its tangent: they determine its multipliers (the norm's zero
    gradient at 0 once left these rows empty, singular for SuperLU and for the
    iterative solver's multiplier block)."""
    law = CoulombDisc()
    cp = law.values(P)
    plane = Plane(point=(0.0, 0.0, 0.0), normal_vector=(0.0, 0.0, -1.0))
    geo = plane.geometry(P, 0.0)
    e = jnp.array([1.0, 0.0, 0.0])
    x = jnp.array([0.2, -0.1, -0.5])  # away from the plane: open
    A = 0.7
    for lam in ([0.0, 0.0, 0.0], [0.0, 0.3, -0.2]):
        r = lambda v: law.residual(v[:3], v[3:], A, geo, plane, cp, (plane.closest(x, geo), e, 1.0))
        K = np.asarray(jax.jacfwd(r)(jnp.concatenate([x, jnp.array(lam)])))
        assert int(law.status(x, jnp.array(lam), A, geo, plane, cp, (plane.closest(x, geo), e, 1.0))) == 0
        assert np.allclose(K[3:, 3:], -A / np.array([cp["eps_n"], cp["eps_t"], cp["eps_t"]]) * np.eye(3),
                           rtol=1e-14, atol=0.0)
