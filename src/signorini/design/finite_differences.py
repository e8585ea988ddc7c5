"""Central finite differences of any output of a solve, for checking the DDM.

The load stepping, mesh and options are those of the DDM run; only the one
parameter moves (docs/theory.md §9).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from ..algorithms.stepping import solve
from ..sensitivity.methods import FiniteDifferences


def finite_difference(problem, name: str, quantity: Callable, *, step: float | None = None,
                      rel_step: float = 1e-6, **solve_kwargs) -> np.ndarray:
    """Central finite difference of ``quantity(solution)`` with respect to a parameter.

    Args:
        problem: the :class:`~signorini.model.problem.Problem` (nominal values).
        name: parameter to perturb.
        quantity: maps a :class:`~signorini.algorithms.solution.Solution` to an array.
        step: absolute step; default ``rel_step * max(|phi|, 1)``.
        **solve_kwargs: passed to :func:`signorini.solve` (use the same load
            stepping as the DDM run and a tight ``NewtonOptions(rtol=...)``).

    Returns:
        (quantity(phi + h) - quantity(phi - h)) / (2 h).
    """
    problem.with_params(**{name: 0.0})  # raises a clear error for an unknown name
    base = problem.params[name]
    h = FiniteDifferences(step=step, rel_step=rel_step).step_for(base)
    solve_kwargs = {k: v for k, v in solve_kwargs.items() if k not in ("sensitivities", "wrt", "method", "label")}
    qp = np.asarray(quantity(solve(problem.with_params(**{name: base + h}), label=f"FD {name}+",
                                   **solve_kwargs)))
    qm = np.asarray(quantity(solve(problem.with_params(**{name: base - h}), label=f"FD {name}-",
                                   **solve_kwargs)))
    return (qp - qm) / (2.0 * h)
