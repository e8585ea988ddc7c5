"""Contact methods: Alart-Curnier augmented Lagrangian and penalty.

A method defines, per contact node S, a pure function of the node's current
position ``x`` (2,), its multipliers ``lam`` (m,), its equivalent area ``A``,
the obstacle geometry and the method's parameters. The node residual (forces
on x followed by the multiplier equations) is the gradient of the
pseudo-potential (paper eq. 13 / 17); the tangent block is its Jacobian,
taken by JAX in :mod:`signorini.model`.

Case selection: a node is *closed* when lam_hat = lam + eps g <= 0. At
lam_hat = 0 both branches give the same residual, and choosing the closed
tangent there makes a body that touches the obstacle at one point at the start
(force control, zero gap) solvable from the first iteration.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .._jax import jax, jnp
from ..interfaces import ContactLawDefaults
from ..errors import InputError
from ..params import Spec, resolve


def neg_part(x):
    """min(x, 0), with the closed branch taken at x = 0 (see module docstring)."""
    return jnp.where(x <= 0.0, x, 0.0)


@dataclass(frozen=True)
class _Regularised(ContactLawDefaults):
    """A frictionless method with one regularisation parameter ``eps`` (> 0)."""

    eps: Spec = "eps"
    _what = "regularisation"

    def specs(self):
        return (self.eps,)

    def values(self, params):
        return {"eps": resolve(self.eps, params)}

    def check(self, params):
        e = float(resolve(self.eps, params))
        if not e > 0:
            raise InputError(f"the {self._what} parameter must be positive, got eps={e}")


@dataclass(frozen=True)
class AugmentedLagrangian(_Regularised):
    """Frictionless Alart-Curnier augmented Lagrangian (paper eqs. 16-21).

    One multiplier lam (<= 0, nominal normal traction) per contact node is a
    global unknown; displacements and multipliers are solved by one Newton
    scheme. The converged solution does not depend on ``eps`` (> 0).
    """

    n_multipliers: int = field(default=1, init=False)
    _what = "augmented-Lagrangian"

    def potential(self, x, lam, A, geo, obstacle, cp):
        """A_S l(g, lam), l = (<lam + eps g>_-^2 - lam^2) / (2 eps)  (eq. 17)."""
        eps = cp["eps"]
        g = obstacle.gap(x, geo)
        lam_hat = lam[0] + eps * g
        return A * (neg_part(lam_hat) ** 2 - lam[0] ** 2) / (2.0 * eps)

    def residual(self, x, lam, A, geo, obstacle, cp, hist):
        """(2 + 1,): contact force on x and the multiplier equation (eqs. 19-20)."""
        fx, fl = jax.grad(self.potential, argnums=(0, 1))(x, lam, A, geo, obstacle, cp)
        return jnp.concatenate([fx.ravel(), fl])

    def tractions(self, x, lam, A, geo, obstacle, cp):
        """(p_N, p_T): pressure positive in compression, tangential traction.
        p_N = -<lam + eps g>_-: equal to -lam at convergence on a closed node and
        exactly 0 on an open one (whose lam is zero only to round-off when
        Newton started from a predicted state)."""
        return -neg_part(lam[0] + cp["eps"] * obstacle.gap(x, geo)), jnp.zeros(())

    def row_scale(self, cp):
        """Factor that gives the multiplier rows force units (convergence norm only)."""
        return cp["eps"]


@dataclass(frozen=True)
class Penalty(_Regularised):
    """Penalty regularisation (paper eqs. 12-15): a pure displacement method.

    The constraint is satisfied only approximately: the penetration is
    p_N / eps, so the solution and its sensitivities depend on eps.
    """

    n_multipliers: int = field(default=0, init=False)
    _what = "penalty"

    def potential(self, x, lam, A, geo, obstacle, cp):
        """A_S eps/2 <g>_-^2  (eq. 13)."""
        g = obstacle.gap(x, geo)
        return 0.5 * A * cp["eps"] * neg_part(g) ** 2

    def residual(self, x, lam, A, geo, obstacle, cp, hist):
        return jax.grad(self.potential)(x, lam, A, geo, obstacle, cp).ravel()

    def tractions(self, x, lam, A, geo, obstacle, cp):
        return -cp["eps"] * neg_part(obstacle.gap(x, geo)), jnp.zeros(())

    def row_scale(self, cp):
        return 1.0


@dataclass(frozen=True)
class Contact:
    """A contact surface: a boundary set of the body against a rigid obstacle
    (contact between two bodies: :func:`~signorini.contact.mortar.pair`).

    Attributes:
        obstacle: in 2-D (plane strain in the (x, y) plane, axisymmetry in the
            (r, z) half plane) a :class:`~signorini.contact.obstacles.Circle` (a
            cylinder in plane strain; a torus or, centred on the axis, a sphere
            in axisymmetry) or a :class:`~signorini.contact.obstacles.Line` (a
            flat die; a cone, a plane or a cylinder in axisymmetry); in 3-D a
            :class:`~signorini.contact.obstacles3d.Plane`,
            :class:`~signorini.contact.obstacles3d.Sphere`,
            :class:`~signorini.contact.obstacles3d.Cylinder` or
            :class:`~signorini.contact.obstacles3d.Implicit` (a signed-distance
            function; it works in 2-D too).
        edges: name of the boundary set whose nodes are the contact nodes: an
            edge set of a 2-D mesh, a face set of a 3-D one.
        method: the contact law: :class:`AugmentedLagrangian` (default,
            frictionless, one multiplier per node), :class:`Penalty`
            (frictionless, no multiplier) or
            :class:`~signorini.contact.friction.Coulomb` (friction: in 2-D one
            tangential multiplier per node, in 3-D two, on the Coulomb disc).
        kinematics: ``"finite"`` (gap at the current position X + u),
            ``"linear"`` (gap and slip linearised about X in the frame of the
            moving obstacle: geometrically linear analysis, docs/theory.md §6.3;
            in 3-D the slip in the body's reference tangent plane, §12.4)
            or ``"auto"``: linear with a small-strain material, finite otherwise.
    """

    obstacle: object
    edges: str
    method: object = field(default_factory=AugmentedLagrangian)
    kinematics: str = "auto"

    def __post_init__(self):
        if self.kinematics not in ("auto", "linear", "finite"):
            raise InputError(f"Contact kinematics must be 'auto', 'linear' or 'finite', got {self.kinematics!r}")

    def specs(self):
        return (*self.obstacle.specs(), *self.method.specs())
