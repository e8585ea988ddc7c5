"""Coulomb friction in three dimensions: the Alart-Curnier law with a 2-D
tangential multiplier and the return to the Coulomb disc (docs/theory.md §12.4).

Per contact node S three multipliers are unknowns, (lam_N, lam_T1, lam_T2), the
tangential ones in the basis (t1, t2) of the obstacle's tangent plane at the
node: t1 = e_S x n' / |e_S x n'|, t2 = n' x t1, with e_S a unit vector fixed per
node (a property of the mesh). With the closest point y(x) in the obstacle's
frame (:mod:`signorini.contact.obstacles3d`) and its value y_n at the end of
the previous increment (the history), and Q the obstacle's rotation (the
identity unless it turns),

    g_N = g(x_S),   g_T = (t1 . Q (y(x_S) - y_n), t2 . Q (y(x_S) - y_n)),

lam^_N = lam_N + eps_N g_N, lam^_T = lam_T + eps_T g_T, rho = mu <lam^_N>_-, and the
pseudo-potential of the 2-D law (:mod:`signorini.contact.friction`) with squared
norms and the distance from the disc |lam^_T| <= rho:

    l = (<lam^_N>_-^2 - lam_N^2) / (2 eps_N)
        + (|lam^_T|^2 - |lam_T|^2 - <|lam^_T| - rho>^2) / (2 eps_T).

Its gradient in (x_S, lam) at fixed rho and fixed case flags is the node
residual; rho is substituted outside that gradient, so a Jacobian of
:meth:`CoulombDisc.residual` is the exact unsymmetric tangent. In 2-D terms:
with the motion in one plane the law is the 2-D one (the test says so).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._jax import jax, jnp
from .friction import OPEN, SLIP, STICK, TIE, Coulomb


def tangent_basis(n, e):
    """(t1, t2): t1 = e x n / |e x n|, t2 = n x t1 (right-handed with n)."""
    t1 = jnp.cross(e, n)
    t1 = t1 / jnp.sqrt(t1 @ t1)
    return t1, jnp.cross(n, t1)


def reference_axis(N):
    """e_S for a node with reference outward normal N (3,): the coordinate axis
    least aligned with N (never parallel to a normal near N)."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(np.asarray(N))))] = 1.0
    return e


@dataclass(frozen=True)
class CoulombDisc(Coulomb):
    """Coulomb friction on a rigid 3-D obstacle (three multipliers per node).

    A user writes :class:`~signorini.contact.friction.Coulomb` (``sg.Coulomb``) in
    3-D as in 2-D: a 3-D contact surface turns it into this law with the same
    ``mu``, ``eps_n`` and ``eps_t`` when the problem is built (:func:`disc`).

    The node's history is ``hist = (y_n (3,), e_S (3,), tangential (2,)[,
    case flags])``: the closest point after the previous increment, the fixed
    axis of its tangent basis and which of the two tangential multipliers the
    node carries (a component is 0 where the node's motion along it is
    prescribed: a symmetry plane holds t2, an axis both; docs/theory.md §12.4).
    Parameters as :class:`Coulomb`.
    """

    n_multipliers: int = field(default=3, init=False)

    @staticmethod
    def _hist(hist):
        return hist[0], hist[1], hist[2], (hist[3] if len(hist) > 3 else None)

    @staticmethod
    def slip_vector(x, geo, obstacle, y_n, e):
        """g_T (2,) in the tangent basis at x."""
        t1, t2 = tangent_basis(obstacle.normal(x, geo), e)
        d = obstacle.closest(x, geo) - y_n
        if isinstance(geo, dict) and "Q" in geo:  # the obstacle's frame turns with it
            d = geo["Q"] @ d
        return jnp.stack([t1 @ d, t2 @ d])

    def augmented(self, x, lam, geo, obstacle, cp, hist):
        """(lam^_N, lam^_T (2,), g_N, g_T (2,)) of one node; the components the
        node does not carry (``tangential`` 0) are 0 in lam^_T."""
        y_n, e, m, _ = self._hist(hist)
        g_n = obstacle.gap(x, geo)
        g_t = self.slip_vector(x, geo, obstacle, y_n, e)
        return lam[0] + cp["eps_n"] * g_n, m * (lam[1:] + cp["eps_t"] * g_t), g_n, g_t

    def cases(self, x, lam, geo, obstacle, cp, hist):
        """(closed, stick) flags of one node: closed = lam^_N <= 0; stick =
        closed & mu > 0 & (1 + TIE) |lam^_T| <= (1 - TIE) rho."""
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, hist)
        closed = lhn <= 0.0
        rho = -cp["mu"] * jnp.where(closed, lhn, 0.0)
        stick = closed & (cp["mu"] > 0.0) & ((1.0 + TIE) * _norm(lht) <= (1.0 - TIE) * rho)
        return closed, stick

    def potential(self, x, lam, A, geo, obstacle, cp, hist, rho, case):
        """A_S l(x, lam; rho) at fixed rho and case flags; a component the node
        does not carry has l = -lam_Ti^2 / (2 eps_T) (its equation lam_Ti = 0)."""
        _, _, m, _ = self._hist(hist)
        closed, stick = case
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, hist)
        l_n = (jnp.where(closed, lhn, 0.0) ** 2 - lam[0] ** 2) / (2.0 * cp["eps_n"])
        outside = jnp.where(stick, 0.0, _norm(lht) - rho)  # the distance from the disc
        # open (rho = 0): the distance squared is lam^_T . lam^_T, whose curvature the
        # norm's zero gradient at lam^_T = 0 would lose (an open node at rest: a zero
        # tangential row, singular for SuperLU and the multipliers' Schur complement)
        outside2 = jnp.where(closed, outside**2, lht @ lht)
        lt = lam[1:]
        l_t = (lht @ lht - lt @ (m * lt) - outside2 - lt @ ((1.0 - m) * lt)) / (2.0 * cp["eps_t"])
        return A * (l_n + l_t)

    def _flags(self, hist):
        return self._hist(hist)[3]

    def tractions(self, x, lam, A, geo, obstacle, cp):
        """(p_N, p_T (2,)): pressure and tangential traction on the body in the
        basis (t1, t2); zero at an open node."""
        lhn = lam[0] + cp["eps_n"] * obstacle.gap(x, geo)
        closed = lhn <= 0.0
        return -jnp.where(closed, lhn, 0.0), jnp.where(closed, -lam[1:], 0.0)

    def status(self, x, lam, A, geo, obstacle, cp, hist):
        """OPEN, STICK or SLIP by the branch the residual takes."""
        closed, stick = self.cases(x, lam, geo, obstacle, cp, hist)
        stick = stick | jnp.all(self._hist(hist)[2] <= 0)
        return jnp.where(closed, jnp.where(stick, STICK, SLIP), OPEN)

    def stick_margin(self, x, lam, A, geo, obstacle, cp, hist):
        """|lam^_T| - rho of a closed friction node (negative: stick); inf elsewhere."""
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, hist)
        closed = lhn <= 0.0
        rho = -cp["mu"] * jnp.where(closed, lhn, 0.0)
        on = closed & jnp.any(self._hist(hist)[2] > 0) & (cp["mu"] > 0.0)
        return jnp.where(on, _norm(lht) - rho, jnp.inf)

    @staticmethod
    def history_point(x, geo, obstacle):
        """The node's history value at x: its closest point y(x) on the obstacle."""
        return obstacle.closest(x, geo)

    def slip(self, x, geo, obstacle, hist):
        y_n, e, _, _ = self._hist(hist)
        return self.slip_vector(x, geo, obstacle, y_n, e)

    def row_scale(self, cp):
        return jnp.stack([cp["eps_n"], cp["eps_t"], cp["eps_t"]])


def disc(method):
    """The law a 3-D contact surface uses for ``method``: a 2-D :class:`Coulomb`
    becomes the :class:`CoulombDisc` of the same parameters; others are kept."""
    if isinstance(method, Coulomb) and not isinstance(method, CoulombDisc):
        return CoulombDisc(mu=method.mu, eps_n=method.eps_n, eps_t=method.eps_t)
    return method


def _norm(v):
    """|v| with a zero gradient at v = 0 (a stick node at rest)."""
    s = v @ v
    safe = jnp.where(s > 0, s, 1.0)
    return jnp.where(s > 0, jnp.sqrt(safe), 0.0)
