"""Coarse-to-fine initial guesses (docs/theory.md §10).

Newton's cost in a one-step contact solve is set by how far its first active
set is from the final one: from the undeformed state only the touching node is
closed, the first iterate penetrates over about twice the contact width, and
every further iteration releases only the outermost closed nodes, so the
count grows with the number of nodes in the contact zone, that is with the
mesh (docs/theory.md §10.3). Started from the solution of a coarser mesh,
interpolated, the active set is off by a node or two and Newton needs 2-3
iterations on the fine mesh.

The same holds for every later increment of a load path: the contact zone
moves by several nodes per increment on a fine mesh, and an extrapolation of
the last two states overshoots it (zones grow like sqrt(t)), so Newton again
releases node after node. A coarser mesh solved along the same path locates
the zone within a coarse node; its interpolated increment, added to the fine
state, starts each fine increment (``solve(..., start=coarse_solution)``).

The start changes only the first iterate, never the converged solution (to
the Newton tolerance), so sensitivities and finite differences of the results
are unaffected.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Sequence

import numpy as np

import time
from ..model import checks
from ..errors import InputError
from ..model.problem import Problem
from .prolongation import Prolongation
from .solution import Solution
from .stepping import model_for, solve
from ..errors import ConvergenceError
from .newton import NewtonOptions

log = logging.getLogger("signorini")


def prolong(coarse: Solution, fine: Problem, increment: int = 0) -> np.ndarray:
    """Interpolate a converged coarse solution onto the mesh of ``fine``
    (:class:`Prolongation`).

    Args:
        coarse: a solution of the same body, obstacle and loads on a coarser mesh.
        fine: the problem to start.
        increment: which converged increment of ``coarse`` to interpolate.

    Returns:
        (n_dof,) initial guess for ``signorini.solve(fine, start=...)``.
    """
    if not coarse.increments:
        raise InputError("prolong: the coarse solution has no converged increment")
    return Prolongation.between(coarse.model, model_for(fine))(coarse.increments[increment].w)


def solve_coarse_to_fine(problems: Sequence[Problem], *, steps: int = 1, wrt=(),
                         whole_path: bool = True, **solve_kwargs) -> tuple[Solution, list[dict]]:
    """Solve ``problems`` (coarse to fine, same physics and load steps), each
    guided by the one before (``solve(..., start=...)``): its first increment
    starts from the interpolated coarser solution, every later one from its own
    last state plus the interpolated coarser increment. Every level solves the
    whole load path; sensitivities on the finest only. ``whole_path=False``
    treats the last problem as a coarse level too (a guide for yet another mesh:
    no sensitivities, no switch report, its warnings kept in its solution).

    A coarse level is only a start, so it may not cost the run: its increments
    are never cut (``max_cuts=0``), and the first that fails abandons it at once,
    with the coarser levels after it: the next mesh solved (the finest) is
    guided by the last level that converged along the whole path, or starts
    without a guide (recorded as ``failed`` in the level, and as a warning in
    the finest solution when ``whole_path``; :func:`warn_failed_levels` puts
    them into a solution of another mesh). The finest level's failure is raised.

    Returns:
        (solution of the finest problem, per level: dofs, Newton iterations per
        increment, time_s[, failed]).
    """

    if not problems:
        raise InputError("solve_coarse_to_fine needs at least one problem")
    levels, sol, label = [], None, solve_kwargs.pop("label", None)
    options = solve_kwargs.pop("options", None) or NewtonOptions()
    abandoned = False
    models = [model_for(pb) for pb in problems]
    for coarse, fine in zip(models, models[1:]):  # built while the coarser levels solve
        Prolongation.prepare(coarse, fine)
    for k, pb in enumerate(problems):
        last = k == len(problems) - 1 and whole_path
        if abandoned and not last:
            continue
        t0 = time.perf_counter()
        # coarse levels: no switch-point report (only a result needs it), no warnings
        # issued, no step cutting
        kw = dict(solve_kwargs, options=options) if last else {
            **solve_kwargs, "switch_tol": None, "options": dataclasses.replace(options, max_cuts=0)}
        level: dict = {}
        done: list = []
        try:
            with contextlib.nullcontext() if last else checks.silenced():
                new = solve(pb, steps=steps, wrt=wrt if last else (),
                            start=sol, label=label if last else f"level {k}", **kw)
            sol, done = new, list(new.newton_iterations)
        except ConvergenceError as e:
            if last:
                raise
            part = e.partial
            done = list(part.newton_iterations) if part is not None else []
            level["failed"] = str(e)
            abandoned = True
            log.info("coarse level %d failed (%s); abandoned: the next mesh is %s", k, e,
                     "unguided" if sol is None else "guided by the level before")
        levels.append({"dofs": int(model_for(pb).n_dof), "newton_iterations": done,
                       "time_s": time.perf_counter() - t0, **level})
        log.debug("coarse-to-fine level %d: %d DOFs, %s iterations", k, levels[-1]["dofs"], done)
    if whole_path:
        warn_failed_levels(sol, levels)
    return sol, levels


def warn_failed_levels(solution: Solution, levels: list[dict]) -> None:
    """A warning in ``solution`` (the mesh the levels started) for every coarse
    level that failed (``levels`` of :func:`solve_coarse_to_fine`)."""
    for k, lv in enumerate(levels):
        if "failed" in lv:
            checks.warn(solution, f"the coarse start's level {k} ({lv.get('dofs', '?')} DOFs) "
                                  f"failed and was abandoned ({lv['failed']}); the mesh after it "
                                  "started without its guide (the result is the same, Newton may "
                                  "need more iterations)")
