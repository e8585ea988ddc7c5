"""Reading a TOML problem file into a :class:`~signorini.model.problem.Problem` and
a :class:`RunConfig` (the schema: :mod:`signorini.app.problemfile`)."""


from __future__ import annotations

import difflib
import math
import tomllib
import warnings
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...contact import AugmentedLagrangian, Contact, Coulomb, Penalty
from ...errors import InputError, SignoriniWarning, UnknownParameterError
from ...fem.loads import Fixed, Pressure, Traction
from ...materials import LinearElastic, NeoHooke
from ...fem.mesh import Mesh, rectangle
from ...algorithms.newton import NewtonOptions
from ...contact.obstacles import Circle, Line
from ...model.problem import Problem
from ...fem.meshfile import read_mesh
from ...linsolve import check_size


__all__ = ["Response", "RunConfig", "load"]


_REQUIRED = object()

_TOP = {"title": "a string", "params": "[params]", "mesh": "[mesh]", "material": "[material]",
        "fixed": "[[fixed]]", "load": "[[load]]", "contact": "[[contact]]", "solve": "[solve]",
        "response": "[[response]]", "output": "[output]"}
_ARRAYS = ("fixed", "load", "contact", "response")
_RESPONSE_TYPES = ("max_pressure", "normal_force", "displacement", "reaction")


@dataclass(frozen=True)
class Response:
    """A scalar result requested by ``[[response]]``.

    Attributes:
        name: the key in ``summary.json["responses"]``.
        type: ``max_pressure``, ``normal_force``, ``displacement`` or ``reaction``.
        surface: index of the contact surface (pressure and force responses).
        node_set: node set (displacement and reaction responses).
        component: 0 (x) or 1 (y) (displacement and reaction responses).
    """
    name: str
    type: str
    surface: int | None = None
    node_set: str | None = None
    component: int | None = None


@dataclass(frozen=True)
class RunConfig:
    """How to solve a problem file and what to write (``[solve]``, ``[output]``,
    ``[[response]]``), and what reading it found suspicious (``warnings``, also
    raised as :class:`~signorini.errors.SignoriniWarning`)."""
    path: Path
    title: str = ""
    steps: int = 1
    sensitivities: tuple[str, ...] = ()
    options: NewtonOptions = field(default_factory=NewtonOptions)
    responses: tuple[Response, ...] = ()
    vtu: bool = True
    pvd: bool = True
    csv: bool = True
    warnings: tuple[str, ...] = ()

    @property
    def stem(self) -> str:
        return self.path.stem


# ---------------------------------------------------------------- reading

def _kind(v) -> str:
    if isinstance(v, bool):
        return f"a boolean ({str(v).lower()})"
    if isinstance(v, int):
        return f"an integer ({v})"
    if isinstance(v, float):
        return f"a number ({v})"
    if isinstance(v, str):
        return f"a string ({v!r})"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return type(v).__name__


class _Reader:
    """Validation state of one file: its label (for messages) and parameters."""
    def __init__(self, path: Path, force_size: bool = False, solver="auto"):
        self.path = path
        self.label = str(path)
        self.params: dict[str, float] = {}
        self.warnings: list[str] = []  # what reading found suspicious
        # the size guard of a generated mesh, before it is built
        self.force_size, self.solver = force_size, solver

    def error(self, where: str, msg: str, cls=InputError):
        return cls(f"{self.label}: {where} {msg}")


class _Table:
    """One TOML table with strict keys; typed getters name the key on error."""
    def __init__(self, rd: _Reader, where: str, data, allowed, required=()):
        self.rd, self.where = rd, where
        if not isinstance(data, dict):
            raise rd.error(where, f"must be a table, got {_kind(data)}; see the schema in "
                                  "signorini.problemfile")
        self.data = data
        allowed = sorted(set(allowed))
        for k in data:
            if k not in allowed:
                near = difflib.get_close_matches(k, allowed, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise rd.error(where, f"unknown key {k!r}{hint}; allowed: {', '.join(allowed)}")
        for k in required:
            if k not in data:
                raise rd.error(where, f"missing required key {k!r}; add {k} = ...")

    def err(self, key, msg, cls=InputError):
        return self.rd.error(self.where, f"{key}: {msg}", cls)

    def _get(self, key, default):
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.rd.error(self.where, f"missing required key {key!r}; add {key} = ...")
        return default

    def has(self, key) -> bool:
        return key in self.data

    # typed getters
    def string(self, key, default=_REQUIRED, choices=None):
        v = self._get(key, default)
        if v is default and key not in self.data:
            return v
        if not isinstance(v, str):
            raise self.err(key, f"expected a string, got {_kind(v)}")
        if choices is not None and v not in choices:
            near = difflib.get_close_matches(v, choices, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise self.err(key, f"{v!r} is not one of {', '.join(map(repr, choices))}{hint}")
        return v

    def boolean(self, key, default=_REQUIRED):
        v = self._get(key, default)
        if not isinstance(v, bool):
            raise self.err(key, f"expected true or false, got {_kind(v)}")
        return v

    def integer(self, key, default=_REQUIRED, minimum=None):
        v = self._get(key, default)
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(key, f"expected an integer, got {_kind(v)}")
        if minimum is not None and v < minimum:
            raise self.err(key, f"must be >= {minimum}, got {v}")
        return v

    def real(self, key, default=_REQUIRED, positive=False, nonnegative=False):
        """A plain number (no parameter name)."""
        v = self._get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.err(key, f"expected a number, got {_kind(v)}")
        v = float(v)
        if not math.isfinite(v) or (positive and not v > 0) or (nonnegative and not v >= 0):
            need = "a positive" if positive else "a non-negative" if nonnegative else "a finite"
            raise self.err(key, f"must be {need} number, got {v}")
        return v

    def spec(self, key, default=_REQUIRED, value=None, what=None):
        """A number or the name of a parameter (returned as float or str)."""
        v = self._get(key, default) if value is None else value
        what = what or key
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            raise self.err(what, f"expected a number or a parameter name, got {_kind(v)}")
        if isinstance(v, str):
            if v not in self.rd.params:
                defined = ", ".join(sorted(self.rd.params)) or "none"
                raise self.err(what, f"{v!r} is not a parameter (defined in [params]: {defined}); "
                                     "add it to [params] or write a number", UnknownParameterError)
            return v
        v = float(v)
        if not math.isfinite(v):
            raise self.err(what, f"must be finite, got {v}")
        return v

    def vector(self, key, default=_REQUIRED):
        v = self._get(key, default)
        if not isinstance(v, list) or len(v) != 2:
            raise self.err(key, f"expected a list of two numbers [a, b], got {_kind(v)}"
                                + (f" of length {len(v)}" if isinstance(v, list) else ""))
        return tuple(self.spec(key, value=x, what=f"{key}[{i}]") for i, x in enumerate(v))

    def component(self, key):
        v = self._get(key, _REQUIRED)
        if v in ("x", "y"):
            return "xy".index(v)
        if isinstance(v, int) and not isinstance(v, bool) and v in (0, 1):
            return v
        raise self.err(key, f"expected 0, 1, \"x\" or \"y\", got {_kind(v)}")

    def value(self, key):
        return self.rd.params[key] if isinstance(key, str) else key


def _read_toml(path: Path) -> dict:
    if not path.exists():
        raise InputError(f"{path}: problem file not found; check the file name and path")
    if path.is_dir():
        raise InputError(f"{path}: is a directory; give the path of a .toml problem file")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: TOML syntax error: {e}; fix the file (TOML: key = value lines, "
                         "[table] headers, strings in quotes)") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a UTF-8 text file ({e.reason} at byte {e.start}); "
                         "a problem file must be TOML text") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read the problem file ({e.strerror or e})") from None


# Meshes and materials are reused between loads of equal descriptions, so that
# problems differing only in [params] values share the compiled model
# (signorini.solve caches models by mesh and material identity): finite
# differences and design loops by re-running a file do not recompile.
_INTERN: OrderedDict = OrderedDict()


def _intern(key, make):
    try:
        v = _INTERN[key]
        _INTERN.move_to_end(key)
        return v
    except KeyError:
        pass
    v = make()
    _INTERN[key] = v
    if len(_INTERN) > 32:
        _INTERN.popitem(last=False)
    return v


#: what a problem file with a 3-D mesh is told (its other tables are 2-D: edge sets, [x, y] vectors)
_NO_3D = ("; problem files take 2-D meshes only (3-D meshes in problem files are not supported "
          "yet): mesh a plane section of the body, or set up the 3-D problem in Python "
          "(signorini.read_mesh reads 3-D meshes of hexahedra or tetrahedra)")


def _mesh(rd: _Reader, data) -> tuple[Mesh, dict]:
    where = "[mesh]"
    if not isinstance(data, dict):
        raise rd.error(where, f"must be a table, got {_kind(data)}")
    if "file" in data and "type" in data:
        raise rd.error(where, "give either file = \"...\" or type = \"rectangle\", not both")
    if "file" in data:
        t = _Table(rd, where, data, {"file"})
        name = t.string("file")
        f = Path(name)
        if not f.is_absolute():
            f = rd.path.parent / f
        try:
            st = f.stat()
            key = ("file", str(f.resolve()), st.st_mtime_ns, st.st_size)
        except OSError:
            key = None

        def make():
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", SignoriniWarning)
                    mesh = read_mesh(f, dim=2)
            except InputError as e:
                hint = _NO_3D if getattr(e, "dim", None) == 3 else ""
                raise type(e)(f"{rd.label}: [mesh] file = {name!r}: {e}{hint}") from None
            return mesh, tuple(str(w.message) for w in caught
                               if issubclass(w.category, SignoriniWarning))

        mesh, notes = make() if key is None else _intern(key, make)
        for message in notes:  # heard again when the file is loaded again
            rd.warnings.append(message)
            warnings.warn(message, SignoriniWarning, stacklevel=2)
        return mesh, {}
    if "type" not in data:
        raise rd.error(where, "missing 'file' or 'type'; write file = \"body.msh\" or "
                              "type = \"rectangle\" with x, y, nx, ny")
    t = _Table(rd, where, data, {"type", "x", "y", "nx", "ny"}, required=("type", "x", "y", "nx", "ny"))
    t.string("type", choices=("rectangle",))
    xs, ys = t.vector("x"), t.vector("y")
    nx, ny = t.integer("nx", minimum=1), t.integer("ny", minimum=1)
    x0, x1 = (t.value(s) for s in xs)
    y0, y1 = (t.value(s) for s in ys)
    if not x1 > x0:
        raise t.err("x", f"must be increasing [x0, x1] with x0 < x1, got [{x0}, {x1}]")
    if not y1 > y0:
        raise t.err("y", f"must be increasing [y0, y1] with y0 < y1, got [{y0}, {y1}]")

    # every node's two displacements (a lower bound: the multipliers come with the
    # contact surfaces): checked before the grid is built (a file's mesh once it is read)
    check_size(2 * (nx + 1) * (ny + 1), force=rd.force_size, what=f"{rd.label}: [mesh] {nx} x {ny}",
               solver=rd.solver, lower_bound=True, hint="a coarser mesh (smaller nx, ny)")

    def make():
        mesh = rectangle(np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1))
        X = mesh.nodes
        s = (X[:, 0] - x0) / (x1 - x0)
        r = (X[:, 1] - y0) / (y1 - y0)
        zero = np.zeros(len(X))
        parts = [(xs[0], np.column_stack([1 - s, zero])), (xs[1], np.column_stack([s, zero])),
                 (ys[0], np.column_stack([zero, 1 - r])), (ys[1], np.column_stack([zero, r]))]
        shape = {}
        for spec, V in parts:
            if isinstance(spec, str):
                shape[spec] = shape.get(spec, 0.0) + V
        return mesh, shape

    return _intern(("rectangle", xs, ys, x0, x1, y0, y1, nx, ny), make)


def _material(rd: _Reader, data):
    t = _Table(rd, "[material]", data, {"type", "E", "nu"}, required=("type", "E", "nu"))
    kind = t.string("type", choices=("linear_elastic", "neo_hooke"))
    cls = LinearElastic if kind == "linear_elastic" else NeoHooke
    mat = _intern(("material", cls, t.spec("E"), t.spec("nu")), lambda: cls(t.spec("E"), t.spec("nu")))
    try:
        mat.check(rd.params)
    except InputError as e:
        raise rd.error("[material]", f"{e}") from None
    return mat, t.value(t.spec("E"))


def _array(rd: _Reader, doc: dict, key: str) -> list:
    v = doc.get(key, [])
    if isinstance(v, dict):
        raise rd.error(f"[{key}]", f"must be an array of tables: write [[{key}]] (double brackets) "
                                   "for each entry")
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise rd.error(f"[[{key}]]", f"must be an array of tables ([[{key}]] entries), got {_kind(v)}")
    return v


def _node_set(t: _Table, mesh: Mesh, key: str) -> str:
    name = t.string(key)
    if name not in mesh.node_sets:
        raise t.err(key, f"{name!r} is not a node set of the mesh; the mesh has "
                         f"{', '.join(sorted(mesh.node_sets))}")
    return name


def _edge_set(t: _Table, mesh: Mesh, key: str) -> str:
    name = t.string(key)
    if name not in mesh.edge_sets:
        raise t.err(key, f"{name!r} is not an edge set of the mesh; the mesh has "
                         f"{', '.join(sorted(mesh.edge_sets)) or 'none'} (boundary edge sets: "
                         "gmsh physical lines, or left/right/bottom/top of a rectangle)")
    return name


def _obstacle(rd: _Reader, where: str, data):
    where = f"{where} obstacle"
    if not isinstance(data, dict):
        raise rd.error(where, f"must be a table such as {{type = \"circle\", radius = 1.0, "
                              f"centre = [0.0, 1.0]}}, got {_kind(data)}")
    if "type" not in data:
        raise rd.error(where, "missing required key 'type'; add type = \"circle\" or \"line\"")
    kind = _Table(rd, where, {"type": data["type"]}, {"type"}).string("type", choices=("circle", "line"))
    if kind == "circle":
        t = _Table(rd, where, data, {"type", "radius", "centre", "motion"}, required=("radius", "centre"))
        ob = Circle(radius=t.spec("radius"), centre=t.vector("centre"),
                    motion=t.vector("motion", [0.0, 0.0]))
    else:
        t = _Table(rd, where, data, {"type", "point", "normal", "motion"}, required=("point", "normal"))
        ob = Line(point=t.vector("point"), normal_vector=t.vector("normal"),
                  motion=t.vector("motion", [0.0, 0.0]))
    try:
        ob.check(rd.params)
    except InputError as e:
        raise rd.error(where, f"{e}") from None
    return ob


def _contact(rd: _Reader, k: int, data, mesh: Mesh, E: float):
    where = f"[[contact]] #{k + 1}"
    t = _Table(rd, where, data, {"edges", "obstacle", "method", "eps", "mu", "eps_t", "kinematics"},
               required=("edges", "obstacle"))
    edges = _edge_set(t, mesh, "edges")
    ob = _obstacle(rd, where, data["obstacle"])
    method = t.string("method", "al", choices=("al", "penalty", "coulomb"))
    if method != "coulomb":
        for key in ("mu", "eps_t"):
            if t.has(key):
                raise t.err(key, f"applies only to method = \"coulomb\" (this surface has method = "
                                 f"{method!r}); remove it or change the method")
    if method == "penalty" and not t.has("eps"):
        raise rd.error(where, "missing required key 'eps': the penalty solution depends on it; add "
                              "eps = ... (e.g. 100 E/h for about 1 % penetration error)")
    if t.has("eps"):
        eps = t.spec("eps")
    else:
        e = mesh.edge_set(edges)
        h = float(np.linalg.norm(mesh.nodes[e[:, 1]] - mesh.nodes[e[:, 0]], axis=1).min())
        eps = float(E) / h
    if method == "al":
        meth = AugmentedLagrangian(eps)
    elif method == "penalty":
        meth = Penalty(eps)
    else:
        meth = Coulomb(mu=t.spec("mu"), eps_n=eps, eps_t=t.spec("eps_t", eps))
    try:
        meth.check(rd.params)
    except InputError as err:
        raise rd.error(where, f"{err}") from None
    kin = t.string("kinematics", "auto", choices=("auto", "linear", "finite"))
    return Contact(ob, edges, meth, kinematics=kin)


def _fixed(rd: _Reader, k: int, data, mesh: Mesh) -> Fixed:
    t = _Table(rd, f"[[fixed]] #{k + 1}", data, {"set", "component", "value"}, required=("set", "component"))
    return Fixed(_node_set(t, mesh, "set"), t.component("component"), t.spec("value", 0.0))


def _load(rd: _Reader, k: int, data, mesh: Mesh):
    t = _Table(rd, f"[[load]] #{k + 1}", data, {"type", "edges", "value", "resultant"},
               required=("type", "edges", "value"))
    kind = t.string("type", choices=("pressure", "traction"))
    edges = _edge_set(t, mesh, "edges")
    resultant = t.boolean("resultant", False)
    if kind == "pressure":
        if isinstance(data["value"], list):
            raise t.err("value", "a pressure is a scalar (positive pushes into the body); for a "
                                 "force vector use type = \"traction\" with value = [fx, fy]")
        return Pressure(edges, t.spec("value"), resultant=resultant)
    return Traction(edges, t.vector("value"), resultant=resultant)


def _solve(rd: _Reader, data):
    t = _Table(rd, "[solve]", data, {"steps", "sensitivities", "rtol", "atol", "max_iter", "max_cuts",
                                     "predictor"})
    steps = t.integer("steps", 1, minimum=1)
    sens = t._get("sensitivities", [])
    if not isinstance(sens, list) or not all(isinstance(s, str) for s in sens):
        raise t.err("sensitivities", f"expected a list of parameter names such as [\"E\", \"R\"], "
                                     f"got {_kind(sens)}")
    for s in sens:
        if s not in rd.params:
            raise t.err("sensitivities", f"{s!r} is not a parameter (defined in [params]: "
                        f"{', '.join(sorted(rd.params)) or 'none'}); add it to [params] or remove it",
                        UnknownParameterError)
    if len(set(sens)) != len(sens):
        raise t.err("sensitivities", f"lists a parameter twice: {sens}")
    d = NewtonOptions()
    rtol = t.real("rtol", d.rtol, nonnegative=True)
    if not rtol < 1:
        raise t.err("rtol", f"must be below 1 (a fraction of the reference residual, e.g. 1e-10), "
                            f"got {rtol!r}")
    opts = NewtonOptions(rtol=rtol,
                         atol=t.real("atol", d.atol, nonnegative=True),
                         max_iter=t.integer("max_iter", d.max_iter, minimum=1),
                         max_cuts=t.integer("max_cuts", d.max_cuts, minimum=0),
                         predictor=t.string("predictor", d.predictor, choices=("extrapolate", "none"))) \
        if any(t.has(k) for k in ("rtol", "atol", "max_iter", "max_cuts", "predictor")) else d
    if not (opts.rtol > 0 or opts.atol > 0):
        raise t.err("rtol", "rtol or atol must be positive")
    return steps, tuple(sens), opts


def _responses(rd: _Reader, items: list, mesh: Mesh, contacts, fixed) -> tuple[Response, ...]:
    out, names = [], set()
    for k, data in enumerate(items):
        where = f"[[response]] #{k + 1}"
        t = _Table(rd, where, data, {"name", "type", "surface", "set", "component"},
                   required=("name", "type"))
        name = t.string("name")
        if name in names:
            raise t.err("name", f"{name!r} is used by two responses; give each a unique name")
        names.add(name)
        kind = t.string("type", choices=_RESPONSE_TYPES)
        if kind in ("max_pressure", "normal_force"):
            _Table(rd, where, data, {"name", "type", "surface"})
            if not contacts:
                raise rd.error(where, f"type = {kind!r} needs a [[contact]] surface; the file has none")
            surf = 0
            if t.has("surface"):
                edges = t.string("surface")
                found = [i for i, c in enumerate(contacts) if c.edges == edges]
                if not found:
                    raise t.err("surface", f"{edges!r} is not the edges of any [[contact]] (they are "
                                           f"{', '.join(c.edges for c in contacts)})")
                surf = found[0]
            out.append(Response(name, kind, surface=surf))
        else:
            _Table(rd, where, data, {"name", "type", "set", "component"},
                   required=("name", "type", "set", "component"))
            node_set, comp = _node_set(t, mesh, "set"), t.component("component")
            if kind == "reaction":
                fixed_nodes = set()
                for f in fixed:
                    if f.component == comp:
                        fixed_nodes.update(int(n) for n in mesh.node_set(f.node_set))
                free = sorted(set(int(n) for n in mesh.node_set(node_set)) - fixed_nodes)
                if free:
                    raise rd.error(where, f"reaction of set {node_set!r}, component {comp}: node(s) "
                                          f"{free[:5]} are not prescribed by any [[fixed]] in that "
                                          "component; reactions exist only on prescribed DOFs")
            out.append(Response(name, kind, node_set=node_set, component=comp))
    return tuple(out)


def load(path, *, force_size: bool = False, solver="auto") -> tuple[Problem, RunConfig]:
    """Read a problem file (schema: module docstring). A generated mesh is refused
    before it is built if it is estimated not to fit in memory with ``solver``
    (the run's linear solver), unless ``force_size``.

    Returns:
        (problem, config): the :class:`~signorini.model.problem.Problem` at the
        nominal parameter values and the :class:`RunConfig`.

    Raises:
        InputError: syntax errors (with the line), unknown tables or keys,
            missing keys, wrong types or values, unknown sets; the message
            names the file and the key.
        UnknownParameterError: a parameter name that ``[params]`` does not define.
        ResourceError: the generated mesh is estimated not to fit in memory.
    """
    path = Path(path)
    rd = _Reader(path, force_size, solver)
    doc = _read_toml(path)
    for k, v in doc.items():
        if k not in _TOP:
            near = difflib.get_close_matches(k, list(_TOP), n=1)
            hint = f" (did you mean {_TOP[near[0]]}?)" if near else ""
            tables = ", ".join(v for n, v in _TOP.items() if n != "title")
            raise InputError(f"{rd.label}: unknown table or key {k!r}{hint}; allowed: {tables} "
                             "and the key title")
    for k in ("mesh", "material"):
        if k not in doc:
            raise InputError(f"{rd.label}: missing required table [{k}]; see the schema in "
                             "signorini.problemfile")
    title = doc.get("title", "")
    if not isinstance(title, str):
        raise InputError(f"{rd.label}: title must be a string, got {_kind(title)}")

    params = doc.get("params", {})
    if not isinstance(params, dict):
        raise InputError(f"{rd.label}: [params] must be a table of name = number, got {_kind(params)}")
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{rd.label}: [params] {k}: expected a number, got {_kind(v)}; "
                             "parameters are numbers (name = value)")
        rd.params[k] = float(v)

    mesh, shape = _mesh(rd, doc["mesh"])
    material, E = _material(rd, doc["material"])
    fixed = tuple(_fixed(rd, k, d, mesh) for k, d in enumerate(_array(rd, doc, "fixed")))
    loads = tuple(_load(rd, k, d, mesh) for k, d in enumerate(_array(rd, doc, "load")))
    contact = tuple(_contact(rd, k, d, mesh, E) for k, d in enumerate(_array(rd, doc, "contact")))
    steps, sens, opts = _solve(rd, doc.get("solve", {}))
    responses = _responses(rd, _array(rd, doc, "response"), mesh, contact, fixed)
    out = _Table(rd, "[output]", doc.get("output", {}), {"vtu", "pvd", "csv"})
    cfg = RunConfig(path=path, title=title, steps=steps, sensitivities=sens, options=opts,
                    responses=responses, vtu=out.boolean("vtu", True), pvd=out.boolean("pvd", True),
                    csv=out.boolean("csv", True), warnings=tuple(rd.warnings))
    try:
        problem = Problem(mesh=mesh, material=material, params=dict(rd.params), fixed=fixed,
                          loads=loads, contact=contact, shape=shape)
    except InputError as e:
        raise type(e)(f"{rd.label}: {e}") from None
    return problem, cfg


# ---------------------------------------------------------------- running

