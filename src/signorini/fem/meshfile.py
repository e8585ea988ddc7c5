"""Reading meshes: gmsh ``.msh`` and the other formats meshio knows, into a
:class:`~signorini.fem.mesh.Mesh` with named edge and node sets, or, for a file
of hexahedra or tetrahedra, a :class:`~signorini.fem.mesh3d.Mesh3D` with named
face and node sets."""

from __future__ import annotations

import contextlib
import io as _stdio
import logging
import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import InputError, SignoriniWarning
from .mesh import Mesh, signed_jacobians
from .mesh3d import Mesh3D, cell_jacobians, face_key

log = logging.getLogger("signorini")

_MESH_HINT = ("signorini reads 2-D meshes of quadrilaterals and 3-D meshes of hexahedra or tetrahedra, "
              "e.g. gmsh .msh (in gmsh: Recombine Surface for quadrilaterals, then File > Export as .msh)")


def _meshio():
    import meshio  # noqa: PLC0415  (lazy: only a run that reads a mesh file needs it)

    return meshio


def _mesh_formats(path: Path) -> list[str]:
    """meshio formats that match the file's extension (longest suffix first, as meshio)."""
    ext, out = "", []
    for suffix in reversed(path.suffixes):
        ext = (suffix + ext).lower()
        out += _meshio().extension_to_filetypes.get(ext, [])
    return out


def _meshio_read(path: Path):
    """``meshio.read`` with every failure turned into an :class:`InputError`.

    meshio prints its errors and calls ``sys.exit`` when no reader accepts a
    file; here each candidate format is tried with meshio's console output
    captured (what it prints on success becomes a :class:`SignoriniWarning`).
    """

    if not path.exists():
        where = "" if path.is_absolute() else f" (relative to the current directory {os.getcwd()})"
        raise InputError(f"{path}: mesh file not found{where}; check the file name and path")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a mesh file; give the path of the mesh file")
    formats = _mesh_formats(path)
    if not formats:
        known = ", ".join(sorted(_meshio().extension_to_filetypes))
        raise InputError(f"{path}: unknown mesh file extension {path.suffix or '(none)'!r}; use a mesh "
                         f"format meshio knows ({known}); {_MESH_HINT}")
    try:
        size = path.stat().st_size
    except OSError as e:
        raise InputError(f"{path}: cannot access the mesh file ({e.strerror or e})") from None
    if size == 0:
        raise InputError(f"{path}: the mesh file is empty; write the mesh again ({_MESH_HINT})")
    problems = []
    for fmt in formats:
        buf = _stdio.StringIO()
        try:
            with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
                m = _meshio().read(path, file_format=fmt)
        except (Exception, SystemExit) as e:  # meshio exits when a reader gives up
            detail = str(e) if not isinstance(e, SystemExit) else ""
            detail = " ".join((buf.getvalue() + " " + detail).split()) or type(e).__name__
            problems.append(f"as {fmt}: {detail}")
            continue
        for line in buf.getvalue().splitlines():
            if line.strip():
                _warn(f"{path}: meshio: {line.strip()}")
        return m
    raise InputError(f"{path}: not a readable mesh file ({'; '.join(problems)}); check that the file "
                     f"is a complete mesh in the format of its extension. {_MESH_HINT}")


def read_mesh(path, dim: int | None = None) -> "Mesh | Mesh3D":
    """Read a mesh file (gmsh .msh or any format meshio knows) with its named sets:
    a 2-D file gives a :class:`~signorini.fem.mesh.Mesh`, a 3-D file a
    :class:`~signorini.fem.mesh3d.Mesh3D`.

    A file's dimension is that of its cells: 3 if it has volume cells, 2 if it has
    surface cells and no volume cells. ``dim`` (2 or 3) demands one: a file of the
    other dimension is then an error, before its cells are checked (a plane-strain
    or axisymmetric problem asks for ``dim=2``). ``None`` (the default) takes either.

    **2-D** (plane strain and axisymmetry, the mesh in the x-y plane, z = 0; for
    axisymmetry x is the radius r and y the axis z): 4-node quadrilaterals become
    the cells, renumbered counter-clockwise if needed. Every named physical group
    of line elements (gmsh ``$PhysicalNames``) becomes an edge set (oriented
    counter-clockwise from its cell: the body on the left) and a node set of the
    same name; named groups of vertex elements become node sets, and named groups
    of quadrilaterals (physical surfaces: the bodies of a file with several) the
    node set of their cells (what :class:`~signorini.materials.Bodies` names).

    **3-D**: 8-node hexahedra and 4-node tetrahedra become the cells, renumbered
    where their volume is negative (a file with both: a mixed mesh, hexahedra first,
    each body of one kind; see :mod:`signorini.fem.mesh3d`). Every named physical
    group of faces (quadrilaterals for hexahedra, triangles for tetrahedra, one
    kind per group) becomes a face set, numbered outward as in the cell that owns each face, and a node set of the
    same name; named groups of volumes (the bodies), lines and points become node
    sets.

    In both, nodes that belong to no cell (gmsh writes one for every geometry
    point, e.g. the centre of an arc) are dropped and the remaining nodes
    renumbered in file order, since they would carry no stiffness; the node set
    ``"all"`` holds every node.

    Raises:
        InputError: the file is missing, empty, of an unknown format, not a
            valid mesh, has no cells of a body (only lines or points), is not of
            dimension ``dim`` (the error's ``dim`` attribute is then the file's
            dimension); a 2-D file that is not planar or has no quadrilaterals; a
            3-D file with other volume cells, or with hexahedra and tetrahedra
            sharing nodes; a set that is not on the boundary. The message names the file.
    """

    if dim not in (None, 2, 3):
        raise InputError(f"read_mesh: dim must be 2, 3 or None (either), got {dim!r}")
    path = Path(path)
    m = _meshio_read(path)
    if _dimension(path, m, dim) == 3:
        return _mesh_3d(path, m)
    nodes, cells, used, new = _quad_mesh(path, m)
    names = {int(v[0]): k for k, v in (m.field_data or {}).items()}
    phys = m.cell_data.get("gmsh:physical")
    edge_sets, node_sets = {}, {}
    if phys is not None:
        try:
            probe = Mesh(nodes, cells)
        except InputError as e:
            raise type(e)(f"{path}: {e}") from None
        boundary = {tuple(sorted(e)): tuple(e) for e in probe.boundary_edges()}
        for block, tags in zip(m.cells, phys):
            for tag in np.unique(tags):
                name = names.get(int(tag), f"physical_{int(tag)}")
                _add_set(path, name, block.type, block.data[tags == tag], used, new, nodes, boundary,
                         edge_sets, node_sets)
    node_sets.setdefault("all", np.arange(len(nodes)))
    try:
        return Mesh(nodes, cells, node_sets, edge_sets)
    except InputError as e:
        raise type(e)(f"{path}: {e}") from None


def _cell_dimension(kind: str) -> int:
    """The topological dimension of a meshio cell type (0 points, 1 lines, 2 faces, 3 volumes)."""
    known = getattr(getattr(_meshio(), "_mesh", None), "topological_dimension", {})
    if kind in known:
        return int(known[kind])
    name = kind.lower().removeprefix("vtk_lagrange_")
    for prefix, d in (("vertex", 0), ("line", 1), ("curve", 1), ("triangle", 2), ("quad", 2),
                      ("polygon", 2), ("tetra", 3), ("hexahedron", 3), ("wedge", 3),
                      ("pyramid", 3), ("polyhedron", 3)):
        if name.startswith(prefix):
            return d
    return 2  # an unknown kind: reported as an unsupported cell type of a 2-D mesh


def _count(m) -> str:
    """The cells of a meshio mesh, e.g. '12 hexahedron, 8 quad'."""
    n = Counter()
    for c in m.cells:
        n[c.type] += len(c.data)
    return ", ".join(f"{v} {k}" for k, v in sorted(n.items(), key=lambda kv: -kv[1]))


def _dimension(path: Path, m, dim: int | None) -> int:
    """The dimension of a mesh file (3: volume cells, 2: faces, no volumes), checked
    against the one asked for (None: either)."""
    dims = {_cell_dimension(c.type) for c in m.cells if len(c.data)}
    found = max(dims, default=0)
    if found < 2:
        what = f"no cells of a body (cells: {_count(m)})" if dims else "no cells at all"
        raise InputError(f"{path}: {what}; a mesh file needs the cells of a body: quadrilaterals "
                         "for a 2-D mesh, hexahedra or tetrahedra for a 3-D one (in gmsh: Mesh > 2D "
                         "with Recombine Surface, or Mesh > 3D), lines and points only naming sets")
    if dim is not None and found != dim:
        if dim == 2:
            err = InputError(f"{path}: a 3-D mesh (cells: {_count(m)}), where a 2-D mesh of "
                             "quadrilaterals in the z = 0 plane is expected")
        else:
            err = InputError(f"{path}: a 2-D mesh (cells: {_count(m)}; no volume cells), where a 3-D "
                             "mesh of hexahedra or tetrahedra is expected; read a 2-D mesh with "
                             "read_mesh, or mesh the volume (in gmsh: Mesh > 3D)")
        err.dim = found
        raise err
    return found


def _quad_mesh(path, m):
    """(nodes (n, 2), cells counter-clockwise, used (the file's nodes a quad uses),
    new (file node -> mesh node, -1 for dropped ones)) of a meshio mesh."""
    quads = [c.data for c in m.cells if c.type == "quad"]
    if not quads:
        kinds = sorted({c.type for c in m.cells})
        raise InputError(f"{path}: no quadrilateral cells (found {kinds}); a 2-D mesh is made of "
                         "4-node quadrilaterals (in gmsh: Recombine Surface)")
    other = sorted({c.type for c in m.cells} - {"quad", "line", "vertex"})
    if other:
        raise InputError(f"{path}: unsupported cell types {other}; only quad (+ line/vertex sets)")
    points = np.asarray(m.points, dtype=float)
    if points.ndim != 2 or points.shape[1] < 2:
        raise InputError(f"{path}: points have shape {points.shape}; expected 2-D or 3-D coordinates")
    if points.shape[1] > 2 and np.ptp(points[:, 2]) > 1e-12 * max(np.ptp(points[:, :2]), 1e-300):
        raise InputError(f"{path}: the mesh is not planar in the x-y plane (z varies from "
                         f"{points[:, 2].min():.6g} to {points[:, 2].max():.6g}); a 2-D mesh lies in the "
                         "z = 0 plane: draw the body there (a 3-D body is a mesh of its volume: "
                         "hexahedra or tetrahedra, in gmsh Mesh > 3D)")
    cells = np.concatenate(quads).astype(np.int64)
    # drop nodes that no quad uses and renumber (set data uses the same map)
    used = np.zeros(len(points), bool)
    used[cells.ravel()] = True
    new = -np.ones(len(points), np.int64)
    new[used] = np.arange(used.sum())
    nodes = points[used, :2]
    cells = new[cells]
    det = signed_jacobians(nodes, cells)
    flip = det.sum(axis=1) < 0
    cells[flip] = cells[flip][:, ::-1]
    return nodes, cells, used, new


def _warn(message: str) -> None:
    """A suspicious mesh file: a :class:`SignoriniWarning` (which a library user can
    filter) and an INFO line of the ``signorini`` log (which the command shows)."""
    log.info("warning: %s", message)
    warnings.warn(message, SignoriniWarning, stacklevel=3)


def _add_set(path, name, kind, data, used, new, nodes, boundary, edge_sets, node_sets) -> None:
    """Add one physical group's block (line: an edge set and its node set; vertex: a
    node set) to the sets, checking that lines lie on the boundary."""
    if kind == "line" and (~used[data]).any():
        raise InputError(f"{path}: edge set {name!r} has nodes that belong to no "
                         "quadrilateral; put the group on the meshed body's boundary")
    if kind == "vertex" and (~used[data]).any():
        _warn(f"{path}: point set {name!r}: {int((~used[data]).sum())} node(s) belong to no "
              "quadrilateral (e.g. an arc centre) and are left out of the set")
        data = data[used[data]]
        if not data.size:
            return
    data = new[data]
    if kind == "line":
        edges = []
        for a, b in data:
            key = (min(a, b), max(a, b))
            if key not in boundary:
                xa, xb = (nodes[n].round(6).tolist() for n in (a, b))
                raise InputError(f"{path}: edge set {name!r} has the edge {xa}-{xb} that "
                                 "is not on the boundary of the quad mesh; loads and "
                                 "contact need boundary edges")
            edges.append(boundary[key])
        # a group may span several blocks (one per gmsh entity): merge them
        edge_sets[name] = np.concatenate(
            [edge_sets.get(name, np.empty((0, 2), np.int64)), np.asarray(edges, np.int64)])
        node_sets[name] = np.union1d(node_sets.get(name, []), data).astype(np.int64)
    elif kind == "vertex":
        node_sets[name] = np.union1d(node_sets.get(name, []), data).astype(np.int64)
    elif kind == "quad":  # a physical surface (a body): the node set of its cells
        node_sets[name] = np.union1d(node_sets.get(name, []), data.ravel()).astype(np.int64)


#: the 3-D cells read, and the face cells that name their boundary sets
_VOLUME = {"hexahedron": "quad", "tetra": "triangle"}
#: a node order of the same cell with the opposite orientation
_MIRROR = {"hexahedron": [4, 5, 6, 7, 0, 1, 2, 3], "tetra": [0, 2, 1, 3]}


def read_mesh_3d(path) -> Mesh3D:
    """:func:`read_mesh` with ``dim=3``: a 3-D mesh of 8-node hexahedra or 4-node
    tetrahedra with its face and node sets, and an
    :class:`~signorini.errors.InputError` for a 2-D file (no volume cells).
    ``signorini.read_mesh(path)`` reads a 3-D file the same way; this name is kept
    for the code that calls it.
    """
    return read_mesh(path, dim=3)


def _mesh_3d(path, m) -> Mesh3D:
    types = {c.type for c in m.cells}
    kinds = sorted(types & set(_VOLUME))
    if not kinds:  # volume cells, none of them hexahedra or tetrahedra
        raise InputError(f"{path}: no hexahedra or tetrahedra (found {sorted(types)}); signorini "
                         "reads 3-D meshes of 8-node hexahedra or 4-node tetrahedra (in gmsh: mesh "
                         "order 1; recombine the volume for hexahedra, or do not for tetrahedra)")
    kind = " and ".join(kinds)
    faces_of = {_VOLUME[k] for k in kinds}
    other = sorted(types - set(kinds) - faces_of - {"line", "vertex"})
    if other:
        raise InputError(f"{path}: unsupported cell types {other} beside {kind}; signorini reads "
                         f"8-node hexahedra or 4-node tetrahedra with {' and '.join(sorted(faces_of))} "
                         "face sets (second-order cells: mesh with order 1; pyramids and prisms: "
                         "mesh each body with one kind)")
    points = np.asarray(m.points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{path}: points have shape {points.shape}; a 3-D mesh needs x, y, z")
    blocks = {k: np.concatenate([c.data for c in m.cells if c.type == k]).astype(np.int64)
              for k in kinds}
    used = np.zeros(len(points), bool)
    for c in blocks.values():
        used[c.ravel()] = True
    new = -np.ones(len(points), np.int64)
    new[used] = np.arange(used.sum())
    nodes = points[used]
    for k, c in blocks.items():
        c = new[c]
        flip = cell_jacobians(nodes, c).sum(axis=1) < 0
        c[flip] = c[flip][:, _MIRROR[k]]
        blocks[k] = c
    # hexahedra, then tetrahedra padded as Mesh3D stores them in a mixed mesh
    cells = blocks[kinds[0]] if len(kinds) == 1 else np.concatenate(
        [blocks["hexahedron"], np.concatenate([blocks["tetra"], -np.ones((len(blocks["tetra"]), 4),
                                                                         np.int64)], axis=1)])
    try:
        probe = Mesh3D(nodes, cells)
    except InputError as e:
        raise type(e)(f"{path}: {e}") from None
    boundary = {face_key(f): f for f in probe.boundary_faces()}
    names = {int(v[0]): k for k, v in (m.field_data or {}).items()}
    phys = m.cell_data.get("gmsh:physical")
    face_sets, node_sets = {}, {}
    for block, tags in zip(m.cells, phys if phys is not None else []):
        for tag in np.unique(tags):
            name = names.get(int(tag), f"physical_{int(tag)}")
            data = block.data[tags == tag]
            if (~used[data]).any():
                if block.type == "vertex":
                    data = data[used[data]]
                else:
                    raise InputError(f"{path}: set {name!r} has nodes that belong to no {kind}; put "
                                     "the group on the meshed body")
            data = new[data]
            if block.type in faces_of:
                faces = []
                for f in data:
                    own = boundary.get(face_key(f))
                    if own is None:
                        raise InputError(f"{path}: face set {name!r} has the face at "
                                         f"{nodes[f].round(6).tolist()} that is not on the boundary "
                                         f"of the {kind} mesh; loads and contact need boundary faces")
                    faces.append(own)
                if name in face_sets and face_sets[name].shape[1] != len(faces[0]):
                    raise InputError(f"{path}: face set {name!r} has triangles and quadrilaterals; "
                                     "a face set is of one kind: name the faces of the "
                                     "tetrahedra and of the hexahedra apart")
                face_sets[name] = np.concatenate(
                    [face_sets.get(name, np.empty((0, len(f)), np.int64)), np.asarray(faces)])
            node_sets[name] = np.union1d(node_sets.get(name, []), data.ravel()).astype(np.int64)
    node_sets.setdefault("all", np.arange(len(nodes)))
    try:
        return Mesh3D(nodes, cells, node_sets, face_sets)
    except InputError as e:
        raise type(e)(f"{path}: {e}") from None
