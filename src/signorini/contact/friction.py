"""Coulomb friction by the Alart-Curnier augmented Lagrangian (docs/theory.md §3).

This is the 2-D law (plane strain and axisymmetry); on a 3-D contact surface the
same :class:`Coulomb` becomes the Coulomb disc of
:mod:`signorini.contact.friction3d` (two tangential multipliers per node).

Per contact node S two multipliers are global unknowns: lam_N (<= 0, nominal
normal traction) and lam_T (tangential traction). With the gaps

    g_N = g(x_S),   g_T = s(x_S) - s_n      (s: slip coordinate on the obstacle, s_n: history)

and the augmented multipliers lam^_N = lam_N + eps_N g_N, lam^_T = lam_T + eps_T g_T,
the friction-disc radius is rho = mu <lam^_N>_- and the pseudo-potential is

    l = (<lam^_N>_-^2 - lam_N^2) / (2 eps_N)
        + (lam^_T^2 - lam_T^2 - dist(lam^_T, [-rho, rho])^2) / (2 eps_T)

(dist(y, [-rho, rho]) = <|y| - rho>: the pseudo-potential of docs/theory.md §3). The node
residual is the gradient of A_S l in (x_S, lam) *at fixed rho*; rho is computed
outside that gradient and passed in, so the Jacobian taken by
:class:`~signorini.model.Model` (``jax.jacfwd`` of :meth:`Coulomb.residual`)
differentiates through rho and is the exact, unsymmetric tangent of the
non-associated law (docs/theory.md §3.4). At convergence
lam_N = min(lam^_N, 0) and lam_T = proj(lam^_T) = tau: Signorini and Coulomb
hold exactly for any eps_N, eps_T > 0.

Sign convention (docs/theory.md §0): the traction on the body is
-(lam_N n' + lam_T t'), so the reported tractions are p_N = -lam_N (pressure,
>= 0) and p_T = -lam_T, the tangential traction on the body along the obstacle
tangent t' (it opposes the slip increment g_T).

Case selection at the boundaries (closed at zero, as in
:func:`~signorini.contact.methods.neg_part`): a node is closed when
lam^_N <= 0; a closed node with mu > 0 sticks when (1 + TIE) |lam^_T| <=
(1 - TIE) rho, i.e. strictly inside the disc by a relative :data:`TIE`, and
also when lam^_T = rho = 0 (so a body touching the die at the start is held
tangentially from the first iteration); open nodes and mu = 0 always take the
free (slip) branch, whose tangent for mu = 0 is exactly the frictionless one.

Why a band: every node that slipped in the last increment starts the next one
(from the converged state, without a predictor) exactly on the disc edge,
|lam^_T| = rho to round-off (measured: relative margins below 7.3e-15 on the
frictional Hertz). With the plain test |lam^_T| <= rho the branch of such a node
would be decided by the last bits of the arithmetic, which differ between two
compiled programs of the same formula: the flags and the tangent computed in
one program can then give a singular first tangent (docs/theory.md §3.4). The band
sends these ties to slip, their natural continuation, whatever the rounding.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .._jax import jax, jnp
from ..interfaces import ContactLawDefaults
from ..errors import InputError
from ..params import Spec, resolve

#: Integer codes returned by :meth:`Coulomb.status`.
OPEN, STICK, SLIP = 0, 1, 2

#: Relative width of the stick/slip tie band: a closed node sticks only when
#: (1 + TIE) |lam^_T| <= (1 - TIE) rho. Round-off of the disc-edge test is below
#: 1e-14 (measured), so ties are decided the same way by every compiled program;
#: a node inside the band is on the switch (it is reported as a switch point,
#: :mod:`signorini.sensitivity.nonsmooth`, whose tolerance is far wider), where
#: stick and slip give the same converged state to 1e-12.
TIE = 1e-12
STATUS_NAMES = ("open", "stick", "slip")


@dataclass(frozen=True)
class Coulomb(ContactLawDefaults):
    """Coulomb friction on a rigid obstacle, Alart-Curnier augmented Lagrangian.

    In 2-D (plane strain and axisymmetry) two multipliers per contact node,
    (lam_N, lam_T): one tangential multiplier, along the obstacle's tangent in
    the plane of the model ((x, y), or (r, z) in axisymmetry). The contact
    node's slip coordinate after the previous converged increment, s_n, is
    history data (carried and differentiated by :class:`~signorini.model.Model`).
    Nodes whose tangential displacement is prescribed (a symmetry line) get no
    friction: their lam_T equation is lam_T = 0 (docs/theory.md §3.6).

    In 3-D the same ``Coulomb(mu, eps_n, eps_t)`` is the Coulomb disc
    (:class:`~signorini.contact.friction3d.CoulombDisc`, made from it when the
    problem is built): three multipliers per node, lam_N and a tangential
    traction of two components (lam_T1, lam_T2) in the basis (t1, t2) of the
    obstacle's tangent plane, held inside the disc |lam_T| <= mu |lam_N|
    (docs/theory.md §12.4); :meth:`~signorini.algorithms.solution.Solution.contact`
    gives p_T and the slip with two components and the basis.

    Attributes:
        mu: friction coefficient (>= 0).
        eps_n, eps_t: augmentation parameters (> 0); they do not change the
            converged solution, only Newton's path. A smaller ``eps_t`` helps when
            stick/slip states cycle.
    """

    mu: Spec = "mu"
    eps_n: Spec = "eps"
    eps_t: Spec = "eps_t"
    n_multipliers: int = field(default=2, init=False)
    has_history: bool = field(default=True, init=False)

    def specs(self):
        return (self.mu, self.eps_n, self.eps_t)

    def values(self, params):
        return {"mu": resolve(self.mu, params), "eps_n": resolve(self.eps_n, params),
                "eps_t": resolve(self.eps_t, params)}

    def check(self, params):
        v = {k: float(x) for k, x in self.values(params).items()}
        if not v["mu"] >= 0:
            raise InputError(f"the friction coefficient must be >= 0, got mu={v['mu']}")
        for k in ("eps_n", "eps_t"):
            if not v[k] > 0:
                raise InputError(f"the augmented-Lagrangian parameter must be positive, got {k}={v[k]}")

    # ------------------------------------------------------------- kinematics
    @staticmethod
    def _hist(hist):
        """Per-node input built by the model: (s_n, tangential[, case flags])."""
        if hist is None:
            raise InputError("Coulomb friction needs the slip history of the contact nodes; "
                             "call Model.residual with state_n = model.initial_state(...) or later")
        return hist[0], hist[1], (hist[2] if len(hist) > 2 else None)

    def _flags(self, hist):
        """The case flags the model passed in ``hist``, or None."""
        return self._hist(hist)[2]

    def augmented(self, x, lam, geo, obstacle, cp, s_n):
        """(lam^_N, lam^_T, g_N, g_T) of one node."""
        g_n = obstacle.gap(x, geo)
        g_t = obstacle.coordinate(x, geo) - s_n
        return lam[0] + cp["eps_n"] * g_n, lam[1] + cp["eps_t"] * g_t, g_n, g_t

    def cases(self, x, lam, geo, obstacle, cp, hist):
        """Case flags (closed, stick, positive) of one node at (x, lam):
        closed = lam^_N <= 0, stick = closed & mu > 0 & (1 + TIE) |lam^_T| <=
        (1 - TIE) rho (a node on the disc edge slips, see :data:`TIE`),
        positive = lam^_T >= 0 (the sign of the slip direction)."""
        s_n = self._hist(hist)[0]
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, s_n)
        closed = lhn <= 0.0
        rho = -cp["mu"] * jnp.where(closed, lhn, 0.0)
        stick = closed & (cp["mu"] > 0.0) & ((1.0 + TIE) * jnp.abs(lht) <= (1.0 - TIE) * rho)
        return closed, stick, lht >= 0.0

    # -------------------------------------------------------- pseudo-potential
    def potential(self, x, lam, A, geo, obstacle, cp, hist, rho, case):
        """A_S l(x, lam; rho) with the disc radius rho and the case flags held
        fixed (docs/theory.md §3)."""
        s_n, tangential, _ = self._hist(hist)
        closed, stick, positive = case
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, s_n)
        l_n = (jnp.where(closed, lhn, 0.0) ** 2 - lam[0] ** 2) / (2.0 * cp["eps_n"])
        tau = jnp.where(stick, lht, jnp.where(positive, rho, -rho))  # proj_[-rho, rho](lam^_T)
        l_t = (lht**2 - lam[1] ** 2 - (lht - tau) ** 2) / (2.0 * cp["eps_t"])
        l_fixed = -lam[1] ** 2 / (2.0 * cp["eps_t"])  # no friction DOF: lam_T = 0
        return A * (l_n + jnp.where(tangential > 0, l_t, l_fixed))

    def residual(self, x, lam, A, geo, obstacle, cp, hist):
        """(4,): contact force on x_S, then R_lamN, R_lamT (docs/theory.md §3).

        rho = mu <lam^_N>_- is evaluated here, outside the inner gradient, so the
        caller's Jacobian of this function includes d rho / d(x, lam_N).

        The case flags come from ``hist`` when the model supplies them (computed
        once per evaluation, :meth:`cases`), else from :meth:`cases` here. Flags
        passed in as data cannot disagree between the force rows and the
        multiplier rows of a node (a mix of stick and slip would leave the
        lam_T column empty); the tie band of :meth:`cases` makes them the same
        in every compiled program."""
        case = self._flags(hist)
        if case is None:
            case = self.cases(x, lam, geo, obstacle, cp, hist)
        lhn = lam[0] + cp["eps_n"] * obstacle.gap(x, geo)
        rho = -cp["mu"] * jnp.where(case[0], lhn, 0.0)
        fx, fl = jax.grad(self.potential, argnums=(0, 1))(x, lam, A, geo, obstacle, cp, hist,
                                                           rho, case)
        return jnp.concatenate([fx.ravel(), fl])

    # ------------------------------------------------------------ post-process
    def tractions(self, x, lam, A, geo, obstacle, cp):
        """(p_N, p_T): pressure (>= 0) and tangential traction on the body along
        the obstacle tangent t'; (-lam_hat_N, -lam_T) at a closed node (lam_hat_N
        = lam_N + eps_n g_N <= 0, equal to lam_N at convergence), exactly (0, 0)
        at an open one, whose multipliers are zero only to round-off when Newton
        started from a predicted state."""
        lhn = lam[0] + cp["eps_n"] * obstacle.gap(x, geo)
        closed = lhn <= 0.0
        return -jnp.where(closed, lhn, 0.0), jnp.where(closed, -lam[1], 0.0)

    def status(self, x, lam, A, geo, obstacle, cp, hist):
        """OPEN (0), STICK (1) or SLIP (2) of a node, by the branch the residual
        takes at (x, lam). A closed node without friction DOF (prescribed
        tangential displacement) cannot slip and counts as STICK."""
        closed, stick, _ = self.cases(x, lam, geo, obstacle, cp, hist)
        stick = stick | (self._hist(hist)[1] <= 0)
        return jnp.where(closed, jnp.where(stick, STICK, SLIP), OPEN)

    def stick_margin(self, x, lam, A, geo, obstacle, cp, hist):
        """|lam^_T| - rho of a closed node with a friction DOF and mu > 0 (negative:
        stick, positive: slip, 0: on the stick/slip switch); inf elsewhere."""
        s_n, tangential, _ = self._hist(hist)
        lhn, lht, _, _ = self.augmented(x, lam, geo, obstacle, cp, s_n)
        closed = lhn <= 0.0
        rho = -cp["mu"] * jnp.where(closed, lhn, 0.0)
        on = closed & (tangential > 0) & (cp["mu"] > 0.0)
        return jnp.where(on, jnp.abs(lht) - rho, jnp.inf)

    @staticmethod
    def history_point(x, geo, obstacle):
        """The node's history value at x: its slip coordinate s(x) on the obstacle."""
        return obstacle.coordinate(x, geo)

    def slip(self, x, geo, obstacle, hist):
        """Slip increment g_T = s(x) - s_n of the current increment."""
        return obstacle.coordinate(x, geo) - self._hist(hist)[0]

    def row_scale(self, cp):
        """Per-multiplier factors giving the lam_N, lam_T rows force units."""
        return jnp.stack([cp["eps_n"], cp["eps_t"]])
