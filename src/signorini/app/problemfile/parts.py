"""The pieces of a problem file that depend on its dimension: meshes (2-D
rectangles, 3-D boxes, mesh files), bodies and their materials, rigid obstacles
and their motions along the load path (the schema: :mod:`signorini.app.problemfile`)."""

from __future__ import annotations

import ast
import warnings
from pathlib import Path

import numpy as np

from ...contact.obstacles import Circle, Line
from ...contact.obstacles3d import Cylinder, Implicit, Plane, Sphere
from ...errors import InputError, SignoriniWarning
from ...fem.loads import Ramp
from ...fem.loads import Table as PathTable
from ...fem.mesh import merge, rectangle
from ...fem.mesh3d import box, tetrahedra
from ...fem.meshfile import read_mesh
from ...linsolve import check_size
from ...materials import Bodies, J2Plasticity, LinearElastic, NeoHooke
from .expr import parse
from .reader import AXES, Reader, Table, intern, kind

MATERIALS = {"linear_elastic": LinearElastic, "neo_hooke": NeoHooke, "j2": J2Plasticity}
OBSTACLES = {2: ("circle", "line", "implicit"), 3: ("plane", "sphere", "cylinder", "implicit")}


# ---------------------------------------------------------------- meshes
def _file(rd: Reader, where: str, data):
    t = Table(rd, where, data, {"file", "dim"})
    name = t.string("file")
    dim = t.integer("dim", None) if t.has("dim") else None
    if dim not in (None, 2, 3):
        raise t.err("dim", f"must be 2 or 3, got {dim}")
    f = Path(name)
    if not f.is_absolute():
        f = rd.path.parent / f
    try:
        st = f.stat()
        key = ("file", str(f.resolve()), st.st_mtime_ns, st.st_size, dim)
    except OSError:
        key = None

    def make():
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", SignoriniWarning)
                mesh = read_mesh(f, dim=dim)
        except InputError as e:
            hint = (f"; [mesh] dim = {dim} asks for a {dim}-D mesh" if getattr(e, "dim", None)
                    not in (None, dim) and dim else "")
            raise type(e)(f"{rd.label}: {where} file = {name!r}: {e}{hint}") from None
        return mesh, tuple(str(w.message) for w in caught if issubclass(w.category, SignoriniWarning))

    mesh, notes = make() if key is None else intern(key, make)
    for message in notes:  # heard again when the file is loaded again
        rd.warnings.append(message)
        warnings.warn(message, SignoriniWarning, stacklevel=3)
    return mesh, {}


def _grid(rd: Reader, where: str, data):
    """A rectangle (2-D) or a box (3-D) with its shape parameters."""
    kind_ = data.get("type")
    dim = 3 if kind_ == "box" else 2
    axes = AXES[:dim]
    keys = {"type", *axes, *(f"n{a}" for a in axes)} | ({"tetrahedra"} if dim == 3 else set())
    t = Table(rd, where, data, keys, required=("type", *axes, *(f"n{a}" for a in axes)))
    t.string("type", choices=("rectangle", "box"))
    saved, rd.dim = rd.dim, 2
    try:
        specs = [t.vector(a, dim=2) for a in axes]
    finally:
        rd.dim = saved
    ns = [t.integer(f"n{a}", minimum=1) for a in axes]
    ends = [tuple(t.value(s) for s in sp) for sp in specs]
    for a, (lo, hi) in zip(axes, ends):
        if not hi > lo:
            raise t.err(a, f"must be increasing [{a}0, {a}1] with {a}0 < {a}1, got [{lo}, {hi}]")
    tets = t.boolean("tetrahedra", False) if dim == 3 else False
    n_nodes = int(np.prod([n + 1 for n in ns]))
    check_size(dim * n_nodes, force=rd.force_size, solver=rd.solver, lower_bound=True, dim=dim,
               what=f"{rd.label}: {where} {' x '.join(map(str, ns))}",
               hint=f"a coarser mesh (smaller {', '.join('n' + a for a in axes)})")

    def make():
        grids = [np.linspace(lo, hi, n + 1) for (lo, hi), n in zip(ends, ns)]
        mesh = rectangle(*grids) if dim == 2 else box(*grids)
        if tets:
            mesh = tetrahedra(mesh)
        X = mesh.nodes
        shape = {}
        for d, ((lo, hi), sp) in enumerate(zip(ends, specs)):
            s = (X[:, d] - lo) / (hi - lo)
            for spec, w in ((sp[0], 1 - s), (sp[1], s)):
                if isinstance(spec, str):
                    V = np.zeros_like(X)
                    V[:, d] = w
                    shape[spec] = shape.get(spec, 0.0) + V
        return mesh, shape

    return intern(("grid", tuple(specs), tuple(ends), tuple(ns), tets), make)


def mesh(rd: Reader, where: str, data):
    """(mesh, shape velocities) of a [mesh] table (or a body's mesh)."""
    if not isinstance(data, dict):
        raise rd.error(where, f"must be a table, got {kind(data)}")
    if "file" in data and "type" in data:
        raise rd.error(where, "give either file = \"...\" or type = \"rectangle\" / \"box\", not both")
    if "file" in data:
        return _file(rd, where, data)
    if "type" not in data:
        raise rd.error(where, "missing 'file' or 'type'; write file = \"body.msh\", type = "
                              "\"rectangle\" with x, y, nx, ny or type = \"box\" with x, y, z, nx, ny, nz")
    return _grid(rd, where, data)


def material(rd: Reader, where: str, data):
    """A material table: type, E, nu (and sigma_y, H for j2)."""
    ty = data.get("type") if isinstance(data, dict) else None
    extra = {"sigma_y", "H"} if ty == "j2" else set()
    t = Table(rd, where, data, {"type", "E", "nu"} | extra,
              required=("type", "E", "nu") + (("sigma_y",) if ty == "j2" else ()))
    cls = MATERIALS[t.string("type", choices=tuple(MATERIALS))]
    args = {k: t.spec(k) for k in ("E", "nu")}
    if cls is J2Plasticity:
        args.update(sigma_y=t.spec("sigma_y"), H=t.spec("H", 0.0))
    mat = intern(("material", cls, tuple(args.items())), lambda: cls(**args))
    try:
        mat.check(rd.params)
    except InputError as e:
        raise rd.error(where, f"{e}") from None
    return mat, t.value(args["E"])


def bodies(rd: Reader, doc: dict, items: list):
    """(mesh, shape, material, E) of [[body]] tables (with or without [mesh])."""
    names, meshes, mats, shapes, E = [], {}, {}, {}, None
    own = [isinstance(b, dict) and "mesh" in b for b in items]
    if any(own) and not all(own):
        raise rd.error("[[body]]", "either every body has its mesh (mesh = {...}) or none has "
                                   "(the bodies are node sets of [mesh], e.g. gmsh physical volumes)")
    if all(own) and "mesh" in doc:
        raise rd.error("[mesh]", "the bodies have their own meshes (in [[body]]); remove [mesh]")
    if not all(own) and "mesh" not in doc:
        raise InputError(f"{rd.label}: missing required table [mesh] (or a mesh in every [[body]])")
    whole = shape = None
    if not all(own):
        whole, shape = mesh(rd, "[mesh]", doc["mesh"])
        rd.dim = int(whole.nodes.shape[1])
    for k, data in enumerate(items):
        where = f"[[body]] #{k + 1}"
        t = Table(rd, where, data, {"name", "mesh", "material"}, required=("name", "material"))
        name = t.string("name")
        if name in names or "." in name:
            raise t.err("name", f"{name!r}: each body needs a unique name without '.'")
        names.append(name)
        if t.has("mesh"):
            m, s = mesh(rd, f"{where} mesh", data["mesh"])
            meshes[name], shapes[name] = m, s
        elif name not in whole.node_sets:
            raise t.err("name", f"{name!r} is not a node set of the mesh (a body is a named group "
                                f"of cells, e.g. a gmsh physical volume); the mesh has "
                                f"{', '.join(sorted(whole.node_sets))}")
        mat, e = material(rd, f"{where} material", t.get("material", None))
        mats[name] = mat
        E = e if E is None else min(E, e)
    if meshes:
        dims = {n: int(m.nodes.shape[1]) for n, m in meshes.items()}
        if len(set(dims.values())) > 1:
            raise rd.error("[[body]]", "the bodies' meshes must all be 2-D or all 3-D; got "
                           + ", ".join(f"{n} {d}-D" for n, d in dims.items()))
        rd.dim = next(iter(dims.values()))
        whole = intern(("merge", tuple((n, id(m)) for n, m in meshes.items())),
                       lambda: merge(meshes))
        offsets = np.cumsum([0] + [m.n_nodes for m in meshes.values()])
        shape = {}
        for i, (n, s) in enumerate(shapes.items()):
            for p, V in s.items():
                full = shape.setdefault(p, np.zeros_like(whole.nodes))
                full[offsets[i]:offsets[i + 1]] += V
    return whole, shape, Bodies(mats), E


# ---------------------------------------------------------------- obstacles
def _path(t: Table, where: str, data):
    """A leg's ramp: ramp = [t0, t1] or table = {times = [...], values = [...]}."""
    if "ramp" in data and "table" in data:
        raise t.rd.error(where, "give either ramp = [t0, t1] or table = {times, values}, not both")
    if "ramp" in data:
        r = data["ramp"]
        if not (isinstance(r, list) and len(r) == 2):
            raise t.err("ramp", f"expected [t0, t1] (load factors), got {kind(r)}")
        try:
            return Ramp(*(t.real("ramp", value=v) for v in r))
        except InputError as e:
            raise t.err("ramp", f"{e}") from None
    if "table" in data:
        tab = Table(t.rd, f"{where} table", data["table"], {"times", "values"}, ("times", "values"))
        times, values = tab.get("times", None), tab.get("values", None)
        for k, v in (("times", times), ("values", values)):
            if not isinstance(v, list):
                raise tab.err(k, f"expected a list of numbers, got {kind(v)}")
        try:
            return PathTable(tuple(tab.real("times", value=v) for v in times),
                             tuple(tab.real("values", value=v) for v in values))
        except InputError as e:
            raise tab.err("times", f"{e}") from None
    return None


def motion(t: Table, key: str):
    """A motion (or rotation): a vector (moved by t times it) or legs
    [{vector = [...], ramp = [t0, t1]}, {vector = [...], table = {times, values}}, ...]."""
    v = t.get(key, None)
    if v is None:
        return None
    if isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
        legs = []
        for i, leg in enumerate(v):
            where = f"{t.where} {key}[{i}]"
            lt = Table(t.rd, where, leg, {"vector", "ramp", "table"}, required=("vector",))
            vec = lt.vector("vector", dim=3 if key == "rotation" else None)
            ramp = _path(lt, where, leg)
            legs.append((vec, ramp if ramp is not None else Ramp(0.0, 1.0)))
        return tuple(legs)
    return t.vector(key, dim=3 if key == "rotation" else None)


def obstacle(rd: Reader, where: str, data):
    where = f"{where} obstacle"
    dim = rd.dim
    if not isinstance(data, dict):
        raise rd.error(where, f"must be a table such as {{type = \"{OBSTACLES[dim][1]}\", ...}}, "
                              f"got {kind(data)}")
    if "type" not in data:
        raise rd.error(where, f"missing required key 'type'; add type = "
                              f"{' | '.join(map(repr, OBSTACLES[dim]))}")
    ty = Table(rd, where, {"type": data["type"]}, {"type"})
    every = sorted(set(OBSTACLES[2] + OBSTACLES[3]))
    kind_ = ty.string("type", choices=every)
    if kind_ not in OBSTACLES[dim]:
        raise ty.err("type", f"{kind_!r} is an obstacle of {5 - dim}-D problems; the mesh is "
                             f"{dim}-D, whose obstacles are {', '.join(map(repr, OBSTACLES[dim]))}")
    rot = {"rotation"} if dim == 3 else set()
    keys = {"circle": {"radius", "centre"}, "line": {"point", "normal"},
            "plane": {"point", "normal"}, "sphere": {"radius", "centre"},
            "cylinder": {"radius", "centre", "axis"}, "implicit": {"expression", "origin"}}[kind_]
    req = tuple(sorted(keys - {"origin"}))
    t = Table(rd, where, data, {"type", "motion"} | keys | (rot if kind_ != "line" else set()), req)
    mo = motion(t, "motion")
    extra = {"rotation": motion(t, "rotation")} if t.has("rotation") else {}
    if kind_ == "circle":
        ob = Circle(radius=t.spec("radius"), centre=t.vector("centre"),
                    motion=mo if mo is not None else (0.0, 0.0))
    elif kind_ == "line":
        ob = Line(point=t.vector("point"), normal_vector=t.vector("normal"),
                  motion=mo if mo is not None else (0.0, 0.0))
    elif kind_ in ("plane", "sphere", "cylinder"):
        args = {"radius": t.spec("radius")} if kind_ != "plane" else {}
        if kind_ == "plane":
            args.update(point=t.vector("point"), normal_vector=t.vector("normal"))
        else:
            args["centre"] = t.vector("centre")
        if kind_ == "cylinder":
            args["axis"] = t.vector("axis")
        cls = {"plane": Plane, "sphere": Sphere, "cylinder": Cylinder}[kind_]
        ob = cls(**args, motion=mo if mo is not None else (0.0, 0.0, 0.0), **extra)
    else:
        text = t.string("expression")
        coords = tuple(AXES[:dim])
        try:
            e = parse(text, coords, rd.params)
        except InputError as err:
            raise t.err("expression", f"{err}") from None
        used = set(e.names)
        if not any(c in text for c in coords) or not _uses_coords(e):
            raise t.err("expression", f"{text!r} is not a function of {', '.join(coords)}: an "
                                      "implicit surface is the zero level of a function of the point")
        dist = intern(("implicit", text, coords, tuple(sorted(rd.params))), e.distance)
        origin = t.vector("origin") if t.has("origin") else (0.0,) * dim
        ob = Implicit(dist, {n: n for n in sorted(used)}, origin=origin, motion=mo, **extra)
    try:
        ob.check(rd.params)
        if kind_ == "implicit":  # a value at the check's point (NaN: e.g. the log of a negative)
            geo = ob.geometry(rd.params, 0.0)
            g = float(ob.distance(geo["c"] + 1.0, geo["p"]))
            if not np.isfinite(g):
                raise InputError(f"the expression is {g} at the point origin + (1, 1, 1)[:dim]; it "
                                 "must be finite where the body may be")
    except InputError as e:
        raise rd.error(where, f"{e}", key="expression" if kind_ == "implicit" else None) from None
    return ob


def _uses_coords(e) -> bool:
    return any(isinstance(n, ast.Name) and n.id in e.coords for n in ast.walk(e._tree))
