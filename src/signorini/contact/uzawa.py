"""The inner problem of Uzawa's augmented-Lagrangian algorithm (docs/theory.md §4).

Uzawa keeps the multipliers lam^k of every contact node *frozen* while Newton
solves for the displacements,

    R_U = grad Pi + sum_i A_i min(lam_i^k + eps g_i(U), 0) grad g_i = 0,

and then updates lam^{k+1} = min(lam^k + eps g(U^{k+1}), 0) in an outer loop
(:func:`signorini.algorithms.uzawa.solve_uzawa`). It is here as a comparator for the
single-Newton augmented Lagrangian: the frozen multipliers travel in the
model's per-node history slot, so the same residual, tangent and DDM
pseudo-load code serves both methods.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .._jax import jax, jnp
from .methods import _Regularised


@dataclass(frozen=True)
class UzawaPenalty(_Regularised):
    """Frozen-multiplier contact law of Uzawa's inner loop; use with
    :func:`signorini.algorithms.uzawa.solve_uzawa` (not :func:`signorini.solve`)."""

    n_multipliers: int = field(default=0, init=False)
    has_history: bool = field(default=True, init=False)
    _what = "Uzawa augmented-Lagrangian"
    driver = "signorini.algorithms.uzawa.solve_uzawa"

    @staticmethod
    def _lam_hat(x, geo, obstacle, cp, hist):
        return hist[0] + cp["eps"] * obstacle.gap(x, geo)

    def cases(self, x, lam, geo, obstacle, cp, hist):
        """(closed,) with closed = lam^k + eps g <= 0."""
        return (self._lam_hat(x, geo, obstacle, cp, hist) <= 0.0,)

    def potential(self, x, A, geo, obstacle, cp, hist, closed):
        """A/(2 eps) min(lam^k + eps g, 0)^2: its x-gradient is the contact force."""
        lh = self._lam_hat(x, geo, obstacle, cp, hist)
        return A * jnp.where(closed, lh, 0.0) ** 2 / (2.0 * cp["eps"])

    def residual(self, x, lam, A, geo, obstacle, cp, hist):
        closed = hist[2][0] if len(hist) > 2 else self.cases(x, lam, geo, obstacle, cp, hist)[0]
        return jax.grad(self.potential)(x, A, geo, obstacle, cp, hist, closed)

    def update(self, x, geo, obstacle, cp, lam_k):
        """Outer update lam^{k+1} = min(lam^k + eps g(x), 0)."""
        lh = lam_k + cp["eps"] * obstacle.gap(x, geo)
        return jnp.where(lh <= 0.0, lh, 0.0)

    def tractions(self, x, lam, A, geo, obstacle, cp):
        """Not available per node without lam^k: see ``UzawaSolution.pressure``."""
        return jnp.zeros(()), jnp.zeros(())

    def row_scale(self, cp):
        return 1.0
