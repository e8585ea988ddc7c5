"""Problem description files: a contact problem, its solve and its outputs in TOML.

:func:`load` reads a file into a :class:`~signorini.model.problem.Problem` and a
:class:`RunConfig`; :func:`run` also solves it (with DDM sensitivities) and
writes the results into a directory. ``signorini run FILE --out DIR`` calls
:func:`run`.

Example (``block.toml``: an elastic block pressed against a rigid cylinder,
half model with a symmetry line)::

    title = "block on a cylinder"

    [params]                 # named design parameters: derivatives are taken w.r.t. these
    E = 100.0
    nu = 0.3
    P = 2.0
    R = 20.0
    W = 2.0

    [mesh]                   # uniform nx x ny Q4 grid; or:  file = "body.msh"
    type = "rectangle"
    x = [0.0, "W"]           # a parameter name here makes W a shape parameter
    y = [-2.0, 0.0]
    nx = 32
    ny = 16

    [material]
    type = "linear_elastic"  # or "neo_hooke" (finite strain)
    E = "E"
    nu = "nu"

    [[fixed]]                # one table per prescribed displacement component
    set = "left"
    component = "x"          # 0 / 1 or "x" / "y"
    value = 0.0              # default 0

    [[load]]
    type = "pressure"        # or "traction" with value = [fx, fy]
    edges = "bottom"
    value = "P"
    resultant = true         # value is the resultant force (per unit thickness)

    [[contact]]
    edges = "top"
    obstacle = { type = "circle", radius = "R", centre = [0.0, "R"] }
    method = "al"            # "al" | "penalty" | "coulomb"
    # eps = 400.0            # default E/h (h: shortest contact edge); required for "penalty"
    # mu = 0.3               # "coulomb" only (required), with eps_t (default eps)
    # kinematics = "auto"    # "auto" | "linear" | "finite"

    [solve]
    steps = 2                # equal load increments (cut automatically on failure)
    sensitivities = ["R", "E", "W"]
    rtol = 1e-10             # Newton tolerances (signorini.NewtonOptions)
    max_iter = 25

    [[response]]             # scalar results with their sensitivities, in summary.json
    name = "p_max"
    type = "max_pressure"    # | "normal_force" | "displacement" | "reaction"
    surface = "top"          # contact edges (default: the first [[contact]])

    [output]
    vtu = true               # <stem>.vtu: last increment
    pvd = true               # <stem>.pvd + <stem>_0001.vtu, ... when there are several increments
    csv = true               # contact.csv (contact_1.csv, ... for further surfaces)

Schema (every key not listed is an error; "number" means a number or the
name of a parameter of ``[params]``, which makes it a design variable):

``title``
    optional string, copied to ``summary.json``.
``[params]``
    ``name = value`` (numbers). Parameter names used elsewhere must be defined
    here (:class:`~signorini.errors.UnknownParameterError` otherwise).
``[mesh]`` (required)
    either ``file = "body.msh"`` (relative to the TOML file; read by
    :func:`signorini.fem.meshfile.read_mesh`: gmsh physical groups of lines become edge
    and node sets, of points node sets, plus ``all``), or
    ``type = "rectangle"``, ``x = [x0, x1]``, ``y = [y0, y1]`` (numbers),
    ``nx``, ``ny`` (cells, integers >= 1): sets ``left``, ``right``,
    ``bottom``, ``top`` (edges and nodes) and ``all`` (nodes). A parameter
    name among the corners makes that parameter a shape parameter (the exact
    design velocity of the uniform grid is supplied).
``[material]`` (required)
    ``type`` = ``"linear_elastic"`` | ``"neo_hooke"``, ``E``, ``nu`` (numbers).
``[[fixed]]``
    ``set`` (node set), ``component`` (0, 1, "x" or "y"), ``value`` (number,
    default 0; ramped with the load factor).
``[[load]]``
    ``type`` = ``"pressure"`` (``value``: number, positive pushes into the
    body) | ``"traction"`` (``value = [fx, fy]``), ``edges`` (edge set),
    ``resultant`` (bool, default false: value is the resultant force).
``[[contact]]``
    ``edges`` (edge set); ``obstacle`` = ``{type = "circle", radius, centre =
    [cx, cy], motion = [vx, vy]}`` or ``{type = "line", point = [x, y],
    normal = [nx, ny], motion = [vx, vy]}`` (normal points into the body;
    motion: displacement of the obstacle at t = 1, default [0, 0]);
    ``method`` = ``"al"`` (default) | ``"penalty"`` | ``"coulomb"``; ``eps``
    (> 0; default E/h with h the shortest edge of the surface, evaluated at the
    nominal values; required for ``"penalty"``, whose solution depends on it);
    ``mu`` (``"coulomb"`` only, required), ``eps_t`` (``"coulomb"`` only,
    default ``eps``); ``kinematics`` = ``"auto"`` | ``"linear"`` | ``"finite"``.
``[solve]``
    ``steps`` (int >= 1, default 1), ``sensitivities`` (list of parameter
    names), and the Newton options ``rtol``, ``atol``, ``max_iter``,
    ``max_cuts``, ``predictor`` (``"extrapolate"`` | ``"none"``) (defaults of
    :class:`~signorini.algorithms.newton.NewtonOptions`).
``[[response]]``
    ``name`` (unique), ``type``: ``"max_pressure"`` (largest p_N of a surface,
    with its DDM sensitivity at that node) or ``"normal_force"`` (sum of p_N
    A_S over the surface) with optional ``surface`` (edges of a
    ``[[contact]]``, default the first); ``"displacement"`` (mean of a
    displacement component over a node set) or ``"reaction"`` (sum of the
    support reactions of a component over a node set; every DOF must be
    prescribed by ``[[fixed]]``; the force of the supports on the body) with
    ``set`` and ``component``.
``[output]``
    ``vtu``, ``pvd``, ``csv`` (bools, default true).

Outputs of :func:`run` in ``out``: ``summary.json`` (status, the failure
reason, parameters, mesh size, load factors and Newton iterations per
increment, warnings, responses and their sensitivities, per-surface contact
summary, files written), ``contact.csv`` per contact surface at the last
increment (``node, x_ref, y_ref, x, y, p_N, p_T, gap, dp_N_d<name>...``; with
friction also ``dp_T_d<name>``, ``status`` and ``slip``), ``<stem>.vtu`` (last
increment; ``<stem>`` is the TOML file's name without extension) and, when
there are several increments, the ParaView series ``<stem>.pvd``.

Every problem in the file is reported as :class:`~signorini.errors.InputError`
naming the file and the key, e.g. ``problem.toml: [material] unknown key
'Ee'; allowed: E, nu, type``.
"""

from __future__ import annotations

import difflib
import math
import time
import tomllib
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..contact import AugmentedLagrangian, Contact, Coulomb, Penalty
from ..errors import InputError, SolverError, UnknownParameterError
from ..fem.loads import Fixed, Pressure, Traction
from ..materials import LinearElastic, NeoHooke
from ..fem.mesh import Mesh, rectangle
from ..algorithms.newton import NewtonOptions
from ..contact.obstacles import Circle, Line
from ..model.problem import Problem
from .._jax import jnp
from ..algorithms.stepping import solve
from ..fem.meshfile import read_mesh
from ..linsolve import check_size
from ..post import files as io
from .runner import prepare_output
from .runner import use_solver

__all__ = ["Response", "RunConfig", "load", "run"]

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
    ``[[response]]``)."""
    path: Path
    title: str = ""
    steps: int = 1
    sensitivities: tuple[str, ...] = ()
    options: NewtonOptions = field(default_factory=NewtonOptions)
    responses: tuple[Response, ...] = ()
    vtu: bool = True
    pvd: bool = True
    csv: bool = True

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
    def __init__(self, path: Path):
        self.path = path
        self.label = str(path)
        self.params: dict[str, float] = {}

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
                return read_mesh(f)
            except InputError as e:
                raise type(e)(f"{rd.label}: [mesh] file = {name!r}: {e}") from None

        return (make() if key is None else _intern(key, make)), {}
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
    opts = NewtonOptions(rtol=t.real("rtol", d.rtol, nonnegative=True),
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


def load(path) -> tuple[Problem, RunConfig]:
    """Read a problem file (schema: module docstring).

    Returns:
        (problem, config): the :class:`~signorini.model.problem.Problem` at the
        nominal parameter values and the :class:`RunConfig`.

    Raises:
        InputError: syntax errors (with the line), unknown tables or keys,
            missing keys, wrong types or values, unknown sets; the message
            names the file and the key.
        UnknownParameterError: a parameter name that ``[params]`` does not define.
    """
    path = Path(path)
    rd = _Reader(path)
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
                    csv=out.boolean("csv", True))
    try:
        problem = Problem(mesh=mesh, material=material, params=dict(rd.params), fixed=fixed,
                          loads=loads, contact=contact, shape=shape)
    except InputError as e:
        raise type(e)(f"{rd.label}: {e}") from None
    return problem, cfg


# ---------------------------------------------------------------- running

def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if o is None or isinstance(o, (str, int, float, bool)):
        return o
    return str(o)


def _response_values(sol, problem: Problem, r: Response) -> dict:
    """Value and DDM sensitivities of one response at the last increment."""
    names = list(sol.names)
    if r.type == "max_pressure":
        c = sol.contact(-1, r.surface)
        j = int(np.argmax(c["p_N"]))
        return {"value": float(c["p_N"][j]), "node": int(c["node"][j]),
                "x_ref": [float(v) for v in c["x_ref"][j]],
                "sensitivities": {n: float(c[f"dp_N_d{n}"][j]) for n in names}}
    if r.type == "normal_force":

        m, k = sol.model, r.surface

        def force(w, p, t):
            f = m.contact_fields(w, p, t, k)
            return jnp.sum(f["p_N"] * f["area"])

        val, d = sol.response(force, -1, key=("problemfile.normal_force", k))
        return {"value": float(val), "sensitivities": {n: float(d[n]) for n in names}}
    nodes = problem.mesh.node_set(r.node_set)
    if r.type == "displacement":
        val = float(sol.displacement()[nodes, r.component].mean())
        sens = {n: float(sol.displacement_sensitivity(n)[nodes, r.component].mean()) for n in names}
    else:
        # force of the supports on the body (Solution.reactions)
        val = float(sol.reactions()[nodes, r.component].sum())
        sens = {n: float(sol.reaction_sensitivity(n)[nodes, r.component].sum()) for n in names}
    return {"value": val, "sensitivities": sens}


def _contact_csv(sol, k: int, path: Path):

    c = sol.contact(-1, k)
    cols = {"node": c["node"], "x_ref": c["x_ref"][:, 0], "y_ref": c["x_ref"][:, 1],
            "x": c["x"][:, 0], "y": c["x"][:, 1], "p_N": c["p_N"], "p_T": c["p_T"], "gap": c["gap"]}
    for n in sol.names:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
    if "status" in c:
        for n in sol.names:
            cols[f"dp_T_d{n}"] = c[f"dp_T_d{n}"]
        cols["status"] = c["status"]
        cols["slip"] = c["slip"]
    io.write_csv(path, cols)
    return c


def _write_results(sol, problem: Problem, cfg: RunConfig, out: Path, summary: dict) -> None:
    """Files of the last converged increment (and the series); fills ``summary``."""
    files = summary["outputs"]
    if not sol.increments:
        return
    surfaces = []
    for k, s in enumerate(sol.model.surfaces):
        name = "contact.csv" if k == 0 else f"contact_{k}.csv"
        if cfg.csv:
            c = _contact_csv(sol, k, out / name)
            files.append(name)
        else:
            c = sol.contact(-1, k)
        surfaces.append({"edges": s.contact.edges, "method": type(s.contact.method).__name__,
                         "nodes": int(len(s.nodes)), "closed_nodes": int(np.sum(c["p_N"] > 0)),
                         "max_p_N": float(np.max(c["p_N"])) + 0.0 if len(c["p_N"]) else 0.0})
    summary["contact"] = surfaces
    summary["responses"] = {r.name: {"type": r.type, **_response_values(sol, problem, r)}
                            for r in cfg.responses}
    if cfg.vtu:
        io.write_vtu(sol, out / f"{cfg.stem}.vtu")
        files.append(f"{cfg.stem}.vtu")
    if cfg.pvd and (cfg.steps > 1 or len(sol.increments) > 1):
        io.write_pvd(sol, out / f"{cfg.stem}.pvd")
        files.append(f"{cfg.stem}.pvd")
        files.extend(f"{cfg.stem}_{i + 1:04d}.vtu" for i in range(len(sol.increments)))


def run(path, out, *, solver="auto", progress=None, force_size: bool = False) -> dict:
    """Load a problem file, solve it with DDM sensitivities and write the results.

    Args:
        path: the TOML problem file (schema: module docstring).
        out: output directory (created if needed).
        solver: linear solver name for :func:`signorini.solve`.
        progress: reserved for progress reporting (accepted, not used yet).
        force_size: run even if the estimated memory exceeds what is available.

    Returns:
        The summary (also written to ``out/summary.json``).

    Raises:
        InputError: an invalid file (nothing is written).
        ConvergenceError: the solve failed; the converged increments' results
            and ``summary.json`` with ``"status": "failed"`` and the reason are
            written first.
    """


    problem, cfg = load(path)
    out = prepare_output(out)
    n_contact = sum(len(np.unique(problem.mesh.edge_set(c.edges))) * c.method.n_multipliers
                    for c in problem.contact)
    check_size(2 * problem.mesh.n_nodes + n_contact, force=force_size, what=str(cfg.path))
    summary = {
        "file": str(cfg.path), "title": cfg.title, "status": "running",
        "params": dict(problem.params),
        "mesh": {"nodes": problem.mesh.n_nodes, "cells": problem.mesh.n_cells},
        "steps": cfg.steps, "sensitivities": list(cfg.sensitivities),
        "options": {"rtol": cfg.options.rtol, "atol": cfg.options.atol,
                    "max_iter": cfg.options.max_iter, "max_cuts": cfg.options.max_cuts,
                    "predictor": cfg.options.predictor},
    }

    solver = use_solver(solver)
    summary["solver"] = solver.name
    t0 = time.perf_counter()
    error = None
    try:
        sol = solve(problem, steps=cfg.steps, wrt=list(cfg.sensitivities),
                    options=cfg.options, solver=solver, label="base")
    except SolverError as e:  # ConvergenceError keeps the converged increments in .partial
        error, sol = e, getattr(e, "partial", None)
    summary["time_solve_s"] = time.perf_counter() - t0
    summary["status"] = "failed" if error is not None else "converged"
    if error is not None:
        summary["reason"] = str(error)
    if sol is not None:
        summary["mesh"]["dofs"] = int(sol.model.n_dof)
        summary["increments"] = len(sol.increments)
        summary["load_factors"] = [float(inc.t) for inc in sol.increments]
        summary["newton_iterations"] = list(sol.newton_iterations)
        summary["newton_log"] = [  # every attempted increment, including cut and failed ones
            {"t": float(s.t), "dt": float(s.dt), "iterations": s.iterations,
             "converged": bool(s.converged), **({"reason": s.reason} if s.reason else {})}
            for s in getattr(sol, "log", [])]
        summary["warnings"] = _jsonable(list(getattr(sol, "warnings", [])))
    else:
        summary.update(increments=0, load_factors=[], newton_iterations=[], newton_log=[], warnings=[])
    summary["contact"], summary["responses"], summary["outputs"] = [], {}, []
    if sol is not None:
        try:
            _write_results(sol, problem, cfg, out, summary)
        except Exception as e:  # noqa: BLE001  (keep the solver's error; record this one)
            if error is None:
                raise
            summary["output_error"] = f"{type(e).__name__}: {e}"
    summary["outputs"].insert(0, "summary.json")
    summary = _jsonable(summary)
    io.write_json(out / "summary.json", summary)
    if error is not None:
        raise error
    return summary
