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
from ..fem.solid import face_areas  # noqa: F401  (the 3-D areas: with the 3-D cells)


def contact_nodes(edges: np.ndarray) -> np.ndarray:
    """Sorted unique nodes of an edge set."""
    return np.unique(edges.ravel())


def equivalent_areas(X, edges: np.ndarray, nodes: np.ndarray | None = None, kinematics=None):
    """A_S (n_contact,) for the nodes ``nodes`` of the edge or face set ``edges``.

    Args:
        X: (n_nodes, 2) reference coordinates in 2-D and axisymmetry, (n_nodes, 3)
            in 3-D (JAX or NumPy, may depend on phi).
        edges: the boundary of the contact surface: (n_edges, 2) edges in 2-D and
            axisymmetry, (n_faces, 4) quadrilaterals or (n_faces, 3) triangles in 3-D.
        nodes: (n_contact,) sorted contact nodes (default ``contact_nodes(edges)``).
        kinematics: :class:`~signorini.fem.kinematics.PlaneStrain` (default, per unit
            thickness), :class:`~signorini.fem.kinematics.Axisymmetric` (full 2 pi)
            or a 3-D body's (:class:`signorini.fem.solid.Solid3D`: each node's share
            of its faces' areas, :func:`signorini.fem.solid.face_areas`).
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
    if X.shape[1] == 3:  # faces: the area-weighted normals of the faces at each node
        Xf = X[edges]
        n = xp.cross(Xf[:, 2] - Xf[:, 0], Xf[:, -1] - Xf[:, 1]) if edges.shape[1] == 4 else \
            xp.cross(Xf[:, 1] - Xf[:, 0], Xf[:, 2] - Xf[:, 0])
        n = xp.repeat(n[:, None, :], edges.shape[1], axis=1).reshape(-1, 3)
        flat = pos.ravel()
        if xp is np:
            N = np.zeros((len(nodes), 3))
            np.add.at(N, flat, n)
        else:
            N = jnp.zeros((len(nodes), 3)).at[flat].add(n)
        return N / xp.linalg.norm(N, axis=1, keepdims=True)
    d = X[edges[:, 1]] - X[edges[:, 0]]
    n = xp.stack([d[:, 1], -d[:, 0]], axis=1)
    if xp is np:
        N = np.zeros((len(nodes), 2))
        np.add.at(N, pos[:, 0], n)
        np.add.at(N, pos[:, 1], n)
    else:
        N = jnp.zeros((len(nodes), 2)).at[pos[:, 0]].add(n).at[pos[:, 1]].add(n)
    return N / xp.linalg.norm(N, axis=1, keepdims=True)

