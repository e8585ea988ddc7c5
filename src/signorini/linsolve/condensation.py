"""The contact multipliers of a tangent condensed exactly, node by node, for the
iterative solver's preconditioner (docs/theory.md §12.7).

A rigid obstacle's multiplier rows couple only to the displacements of their own
node: with K ordered as displacements u, then multipliers l,

    [A B] [x_u]   [r_u]
    [C D] [x_l] = [r_l],      B, C, D node-local (d_S x m, m x d_S, m x m per node S),

each node's m multiplier rows split, by the singular value decomposition
D_S = U S V^T, into the rows in D_S's range, which give V_1^T x_l = S_1^-1 U_1^T
(r_l - C x_u), and the m_c rows in its null space, which are constraints on the
node's displacements alone, G_S x_u = U_2^T r_l with G_S = U_2^T C_S (a closed
normal, a sticking tangential direction, the direction of slip). The remaining
multiplier components z = V_2^T x_l enter the displacement rows through
W_S = B_S V_2. In node frames Q_R = [Z_R Y_R] (Y_R spanning G_S^T) and Q_L =
[Z_L Y_L] (Y_L spanning W_S), the displacement rows of Z_L and the columns of
Z_R form the reduced operator

    A~ = Z_L^T (A - B D^+ C) Z_R,

a displacement block with the constrained directions taken out, as prescribed
displacements are; the rows of Y_L give z. With an exact solve of A~ the whole
is K^-1; the preconditioner replaces that solve by one multigrid V-cycle.

Where a multiplier row reaches the displacements of more than one node (a mortar
pair's weighted gap), :func:`condense` returns None and the solver keeps its
block-triangular preconditioner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: singular values of a node's D below this fraction of its scale are zero
RANK_TOL = 1e-12


@dataclass
class _Bucket:
    """Contact nodes of one shape: m multipliers, d free DOFs, m_c constraints."""

    lam: np.ndarray    #: (n, m) the nodes' multiplier rows (0 = the first multiplier row)
    cols: np.ndarray   #: (n, d) their free displacement DOFs (rows of A)
    Dp: np.ndarray     #: (n, m, m) D's pseudo-inverse
    C: np.ndarray      #: (n, m, d)
    BDp: np.ndarray    #: (n, d, m) B D^+
    Pp: np.ndarray | None = None   #: (n, d, m) r_l -> the constrained displacements
    Zg: np.ndarray | None = None   #: (n, m, d) residual of the Y_L rows -> V_2 z


@dataclass
class Condensed:
    """A tangent's multipliers condensed node by node (see the module's text)."""

    n_u: int
    Ap: sp.csr_matrix | None   #: A - B D^+ C (until :meth:`reduced`)
    TL: sp.csr_matrix          #: the left node frames, identity off the constrained nodes
    TR: sp.csr_matrix          #: the right ones
    free: np.ndarray           #: (n_u,) 1.0 where a rotated DOF is not constrained
    buckets: list
    contact_cols: np.ndarray   #: the displacement DOFs of the contact nodes
    Ap_rows: sp.csr_matrix     #: Ap's rows of contact_cols
    Ap_cols: sp.csr_matrix     #: Ap's columns of contact_cols

    def reduced(self, symmetric: bool, scale: float) -> sp.csr_matrix:
        """The reduced operator in the node frames, its symmetric part unless
        ``symmetric``, the constrained DOFs as decoupled rows of ``scale``. Called
        once: A' is released (the preconditioner needs only its contact rows and
        columns)."""
        At = (self.TL.T @ self.Ap @ self.TR).tocsr()
        self.Ap = None
        if not symmetric:
            At = (0.5 * (At + At.T)).tocsr()
        # in place: a product with diagonal matrices would copy the largest matrix twice
        rows = np.repeat(np.arange(self.n_u, dtype=np.int32), np.diff(At.indptr))
        At.data *= self.free[rows] * self.free[At.indices]
        held = (rows == At.indices) & (self.free[rows] == 0.0)
        del rows
        At.data[held] = scale
        if np.count_nonzero(held) < np.count_nonzero(self.free == 0.0):  # a diagonal not stored
            At = (At + sp.diags(np.where(self.free == 0.0, scale, 0.0))).tocsr()
        return At

    def rotate_modes(self, modes: np.ndarray) -> np.ndarray:
        """Near-null-space vectors (rows: displacement DOFs) in the right frames."""
        return (self.TR.T @ modes) * self.free[:, None]

    def preconditioner(self, v_cycle):
        """r -> x: the exact condensation around one V-cycle on the reduced operator
        (``v_cycle`` acts on displacement vectors in the node frames). ``r`` is a
        vector, or a block (n, k) of vectors where the V-cycle takes blocks."""
        n_u = self.n_u
        nodes = "nij,nj...->ni..."  # a node's matrix times its vector (or block of vectors)

        def apply(r):
            free = self.free if r.ndim == 1 else self.free[:, None]
            r_u = np.array(r[:n_u], dtype=float)
            r_l = r[n_u:]
            xp = np.zeros(r_u.shape)
            for b in self.buckets:
                rl = r_l[b.lam]
                r_u[b.cols] -= np.einsum(nodes, b.BDp, rl)
                if b.Pp is not None:
                    xp[b.cols] = np.einsum(nodes, b.Pp, rl)
            s = r_u - self.Ap_cols @ xp[self.contact_cols]
            y = v_cycle((self.TL.T @ s) * free) * free
            x_u = xp + self.TR @ y
            res = np.zeros(r_u.shape)
            res[self.contact_cols] = r_u[self.contact_cols] - self.Ap_rows @ x_u
            x = np.empty(r.shape)
            x[:n_u] = x_u
            x_l = x[n_u:]
            for b in self.buckets:
                xl = np.einsum(nodes, b.Dp, r_l[b.lam] - np.einsum(nodes, b.C, x_u[b.cols]))
                if b.Zg is not None:
                    xl += np.einsum(nodes, b.Zg, res[b.cols])
                x_l[b.lam] = xl
            return x
        apply.blocks = getattr(v_cycle, "blocks", False)
        return apply


def _node_of_rows(M, rows_group, col_node, n_groups):
    """The one node whose displacements each group's entries of M reach (-1 for a
    group with none), or None where a group reaches more than one."""
    M = M.tocoo()
    nz = M.data != 0
    g, nd = rows_group[M.row[nz]], col_node[M.col[nz]]
    lo = np.full(n_groups, np.iinfo(np.int64).max)
    hi = np.full(n_groups, -1)
    np.minimum.at(lo, g, nd)
    np.maximum.at(hi, g, nd)
    has = hi >= 0
    if np.any(lo[has] != hi[has]):
        return None
    return np.where(has, hi, -1)


def condense(K, n_u: int, lam_group: np.ndarray, u_global: np.ndarray, dim: int):
    """The :class:`Condensed` form of the tangent K (CSR, displacements first), or
    None where a multiplier row is not node-local or a node's constraints are
    dependent."""
    n = K.shape[0]
    if n == n_u:
        return None
    A, B, C, D = K[:n_u, :n_u], K[:n_u, n_u:], K[n_u:, :n_u], K[n_u:, n_u:]
    ng = int(lam_group.max()) + 1
    col_node = u_global // dim
    node_c = _node_of_rows(C, lam_group, col_node, ng)
    node_b = _node_of_rows(B.T, lam_group, col_node, ng)
    if node_c is None or node_b is None:
        return None
    Dc = D.tocoo()
    off = (Dc.data != 0) & (lam_group[Dc.row] != lam_group[Dc.col])
    if np.any(off):
        return None
    node = np.maximum(node_c, node_b)
    if np.any((node_c >= 0) & (node_b >= 0) & (node_c != node_b)):
        return None
    if np.unique(node[node >= 0]).size != np.sum(node >= 0):
        return None  # a node in two contacts
    # the rows of each group, and the free DOFs of its node
    order = np.argsort(lam_group, kind="stable")
    m_of = np.bincount(lam_group, minlength=ng)
    start = np.concatenate([[0], np.cumsum(m_of)])
    where = np.full(dim * (int(col_node.max()) + 1 if col_node.size else 1), -1)
    where[u_global] = np.arange(n_u)
    scale_a = float(np.mean(np.abs(A.diagonal()))) if n_u else 1.0

    buckets, dA, frames = [], [], []
    for m in np.unique(m_of):
        gm = np.flatnonzero(m_of == m)
        lam = order[start[gm][:, None] + np.arange(m)]          # (n, m)
        dofs = np.where(node[gm][:, None] >= 0, node[gm][:, None] * dim + np.arange(dim), -1)
        local = np.where(dofs >= 0, where[np.maximum(dofs, 0)], -1)  # (n, dim), -1 held
        n_free = np.sum(local >= 0, axis=1)
        for d in np.unique(n_free):
            sel = n_free == d
            lam_b = lam[sel]
            cols = np.sort(np.where(local[sel] >= 0, local[sel], np.iinfo(np.int64).max), axis=1)[:, :d]
            nb = lam_b.shape[0]
            Db = np.asarray(D[lam_b.reshape(-1).repeat(m), np.tile(lam_b, (1, m)).reshape(-1)]
                            ).reshape(nb, m, m)
            Cb = np.asarray(C[lam_b.reshape(-1).repeat(d), np.tile(cols, (1, m)).reshape(-1)]
                            ).reshape(nb, m, d) if d else np.zeros((nb, m, 0))
            Bb = np.asarray(B[cols.reshape(-1).repeat(m), np.tile(lam_b, (1, d)).reshape(-1)]
                            ).reshape(nb, d, m) if d else np.zeros((nb, 0, m))
            U, s, Vt = np.linalg.svd(Db)
            ref = np.maximum(np.abs(Db).max(axis=(1, 2)),
                             np.abs(Cb).max(axis=(1, 2), initial=0.0)
                             * np.abs(Bb).max(axis=(1, 2), initial=0.0) / scale_a)
            rank = np.sum(s > RANK_TOL * np.maximum(ref, 1e-300)[:, None], axis=1)
            for k in np.unique(rank):
                b = _bucket(rank == k, int(k), lam_b, cols, U, s, Vt, Cb, Bb)
                if b is None:
                    return None
                bucket, frame = b
                buckets.append(bucket)
                if d:
                    dA.append((bucket.cols, -np.einsum("nij,njk->nik", bucket.BDp, bucket.C)))
                if frame is not None:
                    frames.append(frame)

    def block_matrix(parts, fill_identity: np.ndarray | None = None):
        rows, cols, vals = [], [], []
        for c, blocks in parts:
            rows.append(np.repeat(c, c.shape[1], axis=1).reshape(-1))
            cols.append(np.tile(c, (1, c.shape[1])).reshape(-1))
            vals.append(blocks.reshape(-1))
        if fill_identity is not None:
            rows.append(fill_identity), cols.append(fill_identity)
            vals.append(np.ones(fill_identity.size))
        if not rows:
            return sp.csr_matrix((n_u, n_u))
        return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(n_u, n_u)).tocsr()

    Ap = (A + block_matrix(dA)).tocsr()
    rotated = np.zeros(n_u, dtype=bool)
    free = np.ones(n_u)
    for c, _, _, n_con in frames:
        rotated[c] = True
        free[c[:, c.shape[1] - n_con:]] = 0.0
    plain = np.flatnonzero(~rotated)
    TL = block_matrix([(c, QL) for c, QL, _, _ in frames], plain)
    TR = block_matrix([(c, QR) for c, _, QR, _ in frames], plain)
    contact_cols = np.unique(np.concatenate([b.cols.reshape(-1) for b in buckets]))
    return Condensed(n_u, Ap, TL, TR, free, buckets, contact_cols,
                     Ap[contact_cols].tocsr(), Ap[:, contact_cols].tocsr())


def _bucket(sel, k, lam, cols, U, s, Vt, Cb, Bb):
    """(_Bucket, frame or None) of the nodes ``sel`` whose D has rank k; None where
    their constraints are dependent."""
    lam, cols, U, s, Vt, Cb, Bb = lam[sel], cols[sel], U[sel], s[sel], Vt[sel], Cb[sel], Bb[sel]
    m, d = lam.shape[1], cols.shape[1]
    U1, U2, V1, V2 = U[:, :, :k], U[:, :, k:], np.swapaxes(Vt[:, :k], 1, 2), np.swapaxes(Vt[:, k:], 1, 2)
    Dp = np.einsum("nik,nk,njk->nij", V1, 1.0 / s[:, :k], U1)
    BDp = np.einsum("nij,njk->nik", Bb, Dp)
    bucket = _Bucket(lam, cols, Dp, Cb, BDp)
    mc = m - k
    if mc == 0:
        return bucket, None
    if mc > d:
        return None
    G = np.einsum("nji,njk->nik", U2, Cb)          # (n, mc, d)
    W = np.einsum("nij,njk->nik", Bb, V2)          # (n, d, mc)
    qr = np.linalg.qr(np.swapaxes(G, 1, 2), mode="complete")[0]   # (n, d, d), first mc span G^T
    ql = np.linalg.qr(W, mode="complete")[0]
    YR, YL = qr[:, :, :mc], ql[:, :, :mc]
    GY, YW = G @ YR, np.swapaxes(YL, 1, 2) @ W
    if not (np.all(np.linalg.cond(GY) < 1e12) and np.all(np.linalg.cond(YW) < 1e12)):
        return None  # dependent constraints (an infinite or NaN condition fails too)
    bucket.Pp = YR @ np.linalg.inv(GY) @ np.swapaxes(U2, 1, 2)
    bucket.Zg = V2 @ np.linalg.inv(YW) @ np.swapaxes(YL, 1, 2)
    QR = np.concatenate([qr[:, :, mc:], YR], axis=2)
    QL = np.concatenate([ql[:, :, mc:], YL], axis=2)
    return bucket, (cols, QL, QR, mc)
