"""Equivalent contact areas A_S of the extended node-to-segment element.

A_S belongs to contact node S and its two neighbours N1, N2 along the boundary
of the *reference* mesh (paper section 4, docs/theory.md §5): in plane strain
(per unit thickness) A_S = (l1 + l2) / 2, and l1 / 2 at an end node; the
axisymmetric form is in :mod:`signorini.fem.kinematics`. It depends on the design
parameters through X(phi), never on the displacements.
"""

from __future__ import annotations

import numpy as np

from .._jax import jnp
from ..errors import InputError
from ..fem.kinematics import PLANE_STRAIN


def contact_nodes(edges: np.ndarray) -> np.ndarray:
    """Sorted unique nodes of an edge set."""
    return np.unique(edges.ravel())


def equivalent_areas(X, edges: np.ndarray, nodes: np.ndarray | None = None, kinematics=None):
    """A_S (n_contact,) for the nodes ``nodes`` of the edge set ``edges``.

    Args:
        X: (n_nodes, 2) reference coordinates (JAX or NumPy, may depend on phi).
        edges: (n_edges, 2) boundary edges of the contact surface.
        nodes: (n_contact,) sorted contact nodes (default ``contact_nodes(edges)``).
        kinematics: :class:`~signorini.fem.kinematics.PlaneStrain` (default, per unit
            thickness) or :class:`~signorini.fem.kinematics.Axisymmetric` (full 2 pi).
    """
    edges = np.asarray(edges)
    if nodes is None:
        nodes = contact_nodes(edges)
    return (kinematics or PLANE_STRAIN).contact_areas(X, edges, nodes)


def check_edges(edges: np.ndarray, name: str) -> None:
    """A contact surface must be a simple chain: no node with more than two edges."""
    if len(edges) == 0:
        raise InputError(f"contact edge set {name!r} is empty")
    counts = np.bincount(edges.ravel())
    if counts.max() > 2:
        n = int(np.argmax(counts))
        raise InputError(
            f"contact edge set {name!r}: node {n} has {counts.max()} edges; a contact "
            "surface must be a chain of boundary edges"
        )


def nodal_normals(X, edges: np.ndarray, nodes: np.ndarray):
    """Reference outward unit normals (n_contact, 2) of the body at the contact
    nodes: normalised sum of the adjacent edge normals (dy, -dx)."""
    pos = np.searchsorted(nodes, edges)
    xp = np if isinstance(X, np.ndarray) else jnp  # a fixed mesh: NumPy, no eager JAX op
    d = X[edges[:, 1]] - X[edges[:, 0]]
    n = xp.stack([d[:, 1], -d[:, 0]], axis=1)
    if xp is np:
        N = np.zeros((len(nodes), 2))
        np.add.at(N, pos[:, 0], n)
        np.add.at(N, pos[:, 1], n)
    else:
        N = jnp.zeros((len(nodes), 2)).at[pos[:, 0]].add(n).at[pos[:, 1]].add(n)
    return N / xp.linalg.norm(N, axis=1, keepdims=True)


_G = 1.0 / np.sqrt(3.0)
#: 2x2 Gauss points of the parent square and the bilinear shape functions and
#: parent gradients of a quadrilateral face there
_QUAD_XI = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])
_QUAD_C = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_QUAD_N = 0.25 * (1 + _QUAD_XI[:, None, 0] * _QUAD_C[None, :, 0]) * (1 + _QUAD_XI[:, None, 1] * _QUAD_C[None, :, 1])
_QUAD_DN = 0.25 * np.stack([_QUAD_C[None, :, 0] * (1 + _QUAD_XI[:, None, 1] * _QUAD_C[None, :, 1]),
                            _QUAD_C[None, :, 1] * (1 + _QUAD_XI[:, None, 0] * _QUAD_C[None, :, 0])],
                           axis=-1)  # (gauss, node, 2)


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
    xp = np if isinstance(X, np.ndarray) else jnp
    Xf = X[faces]  # (f, k, 3)
    if faces.shape[1] == 3:
        a = 0.5 * xp.linalg.norm(xp.cross(Xf[:, 1] - Xf[:, 0], Xf[:, 2] - Xf[:, 0]), axis=1)
        per_node = xp.repeat(a[:, None] / 3.0, 3, axis=1)
    elif faces.shape[1] == 4:
        J = xp.einsum("gak,fai->fgki", _QUAD_DN, Xf)  # (f, g, 2, 3): dX/dxi, dX/deta
        dA = xp.linalg.norm(xp.cross(J[:, :, 0], J[:, :, 1]), axis=-1)  # (f, g)
        per_node = xp.einsum("fg,ga->fa", dA, _QUAD_N)
    else:
        raise InputError(f"contact faces must be triangles or quadrilaterals, got {faces.shape[1]} "
                         "nodes per face")
    pos = np.searchsorted(nodes, faces)
    if xp is np:
        out = np.zeros(len(nodes))
        np.add.at(out, pos.ravel(), per_node.ravel())
        return out
    return jnp.zeros(len(nodes)).at[pos.ravel()].add(per_node.ravel())
