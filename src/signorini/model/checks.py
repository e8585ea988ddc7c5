"""Checks that turn a silently non-physical result into a warning or an error.

Each check is cheap next to a Newton iteration. Warnings are logged on the
``signorini`` logger, raised as :class:`~signorini.errors.SignoriniWarning`
and kept in ``Solution.warnings`` (the command-line runs copy them into
``summary.json``); conditions under which the problem is undefined raise
:class:`~signorini.errors.InputError`.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import warnings

import numpy as np

from .._jax import jax, jnp, to_device
from ..errors import InputError, SignoriniWarning
from ..contact import mortar
from ..contact.obstacles import Circle
from ..params import resolve

log = logging.getLogger("signorini")

#: a contact zone with fewer closed nodes than this is poorly resolved
MIN_CONTACT_NODES = 10
#: a friction surface whose contact zone grows by more nodes than this in one
#: increment in the last two thirds of the load path has a path too coarse for
#: its history (benchmarks/study_friction_domain.py: this rule flags exactly the
#: frictional Hertz paths whose stick zone is off by more than 2 %; the early
#: growth of a contact zone, 41 % of a in the 2nd increment, does not matter,
#: because the final stick edge formed after about (c/a)^2 t = 0.47 t)
MAX_NEW_CONTACT_NODES = 1
COARSE_PATH_FROM = 1.0 / 3.0


_SILENT = contextvars.ContextVar("signorini_checks_silent", default=False)


@contextlib.contextmanager
def silenced():
    """Keep warnings in ``solution.warnings`` only, without logging or raising them
    (the auxiliary coarse solves of :mod:`signorini.algorithms.coarse_to_fine`)."""
    token = _SILENT.set(True)
    try:
        yield
    finally:
        _SILENT.reset(token)


def warn(solution, message: str) -> None:
    """Keep ``message`` in ``solution.warnings`` and raise it as a
    :class:`SignoriniWarning` (once per solution). A library user hears of it
    through :mod:`warnings`, which they can filter; the log gets it at INFO (the
    ``signorini`` command shows INFO, so its user sees it there too)."""
    if message in solution.warnings:
        return
    solution.warnings.append(message)
    if _SILENT.get():
        return
    label = getattr(solution, "label", None)
    log.info("warning%s: %s", f" [{label}]" if label else "", message)
    warnings.warn(message, SignoriniWarning, stacklevel=3)


def duplicate_nodes(X: np.ndarray) -> np.ndarray:
    """Indices of nodes that coincide with an earlier node (to 1e-12 of the mesh size)."""
    if len(X) < 2:
        return np.zeros(0, dtype=np.int64)
    tol = 1e-12 * max(float(np.ptp(X, axis=0).max()), 1e-300)
    key = np.round(X / tol).astype(np.int64) if tol > 0 else X
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return np.nonzero(first[inv.ravel()] != np.arange(len(X)))[0]


def points_in_body(P: np.ndarray, X: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(n_points,) True where a point lies strictly inside some (convex, CCW) cell."""
    x = X[cells]  # (n_cells, 4, 2)
    e = np.roll(x, -1, axis=1) - x
    out = np.zeros(len(P), bool)
    for k, p in enumerate(P):
        d = p[None, None, :] - x
        cross = e[..., 0] * d[..., 1] - e[..., 1] * d[..., 0]
        out[k] = bool(np.any(np.all(cross > 0, axis=1)))
    return out


def before_solve(model, params, solution) -> None:
    """Mesh and obstacle checks at the start of a solve (t = 0)."""
    X = np.asarray(model.reference(params))
    kept = model.cache.get("duplicate_nodes")  # (X, result): the same mesh in every solve
    if kept is None or not np.array_equal(kept[0], X):  # unless shape parameters moved it
        kept = model.cache["duplicate_nodes"] = (X, duplicate_nodes(X))
    dup = kept[1]
    paired = [s.patches.nodes.ravel() for s in model.surfaces if s.patches is not None]
    if dup.size and paired:  # two bodies touching at a contact pair: intended
        dup = dup[~np.isin(dup, np.concatenate(paired))]
    if dup.size:
        warn(solution, f"{dup.size} duplicate node(s) (first: node {int(dup[0])} at "
                       f"{X[dup[0]].round(6).tolist()}): coincident nodes that share no cell leave "
                       "the mesh disconnected there; merge them (remove duplicates) unless this "
                       "is intended")
    w0 = to_device(np.zeros(model.n_dof))
    for i, s in enumerate(model.surfaces):
        obst = s.contact.obstacle
        if isinstance(obst, Circle):  # the centre at t = 0, in NumPy
            c = np.array([float(resolve(v, params)) for v in obst.centre])
            if points_in_body(c[None, :], X, model.conn)[0]:
                raise InputError(
                    f"contact {s.contact.edges!r}: the centre {c.round(6).tolist()} of the circular "
                    "obstacle lies inside the body at t = 0, where the gap and its normal are "
                    "undefined; move the obstacle (centre, radius) outside the body")
        g = np.asarray(model.compiled.fields(w0, params, 0.0, i)["gap"])
        k = int(np.argmin(g))
        e = s.edges
        near = np.any(e == s.nodes[k], axis=1)  # the cells' edges at that node
        h = float(np.linalg.norm(X[e[near, 1]] - X[e[near, 0]], axis=1).mean())
        if g[k] < -h:
            warn(solution, f"contact {s.contact.edges!r}: the body starts inside the obstacle by "
                           f"{-g[k]:.4g} at node {int(s.nodes[k])} (more than the size {h:.3g} of "
                           "its cells); the first increment must push it out, which is rarely "
                           "what is meant: check the obstacle's position and the shape parameters")


class IncrementChecks:
    """Checks between consecutive converged increments (tunnelling, coarse paths)."""

    def __init__(self, model, params, solution):
        self.model = model
        self.params = params
        self.solution = solution
        self.prev = None  # (t, x of the contact nodes, closed masks) per surface
        self.pairs = {}  # surface -> (master edges, candidate matrix): pairs, finite kinematics
        self.memo = {}  # surface -> the partner distances of the last configuration (shared)
        for i, s in enumerate(model.surfaces):
            if s.patches is not None and not model.linear_contact[i]:
                master = model.problem.mesh.edge_set(s.contact.obstacle.master)
                self.pairs[i] = (master, mortar.candidates(s.patches, master))
                self.memo[i] = model.cache.setdefault(("partner-distances", i), {})

    def _snapshot(self, w, t):
        m = self.model
        X = np.asarray(m.reference(self.params))
        u = np.asarray(w)[: m.dim * m.n_nodes].reshape(-1, m.dim)
        snap = []
        for i, s in enumerate(m.surfaces):
            f = m.compiled.fields(to_device(w), self.params, t, i)
            snap.append((X[s.nodes] + u[s.nodes], np.asarray(f["p_N"]) > 0))
        return t, snap

    def start(self, w) -> None:
        """The state at t = 0 (the reference for the first increment)."""
        self.prev = self._snapshot(w, 0.0)

    def after(self, w, t, n_inc: int) -> None:
        m = self.model
        now = self._snapshot(w, t)
        self._lost_partners(w, now, n_inc)
        if self.prev is not None:
            t0, before = self.prev
            for i, s in enumerate(m.surfaces):
                x0, closed0 = before[i]
                x1, closed1 = now[1][i]
                obst = s.contact.obstacle
                if isinstance(obst, Circle) and not m.linear_contact[i]:
                    g0, g1 = obst.geometry(self.params, t0), obst.geometry(self.params, t)
                    n0 = np.asarray(jax.vmap(obst.normal, (0, None))(jnp.asarray(x0), g0))
                    n1 = np.asarray(jax.vmap(obst.normal, (0, None))(jnp.asarray(x1), g1))
                    flip = np.nonzero(np.sum(n0 * n1, axis=1) < 0)[0]
                    if flip.size:
                        warn(self.solution,
                             f"contact {s.contact.edges!r}: {flip.size} node(s) (first: node "
                             f"{int(s.nodes[flip[0]])}) passed through the obstacle in increment "
                             f"{n_inc} (t = {t0:.4g} -> {t:.4g}); the result is not physical: use "
                             "more load increments")
                if s.contact.method.has_history and t0 >= COARSE_PATH_FROM - 1e-12:
                    new = int(np.sum(closed1 & ~closed0))
                    if new > MAX_NEW_CONTACT_NODES and closed0.any():
                        warn(self.solution,
                             f"contact {s.contact.edges!r}: the contact zone grew by {new} nodes in "
                             f"increment {n_inc} (t = {t0:.4g} -> {t:.4g}); with friction the "
                             "history of the nodes that close within one increment is not resolved "
                             f"(more than {MAX_NEW_CONTACT_NODES} per increment after t = 1/3), so "
                             "stick and slip zones can be wrong: use more load increments")
        self.prev = now

    def _lost_partners(self, w, now, n_inc) -> None:
        """A slave node of a pair that overlaps a master segment outside its
        candidates (found once on the nominal mesh), closed or within half a
        segment of it, misses (or would miss) that segment's contact: the
        surfaces slid further than the pair allows. An open node that slid past
        all its candidates gets the far gap, so the closed ones are not enough."""
        if not self.pairs:
            return
        m = self.model
        x = np.asarray(m.reference(self.params)) + np.asarray(w)[: m.dim * m.n_nodes].reshape(-1, m.dim)
        for i, (master, cand) in self.pairs.items():
            s = m.surfaces[i]
            closed = now[1][i][1]
            dist = np.where(cand, np.inf, mortar.partner_distances(x, s.patches, master, self.memo[i]))
            lost = (np.any(dist <= 1.0, axis=1) & closed) | np.any(dist <= 0.5, axis=1)
            if lost.any():
                first = int(s.nodes[np.argmax(lost)])
                slide = s.contact.obstacle.slide
                window = "half a segment" + (f" plus slide = {slide:g}" if slide else "")
                warn(self.solution,
                     f"contact pair {s.contact.edges!r}/{s.contact.obstacle.master!r}: in increment "
                     f"{n_inc} (t = {now[0]:.4g}) {int(lost.sum())} slave node(s) (first: node "
                     f"{first}) overlap master segments, in contact or within half a segment of "
                     "them, that are not among their candidate partners (found once on the nominal "
                     f"mesh, within {window} of their own); contact with those segments is missed "
                     "and the result is not physical: give the pair the sliding distance, "
                     "pair(..., slide=...)")

    def final(self) -> None:
        if self.prev is None:
            return
        for i, s in enumerate(self.model.surfaces):
            n = int(self.prev[1][i][1].sum())
            if 0 < n < MIN_CONTACT_NODES:
                warn(self.solution,
                     f"contact {s.contact.edges!r}: the contact zone holds only {n} closed node(s) "
                     f"at the end (fewer than {MIN_CONTACT_NODES}); pressures and their "
                     "sensitivities are poorly resolved: refine the mesh where contact occurs")
