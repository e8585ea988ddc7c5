"""An algebraic coarse start for any mesh (docs/theory.md §10.3).

Where no coarser mesh of the problem exists (a mesh read from a file, a
tetrahedral one, any cell count), Newton's first increment would start from
rest and close the contact zone one ring of nodes per iteration. The start
built here comes from the fine problem itself:

* the displacements are restricted to a coarse space u = P u_c: the mesh's
  nodes grouped twice into aggregates of neighbours (by the geometric
  strength of the iterative solver's aggregation), on each the six
  rigid-body modes of its nodes (orthonormalised), smoothed by one damped
  Jacobi step with the tangent so that P's columns deform like the body does;
* the multipliers are held at their start (zero on a first increment), where
  the Alart-Curnier contact forces are penalty forces eps <-g>: the coarse
  problem P^T R_u(w + P u_c) = 0 is a penalty contact problem of about 5 %
  of the unknowns, solved by Newton (its tangent P^T K_uu P, the bulk part
  kept from the start, the contact rows' part of each iterate);
* the contact zone it finds, with ZONE_RINGS rings of neighbours, is freed to
  its nodes (the coarse space elsewhere) and solved again from there: the
  zone's edge to within a node or two;
* its displacements start the fine Newton, the normal multipliers at the
  penalty pressures: the first fine correction enforces the gaps of the zone
  the coarse problem found.

Only the start changes, never the converged result. A coarse problem that does
not converge within its budget, or whose tangent is singular, is abandoned and
Newton starts as it would have without it (the reason is logged and kept).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from .._jax import to_device
from ..errors import SingularTangentError
from ..fem.assembly import SparsityPattern
from ..linsolve import get_solver
from ..linsolve.iterative import aggregate_once
from ..linsolve.multigrid import _lambda_max

log = logging.getLogger("signorini")

#: ``start="auto"`` builds the start from this many nodes on (3-D): below, Newton's
#: iterations from rest cost less than the coarse problem
AUTO_NODES = 5_000
#: Newton iterations of the coarse problem
MAX_ITERATIONS = 40
#: the coarse problem is solved to this residual, relative to its first one
RTOL = 1e-8
#: a coarse Newton step that does not lower the residual is halved at most this often
HALVINGS = 5
#: rings of neighbours around the first stage's contact zone free in the second
ZONE_RINGS = 4
#: a neighbour is strongly connected when |x_i - x_j|^-2 >= THETA max_k |x_i - x_k|^-2
THETA = 0.1


def _node_graph(K_uu: sp.csr_matrix, u_nodes: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """The nodes' adjacency (n_nodes, n_nodes) from the displacement block's pattern."""
    C = K_uu.tocoo()
    G = sp.csr_matrix((np.ones(C.nnz), (u_nodes[C.row], u_nodes[C.col])), shape=(n_nodes, n_nodes))
    G.sum_duplicates()
    G.data[:] = 1.0
    return G + sp.eye(n_nodes, format="csr")


def aggregates(G: sp.csr_matrix, X: np.ndarray, passes: int = 2) -> np.ndarray:
    """(n_nodes,) the aggregate of every node: each node grouped with its strongly
    connected neighbours, ``passes`` times (the aggregates of aggregates,
    neighbours where two touch, at their centroids)."""
    agg = np.arange(G.shape[0])
    for _ in range(passes):
        a = _one_pass(G, X)
        alone = np.flatnonzero(a < 0)  # pyamg leaves isolated nodes out: each its own
        a[alone] = a.max(initial=-1) + 1 + np.arange(alone.size)
        A = sp.csr_matrix((np.ones(a.size), (np.arange(a.size), a)), shape=(a.size, int(a.max()) + 1))
        count = np.maximum(np.asarray(A.sum(axis=0)).ravel(), 1.0)
        X = (A.T @ X) / count[:, None]
        G = (A.T @ G @ A).tocsr()
        agg = a[agg]
    return agg


def _one_pass(G: sp.csr_matrix, X: np.ndarray) -> np.ndarray:
    """(n_nodes,) the aggregate of every node after one aggregation (-1: left alone)."""
    agg = aggregate_once(G, X, THETA)
    out = np.full(G.shape[0], -1)
    rows = np.repeat(np.arange(agg.shape[0]), np.diff(agg.indptr))
    out[rows] = agg.indices
    return out


def tentative(agg: np.ndarray, X: np.ndarray, u_nodes: np.ndarray, u_comp: np.ndarray,
              dim: int) -> sp.csr_matrix:
    """(n_u, n_c) the rigid-body modes of each aggregate's nodes on its free
    displacement DOFs, orthonormal per aggregate (modes an aggregate's DOFs
    cannot tell apart, as a line of nodes' rotation about itself, dropped)."""
    n_u = u_nodes.size
    a_of = agg[u_nodes]
    ok = a_of >= 0
    order = np.argsort(a_of[ok], kind="stable")
    rows_all = np.flatnonzero(ok)[order]
    a_sorted = a_of[ok][order]
    starts = np.flatnonzero(np.r_[True, a_sorted[1:] != a_sorted[:-1]])
    ends = np.r_[starts[1:], a_sorted.size]
    rows, cols, vals = [], [], []
    col = 0
    pairs = [(0, 1)] if dim == 2 else [(0, 1), (1, 2), (2, 0)]
    for s, e in zip(starts, ends):
        r = rows_all[s:e]
        x = X[u_nodes[r]]
        x = x - x.mean(axis=0)
        comp = u_comp[r]
        B = np.zeros((r.size, dim + len(pairs)))
        B[np.arange(r.size), comp] = 1.0
        for k, (i, j) in enumerate(pairs):
            B[:, dim + k] = np.where(comp == i, -x[:, j], 0.0) + np.where(comp == j, x[:, i], 0.0)
        U, sv, _ = np.linalg.svd(B, full_matrices=False)
        keep = sv > 1e-8 * max(float(sv[0]), 1e-300)
        Q = U[:, keep]
        k = Q.shape[1]
        rows.append(np.repeat(r, k))
        cols.append(np.tile(np.arange(col, col + k), r.size))
        vals.append(Q.ravel())
        col += k
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n_u, col))


def _smoothed(P0: sp.csr_matrix, K_uu: sp.csr_matrix) -> sp.csr_matrix:
    """One damped Jacobi step, P = (I - omega D^-1 K) P0, omega = 4 / (3 lambda_max)."""
    d = K_uu.diagonal()
    Dinv = sp.diags(np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)).tocsr()
    lam = _lambda_max(K_uu, Dinv, K_uu.shape[0])
    return (P0 - (4.0 / (3.0 * lam)) * (Dinv @ (K_uu @ P0))).tocsr()


def wanted(model, options) -> bool:
    """Whether the first increment of ``model`` starts from the algebraic coarse
    problem (``options.start``; see :data:`AUTO_NODES`)."""
    if options.start == "rest" or not model.surfaces:
        return False
    if options.start == "coarse":
        return True
    return model.dim == 3 and model.n_nodes >= AUTO_NODES


class AlgebraicStart:
    """The coarse start of one model (its coarse space is built on first use and
    kept): :meth:`__call__` returns the fine start, or None with a reason."""

    def __init__(self, model):
        self.model = model
        self._P = self._graph = None
        self._zone_nodes = 0
        self._contact_pattern = None
        self._solver = get_solver("auto")  # its analysis of the coarse pattern is kept
        self.info: dict = {}

    def _space(self, K_uu, bulk, n_u):
        """The coarse space: aggregates of the nodes by the bulk's graph (a pair's
        contact couplings, stored also where the bodies are apart, would join
        aggregates across the two bodies, whose relative motion the coarse problem
        is there to find), smoothed with the whole tangent."""
        m = self.model
        u_dofs = np.asarray(m.free[:n_u])
        u_nodes, u_comp = np.divmod(u_dofs, m.dim)
        X = np.asarray(m.reference_nodes, dtype=float)
        G = self._graph = _node_graph(bulk, u_nodes, m.n_nodes)
        agg = aggregates(G, X)
        P0 = tentative(agg, X, u_nodes, u_comp, m.dim)
        return _smoothed(P0, K_uu)

    def _contact_uu(self, blocks, n_u):
        """The contact blocks' displacement-displacement part (n_u, n_u)."""
        if self._contact_pattern is None:
            m = self.model
            self._contact_pattern = SparsityPattern(m.block_dofs()[1:], m.n_dof, m.free)
        return self._contact_pattern.assemble(blocks[1:])[:n_u, :n_u].tocsr()

    def _coupling(self, n_u):
        """(rows, S): the displacement rows a contact block can reach and the 0/1
        pattern (rows x rows) of the couplings between them: a node with itself
        (rigid obstacles), a slave node with its patch's master nodes (pairs)."""
        pat = self._contact_pattern
        S = sp.csr_matrix((np.ones(pat.nnz), pat.indices, pat.indptr), shape=(pat.n, pat.n))
        S = S[:n_u, :n_u].tocsr()
        rows = np.flatnonzero(np.diff(S.indptr))
        return rows, S[rows][:, rows].tocsr()

    def __call__(self, w0, params, t, state_n):
        """(w, info): the fine start w (a copy of w0 with the coarse displacements
        added), or (None, info) where the coarse problem was abandoned."""
        m = self.model
        clock = time.perf_counter()
        free = np.asarray(m.free)
        n_u = int(np.sum(free < m.dim * m.n_nodes))
        _, blocks = m.local_tangents(w0, params, t, state_n)
        K0 = m.pattern.assemble(blocks).tocsr()[:n_u, :n_u].tocsr()
        C0 = self._contact_uu(blocks, n_u)
        bulk = (K0 - C0).tocsr()  # the tangent less its contact part (kept: chord)
        if self._P is None:
            self._P = self._space(K0, bulk, n_u)
        coupling = self._coupling(n_u)
        stage = _Stage(self._P, bulk, coupling, self._solver)
        info = {"coarse_unknowns": int(self._P.shape[1]), "iterations": 0}
        uc, w = stage.solve(m, w0, np.zeros(self._P.shape[1]), params, t, state_n, n_u,
                            self._contact_uu, info)
        if uc is not None:
            # the second stage: the nodes of the zone the first found, with two rings
            # of neighbours, free; the coarse space elsewhere
            P2, map2 = self._refined(w, w0, n_u, params, t, state_n)
            if P2 is not None:
                info2 = {"iterations": 0}
                stage2 = _Stage(P2, bulk, coupling, self._solver)
                uc2, w2 = stage2.solve(m, w0, map2(uc), params, t, state_n, n_u,
                                       self._contact_uu, info2)
                info["zone_nodes"] = int(self._zone_nodes)
                info["coarse_unknowns_zone"] = int(P2.shape[1])
                info["zone_iterations"] = info2["iterations"]
                if "halved_steps" in info2:
                    info["zone_halved_steps"] = info2["halved_steps"]
                if uc2 is None:
                    info["zone_abandoned"] = info2.get("abandoned")
                else:
                    w = w2
        if uc is not None:
            w = self._with_multipliers(w, params, t)
        info["time_s"] = round(time.perf_counter() - clock, 3)
        self.info = info
        if uc is None:
            log.info("algebraic coarse start abandoned (%s): Newton starts without it",
                     info.get("abandoned"))
            return None, info
        log.debug("algebraic coarse start: %s", info)
        return w, info

    def _with_multipliers(self, w, params, t, into=None):
        """``into`` (default w) with each contact node's normal multiplier
        augmented by its gap in w, lambda_N <- min(lambda_N + eps g, 0): from zero,
        the penalty pressure (closed where w penetrates); the others as they
        were. The fine Newton's first correction then enforces the gaps instead of
        building the pressures."""
        m = self.model
        w_gap = w
        w = (w if into is None else into).copy()
        for i, s in enumerate(m.surfaces):
            if not s.n_mult or getattr(s, "patches", None) is not None:
                continue
            eps = float(np.ravel(s.contact.method.row_scale(s.contact.method.values(params)))[0])
            g = np.asarray(m.compiled.fields(to_device(w_gap), params, t, i)["gap"], dtype=float)
            lam = w[s.lam_offset: s.lam_offset + s.nodes.size * s.n_mult].reshape(-1, s.n_mult)
            lam[:, 0] = np.minimum(lam[:, 0] + eps * g, 0.0)
        return w

    def _refined(self, w, w0, n_u, params, t, state_n):
        """(P2, map): the coarse space with the displacements of the nodes in
        contact in ``w`` (penetrating or pressed), and of ZONE_RINGS rings of
        neighbours around them, free; None if no node is in contact."""
        m = self.model
        free = np.asarray(m.free)
        _, blocks = m.local_tangents(w, params, t, state_n)
        C = self._contact_uu(blocks, n_u)
        # a contact row of an active node has stiffness: the nodes of those rows
        active_rows = np.flatnonzero(np.abs(C).sum(axis=1).A.ravel() > 0)
        if not active_rows.size:
            return None, None
        u_nodes = free[:n_u] // m.dim
        zone = np.zeros(m.n_nodes)
        zone[u_nodes[active_rows]] = 1.0
        G = self._graph
        for _ in range(ZONE_RINGS):
            zone = G @ zone
        in_zone = (zone > 0)[u_nodes]  # rows of the free displacements in the zone
        self._zone_nodes = int(np.count_nonzero(zone > 0))
        rows = np.flatnonzero(in_zone)
        keep = sp.diags((~in_zone).astype(float))
        E = sp.csr_matrix((np.ones(rows.size), (rows, np.arange(rows.size))),
                          shape=(n_u, rows.size))
        P = self._P
        outside = (keep @ P).tocsc()
        # a column of the coarse space wholly inside the zone is one of its nodal ones now
        cols = np.flatnonzero(np.diff(outside.indptr))
        P2 = sp.hstack([outside[:, cols], E]).tocsr()

        def map2(uc):
            return np.concatenate([uc[cols], P[rows] @ uc])
        return P2, map2


class OutsidePattern(RuntimeError):
    """A coarse tangent has an entry outside the pattern analysed for it."""


class _Stage:
    """Newton on the coarse problem of one space P: P^T R_u(w0 + P u_c) = 0, its
    tangent P^T (K_bulk + C_k) P with the bulk kept from the start and the contact
    rows' part C_k of each iterate."""

    def __init__(self, P, bulk, coupling, solver):
        self.P, self.PT = P, P.T.tocsr()
        self.bulk = (self.PT @ (bulk @ P)).tocsr()
        self.solver = solver
        # one pattern for every iterate (analysed once by the solver): the bulk's and
        # the projection of every contact coupling (a pair's couples a slave node with
        # master nodes: coarse functions on either side, not only on one node)
        rows, S = coupling
        Ps = abs(P[rows])
        T = (abs(self.bulk) + Ps.T @ (S @ Ps)).tocsr()
        T.sort_indices()
        n = T.shape[0]
        self.T = T
        self.keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(T.indptr)) * n + T.indices

    def _on_template(self, M) -> sp.csr_matrix:
        M = M.tocsr()
        M.sum_duplicates()
        n = M.shape[0]
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(M.indptr)) * n + M.indices
        pos = np.minimum(np.searchsorted(self.keys, keys), max(self.keys.size - 1, 0))
        if keys.size and (not self.keys.size or not np.array_equal(self.keys[pos], keys)):
            # the stage is abandoned, never solved with entries dropped or misplaced
            raise OutsidePattern("a coarse tangent entry outside the coarse pattern")
        data = np.zeros(self.T.nnz)
        data[pos] = M.data
        return sp.csr_matrix((data, self.T.indices, self.T.indptr), shape=self.T.shape)

    def solve(self, m, w0, uc, params, t, state_n, n_u, contact_uu, info):
        """(u_c, w) converged, or (None, None) with ``info["abandoned"]``.

        A Newton step that does not lower the residual is halved (at most
        :data:`HALVINGS` times): with friction the frozen multipliers make the
        contact law a penalty law whose stick/slip switches let full steps cycle
        between two iterates (the spheres' zone stage: residual 2.30e-3, 2.37e-3,
        2.30e-3, ... for 40 iterations)."""
        P, PT = self.P, self.PT
        u_rows = np.asarray(m.free)[:n_u]

        def at(uc):
            w = w0.copy()
            w[u_rows] += P @ uc
            R, blocks = m.local_tangents(w, params, t, state_n)
            if not np.all(np.isfinite(R)):
                return w, None, blocks, np.inf
            rc = PT @ R[u_rows]
            return w, rc, blocks, float(np.linalg.norm(rc))

        uc = np.array(uc, dtype=float)
        w, rc, blocks, norm = at(uc)
        if rc is None:
            info["abandoned"] = "non-finite residual"
            return None, None
        ref = norm
        for k in range(MAX_ITERATIONS + 1):
            if norm <= RTOL * ref or norm == 0.0:
                info.update(converged=True, residual=norm / max(ref, 1e-300))
                return uc, w
            if k == MAX_ITERATIONS:
                info["abandoned"] = f"no convergence in {MAX_ITERATIONS} iterations"
                return None, None
            C = contact_uu(blocks, n_u)
            rows = np.flatnonzero(np.diff(C.indptr))
            Ps = P[rows]
            try:
                Kc = self._on_template(self.bulk + (Ps.T @ (C[rows][:, rows] @ Ps)))
            except OutsidePattern as e:
                info["abandoned"] = str(e)
                return None, None
            try:
                duc = self.solver.factorize(Kc).solve(-rc)
            except (SingularTangentError, RuntimeError) as e:
                info["abandoned"] = f"singular coarse tangent ({e})"
                return None, None
            if not np.all(np.isfinite(duc)):
                info["abandoned"] = "singular coarse tangent"
                return None, None
            step = 1.0
            full = trial = at(uc + duc)
            # the first step leaves a contact-free start: its residual rises as the zone
            # closes, which no shorter step helps
            if k > 0:
                while trial[3] >= norm and step > 0.5 ** HALVINGS:
                    step *= 0.5
                    trial = at(uc + step * duc)
                if trial[3] >= norm:  # no step lowers it: the full one, as Newton's
                    step, trial = 1.0, full
            if trial[1] is None:
                info["abandoned"] = "non-finite residual"
                return None, None
            uc = uc + step * duc
            w, rc, blocks, norm = trial
            info["iterations"] = info.get("iterations", 0) + 1
            log.debug("coarse stage iteration %d: residual %.3e (step %g)", k + 1, norm / ref, step)
            if step < 1.0:
                info["halved_steps"] = info.get("halved_steps", 0) + 1
        raise AssertionError("unreachable")
