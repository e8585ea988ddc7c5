"""Kinematics of the 2-D analysis: plane strain or axisymmetric.

A kinematics object says how the 3x3 displacement gradient H = F - I follows
from the in-plane nodal displacements, how much volume a quadrature point
carries, and how boundary loads and contact areas are integrated. Everything
else (elements, materials, contact laws) is written once for both.

* :class:`PlaneStrain`: coordinates (x, y), per unit thickness, H33 = 0.
* :class:`Axisymmetric`: coordinates (R, Z) with the axis at R = 0; the hoop
  stretch gives H33 = u_r / R; volumes, loads and contact areas carry the
  full 2 pi R (docs/theory.md §5, §7).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._jax import jnp
from ..errors import InputError

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class PlaneStrain:
    """Plane strain per unit thickness."""

    name = "plane strain"
    dim = 2
    n_gauss = 4  # Gauss points of a cell (Q4, 2x2)
    #: the components of H that can be non-zero (the material tangent is taken in these only)
    active = ((0, 0), (0, 1), (1, 0), (1, 1))

    def check_mesh(self, X: np.ndarray) -> None:
        """Nothing to check: any position in the plane is allowed."""

    def displacement_gradients(self, ue, Xe, N, dNdX):
        """H (g, 3, 3) at points with shape functions N (g, 4) and gradients dNdX (g, 4, 2)."""
        H2 = jnp.einsum("ai,gaj->gij", ue, dNdX)
        return jnp.zeros((N.shape[0], 3, 3)).at[:, :2, :2].set(H2)

    def volume_weights(self, Xe, N, w_ref):
        """Quadrature weights (g,): per unit thickness, the parent weight times det J."""
        return w_ref

    def hoop_functions(self, Xe, N):
        """(g, 4) with H33 = sum_a hoop_a u_a,r, or None (no hoop strain)."""
        return None

    def edge_factors(self, Xa, Xb):
        """(2,) weights of the two ends of a straight edge for a uniform load:
        consistent nodal force = traction * factor (plane: L / 2 each)."""
        L = jnp.linalg.norm(Xb - Xa)
        return jnp.stack([0.5 * L, 0.5 * L])

    def contact_areas(self, X, edges: np.ndarray, nodes: np.ndarray):
        """A_S (nc,): half the adjacent reference edge lengths (docs/theory.md §5.2)."""
        L = jnp.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        pos = np.searchsorted(nodes, edges)
        return jnp.zeros(len(nodes)).at[pos[:, 0]].add(0.5 * L).at[pos[:, 1]].add(0.5 * L)


@dataclass(frozen=True)
class Axisymmetric:
    """Axisymmetric analysis about the Z axis; coordinates (R, Z), R >= 0.

    F = [[1 + u_r,R, u_r,Z, 0], [u_z,R, 1 + u_z,Z, 0], [0, 0, 1 + u_r / R]];
    dV = 2 pi R dR dZ. Quadrature points never lie on the axis. Nodes on the
    axis need u_r = 0 (a ``Fixed`` of component 0).
    """

    name = "axisymmetric"
    dim = 2
    n_gauss = 4
    active = ((0, 0), (0, 1), (1, 0), (1, 1), (2, 2))

    def check_mesh(self, X: np.ndarray) -> None:
        if np.min(X[:, 0]) < -1e-12 * max(float(np.ptp(X[:, 0])), 1.0):
            k = int(np.argmin(X[:, 0]))
            raise InputError(f"axisymmetric analysis needs R >= 0 at every node; node {k} is at "
                             f"R = {X[k, 0]:.6g}. Put the axis of symmetry at R = 0 (x = 0)")

    def displacement_gradients(self, ue, Xe, N, dNdX):
        H2 = jnp.einsum("ai,gaj->gij", ue, dNdX)
        R = N @ Xe[:, 0]  # (g,) > 0 at interior points
        hoop = (N @ ue[:, 0]) / R
        return jnp.zeros((N.shape[0], 3, 3)).at[:, :2, :2].set(H2).at[:, 2, 2].set(hoop)

    def volume_weights(self, Xe, N, w_ref):
        return TWO_PI * (N @ Xe[:, 0]) * w_ref

    def hoop_functions(self, Xe, N):
        return N / (N @ Xe[:, 0])[:, None]

    def edge_factors(self, Xa, Xb):
        """Consistent weights of a uniform load on a straight meridian edge:
        int N_a 2 pi R ds = 2 pi L (2 R_a + R_b) / 6."""
        L = jnp.linalg.norm(Xb - Xa)
        return TWO_PI * L / 6.0 * jnp.stack([2 * Xa[0] + Xb[0], Xa[0] + 2 * Xb[0]])

    def contact_areas(self, X, edges: np.ndarray, nodes: np.ndarray):
        """A_S = 2 pi / 6 sum_k l_k (2 R_S + R_Nk) (docs/theory.md §5.3): the row sums
        of the consistent boundary matrix; they add up to the exact lateral area
        and stay positive on the axis."""
        Xa, Xb = X[edges[:, 0]], X[edges[:, 1]]
        L = jnp.linalg.norm(Xb - Xa, axis=1)
        fa = TWO_PI * L / 6.0 * (2 * Xa[:, 0] + Xb[:, 0])
        fb = TWO_PI * L / 6.0 * (Xa[:, 0] + 2 * Xb[:, 0])
        pos = np.searchsorted(nodes, edges)
        return jnp.zeros(len(nodes)).at[pos[:, 0]].add(fa).at[pos[:, 1]].add(fb)


PLANE_STRAIN = PlaneStrain()
AXISYMMETRIC = Axisymmetric()
