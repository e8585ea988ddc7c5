"""Forging preform optimisation (paper §5.3, Figs. 8-9).

For each friction coefficient mu, find the Bezier preform phi0..phi4 of
:mod:`signorini.problems.forging` whose upset billet comes closest to the
cylinder r = r_opt = h0: minimise F = sum_k (r_k - h0)^2 over the lateral
nodes (eq. 24) with BFGS (or L-BFGS-B / SLSQP) and exact DDM gradients, one
forging solve with five sensitivities per design point
(:class:`signorini.design.optimize.Objective`). The start is the cylinder
phi_k = 0.7 h0.

Invalid shapes: with L-BFGS-B and SLSQP the bounds phi_k >= ``phi_min``
keep r0(Z) >= phi_min > 0 (the Bernstein polynomials are non-negative and sum
to 1). BFGS is unbounded: a trial preform with r0 <= 0 somewhere
(:func:`~signorini.problems.forging.check_shape`), an inverted element or a
Newton failure is answered by the objective's penalty (a large finite value
and a gradient back towards the last good point), so the line search backs off.

The optimisation runs, their files and the parallel tasks are the
``optimize-forging`` command's (:mod:`signorini.app.commands.optimize_forging`).
"""

from __future__ import annotations

import functools
import logging

from ..design.optimize import Objective
from ..sensitivity.methods import method_named
from . import forging as fg

log = logging.getLogger("signorini")

#: start design: the cylinder of radius 0.7 h0
START = 0.7 * fg.H0
#: lower bound of phi_k for the bounded methods (keeps r0 >= PHI_MIN)
PHI_MIN = 0.05 * fg.H0


@functools.lru_cache(maxsize=4)
def base_problem(mesh: tuple[int, int] = (10, 20)):
    """The forging problem on ``mesh`` (cached: every mu and design point reuses
    its mesh and so its compiled model)."""
    return fg.forging_problem(mesh=tuple(mesh))


def validate(params: dict) -> None:
    """The preform radius must stay positive on [0, h0] (as forging_problem checks)."""
    fg.check_shape([params[k] for k in fg.SHAPE])


def objective_for(mu: float, *, mesh=(10, 20), steps: int = 50, rtol: float = 1e-11,
                  solver="auto", gradient: str = "ddm", history=None, append: bool = False,
                  label: str | None = None) -> Objective:
    """The :class:`~signorini.design.optimize.Objective` F(phi0..phi4) at friction ``mu``."""
    pb = base_problem(tuple(mesh)).with_params(mu=float(mu))
    lat = fg.lateral_nodes(pb)
    return Objective(pb, list(fg.SHAPE), lambda model: fg.objective(model, lat), steps=steps,
                     options=fg.options(rtol), solver=solver, method=method_named(gradient),
                     validate=validate, response_key=("forging-opt-F", tuple(lat.tolist())),
                     history=history, append=append, label=label or f"opt mu={mu:g}")
