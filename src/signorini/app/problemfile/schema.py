"""Reading a TOML problem file into a :class:`~signorini.model.problem.Problem` and
a :class:`RunConfig` (the schema: :mod:`signorini.app.problemfile`, docs/problem-files.md)."""


from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ... import responses as public
from ...algorithms.newton import NewtonOptions
from ...contact import AugmentedLagrangian, Contact, Coulomb, Penalty, pair
from ...contact.obstacles3d import Implicit
from ...errors import InputError, UnknownParameterError
from ...fem.loads import Fixed, Pressure, Traction
from ...model.problem import Problem
from . import parts
from .fitfile import read_fit
from .reader import Reader, Table, kind, read_toml

__all__ = ["Response", "RunConfig", "load"]

_TOP = {"title": "a string", "params": "[params]", "mesh": "[mesh]", "material": "[material]",
        "body": "[[body]]", "fixed": "[[fixed]]", "load": "[[load]]", "contact": "[[contact]]",
        "pair": "[[pair]]", "solve": "[solve]", "response": "[[response]]", "output": "[output]",
        "fit": "[fit]"}
#: the responses of signorini.responses a file can name (and fit)
PUBLIC = ("contact_force", "reaction", "displacement", "contact_area", "max_pressure",
          "pressure_norm", "contact_work", "stick_area")
_RESPONSE_TYPES = PUBLIC + ("normal_force",)
_SURFACE = ("contact_force", "contact_area", "max_pressure", "pressure_norm", "contact_work",
            "stick_area", "normal_force")


@dataclass(frozen=True)
class Response:
    """A scalar result requested by ``[[response]]``.

    Attributes:
        name: the key in ``summary.json["responses"]``.
        type: one of the responses of :mod:`signorini.responses` (``contact_force``,
            ``reaction``, ``displacement``, ``contact_area``, ``max_pressure``,
            ``pressure_norm``, ``contact_work``, ``stick_area``) or ``normal_force``.
        surface: index of the contact surface (surface responses).
        node_set: node set (displacement and reaction responses).
        component: 0 (x), 1 (y), 2 (z) (displacement, reaction; contact_force:
            None for its magnitude).
        order: the exponent of ``pressure_norm``.
    """
    name: str
    type: str
    surface: int | None = None
    node_set: str | None = None
    component: int | None = None
    order: float = 8.0
    adjoint: bool = False  #: also its gradient w.r.t. every parameter by the adjoint method

    def public(self) -> public.Response:
        """The :mod:`signorini.responses` object of this response (what sg.fit takes)."""
        if self.type == "normal_force":
            raise InputError(f"response {self.name!r}: normal_force is a problem-file response "
                             "only; use type = \"contact_force\" with a component")
        if self.type in ("reaction", "displacement"):
            r = getattr(public, self.type)(self.node_set, self.component)
        elif self.type == "contact_force":
            r = public.contact_force(self.surface, self.component)
        elif self.type == "pressure_norm":
            r = public.pressure_norm(self.surface, self.order)
        else:
            r = getattr(public, self.type)(self.surface)
        r.name = self.name
        return r


@dataclass(frozen=True)
class RunConfig:
    """How to solve a problem file and what to write (``[solve]``, ``[output]``,
    ``[[response]]``, ``[fit]``), and what reading it found suspicious
    (``warnings``, also raised as :class:`~signorini.errors.SignoriniWarning`)."""
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
    fit: object = None  #: the [fit] section (:class:`.fitfile.FitSpec`) or None
    dim: int = 2

    @property
    def stem(self) -> str:
        return self.path.stem


def _array(rd: Reader, doc: dict, key: str) -> list:
    v = doc.get(key, [])
    if isinstance(v, dict):
        raise rd.error(f"[{key}]", f"must be an array of tables: write [[{key}]] (double brackets) "
                                   "for each entry")
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise rd.error(f"[[{key}]]", f"must be an array of tables ([[{key}]] entries), got {kind(v)}")
    return v


def _node_set(t: Table, mesh, key: str) -> str:
    name = t.string(key)
    if name not in mesh.node_sets:
        raise t.err(key, f"{name!r} is not a node set of the mesh; the mesh has "
                         f"{', '.join(sorted(mesh.node_sets))}")
    return name


def _boundary_key(rd: Reader) -> str:
    return "faces" if rd.dim == 3 else "edges"


def _boundary(t: Table, mesh, key: str | None = None) -> str:
    """An edge set (2-D, key ``edges``) or face set (3-D, key ``faces``)."""
    rd = t.rd
    key = key or _boundary_key(rd)
    wrong = "edges" if rd.dim == 3 else "faces"
    if key in ("edges", "faces") and t.has(wrong):
        raise t.err(wrong, f"the mesh is {rd.dim}-D: name its boundary set with {key} = \"...\" "
                           f"({'face sets in 3-D' if rd.dim == 3 else 'edge sets in 2-D'})")
    name = t.string(key)
    sets = mesh.face_sets if rd.dim == 3 else mesh.edge_sets
    what = "a face set" if rd.dim == 3 else "an edge set"
    if name not in sets:
        hint = ("gmsh physical surfaces, or x0/x1/y0/y1/z0/z1 of a box" if rd.dim == 3 else
                "gmsh physical lines, or left/right/bottom/top of a rectangle")
        raise t.err(key, f"{name!r} is not {what} of the mesh; the mesh has "
                         f"{', '.join(sorted(sets)) or 'none'} (boundary sets: {hint})")
    return name


def _shortest(mesh, name: str, dim: int) -> float:
    f = mesh.face_sets[name] if dim == 3 else mesh.edge_sets[name]
    X = mesh.nodes
    return float(min(np.linalg.norm(X[np.roll(f, -1, axis=1)] - X[f], axis=-1).min(), np.inf))


def _law(rd: Reader, t: Table, where: str, h: float, E: float):
    """The contact law of a [[contact]] or [[pair]]: method, eps, mu, eps_t."""
    method = t.string("method", "al", choices=("al", "penalty", "coulomb"))
    if method != "coulomb":
        for key in ("mu", "eps_t"):
            if t.has(key):
                raise t.err(key, f"applies only to method = \"coulomb\" (this surface has method = "
                                 f"{method!r}); remove it or change the method")
    if method == "penalty" and not t.has("eps"):
        raise rd.error(where, "missing required key 'eps': the penalty solution depends on it; add "
                              "eps = ... (e.g. 100 E/h for about 1 % penetration error)")
    eps = t.spec("eps") if t.has("eps") else float(E) / h
    if method == "al":
        meth = AugmentedLagrangian(eps)
    elif method == "penalty":
        meth = Penalty(eps)
    else:
        meth = Coulomb(mu=t.spec("mu"), eps_n=eps, eps_t=t.spec("eps_t", eps))
    try:
        meth.check(rd.params)
    except InputError as err:
        raise rd.error(where, f"{err}", key="eps" if t.has("eps") else None) from None
    return meth, t.string("kinematics", "auto", choices=("auto", "linear", "finite"))


def _contact(rd: Reader, k: int, data, mesh, E: float):
    where = f"[[contact]] #{k + 1}"
    t = Table(rd, where, data, {"edges", "faces", "obstacle", "method", "eps", "mu", "eps_t",
                                "kinematics"}, required=("obstacle",))
    name = _boundary(t, mesh)
    ob = parts.obstacle(rd, where, data["obstacle"])
    meth, kin = _law(rd, t, where, _shortest(mesh, name, rd.dim), E)
    if rd.dim == 2 and isinstance(meth, Coulomb) and isinstance(ob, Implicit):
        raise t.err("method", "a 2-D implicit obstacle takes frictionless laws "
                              "only (\"al\", \"penalty\"): Coulomb friction in 2-D needs a circle or "
                              "a line")
    return Contact(ob, name, meth, kinematics=kin)


def _pair(rd: Reader, k: int, data, mesh, E: float):
    where = f"[[pair]] #{k + 1}"
    t = Table(rd, where, data, {"slave", "master", "method", "eps", "mu", "eps_t", "kinematics",
                                "slide", "search"}, required=("slave", "master"))
    slave, master = _boundary(t, mesh, "slave"), _boundary(t, mesh, "master")
    if slave == master:
        raise t.err("master", f"the slave and master surfaces are both {slave!r}; name two sets")
    meth, kin = _law(rd, t, where, _shortest(mesh, slave, rd.dim), E)
    extra = {k: t.real(k, positive=k == "search", nonnegative=k == "slide")
             for k in ("slide", "search") if t.has(k)}
    return pair(slave, master, meth, kinematics=kin, **extra)


def _ramp(t: Table, where: str, data):
    r = parts._path(t, where, data)
    return {} if r is None else {"ramp": r}


def _fixed(rd: Reader, k: int, data, mesh) -> Fixed:
    where = f"[[fixed]] #{k + 1}"
    t = Table(rd, where, data, {"set", "component", "value", "ramp", "table"},
              required=("set", "component"))
    comps = t.get("component", None)
    if isinstance(comps, list):
        raise t.err("component", "one component per [[fixed]] table; write one table for each")
    return Fixed(_node_set(t, mesh, "set"), t.component("component"), t.spec("value", 0.0),
                 **_ramp(t, where, data))


def _load(rd: Reader, k: int, data, mesh):
    where = f"[[load]] #{k + 1}"
    t = Table(rd, where, data, {"type", "edges", "faces", "value", "resultant", "ramp", "table"},
              required=("type", "value"))
    ty = t.string("type", choices=("pressure", "traction"))
    name = _boundary(t, mesh)
    resultant = t.boolean("resultant", False)
    ramp = _ramp(t, where, data)
    if ty == "pressure":
        if isinstance(data["value"], list):
            raise t.err("value", "a pressure is a scalar (positive pushes into the body); for a "
                                 "force vector use type = \"traction\" with value = [fx, fy(, fz)]")
        return Pressure(name, t.spec("value"), resultant=resultant, **ramp)
    return Traction(name, t.vector("value"), resultant=resultant, **ramp)


def _solve(rd: Reader, data):
    t = Table(rd, "[solve]", data, {"steps", "sensitivities", "rtol", "atol", "max_iter", "max_cuts",
                                    "predictor", "start", "reuse_factor"})
    steps = t.integer("steps", 1, minimum=1)
    sens = t.get("sensitivities", [])
    if not isinstance(sens, list) or not all(isinstance(s, str) for s in sens):
        raise t.err("sensitivities", f"expected a list of parameter names such as [\"E\", \"R\"], "
                                     f"got {kind(sens)}")
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
                         predictor=t.string("predictor", d.predictor, choices=("extrapolate", "none")),
                         start=t.string("start", d.start, choices=("auto", "coarse", "rest")),
                         reuse_factor=t.string("reuse_factor", d.reuse_factor,
                                               choices=("auto", "always", "never"))) \
        if any(t.has(k) for k in ("rtol", "atol", "max_iter", "max_cuts", "predictor", "start",
                                  "reuse_factor")) else d
    if not (opts.rtol > 0 or opts.atol > 0):
        raise t.err("rtol", "rtol or atol must be positive")
    return steps, tuple(sens), opts


def _surface_index(rd: Reader, t: Table, where: str, kind_: str, contacts) -> int:
    if not contacts:
        raise rd.error(where, f"type = {kind_!r} needs a [[contact]] or [[pair]] surface; the file "
                              "has none")
    if not t.has("surface"):
        return 0
    name = t.string("surface")
    found = [i for i, c in enumerate(contacts) if c.edges == name]
    if not found:
        raise t.err("surface", f"{name!r} is not the surface of any [[contact]] or [[pair]] slave "
                               f"(they are {', '.join(c.edges for c in contacts)})")
    return found[0]


def _responses(rd: Reader, items: list, mesh, contacts, fixed) -> tuple[Response, ...]:
    out, names = [], set()
    for k, data in enumerate(items):
        where = f"[[response]] #{k + 1}"
        t = Table(rd, where, data, {"name", "type", "surface", "set", "component", "order", "adjoint"},
                  required=("name", "type"))
        adjoint = t.boolean("adjoint", False)
        if adjoint and t.get("type", None) == "normal_force":
            raise t.err("adjoint", "normal_force has no adjoint here; use type = \"contact_force\"")
        name = t.string("name")
        if name in names:
            raise t.err("name", f"{name!r} is used by two responses; give each a unique name")
        names.add(name)
        ty = t.string("type", choices=_RESPONSE_TYPES)
        if ty in _SURFACE:
            allowed = {"name", "type", "surface", "adjoint"} | ({"component"} if ty == "contact_force" else set()) \
                | ({"order"} if ty == "pressure_norm" else set())
            Table(rd, where, data, allowed)
            surf = _surface_index(rd, t, where, ty, contacts)
            comp = t.component("component") if t.has("component") else None
            order = t.real("order", 8.0, positive=True)
            out.append(Response(name, ty, surface=surf, component=comp, order=order, adjoint=adjoint))
            continue
        Table(rd, where, data, {"name", "type", "set", "component", "adjoint"},
              required=("name", "type", "set", "component"))
        node_set, comp = _node_set(t, mesh, "set"), t.component("component")
        if ty == "reaction":
            fixed_nodes = set()
            for f in fixed:
                if f.component == comp:
                    fixed_nodes.update(int(n) for n in mesh.node_set(f.node_set))
            free = sorted({int(n) for n in mesh.node_set(node_set)} - fixed_nodes)
            if free:
                raise rd.error(where, f"reaction of set {node_set!r}, component {comp}: node(s) "
                                      f"{free[:5]} are not prescribed by any [[fixed]] in that "
                                      "component; reactions exist only on prescribed DOFs", key="set")
        out.append(Response(name, ty, node_set=node_set, component=comp, adjoint=adjoint))
    return tuple(out)


def load(path, *, force_size: bool = False, solver="auto") -> tuple[Problem, RunConfig]:
    """Read a problem file (schema: docs/problem-files.md). A generated mesh is
    refused before it is built if it is estimated not to fit in memory with
    ``solver`` (the run's linear solver), unless ``force_size``.

    Returns:
        (problem, config): the :class:`~signorini.model.problem.Problem` at the
        nominal parameter values and the :class:`RunConfig`.

    Raises:
        InputError: syntax errors (with the line), unknown tables or keys,
            missing keys, wrong types or values, unknown sets; the message
            names the file, the key and its line.
        UnknownParameterError: a parameter name that ``[params]`` does not define.
        ResourceError: the generated mesh is estimated not to fit in memory.
    """
    path = Path(path)
    doc, text = read_toml(path)
    rd = Reader(path, text, force_size, solver)
    for k in doc:
        if k not in _TOP:
            near = difflib.get_close_matches(k, list(_TOP), n=1)
            hint = f" (did you mean {_TOP[near[0]]}?)" if near else ""
            tables = ", ".join(v for n, v in _TOP.items() if n != "title")
            raise InputError(f"{rd.label}: unknown table or key {k!r}{hint}; allowed: {tables} "
                             "and the key title")
    bodies = _array(rd, doc, "body")
    if bodies and "material" in doc:
        raise rd.error("[material]", "the file has [[body]] tables, each with its material; "
                                     "remove [material]")
    for k in (("mesh", "material") if not bodies else ()):
        if k not in doc:
            raise InputError(f"{rd.label}: missing required table [{k}] (or [[body]] tables); see "
                             "the schema in docs/problem-files.md")
    title = doc.get("title", "")
    if not isinstance(title, str):
        raise InputError(f"{rd.label}: title must be a string, got {kind(title)}")

    params = doc.get("params", {})
    if not isinstance(params, dict):
        raise InputError(f"{rd.label}: [params] must be a table of name = number, got {kind(params)}")
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise rd.error("[params]", f"{k}: expected a number, got {kind(v)}; parameters are "
                                       "numbers (name = value)", key=k)
        rd.params[k] = float(v)

    if bodies:
        mesh, shape, material, E = parts.bodies(rd, doc, bodies)
    else:
        mesh, shape = parts.mesh(rd, "[mesh]", doc["mesh"])
        rd.dim = int(mesh.nodes.shape[1])
        material, E = parts.material(rd, "[material]", doc["material"])
    fixed = tuple(_fixed(rd, k, d, mesh) for k, d in enumerate(_array(rd, doc, "fixed")))
    loads = tuple(_load(rd, k, d, mesh) for k, d in enumerate(_array(rd, doc, "load")))
    contact = tuple(_contact(rd, k, d, mesh, E) for k, d in enumerate(_array(rd, doc, "contact")))
    contact += tuple(_pair(rd, k, d, mesh, E) for k, d in enumerate(_array(rd, doc, "pair")))
    steps, sens, opts = _solve(rd, doc.get("solve", {}))
    responses = _responses(rd, _array(rd, doc, "response"), mesh, contact, fixed)
    out = Table(rd, "[output]", doc.get("output", {}), {"vtu", "pvd", "csv"})
    fit = None
    if "fit" in doc:
        fit = read_fit(rd, doc["fit"], responses)
    cfg = RunConfig(path=path, title=title, steps=steps, sensitivities=sens, options=opts,
                    responses=responses, vtu=out.boolean("vtu", True), pvd=out.boolean("pvd", True),
                    csv=out.boolean("csv", True), warnings=tuple(rd.warnings), fit=fit, dim=rd.dim)
    try:
        problem = Problem(mesh=mesh, material=material, params=dict(rd.params), fixed=fixed,
                          loads=loads, contact=contact, shape=shape)
    except InputError as e:
        raise type(e)(f"{rd.label}: {e}") from None
    return problem, cfg
