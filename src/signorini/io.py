"""Writing results: VTU for ParaView (meshio), CSV tables, JSON summaries."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import TYPE_CHECKING

import meshio
import numpy as np

if TYPE_CHECKING:
    from .mesh import Mesh


def read_mesh(path) -> "Mesh":
    """Read a Q4 mesh (gmsh .msh or any meshio format) with named sets.

    Quadrilateral cells become the mesh; every named physical group of line
    elements (gmsh ``$PhysicalNames``) becomes an edge set (oriented
    counter-clockwise from its cell) and a node set of the same name; named
    groups of vertex elements become node sets. Cells are renumbered
    counter-clockwise if needed.
    """
    from .errors import InputError
    from .mesh import Mesh, signed_jacobians

    m = meshio.read(path)
    quads = [c.data for c in m.cells if c.type == "quad"]
    if not quads:
        kinds = sorted({c.type for c in m.cells})
        raise InputError(f"{path}: no quadrilateral cells (found {kinds}); signorini needs Q4 meshes "
                         "(in gmsh: Recombine Surface)")
    other = sorted({c.type for c in m.cells} - {"quad", "line", "vertex"})
    if other:
        raise InputError(f"{path}: unsupported cell types {other}; only quad (+ line/vertex sets)")
    nodes = np.asarray(m.points)[:, :2]
    cells = np.concatenate(quads).astype(np.int64)
    det = signed_jacobians(nodes, cells)
    flip = det.sum(axis=1) < 0
    cells[flip] = cells[flip][:, ::-1]
    names = {int(v[0]): k for k, v in (m.field_data or {}).items()}
    phys = m.cell_data.get("gmsh:physical")
    edge_sets, node_sets = {}, {"all": np.arange(len(nodes))}
    if phys is not None:
        probe = Mesh(nodes, cells)
        boundary = {tuple(sorted(e)): tuple(e) for e in probe.boundary_edges()}
        for block, tags in zip(m.cells, phys):
            for tag in np.unique(tags):
                name = names.get(int(tag), f"physical_{int(tag)}")
                data = block.data[tags == tag]
                if block.type == "line":
                    edges = []
                    for a, b in data:
                        key = (min(a, b), max(a, b))
                        if key not in boundary:
                            raise InputError(f"{path}: edge set {name!r} has edge ({a}, {b}) that is "
                                             "not on the boundary of the quad mesh")
                        edges.append(boundary[key])
                    edge_sets[name] = np.asarray(edges, dtype=np.int64)
                    node_sets[name] = np.unique(data)
                elif block.type == "vertex":
                    node_sets[name] = np.unique(data)
    return Mesh(nodes, cells, node_sets, edge_sets)


def _vec3(a):
    a = np.asarray(a, dtype=float)
    return np.column_stack([a, np.zeros(len(a))])


def write_vtu(solution, path, i: int = -1) -> Path:
    """Write one increment as VTU: displacement, contact tractions and gap (point
    data; with friction also ``contact_status`` 0 open / 1 stick / 2 slip and
    ``slip_increment``), Cauchy stress (cell data), and the sensitivity of each
    of them with respect to every design parameter (``d<field>_d<name>``)."""
    path = Path(path)
    m = solution.model
    X = solution.reference()
    point = {"displacement": _vec3(solution.displacement(i))}
    for name in solution.names:
        point[f"ddisplacement_d{name}"] = _vec3(solution.displacement_sensitivity(name, i))
    for k in range(len(m.surfaces)):
        c = solution.contact(i, k)
        tag = "" if k == 0 else f"_{k}"
        for key in ["p_N", "p_T", "gap"] + [f for f in c if f.startswith(("dp_", "dgap_"))]:
            arr = np.zeros(m.n_nodes)
            arr[c["node"]] = c[key]
            point[key + tag] = arr
        if "status" in c:  # friction: 0 open, 1 stick, 2 slip; -1 off the contact surface
            from .contact.friction import STATUS_NAMES

            code = -np.ones(m.n_nodes)
            code[c["node"]] = [STATUS_NAMES.index(v) for v in c["status"]]
            point["contact_status" + tag] = code
            slip = np.zeros(m.n_nodes)
            slip[c["node"]] = c["slip"]
            point["slip_increment" + tag] = slip
    stress, dstress = solution.stress(i)
    cell = {"cauchy_stress": [stress.reshape(-1, 9)]}
    for name, d in dstress.items():
        cell[f"dcauchy_stress_d{name}"] = [np.asarray(d).reshape(-1, 9)]
    mesh = meshio.Mesh(_vec3(X), [("quad", m.conn)], point_data=point, cell_data=cell)
    mesh.write(path)
    return path


def write_csv(path, columns: dict) -> Path:
    """Write equal-length 1-D arrays (or lists) as CSV columns, header = keys."""
    path = Path(path)
    keys = list(columns)
    rows = zip(*[columns[k] for k in keys])
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(keys)
        for r in rows:
            wr.writerow([v if isinstance(v, str) else f"{float(v):.12g}" for v in r])
    return path


def write_json(path, data: dict) -> Path:
    path = Path(path)

    def conv(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(type(o))

    path.write_text(json.dumps(data, indent=2, default=conv) + "\n")
    return path
