"""The geometry kernel of the 3-D mortar pairs: one slave face against its
candidate master faces (docs/theory.md §13.9).

What differs from the 2-D pair of :mod:`signorini.contact.mortar` is here: a
slave face (a triangle, or a quadrilateral, possibly warped) defines a
projection plane (its centre and averaged normal); the master face's vertices
are projected along that normal onto it; the projected master polygon is
clipped by the projected slave polygon (Sutherland–Hodgman,
:func:`clip_polygon`); the overlap polygon is split into triangles from its
area centroid and integrated with a degree-5 rule on each
(:func:`overlap_quadrature`). The dual (biorthogonal) functions on the covered
part of the face (:func:`dual_functions`) and the weighted gap and slip
(:func:`weighted_gaps`) are the 3-D versions of ``mortar._dual`` and of
``MortarNode._overlap_integrals``; the pair built on them is
:mod:`signorini.contact.mortar3d`.

Every function is pure JAX with fixed array shapes (a polygon is padded to
:data:`MAXV` vertices with a validity mask, a face to 4 vertices with its
vertex count; no Python branch on a value), so that it can be ``jit``-ed,
``vmap``-ed over face pairs and differentiated by ``jvp``/``grad`` to any
order needed by the residual, the tangent, the DDM and the adjoint.

Conventions: a face is ``(4, 3)`` vertex coordinates ordered counter-clockwise
seen from outside its body (a triangle's fourth row is ignored); the slave's
outward normal points towards the master, so that the gap is positive when
the surfaces are apart. Quadrilateral shape functions are the bilinear ones on
[-1, 1]^2 with the vertices at (-1, -1), (1, -1), (1, 1), (-1, 1); triangle
ones are (1 - xi - eta, xi, eta) and a zero fourth.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import _small
from .._jax import jax, jnp

#: most vertices of an overlap polygon: a convex n-gon clipped by a convex
#: m-gon has at most n + m vertices (4 + 4)
MAXV = 8
#: Newton iterations of the inversion of a quadrilateral's bilinear map, taken
#: without derivatives, before the differentiated ones
NEWTON = 12
#: Radon's 7-point rule on a triangle, exact for polynomials of degree <= 5:
#: barycentric coordinates (7, 3) and weights (7,) summing to 1 (times the area)
_S15 = np.sqrt(15.0)
_A1, _A2 = (6.0 - _S15) / 21.0, (6.0 + _S15) / 21.0
_BARY = np.array([[1 / 3, 1 / 3, 1 / 3],
                  [_A1, _A1, 1 - 2 * _A1], [_A1, 1 - 2 * _A1, _A1], [1 - 2 * _A1, _A1, _A1],
                  [_A2, _A2, 1 - 2 * _A2], [_A2, 1 - 2 * _A2, _A2], [1 - 2 * _A2, _A2, _A2]])
_WEIGHTS = np.array([9 / 40] + [(155 - _S15) / 1200] * 3 + [(155 + _S15) / 1200] * 3)
#: the clip keeps what lies within CLIP_TOL x an edge's length outside the clip
#: polygon's edge: an edge of the subject along an edge of the clip (coincident
#: surface boundaries, matching meshes) then stays inside, instead of crossing
#: it at a point that round-off places anywhere along it (docs/theory.md §13.9)
CLIP_TOL = 1e-12
#: quadrature points per face pair
NQ = MAXV * len(_WEIGHTS)
#: an overlap whose mass matrix has det M <= TAU[n] (tr M)^n (n shape functions)
#: contributes nothing (see :func:`dual_functions`); TAU[2] is mortar._dual's
TAU = {2: 1e-17, 3: 1e-60, 4: 1e-60}


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _safe_div(a, b):
    ok = jnp.abs(b) > 1e-300
    return jnp.where(ok, a / jnp.where(ok, b, 1.0), 0.0)


def _compact(P, mask):
    """The valid vertices of ``P`` (n, 2) moved to the front, in order, padded
    with zeros to MAXV rows; and their count."""
    mask = jnp.asarray(mask, bool)
    pos = jnp.cumsum(mask) - 1
    sel = (pos[:, None] == jnp.arange(MAXV)[None, :]) & mask[:, None]
    return sel.T.astype(P.dtype) @ P, jnp.minimum(jnp.sum(mask), MAXV)


def _signed_area2(P, k):
    """Twice the signed area of the first ``k`` vertices of ``P`` (shoelace)."""
    idx = jnp.arange(P.shape[0])
    nxt = jnp.where(idx + 1 < k, idx + 1, 0)
    return jnp.sum(jnp.where(idx < k, _cross2(P, P[nxt]), 0.0))


def _clip_halfplane(P, k, a, b, s):
    """One Sutherland–Hodgman step: the polygon of the first ``k`` vertices of
    ``P`` (MAXV, 2) clipped to the side of the line a -> b where s * cross(b - a,
    p - a) >= -CLIP_TOL |b - a|^2 (s = +1: the left; the line moved outward by
    CLIP_TOL x |b - a|). Each edge (p, q) of the polygon emits the
    crossing point when p and q lie on different sides, then q when q is inside;
    the emitted points are compacted by a 0/1 matrix product (differentiable,
    fixed shapes)."""
    idx = jnp.arange(MAXV)
    valid = idx < k
    nxt = jnp.where(idx + 1 < k, idx + 1, 0)
    Q = P[nxt]
    d = s * _cross2(b - a, P - a) + CLIP_TOL * ((b - a) @ (b - a))
    dq = d[nxt]
    p_in, q_in = d >= 0.0, dq >= 0.0
    # crossing parameter: its denominator is non-zero wherever the point is emitted;
    # elsewhere a safe 1 keeps the unused values (and their derivatives) finite
    den = d - dq
    t = d / jnp.where(den != 0.0, den, 1.0)
    cross_pt = P + t[:, None] * (Q - P)
    cand = jnp.stack([cross_pt, Q], axis=1).reshape(2 * MAXV, 2)
    flags = jnp.stack([valid & (p_in != q_in), valid & q_in], axis=1).reshape(2 * MAXV)
    pos = jnp.cumsum(flags) - 1
    sel = (pos[:, None] == idx[None, :]) & flags[:, None]
    return sel.T.astype(P.dtype) @ cand, jnp.minimum(jnp.sum(flags), MAXV)


def clip_polygon(subject, clip, mask, clip_mask=None):
    """The convex polygon ``subject`` clipped by the convex polygon ``clip`` in a
    plane (Sutherland–Hodgman).

    Args:
        subject: (S, 2) vertices, S <= MAXV, in order (either orientation).
        clip: (C, 2) vertices, C <= 4, in order (either orientation).
        mask: (S,) which rows of ``subject`` are vertices.
        clip_mask: (C,) which rows of ``clip`` are vertices (default: all).

    Returns:
        (MAXV, 2) the overlap's vertices, in the subject's orientation, the valid
        ones first and zeros after them; and (MAXV,) their mask. A vertex on the
        clip's boundary counts as inside (a duplicated vertex, a zero-length edge,
        can result; it adds nothing to an area or an integral).
    """
    subject = jnp.asarray(subject)
    clip = jnp.asarray(clip, subject.dtype)
    if clip_mask is None:
        clip_mask = jnp.ones(clip.shape[0], bool)
    if subject.shape[0] < MAXV:
        pad = MAXV - subject.shape[0]
        subject = jnp.concatenate([subject, jnp.zeros((pad, 2), subject.dtype)])
        mask = jnp.concatenate([jnp.asarray(mask, bool), jnp.zeros(pad, bool)])
    P, k = _compact(subject, mask)
    C, kc = _compact(clip, clip_mask)
    s = jnp.where(_signed_area2(C, kc) >= 0.0, 1.0, -1.0)
    for i in range(clip.shape[0]):
        a, b = C[i], C[jnp.where(i + 1 < kc, i + 1, 0)]
        P1, k1 = _clip_halfplane(P, k, a, b, s)
        use = i < kc
        P, k = jnp.where(use, P1, P), jnp.where(use, k1, k)
    return P, jnp.arange(MAXV) < k


# --------------------------------------------------------------- faces and shapes
def _is_quad(n):
    return jnp.asarray(n) == 4


def shape_functions(xi, is_quad):
    """The face's shape functions (4,) at the face coordinates ``xi`` (2,)."""
    x, e = xi[0], xi[1]
    quad = 0.25 * jnp.stack([(1 - x) * (1 - e), (1 + x) * (1 - e), (1 + x) * (1 + e), (1 - x) * (1 + e)])
    tri = jnp.stack([1 - x - e, x, e, jnp.zeros_like(x)])
    return jnp.where(is_quad, quad, tri)


def face_frame(face, n_vertices):
    """The projection plane of a face: centre c (3,), unit normal n (3,) and unit
    tangents e1, e2 (n = e1 x e2; e1 along the first edge). For a quadrilateral
    n is the mean normal of the bilinear surface (the cross product of the
    diagonals), for a triangle its normal; c is the mean of the vertices."""
    q = _is_quad(n_vertices)
    x0, x1, x2, x3 = face[0], face[1], face[2], face[3]
    c = jnp.where(q, 0.25 * (x0 + x1 + x2 + x3), (x0 + x1 + x2) / 3.0)
    nv = jnp.where(q, jnp.cross(x2 - x0, x3 - x1), jnp.cross(x1 - x0, x2 - x0))
    n = nv / jnp.sqrt(nv @ nv)
    t = (x1 - x0) - ((x1 - x0) @ n) * n
    e1 = t / jnp.sqrt(t @ t)
    return c, n, e1, jnp.cross(n, e1)


def _quad_completed(q, is_quad):
    """The 4 plane vertices used by the bilinear inversion: a triangle's fourth
    completes it to a parallelogram (a well-posed, unused branch: no NaN)."""
    return jnp.where(is_quad, q, q.at[3].set(q[0] + q[2] - q[1]))


def _newton_step(xi, a0, a1, a2, a3, p):
    """One Newton step for a0 + a1 xi + a2 eta + a3 xi eta = p."""
    r = a0 + a1 * xi[0] + a2 * xi[1] + a3 * xi[0] * xi[1] - p
    c1, c2 = a1 + a3 * xi[1], a2 + a3 * xi[0]
    det = _cross2(c1, c2)
    det = jnp.where(jnp.abs(det) > 1e-300, det, 1.0)
    return xi - jnp.stack([c2[1] * r[0] - c2[0] * r[1], c1[0] * r[1] - c1[1] * r[0]]) / det


def invert_face(q, p, is_quad):
    """Face coordinates (2,) of the plane point ``p`` (2,) on the face whose
    projected vertices are ``q`` (4, 2): exact for a triangle; for a
    quadrilateral Newton's method on its bilinear map from the centre
    (:data:`NEWTON` steps without derivatives, which an affine map — a
    parallelogram — ends in one), then two differentiated steps from that
    solution, whose derivatives are then exact to the third order."""
    q0, q1, q2 = q[0], q[1], q[2]
    tri = jnp.stack([_cross2(p - q0, q2 - q0), _cross2(q1 - q0, p - q0)]) / _cross2(q1 - q0, q2 - q0)
    qq = _quad_completed(q, is_quad)
    a0 = 0.25 * (qq[0] + qq[1] + qq[2] + qq[3])
    a1 = 0.25 * (-qq[0] + qq[1] + qq[2] - qq[3])
    a2 = 0.25 * (-qq[0] - qq[1] + qq[2] + qq[3])
    a3 = 0.25 * (qq[0] - qq[1] + qq[2] - qq[3])
    frozen = jax.lax.stop_gradient((a0, a1, a2, a3, p))

    def body(_, xi):
        return jnp.clip(_newton_step(xi, *frozen), -2.0, 2.0)

    xi = jax.lax.stop_gradient(jax.lax.fori_loop(0, NEWTON, body, jnp.zeros(2, q.dtype)))
    xi = _newton_step(xi, a0, a1, a2, a3, p)
    xi = _newton_step(xi, a0, a1, a2, a3, p)
    return jnp.where(is_quad, xi, tri)


# ------------------------------------------------------------------- quadrature
class Quadrature(NamedTuple):
    """Quadrature of one slave face's overlap with one master face (NQ points,
    weight zero where unused)."""

    plane: jnp.ndarray         #: (NQ, 2) the points in the projection plane's (e1, e2) coordinates
    w: jnp.ndarray             #: (NQ,) the weights (areas on the projection plane)
    x_slave: jnp.ndarray       #: (NQ, 3) the slave face's points above them (along the normal)
    N_slave: jnp.ndarray       #: (NQ, 4) the slave's shape functions there
    x_master: jnp.ndarray      #: (NQ, 3) the master face's points on the same lines
    N_master: jnp.ndarray      #: (NQ, 4) the master's shape functions there
    normal: jnp.ndarray        #: (3,) the slave's projection normal n
    polygon: jnp.ndarray       #: (MAXV, 2) the overlap polygon (plane coordinates)
    polygon_mask: jnp.ndarray  #: (MAXV,) its vertices


def _area_centroid(P, k):
    """The area centroid of the first ``k`` vertices of ``P`` (a function of the
    region only, continuous when a vertex appears or vanishes); the vertex mean
    for a polygon of (nearly) no area."""
    idx = jnp.arange(MAXV)
    valid = idx < k
    m = _safe_div(jnp.sum(jnp.where(valid[:, None], P, 0.0), axis=0), k)
    u = P - m  # about the vertex mean: the round-off scales with the polygon, not its position
    nxt = jnp.where(idx + 1 < k, idx + 1, 0)
    cr = jnp.where(valid, _cross2(u, u[nxt]), 0.0)
    a2 = jnp.sum(cr)
    size2 = jnp.max(jnp.where(valid, jnp.sum(u * u, axis=1), 0.0))
    ok = jnp.abs(a2) > 1e-12 * size2
    shift = jnp.sum((u + u[nxt]) * cr[:, None], axis=0) / (3.0 * jnp.where(ok, a2, 1.0))
    return m + jnp.where(ok, shift, 0.0)


def overlap_quadrature(slave_face_xyz, master_face_xyz, n_slave_vertices, n_master_vertices):
    """Points, weights and shape functions of a slave face's overlap with a master
    face (docs/theory.md §13.9).

    The master's vertices are projected along the slave's normal onto its plane,
    the projected master polygon is clipped by the projected slave polygon, the
    overlap is split into triangles from its area centroid, and Radon's 7-point
    rule (degree 5) is applied on each. At every point the slave's and the
    master's face coordinates are found by inverting their projected
    parametrisations (:func:`invert_face`).

    Args:
        slave_face_xyz, master_face_xyz: (4, 3) vertices (a triangle's fourth row
            is ignored).
        n_slave_vertices, n_master_vertices: 3 or 4 (may be traced arrays).

    Returns:
        A :class:`Quadrature`.
    """
    xs = jnp.asarray(slave_face_xyz)
    xm = jnp.asarray(master_face_xyz, xs.dtype)
    sq, mq = _is_quad(n_slave_vertices), _is_quad(n_master_vertices)
    c, n, e1, e2 = face_frame(xs, n_slave_vertices)
    E = jnp.stack([e1, e2], axis=1)  # (3, 2)
    qs = (xs - c) @ E
    qm = (xm - c) @ E
    four = jnp.arange(4)
    poly, pmask = clip_polygon(qm, qs, four < n_master_vertices, four < n_slave_vertices)
    k = jnp.sum(pmask)
    # the fan's origin: the integrals do not depend on it (exactly so for polynomial
    # integrands), so it is held fixed under differentiation; its derivatives would
    # grow like 1 / area on a sliver of an overlap (docs/theory.md §13.9)
    g = jax.lax.stop_gradient(_area_centroid(poly, k))
    nxt = jnp.where(jnp.arange(MAXV) + 1 < k, jnp.arange(MAXV) + 1, 0)
    # the slave polygon is counter-clockwise about n; the overlap has the master's
    # orientation, opposite when the faces face each other
    orient = jnp.where(_signed_area2(_compact(qm, four < n_master_vertices)[0],
                                     jnp.where(mq, 4, 3)) >= 0.0, 1.0, -1.0)
    va, vb = poly - g, poly[nxt] - g
    area = 0.5 * orient * _cross2(va, vb) * pmask  # (MAXV,) fan triangles
    bary = jnp.asarray(_BARY)
    pts = g + bary[None, :, 1:2] * va[:, None, :] + bary[None, :, 2:3] * vb[:, None, :]
    w = (area[:, None] * jnp.asarray(_WEIGHTS)[None, :]).reshape(NQ)
    pts = pts.reshape(NQ, 2)
    used = w != 0.0
    # unused points sit where each inversion is well posed (the face's centre),
    # so that their (discarded) values and derivatives stay finite
    ps = jnp.where(used[:, None], pts, 0.0)
    pm = jnp.where(used[:, None], pts, jnp.where(mq, 0.25 * jnp.sum(qm, axis=0), jnp.sum(qm[:3], axis=0) / 3.0))
    xi_s = jax.vmap(invert_face, (None, 0, None))(qs, ps, sq)
    xi_m = jax.vmap(invert_face, (None, 0, None))(qm, pm, mq)
    Ns = jax.vmap(shape_functions, (0, None))(xi_s, sq)
    Nm = jax.vmap(shape_functions, (0, None))(xi_m, mq)
    # a triangle's fourth vertex has N = 0 but may be anything: keep it out of the products
    xs0 = jnp.where(sq, xs, xs.at[3].set(0.0))
    xm0 = jnp.where(mq, xm, xm.at[3].set(0.0))
    return Quadrature(pts, w, Ns @ xs0, Ns, Nm @ xm0, Nm, n, poly, pmask)


# --------------------------------------------------------------- dual functions
def dual_functions(N, w, mask=None):
    """The dual (biorthogonal) functions Phi (Q, n) at the quadrature points of
    the covered part of a face: Phi = N (D M^-1)^T with M = sum w N N^T the
    overlap's mass matrix and D = diag(sum w N), so that sum w Phi_j N_k =
    delta_jk sum w N_j (the 3-D version of ``mortar._dual``; on a wholly covered
    triangle Phi_j = 3 N_j - N_k - N_l, on a wholly covered parallelogram
    Phi_1 = 4 N_1 - 2 N_2 + N_3 - 2 N_4).

    Args:
        N: (Q, n) the face's shape functions at the points (n = 3 or 4).
        w: (Q,) the weights (zero where unused).
        mask: (n,) which functions exist (a triangle padded to 4: the fourth
            masked; its Phi is zero). Default: all.

    Returns:
        (Q, n) Phi; zero everywhere when the covered part is nearly nothing:
        det M <= TAU[n] (tr M)^n with n the number of functions (the form of
        mortar._dual's guard, whose TAU[2] = 1e-17). In 3-D, det M / (tr M)^n
        falls like the fourth power of the covered area (a corner of a
        quadrilateral, a strip along an edge); TAU[3] = TAU[4] = 1e-60 drops
        covered parts below about 1e-15 of the face. Larger ones are kept:
        measured, the contributions int Phi_j g of a corner or a strip of
        relative size 1e-12 are still within 2e-14 of their value in exact
        arithmetic (Phi itself reaching 1e24): the solve with M is backward
        stable, and a covered part of no area (singular M) is what the guard is for.
    """
    N = jnp.asarray(N)
    n = N.shape[1]
    mask = jnp.ones(n) if mask is None else jnp.asarray(mask, N.dtype)
    N = N * mask
    M = (N * w[:, None]).T @ N
    d = w @ N
    # a missing function: a unit diagonal entry, so that M stays invertible and
    # the missing Phi is zero (its d is zero)
    M = M + jnp.diag(1.0 - mask)
    trace = jnp.sum(mask * jnp.diag(M))
    det = _small.det(M)
    tau = jnp.asarray([TAU.get(int(i), 0.0) for i in range(n + 1)])[jnp.sum(mask).astype(int)]
    ok = det > tau * trace ** jnp.sum(mask)
    M = jnp.where(ok, M, jnp.eye(n, dtype=N.dtype))
    A = d[:, None] * _small.spd_inv(M) * ok  # (n, n): Phi_j = sum_k A_jk N_k
    return N @ A.T


# ----------------------------------------------------------- weighted quantities
class WeightedGaps(NamedTuple):
    """One slave face's contributions to its vertices' weighted quantities. ``slip``
    is taken between the reference positions of the slave point and of the master
    point opposite it; the assembly projects it on the slave node's tangent frame."""

    gap: jnp.ndarray   #: (4,) int Phi_j g dA (g the gap along the slave's normal)
    slip: jnp.ndarray  #: (4, 3) int Phi_j (X_s - X_m) dA
    area: jnp.ndarray  #: (4,) int N_j dA over the covered part


def weighted_gaps(slave_face_xyz, n_slave_vertices, master_faces_xyz, n_master_vertices,
                  master_mask=None, slave_ref=None, master_ref=None):
    """A slave face's contributions to the weighted gap, slip and area of its
    vertices from its M candidate master faces (docs/theory.md §13.9).

    Args:
        slave_face_xyz: (4, 3) the slave face (current positions).
        n_slave_vertices: 3 or 4.
        master_faces_xyz: (M, 4, 3) the candidate master faces (current positions).
        n_master_vertices: (M,) 3 or 4 each.
        master_mask: (M,) which candidates exist (default: all).
        slave_ref, master_ref: reference positions of the same vertices, for the
            slip (default: the current ones).

    Returns:
        :class:`WeightedGaps`: int Phi_j g, int Phi_j (X_s - X_m) and int N_j over
        the part of the face the master faces cover, the dual functions Phi_j
        built on that whole part.
    """
    xs = jnp.asarray(slave_face_xyz)
    xm = jnp.asarray(master_faces_xyz, xs.dtype)
    nm = jnp.broadcast_to(jnp.asarray(n_master_vertices), xm.shape[:1])
    mmask = jnp.ones(xm.shape[0], xs.dtype) if master_mask is None else jnp.asarray(master_mask, xs.dtype)
    q = jax.vmap(overlap_quadrature, (None, 0, None, 0))(xs, xm, n_slave_vertices, nm)
    w = (q.w * mmask[:, None]).reshape(-1)
    Ns = q.N_slave.reshape(-1, 4)
    smask = (jnp.arange(4) < n_slave_vertices).astype(xs.dtype)
    phi = dual_functions(Ns, w, smask)
    n = q.normal[0]
    g = ((q.x_master - q.x_slave) @ n).reshape(-1)
    Xs = xs if slave_ref is None else jnp.asarray(slave_ref, xs.dtype)
    Xm = xm if master_ref is None else jnp.asarray(master_ref, xs.dtype)
    sq = _is_quad(n_slave_vertices)
    Xs0 = jnp.where(sq, Xs, Xs.at[3].set(0.0))
    Xm0 = jnp.where((nm == 4)[:, None, None], Xm, Xm.at[:, 3].set(0.0))
    rel = (Ns @ Xs0) - jnp.einsum("mqa,mak->mqk", q.N_master, Xm0).reshape(-1, 3)
    wphi = w[:, None] * phi
    return WeightedGaps(wphi.T @ g, wphi.T @ rel, w @ Ns)
