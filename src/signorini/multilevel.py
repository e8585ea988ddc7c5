"""Coarse-to-fine initial guesses (docs/theory.md §10).

Newton's cost in a one-step contact solve is set by how far its first active
set is from the final one: from the undeformed state only the touching node is
closed, the first iterate penetrates over about twice the contact width, and
every further iteration releases only the outermost closed nodes, so the
count grows with the number of nodes in the contact zone (7 at 5k DOFs, 11 at
225k). Started from the solution of a coarser mesh, interpolated, the active
set is off by a node or two and Newton needs 2-3 iterations on the fine mesh.

The start changes only the first iterate, never the converged solution (to
the Newton tolerance), so sensitivities and finite differences of the results
are unaffected.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Sequence

import numpy as np
from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
from scipy.spatial import cKDTree

from . import checks
from .errors import InputError
from .problem import Problem
from .solution import Solution

log = logging.getLogger("signorini")


def _along_surface(Xc: np.ndarray, vc: np.ndarray, Xf: np.ndarray) -> np.ndarray:
    """Values vc (nc, m) at coarse surface nodes Xc, interpolated to points Xf on the
    same curve: linear between the two nearest coarse nodes (clamped to the segment)."""
    if len(Xc) == 1:
        return np.repeat(vc, len(Xf), axis=0)
    _, idx = cKDTree(Xc).query(Xf, k=2)
    a, b = Xc[idx[:, 0]], Xc[idx[:, 1]]
    d = b - a
    s = np.clip(np.einsum("ij,ij->i", Xf - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    return vc[idx[:, 0]] + s[:, None] * (vc[idx[:, 1]] - vc[idx[:, 0]])


def prolong(coarse: Solution, fine: Problem, increment: int = 0) -> np.ndarray:
    """Interpolate a converged coarse solution onto the mesh of ``fine``.

    Displacements: piecewise linear on a triangulation of the coarse nodes
    (nearest node outside it); contact multipliers (nominal tractions): linear
    along each contact surface, surface k of the coarse problem to surface k of
    the fine one.

    Args:
        coarse: a solution of the same body, obstacle and loads on a coarser mesh.
        fine: the problem to start.
        increment: which converged increment of ``coarse`` to interpolate.

    Returns:
        (n_dof,) initial guess for ``signorini.solve(fine, initial=...)``.
    """
    from .solve import model_for

    if not coarse.increments:
        raise InputError("prolong: the coarse solution has no converged increment")
    cm, fm = coarse.model, model_for(fine)
    if len(cm.surfaces) != len(fm.surfaces) or any(
            a.n_mult != b.n_mult for a, b in zip(cm.surfaces, fm.surfaces)):
        raise InputError("prolong: the coarse and fine problems must have the same contact "
                         "surfaces (in the same order, with the same multipliers per node)")
    w_c = np.asarray(coarse.increments[increment].w)
    u_c, lams_c = cm.split(w_c)
    Xc, Xf = np.asarray(cm._X0_np), np.asarray(fm._X0_np)
    uf = LinearNDInterpolator(Xc, u_c)(Xf)
    miss = ~np.all(np.isfinite(uf), axis=1)
    if miss.any():
        uf[miss] = NearestNDInterpolator(Xc, u_c)(Xf[miss])
    w = np.zeros(fm.n_dof)
    w[: 2 * fm.n_nodes] = uf.ravel()
    for sc, sf, lc in zip(cm.surfaces, fm.surfaces, lams_c):
        lf = _along_surface(Xc[sc.nodes], np.asarray(lc), Xf[sf.nodes])
        w[sf.lam_offset: sf.lam_offset + lf.size] = lf.ravel()
    return w


def solve_coarse_to_fine(problems: Sequence[Problem], *, steps: int = 1, sensitivities=(),
                         whole_path: bool = True, **solve_kwargs) -> tuple[Solution, list[dict]]:
    """Solve ``problems`` (coarse to fine, same physics), each started from the
    interpolated solution of the one before; sensitivities on the finest only.
    With ``steps > 1`` the coarse meshes are solved to the end of the first
    increment, which starts the first increment of the next mesh;
    ``whole_path=False`` treats the last problem so too (a start for yet another mesh).

    Returns:
        (solution of the finest problem, per level: dofs, Newton iterations, time_s).
    """
    import time

    from .solve import solve

    if not problems:
        raise InputError("solve_coarse_to_fine needs at least one problem")
    levels, sol, label = [], None, solve_kwargs.pop("label", None)
    for k, pb in enumerate(problems):
        last = k == len(problems) - 1 and whole_path
        initial = None if sol is None else prolong(sol, pb)
        t0 = time.perf_counter()
        # coarse levels: the first increment only (its end starts the next level);
        # later increments start from the extrapolating predictor
        # (and without the switch-point report, which only a result needs)
        kw = dict(solve_kwargs) if last else {**solve_kwargs, "switch_tol": None}
        with contextlib.nullcontext() if last else checks.silenced():
            sol = solve(pb, steps=steps, sensitivities=sensitivities if last else (),
                        initial=initial, label=label if last else f"level {k}",
                        until=1.0 if last else 1.0 / steps, **kw)
        levels.append({"dofs": int(sol.model.n_dof), "newton_iterations": list(sol.newton_iterations),
                       "time_s": time.perf_counter() - t0})
        log.debug("coarse-to-fine level %d: %d DOFs, %s iterations", k, sol.model.n_dof,
                  sol.newton_iterations)
    return sol, levels
