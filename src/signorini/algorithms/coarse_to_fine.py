"""Coarse-to-fine initial guesses (docs/theory.md §10).

Newton's cost in a one-step contact solve is set by how far its first active
set is from the final one: from the undeformed state only the touching node is
closed, the first iterate penetrates over about twice the contact width, and
every further iteration releases only the outermost closed nodes, so the
count grows with the number of nodes in the contact zone (7 at 5k DOFs, 11 at
225k). Started from the solution of a coarser mesh, interpolated, the active
set is off by a node or two and Newton needs 2-3 iterations on the fine mesh.

The same holds for every later increment of a load path: the contact zone
moves by several nodes per increment on a fine mesh, and an extrapolation of
the last two states overshoots it (zones grow like sqrt(t)), so Newton again
releases node after node. A coarser mesh solved along the same path locates
the zone within a coarse node; its interpolated increment, added to the fine
state, starts each fine increment (``solve(..., guide=coarse_solution)``).

The start changes only the first iterate, never the converged solution (to
the Newton tolerance), so sensitivities and finite differences of the results
are unaffected.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.spatial import Delaunay, cKDTree

from ..model import checks
from ..errors import InputError
from ..model.problem import Problem
from .solution import Solution

log = logging.getLogger("signorini")


def _linear_weights(Xc: np.ndarray, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) interpolation matrix: piecewise linear on the Delaunay triangulation
    of the coarse points Xc; a point outside it takes the nearest coarse point."""
    nf, nc = len(Xf), len(Xc)
    tri = Delaunay(Xc)
    simplex = tri.find_simplex(Xf)
    inside = simplex >= 0
    rows, cols, vals = [], [], []
    if inside.any():
        s = simplex[inside]
        T = tri.transform[s]  # (m, 3, 2): inverse affine map and the offset
        b = np.einsum("mij,mj->mi", T[:, :2], Xf[inside] - T[:, 2])
        bary = np.column_stack([b, 1.0 - b.sum(axis=1)])
        rows.append(np.repeat(np.nonzero(inside)[0], 3))
        cols.append(tri.simplices[s].ravel())
        vals.append(bary.ravel())
    if (~inside).any():
        _, near = cKDTree(Xc).query(Xf[~inside])
        rows.append(np.nonzero(~inside)[0])
        cols.append(near)
        vals.append(np.ones(near.size))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(nf, nc))


def _along_surface(Xc: np.ndarray, Xf: np.ndarray) -> sp.csr_matrix:
    """(nf, nc) matrix taking values at coarse surface nodes Xc to points Xf on the
    same curve: linear between the two nearest coarse nodes (clamped to the segment)."""
    nf, nc = len(Xf), len(Xc)
    if nc == 1:
        return sp.csr_matrix((np.ones(nf), (np.arange(nf), np.zeros(nf, dtype=int))), shape=(nf, 1))
    _, idx = cKDTree(Xc).query(Xf, k=2)
    a, b = Xc[idx[:, 0]], Xc[idx[:, 1]]
    d = b - a
    s = np.clip(np.einsum("ij,ij->i", Xf - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    rows = np.repeat(np.arange(nf), 2)
    return sp.csr_matrix((np.column_stack([1.0 - s, s]).ravel(), (rows, idx.ravel())), shape=(nf, nc))


class Prolongation:
    """The interpolation of unknowns from a coarse model to a fine one, built once
    as a sparse matrix (it is linear in the coarse unknowns).

    Displacements: piecewise linear on a triangulation of the coarse nodes
    (nearest node outside it); contact multipliers (nominal tractions): linear
    along each contact surface, surface k of the coarse model to surface k of
    the fine one.
    """

    def __init__(self, coarse_model, fine_model):
        cm, fm = coarse_model, fine_model
        if len(cm.surfaces) != len(fm.surfaces) or any(
                a.n_mult != b.n_mult for a, b in zip(cm.surfaces, fm.surfaces)):
            raise InputError("prolong: the coarse and fine problems must have the same contact "
                             "surfaces (in the same order, with the same multipliers per node)")
        Xc, Xf = np.asarray(cm._X0_np), np.asarray(fm._X0_np)
        self.coarse_model, self.fine_model = cm, fm
        if cm.n_dof == fm.n_dof and Xc.shape == Xf.shape and np.array_equal(Xc, Xf) and all(
                np.array_equal(a.nodes, b.nodes) and a.lam_offset == b.lam_offset
                for a, b in zip(cm.surfaces, fm.surfaces)):
            self.matrix = sp.identity(fm.n_dof, format="csr")  # the same mesh (other parameters)
            return
        blocks = []
        Pu = _linear_weights(Xc, Xf)  # nodes -> nodes; DOFs interleave (x, y) per node
        blocks.append((sp.kron(Pu, sp.identity(2)), 0, 0))
        for sc, sf in zip(cm.surfaces, fm.surfaces):
            Ps = _along_surface(Xc[sc.nodes], Xf[sf.nodes])
            blocks.append((sp.kron(Ps, sp.identity(sf.n_mult)), sf.lam_offset, sc.lam_offset))
        rows, cols, vals = [], [], []
        for B, r0, c0 in blocks:
            B = B.tocoo()
            rows.append(B.row + r0)
            cols.append(B.col + c0)
            vals.append(B.data)
        self.matrix = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                    shape=(fm.n_dof, cm.n_dof))

    @classmethod
    def between(cls, coarse_model, fine_model) -> "Prolongation":
        """The prolongation of these two models, built once and kept by the fine
        model (it depends only on their meshes, not on parameter values: 75 ms of
        a 230 ms coarse-to-fine solve at 56k DOFs when rebuilt every solve)."""
        key = ("prolongation", id(coarse_model))
        kept = fine_model.cache.get(key)
        if kept is None or kept.coarse_model is not coarse_model:
            kept = fine_model.cache[key] = cls(coarse_model, fine_model)
        return kept

    def __call__(self, w_coarse) -> np.ndarray:
        """(fine n_dof,) interpolation of coarse unknowns (coarse n_dof,)."""
        return self.matrix @ np.asarray(w_coarse, dtype=float)


def prolong(coarse: Solution, fine: Problem, increment: int = 0) -> np.ndarray:
    """Interpolate a converged coarse solution onto the mesh of ``fine``
    (:class:`Prolongation`).

    Args:
        coarse: a solution of the same body, obstacle and loads on a coarser mesh.
        fine: the problem to start.
        increment: which converged increment of ``coarse`` to interpolate.

    Returns:
        (n_dof,) initial guess for ``signorini.solve(fine, initial=...)``.
    """
    from .stepping import model_for

    if not coarse.increments:
        raise InputError("prolong: the coarse solution has no converged increment")
    return Prolongation.between(coarse.model, model_for(fine))(coarse.increments[increment].w)


def solve_coarse_to_fine(problems: Sequence[Problem], *, steps: int = 1, sensitivities=(),
                         whole_path: bool = True, **solve_kwargs) -> tuple[Solution, list[dict]]:
    """Solve ``problems`` (coarse to fine, same physics and load steps), each
    guided by the one before (``solve(..., guide=...)``): its first increment
    starts from the interpolated coarser solution, every later one from its own
    last state plus the interpolated coarser increment. Every level solves the
    whole load path; sensitivities on the finest only. ``whole_path=False``
    treats the last problem as a coarse level too (a guide for yet another mesh:
    no sensitivities, no switch report, its warnings kept in its solution).

    A coarse level that fails guides the next one over the increments it
    converged, or leaves the guide of the level before when that one reaches
    further (recorded as ``failed`` in its level); the finest level's failure
    is raised.

    Returns:
        (solution of the finest problem, per level: dofs, Newton iterations per
        increment, time_s[, failed]).
    """
    import time

    from ..errors import ConvergenceError
    from .stepping import model_for, solve

    if not problems:
        raise InputError("solve_coarse_to_fine needs at least one problem")
    levels, sol, label = [], None, solve_kwargs.pop("label", None)
    for k, pb in enumerate(problems):
        last = k == len(problems) - 1 and whole_path
        t0 = time.perf_counter()
        # coarse levels: no switch-point report (only a result needs it), no warnings issued
        kw = dict(solve_kwargs) if last else {**solve_kwargs, "switch_tol": None}
        level: dict = {}
        done: list = []
        try:
            with contextlib.nullcontext() if last else checks.silenced():
                sol = solve(pb, steps=steps, sensitivities=sensitivities if last else (),
                            guide=sol, label=label if last else f"level {k}", **kw)
            done = list(sol.newton_iterations)
        except ConvergenceError as e:
            if last:
                raise
            # what converged still guides the next mesh, unless the level before
            # guides further (then it keeps guiding); the rest uses the predictor
            part = e.partial if e.partial is not None and e.partial.increments else None
            done = list(part.newton_iterations) if part is not None else []
            if part is not None and (sol is None or len(part.increments) >= len(sol.increments)):
                sol = part
            level["failed"] = str(e)
            log.info("coarse level %d failed (%s); the next mesh is guided over %d increments",
                     k, e, 0 if sol is None else len(sol.increments))
        levels.append({"dofs": int(model_for(pb).n_dof), "newton_iterations": done,
                       "time_s": time.perf_counter() - t0, **level})
        log.debug("coarse-to-fine level %d: %d DOFs, %s iterations", k, levels[-1]["dofs"], done)
    return sol, levels
