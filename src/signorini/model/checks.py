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
from ..contact import mortar, mortar3d
from ..contact.obstacles import Circle
from ..params import resolve

log = logging.getLogger("signorini")

#: a contact zone with fewer closed nodes than this is poorly resolved
MIN_CONTACT_NODES = 10
#: a friction surface whose contact zone grows by more rings of nodes than this
#: in one increment in the last two thirds of the load path has a path too coarse
#: for its history (benchmarks/study_friction_domain.py: this rule flags exactly
#: the frictional Hertz paths whose stick zone is off by more than 2 %; the early
#: growth of a contact zone, 41 % of a in the 2nd increment, does not matter,
#: because the final stick edge formed after about (c/a)^2 t = 0.47 t). On the
#: half model of that study a ring is one node; see :func:`ring_distances`.
MAX_NEW_CONTACT_RINGS = 1
MAX_NEW_CONTACT_NODES = MAX_NEW_CONTACT_RINGS  # the name before rings were counted
COARSE_PATH_FROM = 1.0 / 3.0
#: newly closed nodes whose distances from the contact centre differ by less than
#: this fraction of the cell size form one ring (see :func:`ring_distances`)
RING_WIDTH = 0.02
#: the same for a zone that travels (rows across its travel, see :func:`ring_distances`):
#: its direction is estimated from the zone's path, and a tilt of a few degrees
#: shifts the nodes of a row by a few percent of a cell along it (ironing3d: 3.6 %)
TRAVEL_RING_WIDTH = 0.1


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


def side_lengths(X: np.ndarray, faces: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(len(nodes),) the mean length of the surface's cell sides (edges in 2-D, the
    sides of the faces in 3-D) that meet at each contact node: the local cell size."""
    f = np.asarray(faces)
    k = f.shape[1]
    sides = f if k == 2 else np.concatenate([f[:, [j, (j + 1) % k]] for j in range(k)])
    length = np.linalg.norm(X[sides[:, 1]] - X[sides[:, 0]], axis=1)
    local = np.full(len(X), -1)
    local[nodes] = np.arange(len(nodes))
    ends = local[sides].ravel()
    keep = ends >= 0
    total = np.bincount(ends[keep], np.repeat(length, 2)[keep], minlength=len(nodes))
    count = np.bincount(ends[keep], minlength=len(nodes))
    h = np.divide(total, count, out=np.zeros(len(nodes)), where=count > 0)
    return np.where(count > 0, h, length.mean() if len(length) else 1.0)


def contact_centre(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The centre of a contact zone: the mean position of its nodes of largest
    pressure (within 1e-6 of the largest). See :func:`ring_distances` for why."""
    top = p >= (1.0 - 1e-6) * p.max()
    return x[top].mean(axis=0)


def _centroid(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The pressure-weighted centroid of a contact zone: where it is, for how far
    it travelled (smooth, where the node of largest pressure jumps between the
    nodes of a row)."""
    return (p[:, None] * x).sum(axis=0) / p.sum()


def ring_distances(x: np.ndarray, new: np.ndarray, p: np.ndarray, h: np.ndarray,
                   width: float | None = None, direction=None) -> tuple[np.ndarray, np.ndarray]:
    """The rings of nodes that the nodes ``new`` (closed in this increment) make:
    the fewest bands ``width`` cell sizes ``h`` wide (``h`` of each band's nearest
    node) that hold their distances from the contact centre (:func:`contact_centre`
    of the current positions ``x`` and pressures ``p``). Returns the distance of
    every node from the centre and the nearest distance of each ring. The
    increment checks pass the reference positions ``x``: nodes at equal distance
    on the mesh are one ring whatever the deformation (measured on the current
    positions, the lateral displacements of a half model of two spheres, which
    differ along x and y, split such rings by a few percent of a cell, and the
    advice then asked for thousands of increments to separate them).

    What more increments can fix. A growing contact zone (Hertz-like: the
    pressure falls from a centre outwards) closes its nodes in order of distance
    from the centre. Nodes at the same distance close at the same load level
    whatever the increment: on a symmetric mesh several of them (in 2-D a node
    and its mirror image in a full model; in 3-D the nodes (i, j) and (j, i) of a
    quarter model, or (5, 0) and (4, 3) of a regular grid) enter together however
    small the steps, so counting nodes asks for what no load path can give. A
    ring is such a set. Distinct distances are distinct rings, however close:
    more increments separate them (a quarter model's distinct radii a few cells
    from the centre differ by a tenth of a cell or more); ``width`` (2 % of a
    cell) only absorbs round-off and the small departures of a discrete solution
    from symmetry (about 4e-4 of a cell between (5, 0) and (4, 3) in ``hertz3d``).
    On a half model in 2-D a ring is one node, and the count is the node count
    the rule was calibrated on. Packing the distances greedily from the nearest
    gives the fewest bands, and never more for a subset of the nodes: an
    increment cut in two never closes more rings in either half.

    The centre: the node of largest pressure, or the mean of several with equal
    largest pressure (a full symmetric model whose centre falls between two
    nodes). A pressure-weighted centroid would do on a full model but lies off the
    centre on a half or quarter model, whose symmetry planes pass through the
    centre while its nodes cover one side; the largest pressure of a Hertz-like
    zone sits on those planes.

    A zone that travels (a die slid along a block: ``direction``, the unit
    vector of its centre's travel) closes its nodes in order of their place
    along the travel, not of their distance from the centre: a row across the
    travel (the nodes under a cylinder's line of contact) closes at once however
    small the steps, and is one ring; ``r`` is then the coordinate along
    ``direction``, and a ring :data:`TRAVEL_RING_WIDTH` cells wide (the
    direction is an estimate; rows of a mesh are a cell apart)."""
    if width is None:
        width = RING_WIDTH if direction is None else TRAVEL_RING_WIDTH
    closed = p > 0
    c = contact_centre(x[closed], p[closed]) if closed.any() else x[new].mean(axis=0)
    r = np.linalg.norm(x - c, axis=1) if direction is None else (x - c) @ direction
    idx = np.nonzero(new)[0]
    starts, edge = [], -np.inf
    for k in idx[np.argsort(r[idx], kind="stable")]:
        if r[k] >= edge:
            starts.append(r[k])
            edge = r[k] + width * h[k]
    return r, np.array(starts)


def closing_rings(x, new, p, h, width: float = RING_WIDTH) -> int:
    """How many rings of nodes the newly closed nodes ``new`` make (:func:`ring_distances`)."""
    return len(ring_distances(x, new, p, h, width)[1]) if np.any(new) else 0


def ring_spread(r: np.ndarray, starts: np.ndarray, closed0: np.ndarray,
                closed1: np.ndarray) -> float:
    """How far the contact front advanced in an increment, in closest spacings of
    its rings ``starts`` (distances ``r`` from the centre; ``closed0``,
    ``closed1``: the closed nodes before and after), plus one: the number of
    increments that give each ring one of its own if the front moves evenly
    (k rings evenly spaced: k + 1, the one for where the increments fall). At the
    start the front lay between the last ring closed before, rho_0, and the first
    new ring; at the end between the last new ring and the nearest node still
    open, rho_n; its advance is taken between the midpoints, and the spacing
    includes rho_0 and rho_n, which must close in increments of their own too."""
    inside = r[closed0 & (r < starts[0])]
    outside = r[~closed1 & (r > starts[-1])]
    levels = np.concatenate([inside.max(keepdims=True) if inside.size else [],
                             starts, outside.min(keepdims=True) if outside.size else []])
    gap = float(np.diff(levels).min())
    lo = 0.5 * (levels[0] + levels[1]) if inside.size else levels[0]
    hi = 0.5 * (levels[-2] + levels[-1]) if outside.size else levels[-1]
    return max((hi - lo) / gap + 1.0, len(starts) + 1.0)


def advised_steps(offenders, threshold: int = MAX_NEW_CONTACT_RINGS) -> int:
    """The number of equal load increments that brings each increment of
    ``offenders`` ((spread, dt): :func:`ring_spread` of the rings that closed
    over the load step dt) to at most ``threshold`` rings: increments of
    ``threshold`` dt / spread."""
    need = max(spread / (threshold * dt) for spread, dt in offenders)
    return int(np.ceil(need - 1e-9))

class IncrementChecks:
    """Checks between consecutive converged increments (tunnelling, coarse paths)."""

    def __init__(self, model, params, solution):
        self.model = model
        self.params = params
        self.solution = solution
        self.prev = None  # (t, x of the contact nodes, closed masks) per surface
        self.pairs = {}  # surface -> (master edges, candidate matrix): pairs, finite kinematics
        self.memo = {}  # surface -> the partner distances of the last configuration (shared)
        self.coarse = {}  # surface -> [(increment, t0, t, new nodes, rings)] over the threshold
        self.sizes = {}  # surface -> the local cell size at each contact node (friction)
        self.reference = {}  # surface -> its nodes' reference positions (friction: the rings)
        self.origin = {}  # surface -> where its contact zone's centre was first (reference)
        self.left = set()  # surfaces whose zone has opened nodes it held (a zone that moves)
        X = None
        for i, s in enumerate(model.surfaces):
            if s.patches is not None and not model.linear_contact[i]:
                if model.dim == 3:
                    master = model.problem.mesh.face_set(s.contact.obstacle.master)
                    self.pairs[i] = (master, mortar3d.candidates(s.patches, len(master)))
                else:
                    master = model.problem.mesh.edge_set(s.contact.obstacle.master)
                    self.pairs[i] = (master, mortar.candidates(s.patches, master))
                self.memo[i] = model.cache.setdefault(("partner-distances", i), {})
            if s.contact.method.has_history:
                X = np.asarray(model.reference(params)) if X is None else X
                self.sizes[i] = side_lengths(X, s.edges, s.nodes)
                self.reference[i] = X[s.nodes]

    def _snapshot(self, w, t):
        m = self.model
        X = np.asarray(m.reference(self.params))
        u = np.asarray(w)[: m.dim * m.n_nodes].reshape(-1, m.dim)
        snap = []
        for i, s in enumerate(m.surfaces):
            f = m.compiled.fields(to_device(w), self.params, t, i)
            p = np.asarray(f["p_N"])
            snap.append((X[s.nodes] + u[s.nodes], p > 0, p))
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
                x0, closed0 = before[i][:2]
                x1, closed1, p1 = now[1][i]
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
                if i in self.sizes and closed0.any() and closed1.any():
                    X = self.reference[i]
                    self.origin.setdefault(i, _centroid(X[closed0], before[i][2][closed0]))
                    if (closed0 & ~closed1).any():  # nodes left behind: the zone moves
                        self.left.add(i)
                if i in self.sizes and t0 >= COARSE_PATH_FROM - 1e-12 and closed0.any():
                    new = closed1 & ~closed0
                    if new.any():
                        r, starts = ring_distances(self.reference[i], new, p1, self.sizes[i],
                                                   direction=self._travel(i, closed1, p1))
                        if len(starts) > MAX_NEW_CONTACT_RINGS:
                            spread = ring_spread(r, starts, closed0, closed1)
                            self.coarse.setdefault(i, []).append(
                                (n_inc, t0, t, int(new.sum()), len(starts), spread))
        self.prev = now

    def _travel(self, i, closed, p):
        """The unit direction in which surface i's contact zone has travelled since
        it formed (it has left nodes behind, open again, and its pressure-weighted
        centroid moved by more than a median cell), or None (a zone that grows
        about its centre: on a half or quarter model its centroid moves outwards
        as it grows, but it opens no node)."""
        if i not in self.left:
            return None
        X = self.reference[i]
        d = _centroid(X[closed], p[closed]) - self.origin[i]
        n = float(np.linalg.norm(d))
        return d / n if n > float(np.median(self.sizes[i])) else None

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
            if m.dim == 3:
                near = [mortar3d.outside(mortar3d.partners(x, s.edges, s.nodes, master, r, self.memo[i]),
                                         cand) for r in (1.0, 0.5)]
                lost = (near[0] & closed) | near[1]
            else:
                dist = np.where(cand, np.inf, mortar.partner_distances(x, s.patches, master, self.memo[i]))
                lost = (np.any(dist <= 1.0, axis=1) & closed) | np.any(dist <= 0.5, axis=1)
            if lost.any():
                first = int(s.nodes[np.argmax(lost)])
                slide = s.contact.obstacle.slide
                window = ("a quarter of a face" if m.dim == 3 else "half a segment") + (
                    f" plus slide = {slide:g}" if slide else "")
                what = "faces" if m.dim == 3 else "segments"
                warn(self.solution,
                     f"contact pair {s.contact.edges!r}/{s.contact.obstacle.master!r}: in increment "
                     f"{n_inc} (t = {now[0]:.4g}) {int(lost.sum())} slave node(s) (first: node "
                     f"{first}) overlap master {what}, in contact or close to them, "
                     "that are not among their candidate partners (found once on the nominal "
                     f"mesh, within {window} of their own); contact with those segments is missed "
                     "and the result is not physical: give the pair the sliding distance, "
                     "pair(..., slide=...)")

    def final(self) -> None:
        if self.prev is None:
            return
        for i, found in self.coarse.items():
            n_inc, t0, t, new, rings, _ = max(found, key=lambda f: (f[5] / (f[2] - f[1]), -f[0]))
            steps = advised_steps([(f[5], f[2] - f[1]) for f in found])
            more = f" (and {len(found) - 1} more increment(s))" if len(found) > 1 else ""
            warn(self.solution,
                 f"contact {self.model.surfaces[i].contact.edges!r}: the contact zone grew by "
                 f"{rings} rings of nodes ({new} nodes) in increment {n_inc} (t = {t0:.4g} -> "
                 f"{t:.4g}){more}; with friction the history of the nodes that close within one "
                 f"increment is not resolved (more than {MAX_NEW_CONTACT_RINGS} ring per increment "
                 "after t = 1/3; nodes at equal distance from the contact centre, or in one row "
                 "across the travel of a zone that slides, are one ring: they close together "
                 "however small the increment), so stick "
                 f"and slip zones can be wrong: use more load increments, at least {steps} "
                 f"(steps={steps}, --steps {steps})")
        for i, s in enumerate(self.model.surfaces):
            n = int(self.prev[1][i][1].sum())
            if 0 < n < MIN_CONTACT_NODES:
                warn(self.solution,
                     f"contact {s.contact.edges!r}: the contact zone holds only {n} closed node(s) "
                     f"at the end (fewer than {MIN_CONTACT_NODES}); pressures and their "
                     "sensitivities are poorly resolved: refine the mesh where contact occurs")
