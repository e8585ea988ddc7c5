"""Finite-strain J2 plasticity (Simo 1988; Simo & Hughes 1998, Box 9.1).

Multiplicative split F = F_e F_p, the plastic state stored as the material
tensor C_p^{-1} = F_p^{-1} F_p^{-T} (with b_e = F C_p^{-1} F^T), a von Mises
yield surface on the Kirchhoff stress with linear isotropic hardening, and the
radial return map of Box 9.1 in closed form. Every function is pure JAX, so the
consistent tangent dP/dH, the history sensitivities and the parameter
sensitivities (DDM) are taken by autodiff.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import _small
from .._jax import jax, jnp
from ..interfaces import MaterialDefaults
from ..errors import InputError
from ..params import Spec, resolve
from .elastic import det_minus_one

_SQ23 = math.sqrt(2.0 / 3.0)
_I = np.eye(3)  # NumPy: a JAX op at import is compiled, one program each (theory §10.5)

#: Newton steps on the cubic det(s/mu + Ibar I) = 1: monotone from an upper
#: bound within ~||s/mu||^2 of the root, quadratic; 8 steps reach round-off for
#: any sigma_y + H alpha up to the shear modulus mu
_NEWTON_STEPS = 8


def _dev(A):
    return A - jnp.trace(A) / 3.0 * _I


def _safe_norm(A):
    """(||A||, A/||A||), with value and derivatives finite at A = 0 (double where)."""
    ss = jnp.sum(A * A)
    pos = ss > 0.0
    nrm = jnp.where(pos, jnp.sqrt(jnp.where(pos, ss, 1.0)), 0.0)
    return nrm, A / jnp.where(pos, nrm, 1.0)


class ReturnMap(NamedTuple):
    """Everything the return map computes at one material point."""

    P: jnp.ndarray        #: first Piola-Kirchhoff stress (3, 3)
    tau: jnp.ndarray      #: Kirchhoff stress (3, 3)
    h: jnp.ndarray        #: updated history (10,): C_p^{-1} row-major, alpha
    J: jnp.ndarray        #: det F
    f_trial: jnp.ndarray  #: trial yield function ||s_tr|| - sqrt(2/3)(sigma_y + H alpha_n)
    dgamma: jnp.ndarray   #: plastic multiplier increment (0 on an elastic step)
    bbar_e: jnp.ndarray   #: updated isochoric elastic left Cauchy-Green tensor (3, 3)


@dataclass(frozen=True)
class J2Plasticity(MaterialDefaults):
    """Simo's multiplicative finite-strain J2 plasticity with linear isotropic hardening.

    Stored energy W = U(J) + mu/2 (tr bbar_e - 3), U(J) = kappa/2 [(J^2 - 1)/2 - ln J],
    mu = E / (2 (1 + nu)), kappa = E / (3 (1 - 2 nu)); bbar_e = J^{-2/3} F C_p^{-1} F^T.
    Kirchhoff stress tau = kappa/2 (J^2 - 1) I + s, s = mu dev(bbar_e).
    Yield function f = ||s|| - sqrt(2/3) (sigma_y + H alpha) <= 0 (H = 0: ideal plasticity).

    History per material point (``n_state = 10``): C_p^{-1} (9 entries, row-major;
    initially I) and the equivalent plastic strain alpha (initially 0).

    Return map (Box 9.1): Fbar = J^{-1/3} F, bbar_tr = Fbar C_p,n^{-1} Fbar^T,
    Ibar = tr(bbar_tr)/3, mubar = mu Ibar, s_tr = mu dev(bbar_tr); if
    f_tr = ||s_tr|| - sqrt(2/3)(sigma_y + H alpha_n) > 0 then
    dgamma = f_tr / (2 mubar + 2 H / 3), s = s_tr - 2 mubar dgamma n (n = s_tr/||s_tr||),
    alpha = alpha_n + sqrt(2/3) dgamma; P = tau F^{-T}. On an elastic step
    (f_tr <= 0) the history is returned unchanged (bitwise).

    **det bbar_e = 1.** The deviatoric part of the updated bbar_e is s/mu; its
    spherical part is *not* taken as the trial Ibar (which keeps tr bbar_e but
    lets det bbar_e drift from 1, by ~5 % at alpha ~ 0.5) but as the root of
    det(s/mu + Ibar I) = Ibar^3 - 1/2 tr[(s/mu)^2] Ibar + det(s/mu) = 1
    (Simo & Hughes 1998, Remark 9.2.2). That root is unique among the Ibar that
    keep bbar_e positive definite; g(Ibar) = det(...) - 1 is increasing and convex
    there, and g(Ibar_tr) >= 0 (shrinking the deviator at fixed trace raises the
    determinant), so Newton started at Ibar_tr converges monotonically. A fixed
    number of Newton steps is unrolled, which keeps the update differentiable to
    any order. Hence det bbar_e = det C_p^{-1} = 1 to round-off (plastic
    incompressibility) along the whole history. The stress of the current step
    does not depend on this choice (only on s and J); the history does.
    """

    E: Spec = "E"
    nu: Spec = "nu"
    sigma_y: Spec = "sigma_y"
    H: Spec = 0.0

    finite_strain = True
    #: history entries per material point: C_p^{-1} (9, row-major) and alpha
    n_state = 10

    def specs(self):
        return (self.E, self.nu, self.sigma_y, self.H)

    def values(self, params):
        return {"E": resolve(self.E, params), "nu": resolve(self.nu, params),
                "sigma_y": resolve(self.sigma_y, params), "H": resolve(self.H, params)}

    def check(self, params):
        v = {k: float(x) for k, x in self.values(params).items()}
        if not 0 < v["E"] < float("inf"):
            raise InputError(f"J2 plasticity: Young's modulus must be positive and finite, got "
                             f"E={v['E']}; give a positive number")
        if not -1.0 < v["nu"] < 0.5:
            raise InputError(f"J2 plasticity: Poisson's ratio must lie in (-1, 0.5), got "
                             f"nu={v['nu']} (0.5 is incompressible, which these displacement "
                             "elements cannot represent); use e.g. nu=0.3 or 0.49")
        if not 0 < v["sigma_y"] < float("inf"):
            raise InputError(f"J2 plasticity: the yield stress must be positive and finite, got "
                             f"sigma_y={v['sigma_y']}; give the initial uniaxial yield stress "
                             "(> 0)")
        if not 0 <= v["H"] < float("inf"):
            raise InputError(f"J2 plasticity: the hardening modulus must be >= 0 and finite, got "
                             f"H={v['H']}; use H=0 for ideal plasticity (softening is not "
                             "supported)")

    @staticmethod
    def moduli(mp):
        """(mu, kappa): shear and bulk moduli."""
        E, nu = mp["E"], mp["nu"]
        return E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))

    def initial_state(self):
        """(10,) virgin history: C_p^{-1} = I, alpha = 0."""
        return jnp.concatenate([_I.ravel(), jnp.zeros(1)])

    @staticmethod
    def equivalent_plastic_strain(h):
        """alpha from a history (..., 10)."""
        return h[..., 9]

    @staticmethod
    def plastic_metric_inverse(h):
        """C_p^{-1} (..., 3, 3) from a history (..., 10)."""
        return h[..., :9].reshape(h.shape[:-1] + (3, 3))

    def stored_energy(self, H, h_n, mp):
        """W(F) = U(J) + mu/2 (tr(Fbar C_p^{-1} Fbar^T) - 3) at the frozen plastic state h_n.

        On an elastic step P = dW/dF (``jax.grad`` of this in H).
        """
        mu, kappa = self.moduli(mp)
        Cpinv = self.plastic_metric_inverse(h_n)
        d = det_minus_one(H)
        J = 1.0 + d
        F = _I + H
        U = 0.5 * kappa * (0.5 * d * (2.0 + d) - jnp.log1p(d))
        return U + 0.5 * mu * (J ** (-2.0 / 3.0) * jnp.trace(F @ Cpinv @ F.T) - 3.0)

    def return_map(self, H, h_n, mp) -> ReturnMap:
        """The closed-form return map of Box 9.1 (see the class docstring)."""
        mu, kappa = self.moduli(mp)
        sy, Hk = mp["sigma_y"], mp["H"]
        Cpinv_n = self.plastic_metric_inverse(h_n)
        alpha_n = h_n[9]

        F = _I + H
        d = det_minus_one(H)                      # J - 1 without cancellation
        J = 1.0 + d
        c = jnp.expm1(-2.0 / 3.0 * jnp.log1p(d))  # J^{-2/3} - 1
        # F C_p^{-1} F^T - I, summed so that small H and C_p^{-1} ~ I lose no digits
        X = (Cpinv_n - _I) + H @ Cpinv_n + (H @ Cpinv_n).T + H @ Cpinv_n @ H.T
        X = 0.5 * (X + X.T)
        # bbar_tr = (1 + c)(I + X): deviator and mean of the diagonal
        s_tr = mu * (1.0 + c) * _dev(X)
        Ibar_tr = 1.0 + ((1.0 + c) * jnp.trace(X) + 3.0 * c) / 3.0
        mubar = mu * Ibar_tr

        nrm, n = _safe_norm(s_tr)
        f_tr = nrm - _SQ23 * (sy + Hk * alpha_n)
        plastic = f_tr > 0.0
        dgamma = jnp.where(plastic, f_tr / (2.0 * mubar + 2.0 / 3.0 * Hk), 0.0)
        s = s_tr - 2.0 * mubar * dgamma * n
        alpha = alpha_n + _SQ23 * dgamma

        tau = 0.5 * kappa * d * (2.0 + d) * _I + s   # J U'(J) = kappa/2 (J^2 - 1)
        Finv = _small.adjugate(F) / J
        P = tau @ Finv.T

        # updated bbar_e = s/mu + Ibar I with det bbar_e = 1: Newton on the cubic,
        # fed harmless inputs (a = 0, root 1) on elastic steps so that no branch
        # produces a non-finite value or derivative
        a = jnp.where(plastic, s / mu, 0.0)
        j2 = 0.5 * jnp.sum(a * a)
        det_a = _small.det(a)
        # start: an upper bound of the root (x + a_i >= 1 for every eigenvalue a_i
        # of the deviator a, whose |a_i| <= sqrt(2/3) ||a||), within ~||a||^2 of it
        x0 = jnp.minimum(Ibar_tr, 1.0 + 2.0 / 3.0 * (sy + Hk * alpha) / mu)

        def newton(_, x):
            g = x * x * x - j2 * x + det_a - 1.0
            gp = 3.0 * x * x - j2
            return x - g / jnp.where(gp > 0.0, gp, 1.0)

        x = jax.lax.fori_loop(0, _NEWTON_STEPS, newton, jnp.where(plastic, x0, 1.0))
        bbar_e = a + x * _I
        # C_p^{-1} = Fbar^{-1} bbar_e Fbar^{-T} = J^{2/3} F^{-1} bbar_e F^{-T}
        Cpinv = Finv @ bbar_e @ Finv.T / (1.0 + c)
        Cpinv = 0.5 * (Cpinv + Cpinv.T)
        h_plastic = jnp.concatenate([Cpinv.ravel(), alpha[None]])
        h = jnp.where(plastic, h_plastic, h_n)
        bbar_e = jnp.where(plastic, bbar_e, (1.0 + c) * (_I + X))
        return ReturnMap(P=P, tau=tau, h=h, J=J, f_trial=f_tr, dgamma=dgamma, bbar_e=bbar_e)

    def yield_ratio(self, H, h_n, mp):
        """Trial yield function over the current yield stress, f_tr / (sqrt(2/3)
        (sigma_y + H alpha_n)): <= 0 elastic step, > 0 plastic, 0 on the switch."""
        return self.return_map(H, h_n, mp).f_trial / (_SQ23 * (mp["sigma_y"] + mp["H"] * h_n[9]))

    def update(self, H, h_n, mp):
        """(P, h): first Piola-Kirchhoff stress and updated history."""
        r = self.return_map(H, h_n, mp)
        return r.P, r.h

    def cauchy(self, H, h_n, mp):
        """Cauchy stress sigma = tau / J at the end of the increment from h_n."""
        r = self.return_map(H, h_n, mp)
        return r.tau / r.J
