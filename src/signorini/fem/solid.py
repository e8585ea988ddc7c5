"""Three-dimensional elements: the 8-node hexahedron and the 4-node tetrahedron.

A :class:`CellType` holds what depends on the reference cell only (corners,
Gauss points and weights, shape functions and their parent gradients at the
Gauss points and at the centroid, the faces). The element kernels below are
written once for every cell type, formulation (:class:`~signorini.fem.element.Standard`
or :class:`~signorini.fem.element.FBar`) and material
(``update(H, h_n, mp) -> (P, h)``, :mod:`signorini.materials`), exactly as the
2-D ones of :mod:`signorini.fem.element`, with the full 3x3 displacement
gradient H_ij = u_ai dN_a/dX_j (docs/theory.md §12.1):

    r_ai = sum_g w_g P_ij(Hbar_g, h_n,g) dN_a/dX_j            (standard)
    K_aibk = sum_g w_g dN_a/dX_j C_ijkl dN_b/dX_l,  C = dP/dH

with C from forward-mode autodiff at the material point (9 directions per
Gauss point). F-bar (hexahedra only) differentiates the element residual, a
VJP of u_e -> Hbar, forward in the 3 n_nodes nodal directions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import _small
from .._jax import jax, jnp
from ..errors import InputError
from .element import DN_PARENT, N_PARENT, STANDARD, FBar, average_cauchy

_G = 1.0 / np.sqrt(3.0)


@dataclass(frozen=True, eq=False)
class CellType:
    """A reference cell of a 3-D mesh.

    Attributes:
        name: the cell's name (as meshio and gmsh call it).
        corners: (n_nodes, 3) parent coordinates of the nodes.
        points: (n_gauss, 3) Gauss points; weights: (n_gauss,).
        faces: (n_faces, k) local node indices of each face, numbered
            counter-clockwise seen from outside (outward normal by the right hand).
        fbar: whether the F-bar formulation applies (a cell with one Gauss point
            has nothing to average).
    """

    name: str
    corners: np.ndarray
    points: np.ndarray
    weights: np.ndarray
    faces: np.ndarray
    fbar: bool
    shape: object = field(repr=False)  # xi (3,) -> N (n_nodes,), NumPy or JAX

    def __post_init__(self):
        N = np.stack([self.shape(p) for p in self.points])
        dN = np.stack([self.gradient(p) for p in self.points])
        c = self.corners.mean(axis=0)
        object.__setattr__(self, "N", N)
        object.__setattr__(self, "dN", dN)
        object.__setattr__(self, "N0", self.shape(c)[None])
        object.__setattr__(self, "dN0", self.gradient(c)[None])

    @property
    def n_nodes(self) -> int:
        return len(self.corners)

    @property
    def n_gauss(self) -> int:
        return len(self.points)

    def gradient(self, xi) -> np.ndarray:
        """dN/dxi (n_nodes, 3) at the parent point ``xi`` (exact: forward
        differences of an affine-in-each-coordinate N are exact at unit step)."""
        xi = np.asarray(xi, dtype=float)
        return np.stack([self.shape(xi + e) - self.shape(xi) for e in np.eye(3)], axis=1)


HEX_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)


# The shape functions read no global name (their data are defaults): a model's key
# (model.identity) then knows them by their code and data, so that its programs are
# kept between processes; a function reading a global is known by its identity only.
def _hex_shape(xi, c=HEX_CORNERS):
    return 0.125 * (1 + c[:, 0] * xi[0]) * (1 + c[:, 1] * xi[1]) * (1 + c[:, 2] * xi[2])


def _tet_shape(xi, a=np.array([1.0, 0.0, 0.0, 0.0]),
               b=np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])):
    return a + b @ xi

#: trilinear hexahedron (VTK/gmsh node order), 2x2x2 Gauss points
HEXAHEDRON = CellType(
    name="hexahedron", corners=HEX_CORNERS,
    points=_G * HEX_CORNERS, weights=np.ones(8),
    faces=np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6],
                    [3, 0, 4, 7]]),
    fbar=True, shape=_hex_shape)

#: linear tetrahedron (VTK/gmsh node order), one Gauss point (exact for its constant strain)
TETRA = CellType(
    name="tetra", corners=np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float),
    points=np.full((1, 3), 0.25), weights=np.full(1, 1.0 / 6.0),
    faces=np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]),
    fbar=False, shape=_tet_shape)

CELL_TYPES = {c.name: c for c in (HEXAHEDRON, TETRA)}


def cell_type(n_nodes: int) -> CellType:
    """The cell type with ``n_nodes`` nodes (8: hexahedron, 4: tetrahedron)."""
    return {8: HEXAHEDRON, 4: TETRA}[n_nodes]


@dataclass(frozen=True)
class Solid3D:
    """The kinematics of a 3-D body of ``cell`` cells (hexahedra or tetrahedra): the
    full 3x3 displacement gradient, volumes det J, contact areas of the faces
    (:func:`face_areas`). The element kernels of this module
    take it (or the cell type) where the 2-D ones take their kinematics.
    ``cell`` None: a mixed mesh (:mod:`signorini.fem.mesh3d`), whose model runs
    the kernels of each kind on its cells."""

    cell: CellType = None

    name = "3-D"
    dim = 3
    active = tuple((i, j) for i in range(3) for j in range(3))

    @property
    def n_gauss(self) -> int:
        """Gauss points per cell (a mixed mesh: a hexahedron's; a tetrahedron's
        history is padded to as many)."""
        return (self.cell or HEXAHEDRON).n_gauss

    def check_mesh(self, X) -> None:
        if np.asarray(X).shape[1] != 3:
            raise InputError("a 3-D body needs a 3-D mesh (Mesh3D: three coordinates per node)")

    def contact_areas(self, X, faces, nodes):
        return face_areas(X, faces, nodes)

    @staticmethod
    def displacement_gradients(ue, Xe, N, dNdX):
        """H (g, 3, 3) = u_ai dN_a/dX_j at points with gradients dNdX (g, n, 3)."""
        return jnp.einsum("ai,gaj->gij", ue, dNdX)

    @staticmethod
    def volume_weights(Xe, N, w_ref):
        return w_ref

    @staticmethod
    def hoop_functions(Xe, N):
        return None

    @staticmethod
    def edge_factors(Xa, Xb):
        raise InputError("edge loads do not apply to a 3-D body (its loads act on faces)")


def _cell(cell) -> CellType:
    return cell.cell if isinstance(cell, Solid3D) else cell


def physical_gradients(dN, Xe):
    """dN/dX (g, n, 3) and det(dX/dxi) (g,) from parent gradients dN (g, n, 3)."""
    J = jnp.einsum("gai,aj->gji", dN, Xe)  # dX_j/dxi_i
    detJ = _small.det(J)
    return jnp.einsum("gai,gij->gaj", dN, _small.adjugate(J) / detJ[:, None, None]), detJ


def _points(Xe, cell: CellType):
    dNdX, detJ = physical_gradients(cell.dN, Xe)
    return dNdX, cell.weights * detJ


def cell_volume(Xe, cell=None):
    """The volume of a cell with nodal positions Xe (its Gauss rule; exact for
    a hexahedron whose faces are plane, and for a tetrahedron)."""
    return jnp.sum(_points(Xe, _cell(cell or HEXAHEDRON))[1])


def gauss_gradients(ue, Xe, cell: CellType, formulation=STANDARD):
    """Displacement gradients (g, 3, 3) seen by the material (Hbar for F-bar)
    and the volume weights (g,)."""
    cell = _cell(cell)
    dNdX, w = _points(Xe, cell)
    H = jnp.einsum("ai,gaj->gij", ue, dNdX)
    if not formulation.linear:
        dNdX0, _ = physical_gradients(cell.dN0, Xe)
        H = formulation.modify(H, jnp.einsum("ai,aj->ij", ue, dNdX0[0]))
    return H, w


def _history(cell: CellType, hn):
    return jnp.zeros((cell.n_gauss, 0)) if hn is None else hn


def _check_formulation(cell: CellType, formulation) -> None:
    if isinstance(formulation, FBar) and not cell.fbar:
        raise InputError(f"the F-bar formulation needs cells with several Gauss points; "
                         f"{cell.name} cells have one (use Standard(), or hexahedra)")


def element_update(ue, Xe, material, mp, hn=None, cell: CellType = HEXAHEDRON,
                   formulation=STANDARD):
    """Internal forces (n_nodes, 3) and the updated Gauss-point history of one cell.

    Args:
        ue: (n_nodes, 3) nodal displacements. Xe: (n_nodes, 3) reference coordinates.
        material: a material with ``update(H, h_n, mp)``. mp: its parameter values.
        hn: (n_gauss, n_state) history at the end of the previous increment (None: none).
    """
    cell = _cell(cell)
    _check_formulation(cell, formulation)
    hn = _history(cell, hn)
    if formulation.linear:
        dNdX, w = _points(Xe, cell)
        H = jnp.einsum("ai,gaj->gij", ue, dNdX)
        P, h = jax.vmap(material.update, (0, 0, None))(H, hn, mp)
        return jnp.einsum("g,gij,gaj->ai", w, P, dNdX), h
    w = gauss_gradients(ue, Xe, cell, formulation)[1]
    H, vjp = jax.vjp(lambda u: gauss_gradients(u, Xe, cell, formulation)[0], ue)
    P, h = jax.vmap(material.update, (0, 0, None))(H, hn, mp)
    (r,) = vjp(w[:, None, None] * P)
    return r, h


def element_residual(ue, Xe, material, mp, hn=None, cell: CellType = HEXAHEDRON,
                     formulation=STANDARD):
    """Internal forces (n_nodes, 3) of one cell."""
    return element_update(ue, Xe, material, mp, hn, cell, formulation)[0]


def element_residual_tangent(ue, Xe, material, mp, hn=None, cell: CellType = HEXAHEDRON,
                             formulation=STANDARD):
    """Internal forces (3 n,), tangent (3 n, 3 n) (node-major DOFs) and the
    updated history of one cell."""
    cell = _cell(cell)
    _check_formulation(cell, formulation)
    hn = _history(cell, hn)
    n = cell.n_nodes
    if formulation.linear:
        dNdX, w = _points(Xe, cell)
        H = jnp.einsum("ai,gaj->gij", ue, dNdX)

        def stress(Hg, h_):
            P, h = material.update(Hg, h_, mp)
            return P, (P, h)

        C, (P, h) = jax.vmap(jax.jacfwd(stress, has_aux=True))(H, hn)  # (g,3,3,3,3), (g,3,3)
        r = jnp.einsum("g,gij,gaj->ai", w, P, dNdX)
        K = jnp.einsum("g,gaj,gijkl,gbl->aibk", w, dNdX, C, dNdX)
        return r.reshape(3 * n), K.reshape(3 * n, 3 * n), h

    def residual(u):
        r, h = element_update(u.reshape(n, 3), Xe, material, mp, hn, cell, formulation)
        return r.reshape(3 * n), (r.reshape(3 * n), h)

    K, (r, h) = jax.jacfwd(residual, has_aux=True)(ue.reshape(3 * n))
    return r, K, h


def element_stress(ue, Xe, material, mp, hn=None, cell: CellType = HEXAHEDRON,
                   formulation=STANDARD):
    """Cauchy stress (3, 3) averaged over the Gauss points of one cell."""
    cell = _cell(cell)
    H, w = gauss_gradients(ue, Xe, cell, formulation)
    return average_cauchy(material, mp, H, w, _history(cell, hn))


def element_yield_ratio(ue, Xe, material, mp, hn, cell=HEXAHEDRON, formulation=STANDARD):
    """(n_gauss,) ``material.yield_ratio`` at the Gauss points of one cell."""
    cell = _cell(cell)
    H, _ = gauss_gradients(ue, Xe, cell, formulation)
    return jax.vmap(lambda h, hs: material.yield_ratio(h, hs, mp))(H, _history(cell, hn))


def face_integrals(X, faces: np.ndarray):
    """(w (f, k), a (f, k, 3)): per face and face node, int_f N_a dA and
    int_f N_a n dA (n: the unit normal of the face's node order, outward for the
    face sets of a mesh) on the reference surface: the consistent nodal weights
    of a uniform traction and of a uniform pressure (docs/theory.md §12.5)."""
    xp = np if isinstance(X, np.ndarray) else jnp
    Xf = X[np.asarray(faces)]  # (f, k, 3)
    if faces.shape[1] == 3:
        na = 0.5 * xp.cross(Xf[:, 1] - Xf[:, 0], Xf[:, 2] - Xf[:, 0])  # n dA of the triangle
        w = xp.repeat(xp.linalg.norm(na, axis=1)[:, None] / 3.0, 3, axis=1)
        return w, xp.repeat(na[:, None, :] / 3.0, 3, axis=1)
    if faces.shape[1] != 4:
        raise InputError(f"faces must be triangles or quadrilaterals, got {faces.shape[1]} "
                         "nodes per face")
    # the face's bilinear map at the Q4's 2x2 Gauss points (its unit weights)
    J = xp.einsum("gak,fai->fgki", DN_PARENT, Xf)  # (f, g, 2, 3): dX/dxi, dX/deta
    nda = xp.cross(J[:, :, 0], J[:, :, 1])  # (f, g, 3): n dA
    w = xp.einsum("fg,ga->fa", xp.linalg.norm(nda, axis=-1), N_PARENT)
    return w, xp.einsum("fgi,ga->fai", nda, N_PARENT)


def face_areas(X, faces: np.ndarray, nodes: np.ndarray | None = None):
    """A_S (n_contact,) = sum over the faces f of the set of int_f N_S dA, on the
    reference surface (docs/theory.md §12.5): a third of each triangle's area, or
    the 2x2 Gauss rule on each bilinear quadrilateral. They add up to the area
    of the surface.

    Args:
        X: (n_nodes, 3) reference coordinates (JAX or NumPy, may depend on phi).
        faces: (n_faces, 3) triangles or (n_faces, 4) quadrilaterals.
        nodes: (n_contact,) sorted nodes of the faces (default: all of them).
    """
    faces = np.asarray(faces)
    if nodes is None:
        nodes = np.unique(faces.ravel())
    if faces.shape[1] not in (3, 4):
        raise InputError(f"contact faces must be triangles or quadrilaterals, got {faces.shape[1]} "
                         "nodes per face")
    xp = np if isinstance(X, np.ndarray) else jnp
    per_node = face_integrals(X, faces)[0]
    pos = np.searchsorted(nodes, faces)
    if xp is np:
        out = np.zeros(len(nodes))
        np.add.at(out, pos.ravel(), per_node.ravel())
        return out
    return jnp.zeros(len(nodes)).at[pos.ravel()].add(per_node.ravel())
