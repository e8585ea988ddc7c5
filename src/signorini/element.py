"""Isoparametric 4-node quadrilateral, 2x2 Gauss quadrature, plane strain.

The element is described by its energy; residual and tangent come from JAX:
``residual = grad(energy)``, ``tangent = jacfwd(residual)``.
"""

from __future__ import annotations

import numpy as np

from ._jax import jax, jnp

_G = 1.0 / np.sqrt(3.0)
#: Gauss points (4, 2) in the parent square and their weights (4,).
GAUSS_POINTS = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])
GAUSS_WEIGHTS = np.ones(4)
_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def shape_functions(xi):
    """Bilinear shape functions N (4,) at parent point xi (2,)."""
    return 0.25 * (1 + _CORNERS[:, 0] * xi[0]) * (1 + _CORNERS[:, 1] * xi[1])


def shape_gradients(xi):
    """dN/dxi (4, 2) at parent point xi (2,)."""
    dxi = 0.25 * _CORNERS[:, 0] * (1 + _CORNERS[:, 1] * xi[1])
    deta = 0.25 * _CORNERS[:, 1] * (1 + _CORNERS[:, 0] * xi[0])
    return jnp.stack([dxi, deta], axis=1)


#: dN/dxi at the Gauss points, (4 gauss, 4 nodes, 2).
_DN = np.stack([np.asarray(shape_gradients(p)) for p in GAUSS_POINTS])


def reference_gradients(Xe):
    """Shape-function gradients w.r.t. X and quadrature weights.

    Args:
        Xe: (4, 2) reference nodal coordinates.

    Returns:
        dNdX (4 gauss, 4 nodes, 2) and w (4,) = Gauss weight * det(dX/dxi).
    """
    J = jnp.einsum("gai,aj->gji", _DN, Xe)  # (g, 2, 2): dX_j/dxi_i
    detJ = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    Jinv = jnp.stack([jnp.stack([J[:, 1, 1], -J[:, 0, 1]], -1),
                      jnp.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], -2) / detJ[:, None, None]  # dxi/dX
    dNdX = jnp.einsum("gai,gij->gaj", _DN, Jinv)
    return dNdX, GAUSS_WEIGHTS * detJ


def displacement_gradients(ue, Xe):
    """Plane-strain displacement gradients H = du/dX (4 gauss, 3, 3) and weights (4,).

    Materials receive H rather than F = I + H: a small-strain law needs H, and
    recovering it as F - I would cost ~1e-13 relative accuracy in the residual
    (a floor that tight Newton tolerances over many small increments hit).
    """
    dNdX, w = reference_gradients(Xe)
    H = jnp.einsum("ai,gaj->gij", ue, dNdX)  # (g, 2, 2)
    return jnp.zeros((4, 3, 3)).at[:, :2, :2].set(H), w


def element_energy(ue, Xe, material, mp):
    """Stored energy of one element: sum_g w_g W(H_g).

    Args:
        ue: (4, 2) nodal displacements. Xe: (4, 2) reference coordinates.
        material: a material object with ``energy(H, mp)``. mp: its parameter values.
    """
    H, w = displacement_gradients(ue, Xe)
    return jnp.sum(w * jax.vmap(lambda h: material.energy(h, mp))(H))


def element_residual(ue, Xe, material, mp):
    """Internal force vector (4, 2) = d(energy)/d(ue)."""
    return jax.grad(element_energy)(ue, Xe, material, mp)


def element_residual_tangent(ue, Xe, material, mp):
    """Internal forces (8,) and tangent (8, 8) of one element, node-major DOFs.

    Equal to ``grad`` / ``hessian`` of :func:`element_energy` (H is linear in ue),
    but autodiff is applied at the material point only: P = dW/dH and
    C = d2W/dH2 per Gauss point, then r = sum_g w_g B^T P, K = sum_g w_g B^T C B.
    Differentiating the whole element in forward mode cost 3-4x more.
    """
    dNdX, w = reference_gradients(Xe)  # (g, a, 2), (g,)
    H = jnp.zeros((4, 3, 3)).at[:, :2, :2].set(jnp.einsum("ai,gaj->gij", ue, dNdX))
    P = jax.vmap(jax.grad(material.energy), (0, None))(H, mp)[:, :2, :2]  # (g, 2, 2)
    C = jax.vmap(jax.hessian(material.energy), (0, None))(H, mp)[:, :2, :2, :2, :2]
    r = jnp.einsum("g,gij,gaj->ai", w, P, dNdX).reshape(8)
    K = jnp.einsum("g,gaj,gijkl,gbl->aibk", w, dNdX, C, dNdX).reshape(8, 8)
    return r, K


def element_stress(ue, Xe, material, mp):
    """Cauchy stress (3, 3) averaged over the Gauss points of one element."""
    H, w = displacement_gradients(ue, Xe)
    sig = jax.vmap(lambda h: material.cauchy(h, mp))(H)
    return jnp.einsum("g,gij->ij", w, sig) / jnp.sum(w)
