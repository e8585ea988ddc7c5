"""Isoparametric 4-node quadrilateral: quadrature, formulations, element kernels.

The element is written once for every kinematics (plane strain,
axisymmetric: :mod:`signorini.fem.kinematics`), formulation (:class:`Standard`
2x2 Gauss, :class:`FBar` = selective reduced integration of the volume change)
and material (``update(H, h_n, mp) -> (P, h)``, :mod:`signorini.materials`):

    r_e = sum_g w_g P(Hbar_g, h_n,g) : dHbar_g/du_e       (a VJP of u_e -> Hbar)

with the history h_n of each Gauss point as input and the updated history as
output. The tangent is JAX's derivative of r_e: for the standard formulation
(H linear in u_e) autodiff is applied at the material point only,
K_e = sum_g w_g B^T C B with C = dP/dH; for F-bar the whole element residual
is differentiated forward (Hbar is nonlinear in u_e).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._jax import jax, jnp
from .kinematics import PLANE_STRAIN
from ..materials import det_minus_one

_G = 1.0 / np.sqrt(3.0)
#: Gauss points (4, 2) in the parent square and their weights (4,).
GAUSS_POINTS = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])
GAUSS_WEIGHTS = np.ones(4)
N_GAUSS = 4
_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def shape_functions(xi):
    """Bilinear shape functions N (4,) at parent point xi (2,)."""
    return 0.25 * (1 + _CORNERS[:, 0] * xi[0]) * (1 + _CORNERS[:, 1] * xi[1])


def shape_gradients(xi):
    """dN/dxi (4, 2) at parent point xi (2,)."""
    dxi = 0.25 * _CORNERS[:, 0] * (1 + _CORNERS[:, 1] * xi[1])
    deta = 0.25 * _CORNERS[:, 1] * (1 + _CORNERS[:, 0] * xi[0])
    return (np if isinstance(xi, np.ndarray) else jnp).stack([dxi, deta], axis=1)


#: N and dN/dxi at the Gauss points, (4 gauss, 4 nodes) and (4 gauss, 4 nodes, 2).
N_PARENT = np.stack([np.asarray(shape_functions(p)) for p in GAUSS_POINTS])
DN_PARENT = np.stack([np.asarray(shape_gradients(p)) for p in GAUSS_POINTS])
#: the same at the centroid (1 point)
_N0 = np.asarray(shape_functions(np.zeros(2)))[None]
_DN0 = np.asarray(shape_gradients(np.zeros(2)))[None]


def physical_gradients(DN, Xe):
    J = jnp.einsum("gai,aj->gji", DN, Xe)  # (g, 2, 2): dX_j/dxi_i
    detJ = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    Jinv = jnp.stack([jnp.stack([J[:, 1, 1], -J[:, 0, 1]], -1),
                      jnp.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], -2) / detJ[:, None, None]  # dxi/dX
    return jnp.einsum("gai,gij->gaj", DN, Jinv), detJ


def reference_gradients(Xe):
    """Shape-function gradients w.r.t. X and parent quadrature weights.

    Args:
        Xe: (4, 2) reference nodal coordinates.

    Returns:
        dNdX (4 gauss, 4 nodes, 2) and w (4,) = Gauss weight * det(dX/dxi)
        (per unit thickness; see the kinematics for the volume weights).
    """
    dNdX, detJ = physical_gradients(DN_PARENT, Xe)
    return dNdX, GAUSS_WEIGHTS * detJ


def _points(Xe, kinematics):
    """dN/dX (4 gauss, 4 nodes, 2) and the volume weights w (4,) of the kinematics."""
    dNdX, detJ = physical_gradients(DN_PARENT, Xe)
    return dNdX, kinematics.volume_weights(Xe, N_PARENT, GAUSS_WEIGHTS * detJ)


@dataclass(frozen=True)
class Standard:
    """Full 2x2 Gauss integration of the displacement-based Q4."""

    name = "standard"
    linear = True  # H at the Gauss points is linear in the nodal displacements

    def modify(self, H, H0):
        return H


@dataclass(frozen=True)
class FBar:
    """F-bar Q4 (selective reduced integration of the volume change, docs/theory.md §7).

    At each 2x2 Gauss point Fbar_g = (J0 / J_g)^(1/3) F_g, J0 = det F at the
    centroid: the deviatoric part is integrated at the four points, the
    volumetric part at one, which removes volumetric locking of (nearly)
    incompressible plastic flow. For finite-strain materials.
    """

    name = "F-bar"
    linear = False

    def modify(self, H, H0):
        # Hbar = c F - I = (c - 1)(I + H) + H, c - 1 = expm1((ln J0 - ln J) / 3): no cancellation
        d = (jnp.log1p(det_minus_one(H0)) - jax.vmap(lambda h: jnp.log1p(det_minus_one(h)))(H)) / 3.0
        cm1 = jnp.expm1(d)[:, None, None]
        return cm1 * (jnp.eye(3) + H) + H

    @staticmethod
    def linearization(x, rows, cols, brows, bcols):
        """The F-bar map at one Gauss point and its first two derivatives, by hand.

        x = (H, H0) on the active components (rows, cols); Hbar = c F - I with
        ln c = (ln J0 - ln J) / 3. Returns Hbar on (brows, bcols), c,
        ell = d ln c / dx = (-F^-T, F0^-T) / 3, the Hessian L2 of ln c
        (d^2 ln J / dH_a dH_b = -F^-1_{j_a i_b} F^-1_{j_b i_a}) and F on
        (brows, bcols). Then dHbar/dx = c ([E, 0] + F ell^T) and, at fixed P,
        d^2(P : Hbar)/dx^2 = c [(P : F)(ell ell^T + L2) + ell p^T + p ell^T]
        with p = d(P : F)/dx (docs/theory.md §10.2).
        """
        na = rows.size
        H = jnp.zeros((3, 3)).at[rows, cols].set(x[:na])
        H0 = jnp.zeros((3, 3)).at[rows, cols].set(x[na:])
        d = (jnp.log1p(det_minus_one(H0)) - jnp.log1p(det_minus_one(H))) / 3.0
        cm1 = jnp.expm1(d)
        F, F0 = jnp.eye(3) + H, jnp.eye(3) + H0
        Fi, F0i = _inverse_planar(F), _inverse_planar(F0)
        gH, g0 = Fi[cols, rows], F0i[cols, rows]  # F^-T on the active components
        ell = jnp.concatenate([-gH, g0]) / 3.0
        MH = Fi[cols[:, None], rows[None, :]] * Fi[cols[None, :], rows[:, None]]
        M0 = F0i[cols[:, None], rows[None, :]] * F0i[cols[None, :], rows[:, None]]
        z = jnp.zeros((na, na))
        L2 = jnp.block([[MH, z], [z, -M0]]) / 3.0
        Hb = (cm1 * F + H)[brows, bcols]
        return Hb, 1.0 + cm1, ell, L2, F[brows, bcols]


STANDARD = Standard()
FBAR = FBar()


def gauss_gradients(ue, Xe, kinematics=PLANE_STRAIN, formulation=STANDARD):
    """Displacement gradients (g, 3, 3) seen by the material at the Gauss points
    (Hbar for F-bar) and the volume weights w (g,)."""
    dNdX, w = _points(Xe, kinematics)
    H = kinematics.displacement_gradients(ue, Xe, N_PARENT, dNdX)
    if not formulation.linear:
        dNdX0, _ = physical_gradients(_DN0, Xe)
        H0 = kinematics.displacement_gradients(ue, Xe, _N0, dNdX0)[0]
        H = formulation.modify(H, H0)
    return H, w


def _inverse_planar(F):
    """Inverse of a 3x3 F that is zero outside the in-plane block and the 33 entry."""
    det2 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return jnp.array([[F[1, 1] / det2, -F[0, 1] / det2, 0.0],
                      [-F[1, 0] / det2, F[0, 0] / det2, 0.0],
                      [0.0, 0.0, 1.0 / F[2, 2]]])


def _history(material, hn):
    return jnp.zeros((N_GAUSS, 0)) if hn is None else hn


def element_update(ue, Xe, material, mp, hn=None, kinematics=PLANE_STRAIN, formulation=STANDARD):
    """Internal forces (4, 2) and updated Gauss-point history (4, n_state) of one element.

    Args:
        ue: (4, 2) nodal displacements. Xe: (4, 2) reference coordinates.
        material: a material with ``update(H, h_n, mp)``. mp: its parameter values.
        hn: (4, n_state) history at the end of the previous increment (None: no history).
    """
    hn = _history(material, hn)
    if formulation.linear:  # r = sum_g w B^T P, H = B u_e (no VJP of the gradients)
        dNdX, w = _points(Xe, kinematics)
        H = kinematics.displacement_gradients(ue, Xe, N_PARENT, dNdX)
        P, h = jax.vmap(material.update, (0, 0, None))(H, hn, mp)
        return _forces(w, dNdX, kinematics.hoop_functions(Xe, N_PARENT), P[:, :2, :2], P[:, 2, 2]), h
    w = gauss_gradients(ue, Xe, kinematics, formulation)[1]
    H, vjp = jax.vjp(lambda u: gauss_gradients(u, Xe, kinematics, formulation)[0], ue)
    P, h = jax.vmap(material.update, (0, 0, None))(H, hn, mp)
    (r,) = vjp(w[:, None, None] * P)
    return r, h


def _forces(w, dNdX, hoop, P2, P33):
    """r (4, 2) = sum_g w B^T P from the in-plane stresses P2 (g, 2, 2) and P_33
    (g,): r_ai = sum_g w P_ij dN_a/dX_j (+ w P_33 hoop_a for i = r, axisymmetric).
    A broadcast sum, not an einsum: XLA on the CPU runs the vmapped einsum as
    many tiny batched products, slower than the fused broadcast (docs/theory.md
    §10.2)."""
    r = jnp.sum((w[:, None, None, None] * P2[:, None]) * dNdX[:, :, None, :], axis=(0, 3))
    if hoop is not None:
        r = r.at[:, 0].add(jnp.sum((w * P33)[:, None] * hoop, axis=0))
    return r


def element_residual(ue, Xe, material, mp, hn=None, kinematics=PLANE_STRAIN, formulation=STANDARD):
    """Internal force vector (4, 2) of one element."""
    return element_update(ue, Xe, material, mp, hn, kinematics, formulation)[0]


def element_residual_tangent(ue, Xe, material, mp, hn=None, kinematics=PLANE_STRAIN,
                             formulation=STANDARD):
    """Internal forces (8,), tangent (8, 8) (node-major DOFs) and updated history.

    Standard formulation: H_g = B_g u_e is linear, so autodiff is applied at the
    material point only: P and C = dP/dH per Gauss point (at fixed h_n), then
    r = sum_g w_g B^T P, K = sum_g w_g B^T C B (differentiating the whole element
    in forward mode would push 8 directions through the geometry as well, instead
    of the few active components of H through the material). F-bar: the same at
    the Gauss point, on the
    2 x n_active components of (H_g, H_0) that Hbar_g depends on
    (:func:`_fbar_residual_tangent`).
    """
    hn = _history(material, hn)
    if formulation.linear:
        dNdX, w = _points(Xe, kinematics)
        rows, cols = (np.array(c) for c in zip(*kinematics.active))  # the non-zero components of H
        hv = kinematics.displacement_gradients(ue, Xe, N_PARENT, dNdX)[:, rows, cols]  # (g, na)

        def stress(v, h_):
            P, h = material.update(jnp.zeros((3, 3)).at[rows, cols].set(v), h_, mp)
            return P[rows, cols], (P[rows, cols], h)

        C, (P, h) = jax.vmap(jax.jacfwd(stress, has_aux=True))(hv, hn)  # (g, na, na), (g, na)
        r, K = _contract(w, dNdX, kinematics.hoop_functions(Xe, N_PARENT), P, C)
        return r, K, h

    return _fbar_residual_tangent(ue, Xe, material, mp, hn, kinematics, formulation)


def _fbar_residual_tangent(ue, Xe, material, mp, hn, kinematics, formulation):
    """Internal forces, tangent and history of a formulation whose Hbar_g is a
    nonlinear function of H_g = B_g u_e and H_0 = B_0 u_e (F-bar).

    With v = (H_g, H_0) on the active components and Hbar_g(v) on its own
    non-zero components (in-plane and 33), the chain rule is taken apart:
    A_g = dHbar_g/dv, C_g = dP/dHbar (forward mode at the material point, one
    direction per component of Hbar), S_g = A_g^T P, and
    dS_g/dv = A_g^T C_g A_g + d^2(P . Hbar_g(v))/dv^2 at fixed P (the curvature
    of the F-bar map). Then r = sum_g w_g [B_g; B_0]^T S_g and
    K = sum_g w_g [B_g; B_0]^T (dS_g/dv) [B_g; B_0]. FBar's map is differentiated
    by hand (:meth:`FBar.linearization`), another formulation's by autodiff. The
    forward-mode Jacobian of the whole element would push 8 directions through
    the geometry, the F-bar map, the return map and its VJP, the split pushes
    derivatives of the material point only (docs/theory.md §10.2).
    """
    rows, cols = (np.array(c) for c in zip(*kinematics.active))
    na = rows.size
    # Hbar = c (I + H) - I is zero outside the in-plane block and the 33 entry
    brows, bcols = np.array([0, 0, 1, 1, 2]), np.array([0, 1, 0, 1, 2])
    dNdX, w = _points(Xe, kinematics)
    dNdX0, _ = physical_gradients(_DN0, Xe)
    # B_g (g, na, 8) and B_0 (na, 8): the displacement gradients are linear in u_e
    grad_g = lambda u: kinematics.displacement_gradients(u.reshape(4, 2), Xe, N_PARENT, dNdX)[:, rows, cols]
    grad_0 = lambda u: kinematics.displacement_gradients(u.reshape(4, 2), Xe, _N0, dNdX0)[0, rows, cols]
    u8 = ue.reshape(8)
    B = jnp.concatenate([jax.jacfwd(grad_g)(u8),
                         jnp.broadcast_to(jax.jacfwd(grad_0)(u8), (N_GAUSS, na, 8))], axis=1)
    v = jnp.einsum("gkj,j->gk", B, u8)  # (g, 2 na): (H_g, H_0) on the active components

    def hbar(x):
        H = jnp.zeros((3, 3)).at[rows, cols].set(x[:na])
        H0 = jnp.zeros((3, 3)).at[rows, cols].set(x[na:])
        return formulation.modify(H[None], H0)[0][brows, bcols]

    def stress(b, h_):
        P, h = material.update(jnp.zeros((3, 3)).at[brows, bcols].set(b), h_, mp)
        return P[brows, bcols], (P[brows, bcols], h)

    def point_autodiff(x, h_):
        A = jax.jacfwd(hbar)(x)  # (5, 2 na)
        C, (P, h) = jax.jacfwd(stress, has_aux=True)(hbar(x), h_)  # (5, 5), (5,)
        G = jax.hessian(lambda y: jnp.dot(P, hbar(y)))(x)  # P held fixed
        return A.T @ P, A.T @ C @ A + G, h

    E = np.array([[float(br == r_ and bc == c_) for r_, c_ in zip(rows, cols)]
                  for br, bc in zip(brows, bcols)])  # (5, na): H's entries among Hbar's

    def point_fbar(x, h_):
        Hb, c, ell, L2, f5 = formulation.linearization(x, rows, cols, brows, bcols)
        C, (P, h) = jax.jacfwd(stress, has_aux=True)(Hb, h_)
        A = c * (jnp.concatenate([E, jnp.zeros_like(E)], axis=1) + jnp.outer(f5, ell))
        p = jnp.concatenate([E.T @ P, jnp.zeros(na)])
        G = c * (jnp.dot(f5, P) * (jnp.outer(ell, ell) + L2) + jnp.outer(ell, p) + jnp.outer(p, ell))
        return A.T @ P, A.T @ C @ A + G, h

    point = point_fbar if isinstance(formulation, FBar) else point_autodiff
    S, D, h = jax.vmap(point)(v, hn)
    r = jnp.einsum("g,gkj,gk->j", w, B, S)
    K = jnp.einsum("g,gki,gkl,glj->ij", w, B, D, B)
    return r, K, h


def _contract(w, dNdX, hoop, P, C):
    """r = sum_g w B^T P and K = sum_g w B^T C B without forming B.

    The active components are (H11, H12, H21, H22[, H33]): H_ij = u_a,i dN_a/dX_j
    in the plane, H33 = hoop_a u_a,r (axisymmetric). P (g, na), C (g, na, na).
    """
    r = _forces(w, dNdX, hoop, P[:, :4].reshape(-1, 2, 2), None if hoop is None else P[:, 4])
    C4 = C[:, :4, :4].reshape(-1, 2, 2, 2, 2)
    K = jnp.einsum("g,gaj,gijkl,gbl->aibk", w, dNdX, C4, dNdX)
    if hoop is not None:
        K = K.at[:, 0, :, :].add(jnp.einsum("g,ga,gkl,gbl->abk", w, hoop,
                                            C[:, 4, :4].reshape(-1, 2, 2), dNdX))
        K = K.at[:, :, :, 0].add(jnp.einsum("g,gaj,gij,gb->aib", w, dNdX,
                                            C[:, :4, 4].reshape(-1, 2, 2), hoop))
        K = K.at[:, 0, :, 0].add(jnp.einsum("g,ga,g,gb->ab", w, hoop, C[:, 4, 4], hoop))
    return r.reshape(8), K.reshape(8, 8)


def element_yield_ratio(ue, Xe, material, mp, hn, kinematics=PLANE_STRAIN, formulation=STANDARD):
    """(4,) ``material.yield_ratio`` at the Gauss points of one element (the trial
    state of the increment from h_n)."""
    H, _ = gauss_gradients(ue, Xe, kinematics, formulation)
    return jax.vmap(lambda h, hs: material.yield_ratio(h, hs, mp))(H, _history(material, hn))


def element_stress(ue, Xe, material, mp, hn=None, kinematics=PLANE_STRAIN, formulation=STANDARD):
    """Cauchy stress (3, 3) averaged over the Gauss points of one element (with
    history: the stress of the update from h_n, i.e. at the end of the increment)."""
    H, w = gauss_gradients(ue, Xe, kinematics, formulation)
    return average_cauchy(material, mp, H, w, _history(material, hn))


def average_cauchy(material, mp, H, w, hn):
    """The Cauchy stress (3, 3) of the material at the points' gradients H (g, 3, 3)
    and histories hn (g, n_state), averaged with the weights w (g,)."""
    if material.n_state:
        sig = jax.vmap(lambda h, hs: material.cauchy(h, hs, mp))(H, hn)
    else:
        sig = jax.vmap(lambda h: material.cauchy(h, mp))(H)
    return jnp.einsum("g,gij->ij", w, sig) / jnp.sum(w)
