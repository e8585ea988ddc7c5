"""Writing results: VTU and PVD time series for ParaView (:mod:`.vtu`), CSV tables,
JSON summaries. Meshes are read by :mod:`signorini.fem.meshfile`."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..contact.friction import STATUS_NAMES
from . import helper
from .atomic import atomic
from ..errors import InputError
from ..fem.mesh import parts
from .vtu import write_unstructured


def _vec3(a):
    """Points or vectors with three components (2-D ones get z = 0)."""
    a = np.asarray(a, dtype=float)
    return a if a.shape[1] == 3 else np.column_stack([a, np.zeros(len(a))])


def bodies(solution) -> list:
    """The bodies of the solution's mesh, (name, nodes, cells) (:func:`signorini.fem.mesh.parts`)."""
    m = solution.model
    kept = m.cache.get("vtu-bodies")
    if kept is None:
        kept = m.cache["vtu-bodies"] = parts(m.problem.mesh)
    return kept


def write_vtu(solution, path, i: int = -1, body: str | None = None) -> Path:
    """Write one increment as VTU: displacement, contact tractions and gap (point
    data; with friction also ``contact_status`` 0 open / 1 stick / 2 slip and
    ``slip_increment``; in 3-D the contact force vector ``traction`` and two
    components of p_T and of the slip, in each node's tangent basis), Cauchy stress (cell data), and the sensitivity of each
    of them with respect to every design parameter (``d<field>_d<name>``); the
    switch points of the increment (docs/theory.md §11: point data ``switch`` 1
    weakly active, 2 stick/slip switch, 3 under a master surface's end, 4
    partner change of a pair; cell data ``plastic_switch``) and, on
    the last increment, an adjoint shape gradient if one was attached
    (``solution.shape_gradient``, (n_nodes, dim)). A mesh of several bodies
    (:func:`signorini.fem.mesh.parts`) gets the cell data ``body`` (their index);
    with ``body`` (a name) only that body's nodes and cells are written. The
    fields are computed here; the file is written by the output helper if one
    runs (:mod:`signorini.post.helper`)."""
    if not helper.discarding():
        _write_part(Path(path), _fields(solution, i), bodies(solution), body)
    return Path(path)


def _fields(solution, i: int) -> tuple:
    """The points, cell kind, connectivity, point data and cell data of increment
    ``i`` on the whole mesh (what :func:`write_vtu` writes)."""
    m = solution.model
    X = solution.reference()
    point = {"displacement": _vec3(solution.displacement(i))}
    for name in solution.names:
        point[f"ddisplacement_d{name}"] = _vec3(solution.displacement_sensitivity(name, i))
    for k in range(len(m.surfaces)):
        c = solution.contact(i, k)
        tag = "" if k == 0 else f"_{k}"
        keys = ["p_N", "p_T", "gap"] + [f for f in c if f.startswith(("dp_", "dgap_"))]
        for key in keys + (["traction"] if "traction" in c else []):  # 3-D: the force vector
            arr = np.zeros((m.n_nodes,) + np.shape(c[key])[1:])
            arr[c["node"]] = c[key]
            point[key + tag] = arr
        if "status" in c:  # friction: 0 open, 1 stick, 2 slip; -1 off the contact surface

            code = -np.ones(m.n_nodes)
            code[c["node"]] = [STATUS_NAMES.index(v) for v in c["status"]]
            point["contact_status" + tag] = code
            slip = np.zeros((m.n_nodes,) + np.shape(c["slip"])[1:])
            slip[c["node"]] = c["slip"]
            point["slip_increment" + tag] = slip
    inc = solution.increments[i]
    if inc.switches is not None:  # docs/theory.md §11, §13
        code = np.zeros(m.n_nodes)
        for key, value in (("partner_change", 4), ("master_end", 3)):
            for nodes in inc.switches.get(key, ()):
                code[nodes] = value
        for nodes in inc.switches["stick_slip"]:
            code[nodes] = 2
        for nodes in inc.switches["weakly_active"]:
            code[nodes] = 1
        point["switch"] = code
    stress, dstress = solution.stress(i)
    cell = {"cauchy_stress": [stress.reshape(-1, 9)]}
    for name, d in dstress.items():
        cell[f"dcauchy_stress_d{name}"] = [np.asarray(d).reshape(-1, 9)]
    alpha = m.material.equivalent_plastic_strain
    state = solution.state_after(range(len(solution.increments))[i])
    if alpha is not None and m.n_state and state is not None:
        # Gauss-point history after the increment, averaged per cell
        cell["equivalent_plastic_strain"] = [m.gauss_mean(np.asarray(state[2])[..., 9])]
        if inc.state_sens is not None:
            for k, name in enumerate(solution.names):
                cell[f"dequivalent_plastic_strain_d{name}"] = [
                    m.gauss_mean(np.asarray(inc.state_sens[2])[k, ..., 9])]
    if inc.switches is not None and m.n_state:
        on = np.zeros(len(m.conn))
        on[inc.switches["elastic_plastic"]] = 1
        cell["plastic_switch"] = [on]
    if getattr(solution, "shape_gradient", None) is not None and i in (-1, len(solution.increments) - 1):
        point["adjoint_shape_gradient"] = _vec3(solution.shape_gradient)
    if m.dim == 2:
        kind = "quad"
    elif m.mixed:  # one kind per cell
        kind = np.empty(len(m.conn), dtype=object)
        for g in m.groups:
            kind[g.idx] = g.kin.cell.name
    else:
        kind = m.kinematics.cell.name  # "hexahedron" or "tetra"
    conn = np.asarray(m.conn)
    parts_ = bodies(solution)
    if len(parts_) > 1:
        index = np.zeros(len(conn))
        for k, (_, _, cells) in enumerate(parts_):
            index[cells] = k
        cell["body"] = [index]
    return X, kind, conn, point, cell


def _write_part(path: Path, fields: tuple, parts_: list, body: str | None) -> None:
    """Write the fields of one increment (:func:`_fields`), all bodies or one."""
    X, kind, conn, point, cell = fields
    if body is not None:
        found = [p for p in parts_ if p[0] == body]
        if not found:
            raise InputError(f"write_vtu: no body {body!r}; the mesh's bodies: {[p[0] for p in parts_]}")
        _, nodes, cells = found[0]
        new = np.full(len(X), -1)
        new[nodes] = np.arange(nodes.size)
        X, conn = np.asarray(X)[nodes], new[conn[cells]]
        if not isinstance(kind, str):  # a mixed mesh: a body is of one kind
            kind = list(kind[cells])
            kind = kind[0] if len(set(kind)) == 1 else kind
            conn = conn[:, :4] if kind == "tetra" else conn
        point = {k: np.asarray(v)[nodes] for k, v in point.items()}
        cell = {k: [np.asarray(v[0])[cells]] for k, v in cell.items()}
    helper.run("vtu", path, _vec3(X), kind if isinstance(kind, str) else list(kind), conn, point,
               cell)


def _write_vtu_arrays(path, points, cell_kind: str, cells, point_data: dict, cell_data: dict) -> None:
    """Write a VTU file (atomically) of one cell block with its point and cell data
    (:func:`signorini.post.vtu.write_unstructured`)."""
    with atomic(path) as tmp:
        write_unstructured(tmp, points, cell_kind, cells, point_data, cell_data)


def write_pvd(solution, path, increments=None) -> Path:
    """Write a ParaView time series: one VTU per converged increment and a PVD file.

    Each increment ``k`` (1-based position in ``solution.increments``) is
    written by :func:`write_vtu` as ``<stem>_<k:04d>.vtu`` in the directory of
    the ``.pvd`` file; the PVD collection lists them (relative file names) with
    ``timestep`` = the increment's load factor t. Open the ``.pvd`` in
    ParaView to step through the load history. A mesh of several bodies is
    written one file per body, ``<stem>_<body>_<k:04d>.vtu``, each body a
    ``part`` of the collection (a block of its own in ParaView).

    Args:
        solution: a :class:`~signorini.algorithms.solution.Solution` (possibly the
            ``partial`` of a :class:`~signorini.errors.ConvergenceError`).
        path: the ``.pvd`` file to write (its directory must exist).
        increments: indices into ``solution.increments`` to write (default: all).

    Returns:
        The path of the ``.pvd`` file.
    """

    path = Path(path)
    n = len(solution.increments)
    if increments is None:
        increments = range(n)
    idx = []
    for i in increments:
        try:
            idx.append(range(n)[i])
        except (IndexError, TypeError):
            raise InputError(f"write_pvd: increment {i!r} does not exist; the solution has {n} "
                             "converged increment(s)") from None
    for i in idx:
        _write_increment(solution, path, i)
    return _write_collection(solution, path, idx)


def _series_files(solution, path: Path, i: int) -> list[tuple[str | None, Path]]:
    """(body, VTU file) of increment ``i`` of the series ``path``: one file (body
    None), or one per body of a mesh of several."""
    parts_ = bodies(solution)
    out = []
    for body in [p[0] for p in parts_] if len(parts_) > 1 else [None]:
        stem = path.stem if body is None else f"{path.stem}_{body}"
        out.append((body, path.with_name(f"{stem}_{i + 1:04d}.vtu")))
    return out


def _write_increment(solution, path: Path, i: int) -> None:
    """The VTU files of increment ``i`` of the series ``path``."""
    if helper.discarding():
        return
    fields = _fields(solution, i)  # once per increment, whatever the number of bodies
    for body, vtu in _series_files(solution, path, i):
        _write_part(vtu, fields, bodies(solution), body)


def _write_collection(solution, path: Path, idx) -> Path:
    """The ``.pvd`` file of the series ``path`` listing increments ``idx``."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for i in idx:
        t = float(solution.increments[i].t)
        for part, (_, vtu) in enumerate(_series_files(solution, path, i)):
            lines.append(f'    <DataSet timestep="{t!r}" group="" part="{part}" '
                         f'file={quoteattr(vtu.name)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    with atomic(path) as tmp:
        tmp.write_text("\n".join(lines))
    return path


class Series:
    """A ParaView series (:func:`write_pvd`) written while a solve converges its
    increments: :meth:`add` writes one increment's VTU files and the ``.pvd``
    listing the increments written so far, :meth:`complete` those not yet written
    and the ``.pvd`` of them all. The files are those of :func:`write_pvd` of the
    whole solution; the last increment's are written again once an adjoint shape
    gradient is attached to the solution (:func:`write_vtu`)."""

    def __init__(self, path):
        self.path = Path(path)
        #: increment index -> (the Increment, the shape gradient) its files show
        self._written: dict[int, tuple] = {}

    def _shown(self, solution, i: int) -> tuple:
        last = i == len(solution.increments) - 1
        return solution.increments[i], getattr(solution, "shape_gradient", None) if last else None

    def _write(self, solution, i: int) -> None:
        _write_increment(solution, self.path, i)
        self._written[i] = self._shown(solution, i)

    def add(self, solution, i: int = -1) -> Path:
        """Write increment ``i`` (default: the last) and the ``.pvd`` of the
        increments up to it."""
        i = range(len(solution.increments))[i]
        self._write(solution, i)
        return _write_collection(solution, self.path, range(i + 1))

    def complete(self, solution) -> Path:
        """Write the increments of ``solution`` not yet written from the same
        increment, and the ``.pvd`` of them all; the path of the ``.pvd``."""
        n = len(solution.increments)
        for i in range(n):
            done = self._written.get(i)
            now = self._shown(solution, i)
            if done is None or done[0] is not now[0] or done[1] is not now[1]:
                self._write(solution, i)
        return _write_collection(solution, self.path, range(n))


def write_csv(path, columns: dict) -> Path:
    """Write equal-length 1-D arrays (or lists) as CSV columns, header = keys."""
    path = Path(path)
    keys = list(columns)
    rows = zip(*[columns[k] for k in keys])
    with atomic(path) as tmp, open(tmp, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(keys)
        for r in rows:
            wr.writerow([v if isinstance(v, str) else f"{float(v) + 0.0:.12g}" for v in r])  # no -0
    return path


def write_json(path, data: dict) -> Path:
    path = Path(path)

    def conv(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(type(o))

    text = json.dumps(data, indent=2, default=conv) + "\n"
    with atomic(path) as tmp:
        tmp.write_text(text)
    return path
