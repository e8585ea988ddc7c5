"""Hyperelastic materials, each defined by its strain-energy density W(F).

A material stores parameter *specs* (see :mod:`signorini.params`) for its
constants, so E and nu can be design parameters. ``energy(F, mp)`` takes the
3x3 deformation gradient (plane strain: F33 = 1) and the resolved values
``mp = material.values(params)``; stresses come from ``jax.grad``.
"""

from __future__ import annotations

from dataclasses import dataclass

from ._jax import jax, jnp
from .errors import InputError
from .params import Spec, resolve


@dataclass(frozen=True)
class _Elastic:
    E: Spec = "E"
    nu: Spec = "nu"

    def specs(self):
        return (self.E, self.nu)

    def values(self, params):
        return {"E": resolve(self.E, params), "nu": resolve(self.nu, params)}

    def check(self, params):
        v = {k: float(x) for k, x in self.values(params).items()}
        if not v["E"] > 0:
            raise InputError(f"Young's modulus must be positive, got E={v['E']}")
        if not -1.0 < v["nu"] < 0.5:
            raise InputError(f"Poisson's ratio must lie in (-1, 0.5), got nu={v['nu']}")

    @staticmethod
    def lame(mp):
        E, nu = mp["E"], mp["nu"]
        return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    def first_piola(self, F, mp):
        return jax.grad(self.energy)(F, mp)


@dataclass(frozen=True)
class LinearElastic(_Elastic):
    """Small-strain isotropic elasticity, W = mu eps:eps + lambda/2 (tr eps)^2."""

    finite_strain = False

    def energy(self, F, mp):
        mu, lam = self.lame(mp)
        H = F - jnp.eye(3)
        eps = 0.5 * (H + H.T)
        return mu * jnp.sum(eps * eps) + 0.5 * lam * jnp.trace(eps) ** 2

    def cauchy(self, F, mp):
        return self.first_piola(F, mp)


@dataclass(frozen=True)
class NeoHooke(_Elastic):
    """Compressible neo-Hookean solid (total Lagrangian, finite strain):
    W = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2.

    W is undefined for J <= 0; the solver reports such states as inverted elements.
    """

    finite_strain = True

    def energy(self, F, mp):
        mu, lam = self.lame(mp)
        J = jnp.linalg.det(F)
        lnJ = jnp.log(J)
        return 0.5 * mu * (jnp.sum(F * F) - 3.0) - mu * lnJ + 0.5 * lam * lnJ**2

    def cauchy(self, F, mp):
        return self.first_piola(F, mp) @ F.T / jnp.linalg.det(F)
