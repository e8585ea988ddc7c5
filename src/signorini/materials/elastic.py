"""Hyperelastic materials, each defined by its strain-energy density W(F).

A material stores parameter *specs* (see :mod:`signorini.params`) for its
constants, so E and nu can be design parameters. ``energy(H, mp)`` takes the
3x3 displacement gradient H = du/dX (plane strain: H33 = 0; F = I + H) and the
resolved values ``mp = material.values(params)``; stresses come from ``jax.grad``.
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import _small
from .._jax import jax, jnp
from ..interfaces import MaterialDefaults
from ..errors import InputError
from ..params import Spec, resolve


def det_minus_one(H):
    """det(I + H) - 1 = I1(H) + I2(H) + I3(H), without cancellation for small H."""
    tr = jnp.trace(H)
    # tr(H H) as the sum of H_ij H_ji: no matrix product
    return tr + 0.5 * (tr**2 - jnp.sum(H * H.T)) + _small.det(H)


@dataclass(frozen=True)
class _Elastic(MaterialDefaults):
    E: Spec = "E"
    nu: Spec = "nu"

    #: the constant the stress is proportional to at fixed nu (W is linear in the
    #: Lame constants, both proportional to E): the DDM's pseudo-load of E in a
    #: linear body is then its internal force over E
    stress_proportional_to = "E"

    def specs(self):
        return (self.E, self.nu)

    def values(self, params):
        return {"E": resolve(self.E, params), "nu": resolve(self.nu, params)}

    def check(self, params):
        v = {k: float(x) for k, x in self.values(params).items()}
        if not 0 < v["E"] < float("inf"):
            raise InputError(f"Young's modulus must be positive, got E={v['E']} (a finite number)")
        if not -1.0 < v["nu"] < 0.5:
            raise InputError(f"Poisson's ratio must lie in (-1, 0.5), got nu={v['nu']} (0.5 is "
                             "incompressible, which these displacement elements cannot represent)")

    @staticmethod
    def lame(mp):
        E, nu = mp["E"], mp["nu"]
        return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    #: history entries per material point (hyperelastic: none)
    n_state = 0

    def first_piola(self, H, mp):
        """P = dW/dF = dW/dH."""
        return jax.grad(self.energy)(H, mp)

    def initial_state(self):
        """(n_state,) history at the start of the load path."""
        return jnp.zeros(0)

    def update(self, H, h_n, mp):
        """(P, h): the stress of the energy and the (empty) history, unchanged."""
        return self.first_piola(H, mp), h_n


@dataclass(frozen=True)
class LinearElastic(_Elastic):
    """Small-strain isotropic elasticity, W = mu eps:eps + lambda/2 (tr eps)^2."""

    finite_strain = False
    #: stress linear in H and zero at H = 0: the element stiffness does not depend
    #: on the displacements, so the model computes it once per parameter set
    linear = True

    def energy(self, H, mp):
        mu, lam = self.lame(mp)
        eps = 0.5 * (H + H.T)
        return mu * jnp.sum(eps * eps) + 0.5 * lam * jnp.trace(eps) ** 2

    def cauchy(self, H, mp):
        return self.first_piola(H, mp)


@dataclass(frozen=True)
class NeoHooke(_Elastic):
    """Compressible neo-Hookean solid (total Lagrangian, finite strain):
    W = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2.

    W is undefined for J <= 0; the solver reports such states as inverted elements.
    """

    finite_strain = True

    def energy(self, H, mp):
        mu, lam = self.lame(mp)
        lnJ = jnp.log1p(det_minus_one(H))
        # tr(F^T F) - 3 = 2 tr H + H:H, written so small H loses no digits
        return 0.5 * mu * (2.0 * jnp.trace(H) + jnp.sum(H * H)) - mu * lnJ + 0.5 * lam * lnJ**2

    def cauchy(self, H, mp):
        F = jnp.eye(3) + H
        return self.first_piola(H, mp) @ F.T / _small.det(F)
