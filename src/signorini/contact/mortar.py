"""Two deformable surfaces in contact: the segment-to-segment (mortar) pair.

A pair has a *slave* surface (an edge set whose nodes carry the multipliers)
and a *master* surface (another edge set, of the same body or of another one).
Per slave node j the contact law (:class:`~signorini.contact.methods.AugmentedLagrangian`,
:class:`~signorini.contact.friction.Coulomb`) sees, in place of the distance to a
rigid obstacle, the mortar-weighted gap and slip (docs/theory.md §13)::

    g_j = (1 / A_j) int_Gs Phi_j(X) g(X) dGamma_0,     s_j = (1 / A_j) int_Gs Phi_j(X) s(X) dGamma_0,

A_j = int N_j dGamma_0 (the node's equivalent area, the same as on a rigid
obstacle), N_j the slave node's shape function and Phi_j its dual function
(biorthogonal to the shape functions over the overlapped part of each slave
segment: 2 N_j - N_other on a segment the master covers; :func:`_dual`), so
that a linear gap's weighted value is its nodal value and the constraints of
neighbouring nodes do not couple; g the distance from a slave
point to the master surface along the slave segment's normal, s the tangential
offset of the master material point now opposite the slave point. The
integrals are taken segment by segment over the overlaps of each slave segment
with the master segments projected onto it (2-point Gauss on each overlap:
exact, the integrands being polynomials of degree <= 3 in the slave
coordinate), so that a flat interface between non-matching meshes transmits a
uniform pressure exactly (the contact patch test).

What a node needs is a fixed *patch* of nodes: the slave node, its two slave
neighbours and the candidate master segments (found once, on the nominal
reference mesh: the pairing does not depend on a parameter's value). The
geometry (projections, overlaps, normals) is a JAX function of the patch's
positions, so the residual, the tangent, the DDM pseudo-loads and the adjoint
differentiate it exactly. With linearised kinematics (small strain) the
normals, tangents and overlaps are those of the reference configuration and
the gap and slip are linear in the displacements; with finite kinematics they
are those of the current configuration (finite sliding within the candidates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._jax import jax, jnp
from ..errors import InputError
from .methods import AugmentedLagrangian, Contact

TWO_PI = 2.0 * np.pi
#: Gauss points of the 2-point rule on [0, 1]
_GP = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])
#: the gap given to a slave node that no master segment overlaps (open: its
#: multiplier equation is lam = 0), relative to the patch size
FAR = 1e6


@dataclass(frozen=True)
class Mortar:
    """The master surface of a contact pair, in the place of a rigid obstacle.

    Attributes:
        master: name of the master edge set.
        search: normal distance (reference configuration) within which a master
            segment is a candidate partner of a slave segment; None: the size of
            the slave surface's bounding box. Candidates are found once, on the
            nominal mesh.
        slide: the largest tangential travel of the master surface along the
            slave over the path (finite sliding): a master segment is a
            candidate when it overlaps the slave segment extended by this much on
            each side (besides half the segment's length). None: small sliding
            (half a segment). A converged increment whose partners left the
            candidates is reported (:func:`partner_report`).
    """

    master: str
    search: float | None = None
    slide: float | None = None

    def specs(self):
        return ()

    def check(self, params):
        return None

    def geometry(self, params, t):
        return {}

    def _per_node(self, *_):
        raise InputError("a mortar surface's gap is defined per slave node with its patch; "
                         "use it in a Problem (signorini.contact.pair), not on its own")

    gap = normal = project = coordinate = _per_node


def pair(slave: str, master: str, method=None, kinematics: str = "auto",
         search: float | None = None, slide: float | None = None):
    """A contact pair between two deformable surfaces (docs/theory.md §13).

    In 2-D (plane strain, axisymmetry) the surfaces are edge sets, in 3-D face
    sets (quadrilaterals of hexahedra or triangles of tetrahedra; the 3-D pair:
    :mod:`signorini.contact.mortar3d`, docs/theory.md §13.10).

    Args:
        slave: edge or face set whose nodes carry the contact multipliers (in a
            pair of different mesh densities, take the finer surface).
        master: edge or face set of the other surface (same or another body).
        method: :class:`~signorini.contact.AugmentedLagrangian` (default),
            :class:`~signorini.contact.Coulomb` or :class:`~signorini.contact.Penalty`.
        kinematics: ``"linear"``, ``"finite"`` or ``"auto"`` as for a rigid obstacle.
        search, slide: see :class:`Mortar` (``slide``: how far the surfaces may
            slide along each other, e.g. the stroke of an ironing die; it sizes
            the candidate partners, found once on the nominal mesh; without it
            sliding is small: half a segment in 2-D, a quarter of a face in 3-D).

    Returns a :class:`~signorini.contact.Contact` to put in ``Problem.contact``.
    """
    if slave == master:
        raise InputError(f"contact pair: the slave and master surfaces are both {slave!r}; "
                         "a pair needs two different edge sets")
    if search is not None and not float(search) > 0:
        raise InputError(f"contact pair {slave!r}/{master!r}: search must be positive, got {search}")
    if slide is not None and not float(slide) >= 0:
        raise InputError(f"contact pair {slave!r}/{master!r}: slide must be >= 0, got {slide}")
    return Contact(Mortar(master, None if search is None else float(search),
                          None if slide is None else float(slide)), slave,
                   AugmentedLagrangian() if method is None else method, kinematics)


def is_mortar(contact) -> bool:
    return isinstance(contact.obstacle, Mortar)


# ---------------------------------------------------------------------- patches
@dataclass(frozen=True)
class Patches:
    """The static pairing of a slave surface: per slave node, its patch of nodes
    ``[prev, j, next, c_0, d_0, c_1, d_1, ...]`` (nc, 3 + 2 M) and the masks of
    the slave segments (prev, j), (j, next) (nc, 2) and of the M candidate
    master segments (c_k, d_k) (nc, M)."""

    nodes: np.ndarray
    slave_mask: np.ndarray
    master_mask: np.ndarray

    def arrays(self) -> tuple:
        """What a node's kernel takes besides the patch positions (per node)."""
        return jnp.asarray(self.slave_mask), jnp.asarray(self.master_mask)

    def inputs(self, X, linear: bool) -> tuple:
        """Per slave node, what its kernel takes (``X`` the reference positions of
        every mesh node): the patch's positions and :meth:`arrays`."""
        return (X[self.nodes],) + self.arrays()

    @staticmethod
    def node(X, slave_mask, master_mask, linear: bool, axisymmetric: bool = False):
        """The pair as seen by one slave node (:class:`MortarNode`)."""
        return MortarNode(X, slave_mask, master_mask, linear=linear, axisymmetric=axisymmetric)

    def master_nodes(self) -> np.ndarray:
        """The mesh nodes of every candidate master segment."""
        nc, M = self.master_mask.shape
        return np.unique(self.nodes[:, 3:].reshape(nc, M, 2)[self.master_mask > 0])

    def has_candidates(self) -> bool:
        return bool(self.master_mask.any())


def check_separate(slave, master, name: str) -> None:
    """A pair's two surfaces (edge or face sets) must share no node."""
    common = np.intersect1d(np.unique(slave), np.unique(master))
    if common.size:
        raise InputError(f"contact pair {name!r}: the slave and master surfaces share "
                         f"{common.size} node(s) (first: node {int(common[0])}); a pair needs two "
                         "surfaces that can separate")


def default_search(X, slave_nodes, search):
    """``search``, or when None the size of the slave surface's bounding box."""
    if search is not None:
        return search
    box = X[slave_nodes].max(axis=0) - X[slave_nodes].min(axis=0)
    return float(max(box.max(), 1e-300))


def build_patches(X: np.ndarray, slave_edges: np.ndarray, slave_nodes: np.ndarray,
                  master_edges: np.ndarray, search: float | None, name: str,
                  slide: float | None = None) -> Patches:
    """Patches of every slave node (NumPy, on the nominal reference mesh ``X``).

    A master segment is a candidate of slave node j when, for one of j's slave
    segments, it faces it (opposite normals: n_e . n_m < 0), its projection on
    the segment's line overlaps the segment extended by half its length on each
    side (and by ``slide``), and its distance along the normal is below ``search``."""
    check_separate(slave_edges, master_edges, name)
    nc = len(slave_nodes)
    prev = np.full(nc, -1)
    nxt = np.full(nc, -1)
    pos = np.searchsorted(slave_nodes, slave_edges)
    prev[pos[:, 1]] = slave_edges[:, 0]
    nxt[pos[:, 0]] = slave_edges[:, 1]
    search = default_search(X, slave_nodes, search)
    # (n_slave_edges, n_master_edges) candidate matrix
    L = np.linalg.norm(X[slave_edges[:, 1]] - X[slave_edges[:, 0]], axis=1)
    xc, xd, gc, gd, facing = _projections(X[slave_edges], X, master_edges)
    reach = 0.5 + (slide or 0.0) / L[:, None]
    overlap = (np.maximum(xc, xd) > -reach) & (np.minimum(xc, xd) < 1.0 + reach)
    dist = np.abs(0.5 * (gc + gd)) * L[:, None]  # the master segment's midpoint
    cand = overlap & facing & (dist <= search)
    edge_of = {(int(a), int(b)): k for k, (a, b) in enumerate(slave_edges)}
    lists = []
    for j in range(nc):
        segs = set()
        for a, b in ((prev[j], slave_nodes[j]), (slave_nodes[j], nxt[j])):
            if a >= 0 and b >= 0:
                segs.update(np.nonzero(cand[edge_of[(int(a), int(b))]])[0].tolist())
        lists.append(sorted(segs))
    M = max(1, max(len(s) for s in lists))
    nodes = np.zeros((nc, 3 + 2 * M), dtype=np.int64)
    smask = np.zeros((nc, 2))
    mmask = np.zeros((nc, M))
    for j in range(nc):
        sj = int(slave_nodes[j])
        nodes[j, 0] = prev[j] if prev[j] >= 0 else sj
        nodes[j, 1] = sj
        nodes[j, 2] = nxt[j] if nxt[j] >= 0 else sj
        smask[j] = [prev[j] >= 0, nxt[j] >= 0]
        nodes[j, 3:] = sj  # padding: the slave node itself, masked out
        for k, m in enumerate(lists[j]):
            nodes[j, 3 + 2 * k: 5 + 2 * k] = master_edges[m]
            mmask[j, k] = 1.0
    return Patches(nodes, smask, mmask)


# ------------------------------------------------------------- the per-node pair
def _dual(Nj, No, w):
    """Phi_j at the quadrature points: the slave node's dual function on one
    segment, biorthogonal to the segment's two shape functions over the part of it
    the master overlaps (quadrature weights ``w``): int Phi_j N_j = int N_j and
    int Phi_j N_o = 0 there. On a wholly overlapped segment Phi_j = 2 N_j - N_o.
    From the overlap's mass matrix M and D = diag(int N):
    Phi_j = d_j (m_oo N_j - m_jo N_o) / det M; zero where nothing overlaps."""
    m_jj, m_jo, m_oo = jnp.sum(w * Nj * Nj), jnp.sum(w * Nj * No), jnp.sum(w * No * No)
    d_j = jnp.sum(w * Nj)
    det = m_jj * m_oo - m_jo * m_jo
    # an overlap of relative length delta has det ~ delta^2 / 12 of scale and Phi_j
    # round-off errors ~ 1e-16 / delta; below delta ~ 1e-8 (where both the error and
    # the overlap's whole contribution are ~1e-8 of a segment's) Phi_j is taken as 0
    scale = (m_jj + m_oo) ** 2
    ok = det > 1e-17 * scale
    c = _safe_div(d_j, jnp.where(ok, det, 1.0)) * ok
    return c * (m_oo * Nj - m_jo * No)


def _safe_div(a, b):
    ok = jnp.abs(b) > 1e-300
    return jnp.where(ok, a / jnp.where(ok, b, 1.0), 0.0)


class MortarNode:
    """The master surface as seen by one slave node: the same methods as a rigid
    obstacle (``gap``, ``coordinate``, ``normal``), of the node's patch
    positions ``x`` (P, 2) in place of one point.

    Args:
        X: reference positions of the patch (P, 2) (at the current parameters).
        slave_mask, master_mask: see :class:`Patches` (one node's rows).
        linear: linearised kinematics (reference normals and overlaps).
        axisymmetric: weight the integrals by 2 pi R (R: reference radius).
    """

    def __init__(self, X, slave_mask, master_mask, linear: bool, axisymmetric: bool):
        self.X = X
        self.smask = slave_mask
        self.mmask = master_mask
        self.linear = linear
        self.axisymmetric = axisymmetric
        self._affine = None
        if linear:
            # linearised kinematics: the integrals are affine in the positions x (the
            # overlaps, normals and dual functions are the reference ones), so they are
            # their values at X and their gradients there, computed once per node; the
            # residual and its tangent then differentiate a dot product instead of the
            # overlap geometry once per patch coordinate (docs/theory.md §13.2)
            (g0, s0, ws), vjp = jax.vjp(self._overlap_integrals, X)
            ga, = vjp((jnp.ones(()), jnp.zeros(()), jnp.zeros(())))
            sa, = vjp((jnp.zeros(()), jnp.ones(()), jnp.zeros(())))
            self._affine = (g0, s0, ws, ga, sa)

    def _integrals(self, x):
        """(int Phi_j g, int Phi_j s, int N_j) over the overlaps (reference measure):
        Phi_j the dual (biorthogonal) function of the slave node on each of its two
        segments, built on the overlapped part of the segment."""
        if self._affine is None:
            return self._overlap_integrals(x)
        g0, s0, ws, ga, sa = self._affine
        d = x - self.X
        return g0 + jnp.sum(ga * d), s0 + jnp.sum(sa * d), ws

    def _overlap_integrals(self, x):
        """:meth:`_integrals` from the overlaps, Gauss point by Gauss point."""
        X = self.X
        geo = X if self.linear else x
        C, D = geo[3::2], geo[4::2]  # (M, 2) candidate master segments
        xC, xD = x[3::2], x[4::2]
        XC, XD = X[3::2], X[4::2]
        gp = jnp.asarray(_GP)[None, :]  # (1, 2) Gauss points, broadcast over the candidates
        gsum = jnp.zeros(())
        ssum = jnp.zeros(())
        wsum = jnp.zeros(())
        # slave segment (prev, j): N_j = xi; (j, next): N_j = 1 - xi
        for e, (a, b, nj) in enumerate(((0, 1, lambda xi: xi), (1, 2, lambda xi: 1.0 - xi))):
            pa, pb = geo[a], geo[b]
            d = pb - pa
            Lg = jnp.sqrt(d @ d + (1.0 - self.smask[e]))  # masked: a unit length, no NaN
            tau = d / Lg
            n = jnp.array([tau[1], -tau[0]])
            L0v = X[b] - X[a]
            L0 = jnp.sqrt(L0v @ L0v + (1.0 - self.smask[e]))
            T0 = L0v / L0
            xc = ((C - pa) @ tau / Lg)[:, None]  # (M, 1)
            xd = ((D - pa) @ tau / Lg)[:, None]
            lo = jnp.clip(jnp.minimum(xc, xd), 0.0, 1.0)
            hi = jnp.clip(jnp.maximum(xc, xd), 0.0, 1.0)
            length = jnp.maximum(hi - lo, 0.0) * self.smask[e] * self.mmask[:, None]
            xi = lo + (hi - lo) * gp  # (M, 2)
            eta = _safe_div(xi - xc, xd - xc)
            xm = xC[:, None, :] + eta[..., None] * (xD - xC)[:, None, :]  # (M, 2, 2)
            xs = x[a] + xi[..., None] * (x[b] - x[a])
            g = (xm - xs) @ n
            if self.linear:
                s = (xs - xm) @ T0
            else:
                Xm = XC[:, None, :] + eta[..., None] * (XD - XC)[:, None, :]
                Xs = X[a] + xi[..., None] * (X[b] - X[a])
                s = (Xs - Xm) @ T0
            w = 0.5 * length * L0
            if self.axisymmetric:
                w = w * TWO_PI * (X[a, 0] + xi * (X[b, 0] - X[a, 0]))
            Nj = nj(xi)
            No = 1.0 - Nj
            phi = _dual(Nj, No, w)
            gsum = gsum + jnp.sum(w * phi * g)
            ssum = ssum + jnp.sum(w * phi * s)
            wsum = wsum + jnp.sum(w * Nj)
        return gsum, ssum, wsum

    def gap(self, x, geo=None):
        """The mortar-weighted gap of the slave node, g_j = int N_j g / int N_j (over
        the overlapped part of its segments; FAR x the patch size where nothing
        overlaps: the node is open)."""
        gs, _, ws = self._integrals(x)
        far = FAR * jnp.max(jnp.abs(self.X - self.X[1]))
        return jnp.where(ws > 0.0, _safe_div(gs, ws), far)

    def coordinate(self, x, geo=None):
        """The mortar-weighted slip coordinate s_j (its increments are the slip)."""
        _, ss, ws = self._integrals(x)
        return _safe_div(ss, ws)

    def normal(self, x, geo=None):
        """The slave node's averaged segment normal (reference for linear kinematics)."""
        geo_ = self.X if self.linear else x
        n = jnp.zeros(2)
        for e, (a, b) in enumerate(((0, 1), (1, 2))):
            d = geo_[b] - geo_[a]
            n = n + self.smask[e] * jnp.array([d[1], -d[0]])
        return n / jnp.sqrt(n @ n)


# ------------------------------------------------- partners in the current state
def _slave_segments(x, patches):
    """Both slave segments of every slave node: ends (2, nc, 2 points, dim), mask (2, nc)."""
    nd = patches.nodes
    segs = np.stack([np.stack([x[nd[:, 0]], x[nd[:, 1]]], axis=1),
                     np.stack([x[nd[:, 1]], x[nd[:, 2]]], axis=1)])
    return segs, patches.slave_mask.T > 0


def _projections(seg, x, master_edges):
    """Master nodes (c, d) of every master segment projected on slave segments
    ``seg`` (n, 2, 2): parameters xc, xd (n, nm) in units of the segment, normal
    distances gc, gd (n, nm) and whether the segments face each other."""
    a, b = seg[:, 0], seg[:, 1]
    d = b - a
    L = np.linalg.norm(d, axis=1)
    L = np.where(L > 0, L, 1.0)
    tau = d / L[:, None]
    n = np.stack([tau[:, 1], -tau[:, 0]], axis=1)
    C, D = x[master_edges[:, 0]], x[master_edges[:, 1]]
    rel_c = C[None, :, :] - a[:, None, :]
    rel_d = D[None, :, :] - a[:, None, :]
    xc = np.einsum("nmk,nk->nm", rel_c, tau) / L[:, None]
    xd = np.einsum("nmk,nk->nm", rel_d, tau) / L[:, None]
    gc = np.einsum("nmk,nk->nm", rel_c, n) / L[:, None]
    gd = np.einsum("nmk,nk->nm", rel_d, n) / L[:, None]
    dm = D - C
    nm = np.stack([dm[:, 1], -dm[:, 0]], axis=1)
    facing = (n @ nm.T) < 0.0
    return xc, xd, gc, gd, facing


def partner_distances(x: np.ndarray, patches: Patches, master_edges: np.ndarray,
                      memo: dict | None = None, chunk: int = 256) -> np.ndarray:
    """(nc, n_master_edges): in the configuration ``x`` (all nodes' positions),
    the normal distance, in segment lengths, between a master segment and a
    slave node's segment it faces and overlaps (the smaller of the two at the
    overlap's ends, the smaller over the node's two segments); inf where it does
    not face or overlap either. ``memo`` (a dict kept by the caller) holds the
    last configuration's result, so the increment checks and the switch
    detector compute it once per increment."""
    x = np.asarray(x, float)
    if memo is not None:
        kept = memo.get("last")
        if kept is not None and kept[0] is patches and np.array_equal(kept[1], x):
            return kept[2]
    segs, mask = _slave_segments(x, patches)
    nc = patches.nodes.shape[0]
    out = np.full((nc, len(master_edges)), np.inf)
    for e in range(2):
        for lo in range(0, nc, chunk):
            sl = slice(lo, min(lo + chunk, nc))
            xc, xd, gc, gd, facing = _projections(segs[e, sl], x, master_edges)
            a = np.clip(np.minimum(xc, xd), 0.0, 1.0)
            b = np.clip(np.maximum(xc, xd), 0.0, 1.0)
            over = b - a > 1e-12
            # the normal distance at the overlap's ends (linear along the master segment)
            den = np.where(np.abs(xd - xc) > 1e-300, xd - xc, 1.0)
            ga = gc + (a - xc) / den * (gd - gc)
            gb = gc + (b - xc) / den * (gd - gc)
            near = np.minimum(np.abs(ga), np.abs(gb))
            on = over & facing & mask[e, sl, None]
            out[sl] = np.minimum(out[sl], np.where(on, near, np.inf))
    if memo is not None:
        memo["last"] = (patches, x.copy(), out)
    return out


def partners(x: np.ndarray, patches: Patches, master_edges: np.ndarray, reach: float = 1.0,
             memo: dict | None = None) -> np.ndarray:
    """(nc, n_master_edges) True where a master segment is, in the configuration
    ``x`` (all nodes' positions), a partner of a slave node: it faces one of the
    node's slave segments, overlaps it, and lies within ``reach`` segment lengths
    of it along the normal over the overlap (:func:`partner_distances`)."""
    return partner_distances(x, patches, master_edges, memo) <= reach


def candidates(patches: Patches, master_edges: np.ndarray) -> np.ndarray:
    """(nc, n_master_edges) True where a master segment is among a slave node's candidates."""
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(master_edges)}
    out = np.zeros((patches.nodes.shape[0], len(master_edges)), bool)
    M = patches.master_mask.shape[1]
    for j in range(patches.nodes.shape[0]):
        for k in range(M):
            if patches.master_mask[j, k]:
                out[j, index[(int(patches.nodes[j, 3 + 2 * k]), int(patches.nodes[j, 4 + 2 * k]))]] = True
    return out


def end_switches(x: np.ndarray, patches: Patches, master_edges: np.ndarray, tol: float) -> np.ndarray:
    """(nc,) True where the end of the master surface (a node of one master
    segment only) is, in the configuration ``x``, over the slave node itself or
    over one of its two neighbours, to ``tol`` of a segment (along it) and within
    one segment length along the normal: there the overlapped part of one of the
    node's segments stops growing or starts, and its weight int N_j and its dual
    function Phi_j, so its weighted gap, have a kink (docs/theory.md §13.7)."""
    ids, count = np.unique(master_edges, return_counts=True)
    ends = ids[count == 1]
    nc = patches.nodes.shape[0]
    out = np.zeros(nc, bool)
    if not ends.size:
        return out
    segs, mask = _slave_segments(np.asarray(x, float), patches)
    pts = np.stack([ends, ends], axis=1)  # degenerate "segments" at the end nodes
    for e in (0, 1):  # the segments (prev, j) and (j, next), each at both of its ends
        xc, _, gc, _, _ = _projections(segs[e], x, pts)
        on = ((np.abs(xc) <= tol) | (np.abs(xc - 1.0) <= tol)) & (np.abs(gc) <= 1.0)
        out |= np.any(on, axis=1) & mask[e]
    return out
