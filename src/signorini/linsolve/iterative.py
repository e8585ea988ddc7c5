"""An iterative solver for large (3-D) tangents: flexible GMRES preconditioned by
algebraic multigrid on the displacements, the contact multipliers condensed
node by node (docs/theory.md §12.7).

The free-free tangent of a contact problem is a saddle point,

    K = [[A, B],      A: displacements (the elements, plus eps grad g grad g^T
         [C, D]],        of the closed nodes), B, C: the contact couplings,
                         D: the multipliers' own block (zero for a closed normal),

whose multiplier rows, for rigid obstacles, couple only to the displacements of
their own node. A full solve (sensitivities, adjoint) condenses them exactly
(:mod:`signorini.linsolve.condensation`): the preconditioner is K^-1 but for one
multigrid V-cycle in place of the solve with the reduced displacement block.
Newton's corrections, and every solve where a multiplier reaches several nodes
(mortar pairs), use the block lower-triangular preconditioner

    P^-1 [r_u; r_l] = [x_u; S^-1 (r_l - C x_u)],   x_u = one AMG V-cycle on A r_u,

with S = D - C diag(A)^-1 B, block-diagonal (m x m per contact node) and
factorised exactly. The multigrid is pyamg's smoothed aggregation on the
displacement block of all the nodes (prescribed DOFs as decoupled identity
rows, so that the nodal 2x2 or 3x3 blocks stay whole), with the rigid-body
modes of the reference mesh as its near-null space and aggregates that follow
the cells' stretching (:func:`geometric_aggregates`), cycled with Chebyshev
smoothing (:mod:`signorini.linsolve.multigrid`); unsymmetric tangents
(friction) are preconditioned with the symmetric part. The Krylov method is
flexible GMRES on K itself, to a relative residual ``rtol``; the solve is then
checked and refined like a direct one (:class:`Factor`). Its products with K,
like the cycle's, are split by rows over the cores.

Newton's corrections are solved inexactly (:meth:`Factor.solve_to`, to its
forcing tolerance). The hierarchy is built on a factor's first solve: a full
solve builds one for its own tangent; an inexact one uses the last hierarchy of
A built while that has served fewer than ``REUSE`` inexact solves, since the
next tangents differ from its tangent mainly in their contact terms, which the
Schur complement (rebuilt for every tangent) carries.

The solver needs the tangent's structure (which rows are displacements of which
node, which multipliers belong together): :func:`signorini.linsolve.for_model`
binds it to a model before a solve.
"""

from __future__ import annotations

import contextlib
import logging
import threading
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, SingularTangentError, SolverError
from .base import LinearSolver
from .condensation import condense
from .factor import Factor
from .multigrid import ChebyshevCycle, RowSplit

log = logging.getLogger("signorini")


@dataclass(frozen=True)
class Structure:
    """Where the rows of a model's free-free tangent come from."""

    n_u: int                 #: the first n_u rows are displacement DOFs
    u_global: np.ndarray     #: (n_u,) their numbers among all dim * n_nodes displacement DOFs
    dim: int
    nodes: np.ndarray        #: (n_nodes, dim) reference coordinates (the rigid-body modes)
    lam_group: np.ndarray    #: (n - n_u,) contact node of each multiplier row (0, 1, ...)


def structure_of(model) -> Structure:
    """The :class:`Structure` of ``model``'s free-free tangent."""
    free = np.asarray(model.free)
    d, nn = model.dim, model.n_nodes
    n_u = int(np.sum(free < d * nn))
    group = np.full(model.n_dof, -1)
    g0 = 0
    for s in model.surfaces:
        lam = s.lam_dofs  # (nc, m)
        group[lam] = g0 + np.arange(lam.shape[0])[:, None]
        g0 += lam.shape[0]
    return Structure(n_u, free[:n_u], d, np.asarray(model.reference_nodes, dtype=float),
                     group[free[n_u:]])


def rigid_body_modes(X: np.ndarray) -> np.ndarray:
    """(dim * n_nodes, 3 or 6): translations and rotations of the nodes X, node-major."""
    n, d = X.shape
    X = X - X.mean(axis=0)
    modes = []
    for k in range(d):
        m = np.zeros((n, d))
        m[:, k] = 1.0
        modes.append(m)
    pairs = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]
    for i, j in pairs:
        m = np.zeros((n, d))
        m[:, i], m[:, j] = -X[:, j], X[:, i]
        modes.append(m)
    return np.column_stack([m.reshape(-1) for m in modes])


def aggregate_once(G, X: np.ndarray, theta: float) -> sp.csr_matrix:
    """(n, n_agg) one aggregation of the nodes X whose neighbours are the nonzeros of
    G: pyamg's standard aggregation on the geometric strength of
    :func:`geometric_aggregates` (a node left alone has an empty row)."""
    from pyamg.aggregation import standard_aggregation  # noqa: PLC0415  (lazy, as below)

    Gc = G.tocoo()
    off = Gc.row != Gc.col
    r, c = Gc.row[off], Gc.col[off]
    w = 1.0 / np.maximum(np.einsum("ij,ij->i", X[r] - X[c], X[r] - X[c]), 1e-300)
    strongest = np.zeros(X.shape[0])
    np.maximum.at(strongest, r, w)
    keep = w >= theta * strongest[r]
    S = sp.csr_matrix((w[keep], (r[keep], c[keep])), shape=G.shape)
    return standard_aggregation((S + S.T + sp.eye(G.shape[0])).tocsr())[0].tocsr()


def geometric_aggregates(M, X: np.ndarray, theta: float, max_nodes: int) -> list:
    """The aggregates of every level of the hierarchy of ``M`` (BSR, one block per
    node of X), chosen by the geometry of the mesh (docs/theory.md §12.7).

    A neighbour j of node i (a nonzero block of M) is strongly connected to it when
    |x_i - x_j|^-2 >= theta max_k |x_i - x_k|^-2: on a flat or long cell only the
    neighbours across its short sides are, so the aggregates, and the coarse space,
    follow the cells' stretching (a mesh of cells of aspect ratio below
    theta^-1/2 keeps every neighbour). The next level's nodes are the aggregates'
    centroids, neighbours where two aggregates touch. Returns the aggregation
    operators (n_l x n_l+1, sparse), coarsening until at most ``max_nodes`` are left
    or a level no longer coarsens.
    """
    G = sp.csr_matrix((np.ones(M.indices.size), M.indices, M.indptr),
                      shape=(M.shape[0] // M.blocksize[0],) * 2)
    out: list = []
    while X.shape[0] > max_nodes:
        agg = aggregate_once(G, X, theta)
        if agg.shape[1] == 0 or agg.shape[1] > 0.9 * agg.shape[0]:
            break
        out.append(agg)
        count = np.maximum(np.asarray(agg.sum(axis=0)).ravel(), 1.0)
        X = (agg.T @ X) / count[:, None]
        G = (agg.T @ G @ agg).tocsr()
    return out


def symmetric_part(A) -> sp.csr_matrix:
    """(A + A^T) / 2 in CSR without stored zeros: on A's own pattern where that is
    symmetric (a finite element tangent's: one sum of the data, 0.02 s at 10M
    nonzeros, instead of SciPy's sum of a CSR and a CSC matrix, 0.9 s). The zeros
    go: the aggregation reads the matrix's graph, and a pair's couplings of nodes
    not in contact, stored as zeros, would join aggregates across the two bodies
    (27k-DOF spheres: 29 GMRES iterations for a Newton correction instead of 19)."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    At = A.T.tocsr()
    At.sort_indices()
    if np.array_equal(A.indptr, At.indptr) and np.array_equal(A.indices, At.indices):
        S = sp.csr_matrix((0.5 * (A.data + At.data), A.indices.copy(), A.indptr.copy()),
                          shape=A.shape)
    else:
        S = (0.5 * (A + At)).tocsr()
    S.eliminate_zeros()
    return S


def _check_options(rtol, restart, max_iterations, theta, condense) -> None:
    """AMGKrylov's options, each checked with the error naming it."""
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
    if not (number(rtol) and 0 < rtol < 1):
        raise InputError(f"AMGKrylov: rtol must be a relative residual in (0, 1), got {rtol!r}")
    for name, v in (("restart", restart), ("max_iterations", max_iterations)):
        if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1):
            raise InputError(f"AMGKrylov: {name} must be a positive integer, got {v!r}")
    if not (number(theta) and 0 <= theta <= 1):
        raise InputError(f"AMGKrylov: theta (the geometric strength threshold) must lie in "
                         f"[0, 1] (0 keeps every neighbour; default 0.05), got {theta!r}")
    if condense not in (True, False, "symmetric") or isinstance(condense, (int, float)) \
            and not isinstance(condense, bool):
        raise InputError(f"AMGKrylov: condense must be True, False or 'symmetric', got {condense!r}")


class AMGKrylov(LinearSolver):
    """Flexible GMRES with an AMG block preconditioner (``solver="amg"``).

    Args:
        rtol: relative residual ||K x - b|| / ||b|| a solve reaches (default 1e-11:
            DDM = FD holds to 1e-6 and better, the Newton iteration is unaffected).
        restart: GMRES inner iterations before a restart.
        max_iterations: the budget of one solve (inner iterations in all); beyond
            it the solve fails with an error that says so.
        theta: the geometric strength threshold of the aggregation
            (:func:`geometric_aggregates`).
        condense: condense node-local multipliers exactly in the preconditioner
            of full solves (:mod:`signorini.linsolve.condensation`): ``True``,
            ``False`` (the block-triangular one everywhere) or ``"symmetric"`` (the
            default: for symmetric tangents, frictionless contact, where it saves a
            quarter of the iterations; a frictional one gains none, and its
            hierarchy can then serve the next increment's Newton corrections).
    """

    name = "amg"
    #: the backward error below which a solve is not refined (Factor.refine_tol)
    REFINE_TOL = 1e-10
    #: tangents a hierarchy of A serves after the one it was built for (Newton's
    #: corrections, and the sensitivities where not condensed): the next tangents differ
    #: in their contact terms, and a solve with the last hierarchy costs a few more
    #: iterations than a new setup would, less than the setup (7 s, 40 iterations, at
    #: 283k displacement DOFs)
    REUSE = 4
    #: a kept hierarchy serves, with its finest level made anew, every later tangent
    #: whose displacement block differs from the one it was built on in at most this
    #: fraction of the rows (the contact nodes' rows, as Newton's iterations and the
    #: increments close, open, stick and slip them), and up to REUSE others (a
    #: tangent that changes everywhere: plasticity, finite strain). Measured on a
    #: 144,780-DOF frictional tangent, six increments after the hierarchy's: 48, 54,
    #: 47 GMRES iterations for three sensitivities with the refreshed hierarchy, 49,
    #: 53, 48 with a new one (1.9 s of setup against 0.1 s), 58, 64, 57 with the
    #: hierarchy as it was
    REFRESH_ROWS = 0.1
    #: nodes (times dim, unknowns) of the coarsest level, solved directly
    MAX_COARSE = 500
    #: strength (pyamg's symmetric measure) of the couplings that smooth the prolongator
    FILTER = 0.1
    #: memory of the search space several right-hand sides share (:meth:`_shared_gmres`);
    #: 0: none shared. Off by default: at 144,780 DOFs (frictional, three parameters)
    #: sharing saved 20 of 150 iterations but cost more in reading the kept space at
    #: every iteration and in adding to it (7.1 s against 6.2 s for the three solves)
    RECYCLE_BYTES = 0
    #: memory of the Krylov bases of the right-hand sides iterated side by side
    #: (:meth:`_lockstep`; two (n, restart + 1) arrays each): as many columns at once
    #: as fit, one after the other where not two do
    LOCKSTEP_BYTES = 2.0e9

    def __init__(self, rtol: float = 1e-11, restart: int = 100, max_iterations: int = 2000,
                 theta: float = 0.05, condense: bool | str = "symmetric"):
        try:
            import pyamg  # noqa: F401, PLC0415  (lazy: checked when the solver is created)
        except ImportError:
            raise InputError("solver 'amg' needs pyamg: python3 -m pip install pyamg") from None
        _check_options(rtol, restart, max_iterations, theta, condense)
        self.rtol, self.restart, self.max_iterations = rtol, restart, max_iterations
        self.theta, self.condense = theta, condense
        self.structure: Structure | None = None
        self.iterations: list[int] = []  # GMRES iterations of every solve, for reports
        self._kept: _Kept | None = None  # the last hierarchy of a tangent's plain blocks

    def bind(self, model) -> None:
        """Take the tangent structure of ``model`` (called before each solve's first use)."""
        self.structure = structure_of(model)
        self._kept = None

    def factorize(self, K, symmetric=False):
        if self.structure is None or self.structure.n_u + self.structure.lam_group.size != K.shape[0]:
            raise InputError("solver 'amg' needs the tangent's structure: pass solver='amg' to "
                             "signorini.solve / gradient (it binds the model), or call "
                             "solver.bind(model) first")
        K = sp.csr_matrix(K)
        parts: dict = {}  # condensed or not -> (() -> the matrix, modes, V-cycle -> preconditioner)
        own: dict = {}    # this tangent's own preconditioners: "full", "plain"

        def blocks(condensed: bool):
            if condensed not in parts:
                parts[condensed] = self._blocks(K, symmetric, condensed)
            return parts[condensed]

        def preconditioner(fresh: bool):
            """A full solve's (``fresh``) preconditioner where it condenses the
            multipliers: this tangent's own hierarchy, on the condensed operator (not
            reused: the next tangents constrain other nodes in other frames). Every
            other solve's: the block-triangular one with the kept hierarchy of A
            where it serves this tangent (:meth:`_plain_cycle`)."""
            condensed = self.condense is True or (self.condense == "symmetric" and symmetric)
            if fresh and condensed:
                if "full" not in own:
                    matrix, modes, with_cycle = blocks(True)
                    if modes is not None:
                        # condensed: the plain hierarchies are not needed for this tangent's
                        # full solves; released before the new one is built (memory)
                        self._kept = None
                        own.pop("plain", None)
                        parts.pop(False, None)
                        own["full"] = with_cycle(self._hierarchy(matrix(), modes))
                    else:  # not condensed: Newton's next corrections may use it
                        own["full"] = own["plain"] = with_cycle(self._plain_cycle(K, matrix, True))
                return own["full"]
            if "plain" not in own:
                matrix, _, with_cycle = blocks(False)
                own["plain"] = with_cycle(self._plain_cycle(K, matrix, fresh))
            return own["plain"]

        def solve(b, transpose=False):
            if transpose:
                raise AssertionError("transposed solves go through transpose_factor")
            return self._krylov(K, preconditioner(True), b)

        f = Factor(solve, K, transpose_factor=lambda: self.factorize(K.T.tocsr(), symmetric),
                   solve_from=lambda b, x0: self._krylov(K, preconditioner(True), b, x0=x0),
                   solve_to=lambda b, rtol: self._krylov(K, preconditioner(False), b,
                                                         max(rtol, self.rtol)))
        f.refine_tol = self.REFINE_TOL
        return f

    # ------------------------------------------------------------------ parts
    def _blocks(self, K, symmetric: bool, condensed: bool):
        """(a function giving the displacement block to build a hierarchy from, a map
        of the rigid-body modes into its frames or None if not condensed, V-cycle ->
        the preconditioner).

        ``condensed`` and where every multiplier row is node-local (rigid
        obstacles), the multipliers are condensed exactly
        (:mod:`signorini.linsolve.condensation`) and the hierarchy is built on the
        reduced operator; otherwise (a mortar pair) on A's symmetric part, the
        multipliers then solved from S = D - C diag(A)^-1 B (block-triangular)."""
        import scipy.sparse.linalg as spla  # noqa: PLC0415  (lazy: 77 ms with scipy.linalg)

        st = self.structure
        n_u, n = st.n_u, K.shape[0]
        diag = K.diagonal()[:n_u]
        if n > n_u and condensed:
            c = condense(K, n_u, st.lam_group, st.u_global, st.dim)
            if c is not None:
                scale = float(np.mean(np.abs(diag))) if diag.size else 1.0
                return (lambda: c.reduced(symmetric, scale)), c.rotate_modes, c.preconditioner

        def matrix():
            A = K[:n_u, :n_u]
            if not symmetric:
                return symmetric_part(A)
            A.eliminate_zeros()  # a copy of K's block; its graph read by the aggregation
            return A
        if n == n_u:
            return matrix, None, lambda v_cycle: self._apply(v_cycle, None)
        inv = sp.diags(1.0 / np.where(diag != 0, diag, 1.0))
        C = K[n_u:, :n_u]
        try:
            S_solve = spla.splu((K[n_u:, n_u:] - C @ inv @ K[:n_u, n_u:]).tocsc()).solve
        except RuntimeError as e:  # SuperLU: "Factor is exactly singular"
            raise SingularTangentError(
                f"the preconditioner's multiplier block S = D - C diag(A)^-1 B is singular ({e}): "
                "a multiplier row that neither its law nor the displacements determine") from None
        multipliers = lambda r_l, x_u: S_solve(r_l - C @ x_u)  # noqa: E731
        return matrix, None, lambda v_cycle: self._apply(v_cycle, multipliers)

    def _plain_cycle(self, K, matrix, fresh: bool):
        """The V-cycle of a tangent's displacement block ``matrix()`` (not condensed):
        the kept hierarchy where it serves this tangent (:attr:`REFRESH_ROWS`,
        :attr:`REUSE`), for a full solve (``fresh``) and for every REUSE + 1-th
        tangent with its finest level made from this block and kept so for the
        next tangents; else a new one, kept."""
        kept = self._kept
        if kept is not None and kept.shape == K.shape:
            # a cycle that cannot be refreshed (an exact solve, PETSc's) serves REUSE tangents
            refreshable = hasattr(kept.cycle, "with_finest")
            few = refreshable and kept.changed_rows(K) <= self.REFRESH_ROWS * self.structure.n_u
            if few or kept.uses < self.REUSE:
                kept.uses += not few
                kept.since += 1
                if refreshable and (fresh or kept.since > self.REUSE):
                    kept.cycle = kept.cycle.with_finest(self._full(matrix()), self.structure.dim)
                    kept.v_cycle = self._on_free(kept.cycle)
                    kept.since = 0
                return kept.v_cycle
        self._kept = None  # released before the new one is built (memory)
        cycle = self._cycle(self._full(matrix(), bsr=True), self._modes())
        self._kept = _Kept(K, self.structure.n_u, cycle, self._on_free(cycle))
        return self._kept.v_cycle

    def _hierarchy(self, As, modes=None):
        """One smoothed-aggregation V-cycle on the displacement block of every node
        (prescribed DOFs as identity rows): a function of r_u. ``modes`` maps the
        rigid-body modes (rows: free DOFs) into the frames of As."""
        return self._on_free(self._cycle(self._full(As, bsr=True), self._modes(modes)))

    def _modes(self, modes=None):
        """The rigid-body modes of the nodes, rows of the free DOFs mapped by ``modes``."""
        st = self.structure
        B = rigid_body_modes(st.nodes)
        if modes is not None:
            B[st.u_global] = modes(B[st.u_global])
        return B

    def _on_free(self, cycle):
        """The V-cycle of every node's DOFs as a function of the free DOFs' r_u (a
        vector, or a block of vectors where the cycle takes blocks)."""
        st = self.structure
        u_full = np.zeros(st.dim * len(st.nodes))

        def v_cycle(r_u):
            if r_u.ndim == 2:
                full = np.zeros((u_full.size, r_u.shape[1]))
                full[st.u_global] = r_u
                return cycle(full)[st.u_global]
            u_full[:] = 0.0
            u_full[st.u_global] = r_u
            return cycle(u_full)[st.u_global]
        v_cycle.blocks = getattr(cycle, "blocks", False)
        return v_cycle

    def _full(self, As, bsr: bool = False):
        """The block As of the free DOFs as a matrix of every node's DOFs, the
        prescribed ones identity rows scaled as As's diagonal: CSR, or BSR of the
        nodes' blocks."""
        st = self.structure
        N = st.dim * len(st.nodes)
        diag = As.diagonal()
        scale = float(np.mean(np.abs(diag))) if diag.size else 1.0
        held = np.setdiff1d(np.arange(N), st.u_global)
        # the CSR of all the nodes' DOFs written directly (the free DOFs keep their
        # order), without the index arrays of a COO matrix: the largest matrix's
        # temporaries set the solver's peak memory
        As = As.tocsr()
        count = np.ones(N, dtype=np.int64)
        count[st.u_global] = np.diff(As.indptr)
        indptr = np.concatenate([[0], np.cumsum(count)])
        indices = np.empty(indptr[-1], dtype=np.int32)
        data = np.empty(indptr[-1])
        at = np.repeat(indptr[st.u_global] - As.indptr[:-1], np.diff(As.indptr))
        at += np.arange(As.nnz)
        indices[at] = st.u_global[As.indices]
        data[at] = As.data
        del at, As
        indices[indptr[held]] = held
        data[indptr[held]] = scale
        full = sp.csr_matrix((data, indices, indptr), shape=(N, N))
        del data, indices
        if np.any(np.diff(st.u_global) < 0):
            full.sort_indices()
        return full.tobsr(blocksize=(st.dim, st.dim)) if bsr else full

    def _cycle(self, full, B):
        """The preconditioner of the nodal displacement block ``full`` (BSR, every
        node's DOFs) with near-null space ``B``: one V-cycle of smoothed
        aggregation (its exact solve where no larger than a coarse level), a
        function of a vector of every node's DOFs."""
        ml = self._smoothed_aggregation(full, B)
        if ml is None:  # no larger than a coarse level: its exact solve is the preconditioner
            import scipy.sparse.linalg as spla  # noqa: PLC0415  (lazy, as above)
            lu = spla.splu(full.tocsc())

            def exact(b):
                return lu.solve(b)
            exact.blocks = True  # SuperLU solves a block of right-hand sides at once
            return exact
        return ChebyshevCycle(ml)

    def _smoothed_aggregation(self, full, B):
        """pyamg's hierarchy of ``full`` on the geometric aggregates, or None where
        ``full`` is no larger than a coarse level."""
        import pyamg  # noqa: PLC0415  (lazy: loaded only by runs that use this solver)

        st = self.structure
        aggregates = geometric_aggregates(full, st.nodes, self.theta, self.MAX_COARSE // st.dim)
        if not aggregates:
            return None
        with _fixed_random_start():
            return pyamg.smoothed_aggregation_solver(
                full, B=B, max_coarse=self.MAX_COARSE, coarse_solver="splu",
                aggregate=[("predefined", {"AggOp": a}) for a in aggregates],
                max_levels=len(aggregates) + 1, improve_candidates=None,
                # the prolongator smoothed with A's strong couplings only (pyamg's
                # strength, theta 0.1): sparser coarse levels, a setup half as long
                strength=("symmetric", {"theta": self.FILTER}),
                smooth=("jacobi", {"omega": 4.0 / 3.0, "filter_entries": True}))

    def _apply(self, v_cycle, multipliers):
        """P^-1: the V-cycle on the displacements, then the multipliers' Schur solve."""
        n_u = self.structure.n_u

        def apply(r):
            x = np.empty_like(r)
            x[:n_u] = v_cycle(r[:n_u])
            if multipliers is not None:
                x[n_u:] = multipliers(r[n_u:], x[:n_u])
            return x
        # a block (n, k) of residuals where the V-cycle takes blocks (SuperLU's solve of
        # the multipliers' S does)
        apply.blocks = getattr(v_cycle, "blocks", False)
        return apply

    def _shared_gmres(self, K, apply, b, rtol: float, x0=None):
        """The right-hand sides ``b`` (n, k) of one tangent (a Newton correction, the
        sensitivities to several parameters), one after the other, by flexible
        GMRES orthogonalising by classical Gram-Schmidt (a vector's products with
        the basis, two passes: at 144,780 DOFs 41 ms an iteration against 44 ms
        for pyamg's Householder reflections). Where :attr:`RECYCLE_BYTES` allows,
        the columns recycle the spaces of the columns before (GCRO's deflation): U and C with K U = C, C
        orthonormal, span what earlier columns searched. A column starts from
        x0 = U C^T b and runs GMRES on (I - C C^T) K P^-1, so that what the
        preconditioner leaves slow, found by the first column's iterations, is
        not searched again; its own space is then added to U, C (K Z = V H,
        H = Q R: C += V Q, U += (Z - U C^T K Z) R^-1). One such cycle (at most
        ``restart`` directions) per column; where it stops short of ``rtol``
        (near the accuracy of K U = C), plain flexible GMRES from its iterate. At
        most :attr:`RECYCLE_BYTES` of U and C are kept. A column starts from its
        guess in ``x0`` where that leaves less residual than zero does."""
        import scipy.linalg as sla  # noqa: PLC0415  (lazy: 77 ms with scipy.linalg)

        n, k = b.shape
        cap = int(min(self.max_iterations, self.RECYCLE_BYTES // (16 * n))) if k > 1 else 0
        together = int(self.LOCKSTEP_BYTES // (16 * n * (self.restart + 1)))
        if not cap and k > 1 and together > 1 and getattr(apply, "blocks", False):
            x = np.empty((n, k), order="F")
            for j in range(0, k, together):
                cols = slice(j, min(k, j + together))
                x[:, cols] = self._lockstep(K, apply, b[:, cols], rtol,
                                            None if x0 is None else x0[:, cols])
            return x
        K_, K = K, RowSplit(K)  # products on all the cores (multigrid.RowSplit)
        U = np.empty((n, cap), order="F")
        C = np.empty((n, cap), order="F")
        q = 0
        x = np.zeros((n, k), order="F")
        mmax = self.restart
        for j in range(k):
            bj = b[:, j]
            nb = float(np.linalg.norm(bj))
            xj = x[:, j]
            start = None if x0 is None else _start(K, bj, x0[:, j])
            if start is None:
                r = bj.copy()
            else:
                xj[:], r = start
            if q:  # the part of b in C's span, from the recycled directions
                a_ = C[:, :q].T @ r
                xj += U[:, :q] @ a_
                r -= C[:, :q] @ a_
            beta = float(np.linalg.norm(r))
            its = 0
            if beta > rtol * nb:  # one deflated cycle
                V = np.empty((n, mmax + 1), order="F")
                Z = np.empty((n, mmax), order="F")
                H = np.zeros((mmax + 1, mmax))
                B = np.zeros((q, mmax))
                V[:, 0] = r / beta
                g = np.zeros(mmax + 1)
                g[0] = beta
                i, broke = 0, False
                while i < mmax and its < self.max_iterations:
                    z = apply(V[:, i])
                    w = K @ z
                    Z[:, i] = z
                    nw = _arnoldi_step(w, V, H, i, (C[:, :q], B) if q else None)
                    i += 1
                    its += 1
                    y, *_ = np.linalg.lstsq(H[:i + 1, :i], g[:i + 1], rcond=None)
                    est = float(np.linalg.norm(g[:i + 1] - H[:i + 1, :i] @ y))
                    broke = not nw > 1e-14 * beta
                    if broke:
                        break  # the space holds the solution (or the preconditioner failed)
                    V[:, i] = w / nw
                    if est <= rtol * nb:
                        break
                # the correction: Z y minus its part K Z y already in C's span
                dz = Z[:, :i] @ y
                if q:
                    dz -= U[:, :q] @ (B[:, :i] @ y)
                xj += dz
                # this cycle's space into the recycled one, where there is room and a
                # column left to use it
                if j < k - 1 and q + i <= cap and np.all(np.isfinite(H[:i + 1, :i])):
                    Qh, Rh = np.linalg.qr(H[:i + 1, :i])
                    if np.min(np.abs(np.diag(Rh))) > 1e-12 * np.max(np.abs(np.diag(Rh))):
                        Unew = Z[:, :i] - U[:, :q] @ B[:, :i] if q else Z[:, :i]
                        U[:, q:q + i] = sla.solve_triangular(Rh.T, Unew.T, lower=True).T
                        C[:, q:q + i] = V[:, :i] @ Qh[:i] if broke else V[:, :i + 1] @ Qh
                        q += i
                del V, Z
            self._finish(K_, K, apply, bj, xj, rtol, its)
        return x

    def _lockstep(self, K, apply, b, rtol: float, x0=None):
        """The right-hand sides ``b`` (n, k) of one tangent by k flexible GMRES
        iterations run side by side: at every step the preconditioner and K act
        on the block of the columns still iterating (one pass over each matrix for
        all of them: a V-cycle of a block of three vectors costs about 0.8 of three
        cycles, a product with K about 0.8 of three, at 66k DOFs), each column
        orthogonalised against its own basis as :meth:`_shared_gmres` does. Each
        column is the same GMRES as alone, and stops when it reaches ``rtol``; one
        cycle of at most ``restart`` iterations, then, for a column short of
        ``rtol``, plain flexible GMRES from its iterate."""
        n, k = b.shape
        K_, K = K, RowSplit(K)
        mmax = self.restart
        x = np.zeros((n, k), order="F")
        nb = np.linalg.norm(b, axis=0)
        its = [0] * k
        state: dict[int, _Column] = {}
        for j in range(k):
            start = None if x0 is None else _start(K, b[:, j], x0[:, j])
            if start is None:
                r = b[:, j].copy()
            else:
                x[:, j], r = start
            beta = float(np.linalg.norm(r))
            if beta > rtol * nb[j]:
                V = np.empty((n, mmax + 1), order="F")
                V[:, 0] = r / beta
                g = np.zeros(mmax + 1)
                g[0] = beta
                state[j] = _Column(V, np.empty((n, mmax), order="F"), np.zeros((mmax + 1, mmax)),
                                   g, beta)
        active = sorted(state)
        i = 0
        while active and i < mmax and i < self.max_iterations:
            Z = apply(np.column_stack([state[j].V[:, i] for j in active]))
            W = K @ Z
            still = []
            for c, j in enumerate(active):
                col = state[j]
                col.Z[:, i] = Z[:, c]
                w = W[:, c].copy()
                nw = _arnoldi_step(w, col.V, col.H, i)
                its[j] += 1
                H, g = col.H[:i + 2, :i + 1], col.g[:i + 2]
                col.y, *_ = np.linalg.lstsq(H, g, rcond=None)
                col.steps = i + 1
                est = float(np.linalg.norm(g - H @ col.y))
                if not nw > 1e-14 * col.beta:
                    continue  # the space holds the solution (or the preconditioner failed)
                col.V[:, i + 1] = w / nw
                if est > rtol * nb[j]:
                    still.append(j)
            active = still
            i += 1
        for j, col in state.items():
            if col.steps:
                x[:, j] += col.Z[:, :col.steps] @ col.y
        del state
        for j in range(k):
            self._finish(K_, K, apply, b[:, j], x[:, j], rtol, its[j])
        return x

    def _finish(self, K_, K, apply, b, x, rtol: float, its: int) -> None:
        """A column after its GMRES cycle: where it stopped short of ``rtol`` (its
        residual's recurrence drifted from the true one, or it ran out of
        directions), plain flexible GMRES from its iterate ``x`` (updated in
        place); its iterations are counted (K_ is K, K its row-split product)."""
        if np.any(b) and np.linalg.norm(b - K @ x) > rtol * np.linalg.norm(b):
            x[:], more = self._fgmres(K_, apply, b, rtol, x0=x.copy(),
                                      budget=self.max_iterations - its, spent=its)
            its += more
        self.iterations.append(its)

    @staticmethod
    def _norm(K) -> float:
        """||K||_inf (the largest absolute row sum), kept on the matrix."""
        v = getattr(K, "_inf_norm", None)
        if v is None:
            v = float(np.max(np.abs(K) @ np.ones(K.shape[1]), initial=0.0))
            K._inf_norm = v
        return v

    def _krylov(self, K, apply, b, rtol: float | None = None, x0=None):
        """x with ||K x - b|| <= rtol ||b|| (b (n,) or (n, k)), from ``x0`` (shaped as
        b) in the columns where it leaves a smaller residual than zero does."""
        b = np.asarray(b, dtype=float)
        one = b.ndim == 1
        if one and not np.any(b):
            return np.zeros_like(b)
        B = b[:, None] if one else b
        X0 = None if x0 is None else np.asarray(x0, dtype=float).reshape(B.shape)
        x = self._shared_gmres(K, apply, B, self.rtol if rtol is None else rtol, X0)
        return x[:, 0] if one else x

    def _fgmres(self, K, apply, b, rtol: float, x0=None, budget: int | None = None,
                spent: int = 0) -> tuple[np.ndarray, int]:
        """(x, iterations): pyamg's flexible GMRES on K x = b from ``x0`` (zero),
        within ``budget`` iterations (``max_iterations``), to the relative residual
        ``rtol`` or the round-off floor of K's products; else a SolverError, which
        counts ``spent`` iterations made before this solve."""
        from pyamg.krylov import fgmres  # noqa: PLC0415  (lazy, as above)
        import scipy.sparse.linalg as spla  # noqa: PLC0415  (lazy, as above)

        budget = self.max_iterations if budget is None else budget
        K_, K = K, RowSplit(K)
        M = spla.LinearOperator(K.shape, matvec=apply, dtype=float)
        res: list = []
        try:
            x, info = fgmres(K, b, x0=x0, tol=rtol, restart=self.restart,
                             maxiter=max(1, budget // self.restart), M=M, residuals=res)
        except ValueError as e:  # SciPy's check of GMRES's Hessenberg matrix: NaN or inf
            raise SolverError(_NOT_FINITE.format(f"non-finite values ({e})")) from None
        its = len(res) - 1
        if info != 0:
            r = b - K @ x
            rel = float(np.linalg.norm(r) / np.linalg.norm(b))
            # at the round-off floor of K's products: the normwise backward error is what
            # a direct solve reaches too (a body held only by its contact, say, has a
            # solution far larger than b / ||K||, and ||r|| / ||b|| cannot go below ~1e-16
            # ||K|| ||x|| / ||b||)
            eta = float(np.abs(r).max() / (self._norm(K_) * np.abs(x).max() + np.abs(b).max()))
            log.debug("GMRES stopped at ||r||/||b|| = %.1e, backward error %.1e", rel, eta)
            if not (rel <= rtol or eta <= self.rtol):
                raise SolverError(
                    f"the iterative solver (AMG-preconditioned GMRES) did not reach the relative "
                    f"residual {rtol:g} in {spent + its} iterations (reached {rel:.1e}); use a "
                    "direct solver (solver='pardiso' or 'superlu'), or a larger max_iterations")
        return x, its


def _arnoldi_step(w, V, H, i: int, deflate=None) -> float:
    """GMRES's step i: ``w`` (K times the i-th preconditioned direction)
    orthogonalised in place by classical Gram-Schmidt against ``deflate`` = (C, B),
    the kept space (its coefficients added to B[:, i]), if given, and the basis
    V[:, :i + 1] (to H[:i + 1, i]), a second pass only where the first cancelled
    (Kahan and Parlett: below 1/sqrt(2) of w); H[i + 1, i] = ||w||, returned,
    checked finite before the least squares, which would fail on it."""
    nw = float(np.linalg.norm(w))
    for _ in range(2):
        before = nw
        if deflate is not None:
            C, B = deflate
            c_ = C.T @ w
            w -= C @ c_
            B[:, i] += c_
        h = V[:, :i + 1].T @ w
        w -= V[:, :i + 1] @ h
        H[:i + 1, i] += h
        nw = float(np.linalg.norm(w))
        if nw > 0.7071 * before:
            break
    if not np.isfinite(nw):
        raise SolverError(_NOT_FINITE.format("non-finite values"))
    H[i + 1, i] = nw
    return nw


_NOT_FINITE = ("the iterative solver's preconditioner returned {}: the multigrid hierarchy "
               "failed on this tangent; use a direct solver (solver='pardiso' or 'superlu') or, "
               "with petsc-amg, other --petsc-options")


@dataclass
class _Column:
    """One column of :meth:`AMGKrylov._lockstep`: its Arnoldi basis V, the
    preconditioned directions Z, the Hessenberg matrix H, the right-hand side g of
    its least-squares problem, the initial residual's norm beta, and, once it has
    iterated, the coefficients y of its correction Z[:, :steps] y."""

    V: np.ndarray
    Z: np.ndarray
    H: np.ndarray
    g: np.ndarray
    beta: float
    y: np.ndarray | None = None
    steps: int = 0


class _Kept:
    """A hierarchy kept for later tangents: its cycle, the free-DOF V-cycle, and
    what tells how far a later tangent's displacement rows differ from those of
    the tangent it was built for (their products with a fixed vector)."""

    def __init__(self, K, n_u: int, cycle, v_cycle):
        self.shape, self.n_u, self.cycle, self.v_cycle = K.shape, n_u, cycle, v_cycle
        self.uses = 0  # the later tangents it served that differ in more rows than REFRESH_ROWS
        self.since = 0  # the tangents it served since its finest level was last made
        self._probe = np.random.default_rng(1).uniform(1.0, 2.0, K.shape[1])
        self._rows = (K @ self._probe)[:n_u]
        # |K| |probe| row by row, a slice of rows at a time (|K| whole would be a copy of K)
        step = max(1, -(-n_u // 8))
        self._size = np.concatenate([abs(K[a:min(a + step, n_u)]) @ self._probe
                                     for a in range(0, n_u, step)]) if n_u else np.zeros(0)

    def changed_rows(self, K) -> int:
        """The displacement rows of ``K`` that differ from the tangent's the hierarchy
        was built for (by more than round-off of the row's size)."""
        return int(np.count_nonzero(np.abs((K @ self._probe)[:self.n_u] - self._rows)
                                    > 1e-12 * self._size))


_RANDOM = threading.Lock()


@contextlib.contextmanager
def _fixed_random_start():
    """NumPy's global random generator seeded for the duration, its state restored
    after.

    pyamg's Jacobi smoothing of the prolongator divides by an estimate of the
    spectral radius of D^-1 A from a few Arnoldi steps that start from
    ``np.random.rand`` (pyamg.util.linalg.approximate_spectral_radius, to 1 %).
    Unseeded, the prolongators, and with them every iteration count and the last
    digits of the solutions, would depend on how much of the generator the process
    had drawn before (earlier solves, anyone's ``np.random``): the same solve takes
    one or two iterations more or fewer from one draw to the next. Seeded, a
    hierarchy is a function of its matrix alone; restored, the caller's stream is
    as if the solver had drawn nothing. The lock keeps two threads' setups from
    seeding and drawing from the one generator at once (a thread that draws from it
    outside a setup meanwhile still moves the start)."""
    with _RANDOM:
        state = np.random.get_state()
        np.random.seed(0)
        try:
            yield
        finally:
            np.random.set_state(state)


def _start(K, b, x0):
    """(x0, b - K x0) if ``x0`` is finite and leaves a smaller residual than zero
    does (||b||), else None: a guess that is no better than none is not used."""
    if x0 is None:
        return None
    x0 = np.asarray(x0, dtype=float)
    if not np.all(np.isfinite(x0)):
        return None
    r = b - K @ x0
    return (x0, r) if np.linalg.norm(r) < np.linalg.norm(b) else None
