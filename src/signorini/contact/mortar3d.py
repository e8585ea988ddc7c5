"""Two deformable 3-D bodies in contact: the face patches of a mortar pair and
the pair as seen by one slave node (docs/theory.md §13.9–§13.10).

What is the same as in 2-D is not repeated here: :func:`signorini.contact.pair`
makes the pair, the law (:class:`~signorini.contact.AugmentedLagrangian`, the
Coulomb disc of :mod:`signorini.contact.friction3d`) acts on the weighted gap
and slip of a slave node exactly as on a rigid obstacle's gap and closest
point, and the patch of a node is found once on the nominal reference mesh.
What differs is the geometry: a slave node's patch is the slave faces around
it and, per face, the master faces that may cover it; the face-pair clip and
its quadrature are :mod:`signorini.contact.clip3d`.

Per slave node j (faces e around it, Γ_e the part of e covered by its
candidates, Φ_j its dual function on that part)::

    G_j = Σ_e ∫_Γe Φ_j g dA,  S_j = Σ_e ∫_Γe Φ_j r dA,  Ā_j = Σ_e ∫_Γe N_j dA,

gap g_j = G_j / Ā_j and the slip point y_j = S_j / Ā_j (3,), whose increments,
projected on the node's tangent basis, are the slip. r is the slip of the slave
relative to the master: with linearised kinematics the relative displacement
x_s − x_m at the reference points opposite each other, with finite kinematics
X_m − X_s, the reference position of the master material point now opposite
the slave point less the slave point's (both move by +d when the slave slides
by d over a fixed master, as a rigid obstacle's closest point does).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._jax import jax, jnp
from ..fem.mesh3d import rows_once
from . import clip3d
from .mortar import check_separate, default_search

#: the gap given to a slave node that no master face covers (open), relative to
#: the patch size (as in 2-D)
FAR = 1e6
#: a master face is a candidate of a slave face when its projection on the slave
#: face's plane comes within this fraction of the slave face's diameter of the
#: slave face's own projection (plus the pair's ``slide``): small sliding
MARGIN = 0.25
#: a placeholder face for the padding (masked: it adds nothing; well posed, so
#: its discarded values and derivatives stay finite)
_DUMMY = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])


def _pad4(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4) vertices (a triangle's fourth = its first) and (n,) vertex counts."""
    faces = np.asarray(faces, dtype=np.int64)
    k = faces.shape[1]
    if k == 4:
        return faces, np.full(len(faces), 4)
    return np.concatenate([faces, faces[:, :1]], axis=1), np.full(len(faces), 3)


def face_frames(X: np.ndarray, faces: np.ndarray, nv: np.ndarray):
    """(centre (n, 3), unit normal (n, 3), e1 (n, 3), e2 (n, 3), radius (n,)) of
    faces (n, 4) (NumPy; the frame of :func:`clip3d.face_frame`)."""
    V = X[faces]
    quad = (nv == 4)[:, None]
    c = np.where(quad, V.mean(axis=1), V[:, :3].mean(axis=1))
    nq = np.cross(V[:, 2] - V[:, 0], V[:, 3] - V[:, 1])
    nt = np.cross(V[:, 1] - V[:, 0], V[:, 2] - V[:, 0])
    n = np.where(quad, nq, nt)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    t = (V[:, 1] - V[:, 0]) - np.einsum("ni,ni->n", V[:, 1] - V[:, 0], n)[:, None] * n
    e1 = t / np.linalg.norm(t, axis=1, keepdims=True)
    radius = np.linalg.norm(V - c[:, None], axis=2).max(axis=1)
    return c, n, e1, np.cross(n, e1), radius


@dataclass(frozen=True)
class Patches3D:
    """The static pairing of a 3-D slave surface (docs/theory.md §13.10). Per
    slave node (nc of them), with P patch nodes, F faces around the node and M
    candidates per face (each padded to the surface's largest):

    Attributes:
        nodes: (nc, P) the patch's mesh nodes, the slave node first (padding:
            the slave node again).
        slave_faces: (nc, F, 4) the node's slave faces, as positions in ``nodes``.
        slave_nv: (nc, F) their vertex counts (3 or 4).
        slave_mask: (nc, F) which faces exist.
        own: (nc, F) the position of the slave node among each face's vertices.
        master_faces: (nc, F, M, 4) each face's candidate master faces, as
            positions in ``nodes``.
        master_nv: (nc, F, M) their vertex counts.
        master_mask: (nc, F, M) which candidates exist.
        master_index: (nc, F, M) the candidates' rows in the master face set (-1: none).
        face_of: (nc, F) each of the node's faces as a row of the slave face set.
        faces: (nf, 4) the slave faces (mesh nodes), nf of them.
        faces_nv: (nf,) their vertex counts.
        cands: (nf, M, 4) each slave face's candidate master faces (mesh nodes),
            in the order of ``master_faces``.
        cands_nv: (nf, M) their vertex counts.
        cands_mask: (nf, M) which candidates exist.
    """

    nodes: np.ndarray
    slave_faces: np.ndarray
    slave_nv: np.ndarray
    slave_mask: np.ndarray
    own: np.ndarray
    master_faces: np.ndarray
    master_nv: np.ndarray
    master_mask: np.ndarray
    master_index: np.ndarray
    face_of: np.ndarray
    faces: np.ndarray
    faces_nv: np.ndarray
    cands: np.ndarray
    cands_nv: np.ndarray
    cands_mask: np.ndarray

    def arrays(self) -> tuple:
        """What a node's kernel takes besides the patch positions (per node)."""
        return (jnp.asarray(self.slave_faces), jnp.asarray(self.slave_nv),
                jnp.asarray(self.slave_mask), jnp.asarray(self.own),
                jnp.asarray(self.master_faces), jnp.asarray(self.master_nv),
                jnp.asarray(self.master_mask))

    def inputs(self, X, linear: bool) -> tuple:
        """Per slave node, what its kernel takes (``X`` the reference positions of
        every mesh node): the patch's positions and :meth:`arrays`, and with
        linearised kinematics the terms of its faces (:func:`face_terms`, one clip
        per face pair for the whole surface, gathered per node)."""
        out = (X[self.nodes],) + self.arrays()
        if not linear:
            return out
        G, S, A, D, Mw, n = face_terms(X, self)
        e = jnp.asarray(self.face_of)
        a = jnp.asarray(self.own)
        return out + ((G[e, a], S[e, a], A[e, a], D[e, a], Mw[e, a], n[e]),)

    @staticmethod
    def node(X, *arrays, linear: bool, axisymmetric: bool = False):
        """The pair as seen by one slave node (:class:`MortarNode3D`)."""
        return MortarNode3D(X, *arrays, linear=linear)

    def master_nodes(self) -> np.ndarray:
        """The mesh nodes of every candidate master face."""
        nc = self.nodes.shape[0]
        pos = self.master_faces.reshape(nc, -1, 4)
        mask = self.master_mask.reshape(nc, -1) > 0
        rows = np.nonzero(mask)[0]
        return np.unique(self.nodes[rows[:, None], pos[mask]])

    def has_candidates(self) -> bool:
        return bool(self.master_mask.any())


def candidate_faces(X: np.ndarray, slave: np.ndarray, snv: np.ndarray, master: np.ndarray,
                    mnv: np.ndarray, search, slide: float, margin: float = MARGIN) -> list[np.ndarray]:
    """Per slave face, the master faces that may cover it (NumPy, on the
    positions ``X``): they face it (n_e . n_m < 0), their centre lies within
    ``search`` of its plane along its normal (a number, or None: one diameter
    of each slave face), and their projection on its plane comes within
    ``margin`` x its diameter + ``slide`` of its own projection (bounding boxes
    in the plane's (e1, e2) coordinates)."""
    cs, ns, e1, e2, rs = face_frames(X, slave, snv)
    search = 2.0 * rs if search is None else np.full(len(slave), float(search))
    cm, nm, _, _, rm = face_frames(X, master, mnv)
    Vm = X[master]  # (nm, 4, 3)
    Vs = X[slave]
    out = []
    chunk = max(1, int(2e6) // max(len(master), 1))
    for lo in range(0, len(slave), chunk):
        sl = slice(lo, min(lo + chunk, len(slave)))
        d = cm[None, :, :] - cs[sl, None, :]  # (c, nm, 3)
        dn = np.einsum("cmi,ci->cm", d, ns[sl])
        reach = 2.0 * margin * rs[sl, None] + slide
        tang = np.linalg.norm(d - dn[..., None] * ns[sl, None, :], axis=2)
        near = ((np.einsum("ci,mi->cm", ns[sl], nm) < 0.0) & (np.abs(dn) <= search[sl, None])
                & (tang <= rs[sl, None] + rm[None, :] + reach))
        for i in range(sl.stop - sl.start):
            e = lo + i
            m = np.nonzero(near[i])[0]
            if not m.size:
                out.append(m)
                continue
            E = np.stack([e1[e], e2[e]], axis=1)  # (3, 2)
            ps = (Vs[e, :snv[e]] - cs[e]) @ E
            pm = (Vm[m] - cs[e]) @ E  # (k, 4, 2); a triangle's fourth is its first
            r = 2.0 * margin * rs[e] + slide
            lo_s, hi_s = ps.min(axis=0) - r, ps.max(axis=0) + r
            over = np.all((pm.max(axis=1) > lo_s) & (pm.min(axis=1) < hi_s), axis=1)
            if margin == 0.0:  # partners: the projected polygons themselves overlap
                over &= np.array([_overlaps(ps, q[:mnv[k]]) for q, k in zip(pm, m)], bool)
            out.append(m[over])
    return out


def _overlaps(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex polygons (k, 2) overlap with a positive area (no
    separating axis among their edges' normals)."""
    for P in (a, b):
        d = np.roll(P, -1, axis=0) - P
        for nrm in np.stack([d[:, 1], -d[:, 0]], axis=1):
            pa, pb = a @ nrm, b @ nrm
            tol = 1e-12 * np.abs(nrm).max() * (np.ptp(a) + np.ptp(b))
            if pa.max() <= pb.min() + tol or pb.max() <= pa.min() + tol:
                return False
    return True


def build_patches(X: np.ndarray, slave_faces: np.ndarray, slave_nodes: np.ndarray,
                  master_faces: np.ndarray, search: float | None, name: str,
                  slide: float | None = None) -> Patches3D:
    """The patches of every slave node of a 3-D pair (NumPy, on the nominal
    reference mesh ``X``; docs/theory.md §13.10)."""
    check_separate(slave_faces, master_faces, name)
    sf, snv = _pad4(slave_faces)
    mf, mnv = _pad4(master_faces)
    cand = candidate_faces(X, sf, snv, mf, mnv, default_search(X, slave_nodes, search),
                           float(slide or 0.0))
    nc = len(slave_nodes)
    pos = {int(n): k for k, n in enumerate(slave_nodes)}
    around: list[list[int]] = [[] for _ in range(nc)]
    for e, f in enumerate(sf):
        for a in range(snv[e]):
            around[pos[int(f[a])]].append(e)
    F = max(len(a) for a in around)
    M = max(1, max((len(c) for c in cand), default=1))
    patch_nodes = []
    s_faces = np.zeros((nc, F, 4), np.int64)
    s_nv = np.full((nc, F), 4, np.int64)
    s_mask = np.zeros((nc, F))
    own = np.zeros((nc, F), np.int64)
    m_faces = np.zeros((nc, F, M, 4), np.int64)
    m_nv = np.full((nc, F, M), 4, np.int64)
    m_mask = np.zeros((nc, F, M))
    m_index = np.full((nc, F, M), -1, np.int64)
    face_of = np.zeros((nc, F), np.int64)
    for j in range(nc):
        sj = int(slave_nodes[j])
        local = {sj: 0}
        order = [sj]

        def at(n, local=local, order=order):
            n = int(n)
            if n not in local:
                local[n] = len(order)
                order.append(n)
            return local[n]

        for k, e in enumerate(around[j]):
            s_faces[j, k] = [at(v) for v in sf[e]]
            s_nv[j, k] = snv[e]
            s_mask[j, k] = 1.0
            own[j, k] = int(np.nonzero(sf[e][:snv[e]] == sj)[0][0])
            face_of[j, k] = e
        for k, e in enumerate(around[j]):
            for i, m in enumerate(cand[e]):
                m_faces[j, k, i] = [at(v) for v in mf[m]]
                m_nv[j, k, i] = mnv[m]
                m_mask[j, k, i] = 1.0
                m_index[j, k, i] = m
        patch_nodes.append(order)
    P = max(len(o) for o in patch_nodes)
    nodes = np.array([o + [o[0]] * (P - len(o)) for o in patch_nodes], dtype=np.int64)
    nf = len(sf)
    cands = np.repeat(sf[:, None, :], M, axis=1)  # padding: the slave face itself (masked)
    c_nv = np.repeat(snv[:, None], M, axis=1)
    c_mask = np.zeros((nf, M))
    for e, c in enumerate(cand):
        cands[e, :len(c)] = mf[c]
        c_nv[e, :len(c)] = mnv[c]
        c_mask[e, :len(c)] = 1.0
    return Patches3D(nodes, s_faces, s_nv, s_mask, own, m_faces, m_nv, m_mask, m_index,
                     face_of, sf, snv, cands, c_nv, c_mask)


# ------------------------------------------------------------- the per-node pair
def _face_quadrature(xs, nvs, xm, nvm, mm):
    """The quadrature of one slave face's covered part: (w (M, NQ), Φ (M, NQ, 4),
    the quadrature of each candidate) from the face's vertices ``xs`` (4, 3),
    the candidates' ``xm`` (M, 4, 3) and their mask ``mm`` (M,) (masked
    candidates are replaced by the slave face itself: well posed, weight zero)."""
    xm = jnp.where((mm > 0)[:, None, None], xm, xs[None])
    nvm = jnp.where(mm > 0, nvm, nvs)
    q = jax.vmap(clip3d.overlap_quadrature, (None, 0, None, 0))(xs, xm, nvs, nvm)
    w = q.w * mm[:, None]  # (M, NQ)
    phi = clip3d.dual_functions(q.N_slave.reshape(-1, 4), w.reshape(-1),
                                (jnp.arange(4) < nvs).astype(xs.dtype))
    return w, phi.reshape(w.shape + (4,)), q


def face_terms(X, patches: Patches3D):
    """Per slave face (nf of them) and per vertex a of it, the reference
    quantities of linearised kinematics (docs/theory.md §13.10), one clip per
    face pair: ∫ Φ_a g and ∫ Φ_a r (3,) at X (from the points' gaps: zero to round-off
    where the two surfaces coincide), ∫ N_a, the weights D_ab = ∫ Φ_a N_b on the
    face's vertices (4, 4) and M_ab = ∫ Φ_a N_b on each candidate's (4, M, 4),
    and the face's normal (3,)."""
    faces = jnp.asarray(patches.faces)
    cands = jnp.asarray(patches.cands)

    def one(f, nvs, c, nvm, mm):
        xs, xm = X[f], X[c]
        w, phi, q = _face_quadrature(xs, nvs, xm, nvm, mm)
        n = q.normal[0]
        wphi = w[..., None] * phi  # (M, NQ, 4): the weights of each vertex's dual function
        vs = jnp.einsum("mqb,bk->mqk", q.N_slave, xs)
        vm = jnp.einsum("mqb,mbk->mqk", q.N_master, xm)
        G = jnp.einsum("mqa,mq->a", wphi, (vm - vs) @ n)
        S = jnp.einsum("mqa,mqk->ak", wphi, vs - vm)
        A = jnp.einsum("mq,mqa->a", w, q.N_slave)
        D = jnp.einsum("mqa,mqb->ab", wphi, q.N_slave)
        Mw = jnp.einsum("mqa,mqb->amb", wphi, q.N_master)
        return G, S, A, D, Mw, n

    return jax.vmap(one)(faces, jnp.asarray(patches.faces_nv), cands,
                         jnp.asarray(patches.cands_nv), jnp.asarray(patches.cands_mask))


class MortarNode3D:
    """The master surface as seen by one slave node of a 3-D pair: ``gap``,
    ``closest`` (the weighted slip point y_j) and ``normal`` of the node's patch
    positions ``x`` (P, 3), the methods the laws call on a rigid obstacle.

    Args:
        X: reference positions of the patch (P, 3) (at the current parameters).
        slave_faces, slave_nv, slave_mask, own, master_faces, master_nv, master_mask:
            one node's rows of :class:`Patches3D`.
        terms: with linearised kinematics, the terms of :func:`face_terms` of the
            node's faces (each at the node's own vertex).
        linear: linearised kinematics (reference normals, projections and
            overlaps: G_j and S_j affine in x).
    """

    def __init__(self, X, slave_faces, slave_nv, slave_mask, own, master_faces, master_nv,
                 master_mask, terms=None, *, linear: bool):
        self.X = X
        self.sf, self.snv, self.smask, self.own = slave_faces, slave_nv, slave_mask, own
        self.mf, self.mnv, self.mmask = master_faces, master_nv, master_mask
        self.linear = linear
        self._linear = None
        self._last = None
        if linear:
            if terms is None:
                raise ValueError("MortarNode3D: linearised kinematics needs the faces' terms "
                                 "(Patches3D.inputs)")
            self._linear = self._coefficients(terms)

    def _coefficients(self, terms):
        """(G_j, S_j, Ā_j at x = X, Ga (P, 3), c (P,)): G_j(x) = G_j(X) + Σ_p Ga_p ·
        (x_p − X_p) and S_j(x) = S_j(X) + Σ_p c_p (x_p − X_p), with Ga_p = Σ_e n_e
        (M_jp − D_jp) and c_p = Σ_e (D_jp − M_jp) over the node's faces e (the
        mortar weights of its dual function gathered on the patch's nodes)."""
        G, S, A, D, Mw, n = terms  # (F,), (F, 3), (F,), (F, 4), (F, M, 4), (F, 3)
        on = self.smask
        P = self.X.shape[0]
        c = jax.vmap(lambda sf, mf, d, m: jnp.zeros(P, self.X.dtype).at[sf].add(d).at[
            mf.reshape(-1)].add(-m.reshape(-1)))(self.sf, self.mf, D * on[:, None],
                                                 Mw * (on[:, None] * self.mmask)[..., None])
        return (jnp.sum(G * on), jnp.sum(S * on[:, None], axis=0), jnp.sum(A * on),
                -jnp.einsum("fp,fi->pi", c, n), jnp.sum(c, axis=0))

    def _integrals(self, x):
        if self._linear is None:
            # gap and closest ask for the same integrals of the same x (one clip of the
            # node's faces per evaluation, not two, in the traced program)
            last = self._last
            if last is None or last[0] is not x:
                self._last = last = (x, self._overlap_integrals(x))
            return last[1]
        G0, S0, A0, Ga, c = self._linear
        d = x - self.X
        return G0 + jnp.sum(Ga * d), S0 + c @ d, A0

    def _face(self, x, f):
        """(∫ Φ_j g, ∫ Φ_j r (3,), ∫ N_j) over slave face f's covered part in the
        configuration x (finite kinematics: the current clip, differentiated)."""
        X = self.X
        on = self.smask[f] > 0
        dummy = jnp.asarray(_DUMMY, X.dtype)
        sidx, midx = self.sf[f], self.mf[f]
        nvs = jnp.where(on, self.snv[f], 4)
        xs = jnp.where(on, x[sidx], dummy)
        w, phi, q = _face_quadrature(xs, nvs, x[midx], self.mnv[f], self.mmask[f] * self.smask[f])
        pick = (jnp.arange(4) == self.own[f]).astype(X.dtype)
        wphi = (w * (phi @ pick)).reshape(-1)
        n = q.normal[0]
        g = ((q.x_master - q.x_slave) @ n).reshape(-1)
        r = (jnp.einsum("mqa,mak->mqk", q.N_master, X[midx]).reshape(-1, 3)
             - q.N_slave.reshape(-1, 4) @ X[sidx])
        return jnp.sum(wphi * g), wphi @ r, w.reshape(-1) @ (q.N_slave.reshape(-1, 4) @ pick)

    def _overlap_integrals(self, x):
        """(G_j, S_j (3,), Ā_j) summed over the node's slave faces."""
        G, S, A = jax.vmap(lambda f: self._face(x, f))(jnp.arange(self.sf.shape[0]))
        return jnp.sum(G), jnp.sum(S, axis=0), jnp.sum(A)

    def gap(self, x, geo=None):
        """g_j = G_j / Ā_j; FAR x the patch size where nothing covers the node's faces."""
        G, _, A = self._integrals(x)
        far = FAR * jnp.max(jnp.abs(self.X - self.X[0]))
        return jnp.where(A > 0.0, clip3d._safe_div(G, A), far)

    def closest(self, x, geo=None):
        """The weighted slip point y_j = S_j / Ā_j (3,)."""
        _, S, A = self._integrals(x)
        return clip3d._safe_div(S, A)

    def normal(self, x, geo=None):
        """Minus the mean outward normal of the node's slave faces (reference ones
        for linearised kinematics): the direction of a rigid obstacle's normal."""
        geo_ = self.X if self.linear else x
        dummy = jnp.asarray(_DUMMY, self.X.dtype)

        def one(f):
            on = self.smask[f] > 0
            xs = jnp.where(on, geo_[self.sf[f]], dummy)
            return clip3d.face_frame(xs, jnp.where(on, self.snv[f], 4))[1] * self.smask[f]

        n = jnp.sum(jax.vmap(one)(jnp.arange(self.sf.shape[0])), axis=0)
        return -n / jnp.sqrt(n @ n)


# ------------------------------------------------- partners in the current state
def partners(x: np.ndarray, slave_faces: np.ndarray, slave_nodes: np.ndarray,
             master_faces: np.ndarray, reach: float = 1.0, memo: dict | None = None):
    """(nc, n_master_faces) sparse boolean matrix: in the configuration ``x`` (all
    nodes' positions), the master faces that face one of a slave node's faces,
    overlap its projection on the face's plane, and lie within ``reach`` (<= 1)
    face diameters of it along its normal (the 3-D version of
    :func:`signorini.contact.mortar.partners`). ``memo`` (a dict kept by the
    caller) holds the last configuration's overlaps, so that the increment checks
    and the switch detector find them once per increment, at any reach."""
    import scipy.sparse as sp  # lazy: only the partner reports of finite sliding need it
    x = np.asarray(x, float)
    sf, snv = _pad4(slave_faces)
    mf, mnv = _pad4(master_faces)
    kept = None if memo is None else memo.get("last")
    if kept is not None and np.array_equal(kept[0], x):
        cand, dist = kept[1]
    else:
        cs, ns, _, _, rs = face_frames(x, sf, snv)
        cand = candidate_faces(x, sf, snv, mf, mnv, None, 0.0, margin=0.0)
        cm = face_frames(x, mf, mnv)[0]
        # the normal distance of each overlapping master face, in slave-face diameters
        dist = [np.abs((cm[c] - cs[e]) @ ns[e]) / (2.0 * rs[e]) for e, c in enumerate(cand)]
        if memo is not None:
            memo["last"] = (x.copy(), (cand, dist))
    pos = np.searchsorted(slave_nodes, sf)
    rows, cols = [], []
    for e, (c, d) in enumerate(zip(cand, dist)):
        c = c[d <= reach]
        for a in range(snv[e]):
            rows.append(np.full(len(c), pos[e, a]))
            cols.append(c)
    data = np.ones(sum(len(r) for r in rows), bool)
    out = sp.csr_matrix((data, (np.concatenate(rows), np.concatenate(cols))),
                        shape=(len(slave_nodes), len(mf)))
    out.sum_duplicates()
    out.data[:] = True
    return out


def candidates(patches: Patches3D, n_master: int):
    """(nc, n_master_faces) sparse boolean matrix of every slave node's candidates."""
    import scipy.sparse as sp  # lazy: only the partner reports of finite sliding need it
    nc = patches.nodes.shape[0]
    idx = patches.master_index.reshape(nc, -1)
    rows, cols = np.nonzero(idx >= 0)
    out = sp.csr_matrix((np.ones(rows.size, bool), (rows, idx[rows, cols])), shape=(nc, n_master))
    out.sum_duplicates()
    out.data[:] = True
    return out


def outside(now, cand) -> np.ndarray:
    """(nc,) True where a node has a partner (``now``) that is not a candidate."""
    extra = now.astype(np.int8) - now.multiply(cand).astype(np.int8)
    return np.asarray(extra.sum(axis=1)).ravel() > 0


def changed(now, before) -> np.ndarray:
    """(nc,) True where a node's partners differ between two configurations."""
    diff = (now.astype(np.int8) - before.astype(np.int8))
    return np.asarray(abs(diff).sum(axis=1)).ravel() > 0


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """(k, 2) the edges of a face set that belong to one face only: its boundary."""
    f, nv = _pad4(faces)
    edges = [np.stack([f[nv == n][:, a], f[nv == n][:, (a + 1) % n]], axis=1)
             for n in (3, 4) for a in range(n) if (nv == n).any()]
    edges = np.concatenate(edges)
    return edges[rows_once(np.sort(edges, axis=1))]


def boundary_switches(x: np.ndarray, patches: Patches3D, master_faces: np.ndarray,
                      tol: float) -> np.ndarray:
    """(nc,) True where, in the configuration ``x``, an edge of the master surface's
    boundary passes over a vertex of one of the slave node's faces (the node
    itself or a neighbour), to ``tol`` of the face's size in the plane of the
    node's faces and within one face size along its normal: there the covered
    part of one of the node's faces starts or stops growing, and its dual
    functions and Ā_j have a kink (the 3-D master end; docs/theory.md §13.10)."""
    x = np.asarray(x, float)
    edges = boundary_edges(master_faces)
    out = np.zeros(patches.nodes.shape[0], bool)
    if not len(edges):
        return out
    on_edge = {}
    for k, (a, b) in enumerate(edges):
        on_edge.setdefault(int(a), []).append(k)
        on_edge.setdefault(int(b), []).append(k)
    for j in range(patches.nodes.shape[0]):
        nodes = patches.nodes[j]
        faces = patches.slave_faces[j][patches.slave_mask[j] > 0]
        nv = patches.slave_nv[j][patches.slave_mask[j] > 0]
        verts = np.unique(np.concatenate([nodes[f[:n]] for f, n in zip(faces, nv)]))
        masters = nodes[patches.master_faces[j][patches.master_mask[j] > 0]].ravel()
        ks = sorted({k for m in np.unique(masters) for k in on_edge.get(int(m), ())})
        if not ks:
            continue
        V = x[verts]
        o = V.mean(axis=0)
        _, n, e1, _, r = face_frames(x, np.asarray([nodes[f] for f in faces]), nv)
        nrm = n.sum(axis=0)
        nrm /= np.linalg.norm(nrm)
        h = 2.0 * r.mean()
        u = e1[0] - (e1[0] @ nrm) * nrm
        u /= np.linalg.norm(u)
        E = np.stack([u, np.cross(nrm, u)], axis=1)  # the plane of the node's faces
        A, B = x[edges[ks, 0]], x[edges[ks, 1]]
        pa, pb, pv = (A - o) @ E, (B - o) @ E, (V - o) @ E
        d = pb - pa  # (e, 2)
        L2 = np.maximum(np.sum(d * d, axis=1), 1e-300)
        t = np.clip(np.einsum("vi,ei->ve", pv, d) - np.einsum("ei,ei->e", pa, d)[None, :], 0, None) / L2
        t = np.minimum(t, 1.0)
        closest = pa[None] + t[..., None] * d[None]
        dist = np.linalg.norm(pv[:, None, :] - closest, axis=2)
        depth = np.abs(((A + B) / 2 - o) @ nrm)
        out[j] = bool(np.any((dist <= tol * h) & (depth[None, :] <= h)))
    return out
