"""Problem description files (TOML): loading, validation, run outputs, DDM vs FD."""

import csv
import json
import re
import warnings
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.app import problemfile as pf
from signorini.fem.meshfile import read_mesh

BLOCK = """\
title = "block on a cylinder"

[params]
E = 100.0
nu = 0.3
P = 2.0
R = 20.0
W = 2.0

[mesh]
type = "rectangle"
x = [0.0, "W"]
y = [-1.0, 0.0]
nx = 8
ny = 4

[material]
type = "linear_elastic"
E = "E"
nu = "nu"

[[fixed]]
set = "left"
component = "x"

[[load]]
type = "pressure"
edges = "bottom"
value = "P"
resultant = true

[[contact]]
edges = "top"
obstacle = { type = "circle", radius = "R", centre = [0.0, "R"] }
method = "al"

[solve]
steps = 1
sensitivities = ["R", "E", "W"]

[[response]]
name = "p_max"
type = "max_pressure"

[[response]]
name = "sink"
type = "displacement"
set = "bottom"
component = "y"
"""


def _write(tmp_path, text, name="problem.toml"):
    f = tmp_path / name
    f.write_text(text)
    return f


def _set_param(text, name, value):
    new, n = re.subn(rf"(?m)^{name} = .*$", f"{name} = {value!r}", text, count=1)
    assert n == 1
    return new


def _csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "status"}


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sg.SignoriniWarning)  # coarse-mesh warnings of the solver
        yield


def test_load_builds_the_problem(tmp_path):
    problem, cfg = pf.load(_write(tmp_path, BLOCK))
    assert problem.params == {"E": 100.0, "nu": 0.3, "P": 2.0, "R": 20.0, "W": 2.0}
    assert problem.mesh.n_cells == 32 and np.isclose(problem.mesh.nodes[:, 0].max(), 2.0)
    assert set(problem.shape) == {"W"}  # x = [0, "W"]: W is a shape parameter
    assert problem.fixed == (sg.Fixed("left", 0, 0.0),)
    (c,) = problem.contact
    assert c.edges == "top" and c.obstacle == sg.Circle("R", (0.0, "R"))
    assert np.isclose(c.method.eps, 100.0 / 0.25)  # default E/h
    assert cfg.steps == 1 and cfg.sensitivities == ("R", "E", "W") and cfg.stem == "problem"
    assert [r.name for r in cfg.responses] == ["p_max", "sink"]


def test_toml_equals_python_problem(tmp_path):
    out = tmp_path / "out"
    summary = pf.run(_write(tmp_path, BLOCK), out)
    assert summary["status"] == "converged"
    mesh = sg.rectangle(np.linspace(0, 2, 9), np.linspace(-1, 0, 5))
    pb = sg.Problem(mesh, sg.LinearElastic("E", "nu"),
                    {"E": 100.0, "nu": 0.3, "P": 2.0, "R": 20.0},
                    fixed=(sg.Fixed("left", 0),),
                    loads=(sg.Pressure("bottom", "P", resultant=True),),
                    contact=(sg.Contact(sg.Circle("R", (0.0, "R")), "top",
                                        sg.AugmentedLagrangian(400.0)),))
    ref = sg.solve(pb, wrt=["R", "E"])
    c = ref.contact()
    assert (c["p_N"] > 0).sum() >= 2
    scale = np.abs(c["p_N"]).max()
    problem, cfg = pf.load(tmp_path / "problem.toml")
    c_file = sg.solve(problem, steps=cfg.steps, wrt=cfg.sensitivities,
                      options=cfg.options).contact()
    np.testing.assert_allclose(c_file["p_N"], c["p_N"], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(c_file["dp_N_dR"], c["dp_N_dR"], rtol=0,
                               atol=1e-10 * np.abs(c["dp_N_dR"]).max())
    # the CSV written by run() holds the same values (12 significant digits)
    got = _csv(out / "contact.csv")
    np.testing.assert_allclose(got["p_N"], c["p_N"], rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(got["x_ref"], c["x_ref"][:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["dp_N_dR"], c["dp_N_dR"], rtol=0,
                               atol=1e-11 * np.abs(c["dp_N_dR"]).max())
    # summary.json on disk is the returned summary
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["responses"]["p_max"]["value"] == pytest.approx(scale, rel=1e-12)
    assert on_disk["newton_iterations"] == ref.newton_iterations
    assert on_disk["mesh"] == {"nodes": 45, "cells": 32, "dofs": ref.model.n_dof}
    assert isinstance(on_disk["warnings"], list)
    assert set(on_disk["outputs"]) == {"summary.json", "contact.csv", "problem.vtu"}
    assert not (out / "problem.pvd").exists()  # one increment: no series
    back = meshio.read(out / "problem.vtu")
    np.testing.assert_allclose(back.point_data["displacement"][:, :2], ref.displacement(), atol=1e-12)


@pytest.mark.parametrize("name", ["R", "W"])
def test_ddm_in_outputs_equals_fd_of_file_runs(tmp_path, name):
    """DDM sensitivity written by run() == central FD of two runs of the file
    with the parameter changed in [params] (R: obstacle, W: shape parameter)."""
    text = BLOCK.replace("[solve]", "[output]\nvtu = false\n\n[solve]")
    base = pf.run(_write(tmp_path, text), tmp_path / "base")
    c0 = _csv(tmp_path / "base" / "contact.csv")
    v = pf.load(tmp_path / "problem.toml")[0].params[name]
    h = 1e-6 * v
    runs = {}
    for sign in (1, -1):
        f = _write(tmp_path, _set_param(text, name, v + sign * h), f"p{sign}.toml")
        s = pf.run(f, tmp_path / f"fd{sign}")
        runs[sign] = (s, _csv(tmp_path / f"fd{sign}" / "contact.csv"))
    inner = c0["p_N"] > 1e-3 * c0["p_N"].max()
    fd = (runs[1][1]["p_N"] - runs[-1][1]["p_N"]) / (2 * h)
    ddm = c0[f"dp_N_d{name}"]
    assert np.abs(ddm[inner]).max() > 0
    assert np.abs(ddm[inner] - fd[inner]).max() <= 1e-5 * np.abs(ddm[inner]).max()
    for r in ("p_max", "sink"):
        fd_r = (runs[1][0]["responses"][r]["value"] - runs[-1][0]["responses"][r]["value"]) / (2 * h)
        ddm_r = base["responses"][r]["sensitivities"][name]
        assert abs(ddm_r - fd_r) <= 1e-5 * abs(ddm_r), (r, ddm_r, fd_r)


def test_gmsh_mesh_file(tmp_path):
    ref = sg.rectangle(np.linspace(0, 2, 9), np.linspace(-1, 0, 5))
    groups = {"top": 2, "bottom": 3, "left": 4}
    lines, tags = [], []
    for g, tag in groups.items():
        e = ref.edge_sets[g][:, ::-1] if g == "bottom" else ref.edge_sets[g]  # any direction
        lines.append(e)
        tags.append(np.full(len(e), tag))
    msh = meshio.Mesh(np.column_stack([ref.nodes, np.zeros(ref.n_nodes)]),
                      [("quad", ref.cells), ("line", np.vstack(lines))],
                      cell_data={"gmsh:physical": [np.ones(ref.n_cells, int), np.concatenate(tags)],
                                 "gmsh:geometrical": [np.ones(ref.n_cells, int), np.concatenate(tags)]},
                      field_data={"body": np.array([1, 2]),
                                  **{g: np.array([tag, 1]) for g, tag in groups.items()}})
    (tmp_path / "meshes").mkdir()
    msh.write(tmp_path / "meshes" / "body.msh", file_format="gmsh22", binary=False)
    m = read_mesh(tmp_path / "meshes" / "body.msh")
    assert {"top", "bottom", "left"} <= set(m.edge_sets) and "all" in m.node_sets

    text = re.sub(r"(?s)\[mesh\].*?\n\n", '[mesh]\nfile = "meshes/body.msh"\n\n', BLOCK)
    text = text.replace('"R", "E", "W"', '"R", "E"')  # no shape parameter with a file mesh
    problem, _ = pf.load(_write(tmp_path, text))
    assert problem.mesh.n_nodes == ref.n_nodes and not problem.shape
    s_file = pf.run(tmp_path / "problem.toml", tmp_path / "gmsh")
    s_rect = pf.run(_write(tmp_path, BLOCK, "rect.toml"), tmp_path / "rect")
    a, b = _csv(tmp_path / "gmsh" / "contact.csv"), _csv(tmp_path / "rect" / "contact.csv")
    np.testing.assert_allclose(a["p_N"], b["p_N"], rtol=0, atol=1e-12 * b["p_N"].max())
    assert s_file["responses"]["p_max"]["value"] == pytest.approx(
        s_rect["responses"]["p_max"]["value"], rel=1e-12)


def test_mesh_file_warnings_land_in_summary(tmp_path):
    """A suspicious mesh file (a point set with a node outside the body) is heard
    once per load as a SignoriniWarning and listed in summary.json, also when the
    mesh comes from the reader's cache."""
    ref = sg.rectangle(np.linspace(0, 2, 9), np.linspace(-1, 0, 5))
    pts = np.vstack([ref.nodes, [[5.0, 5.0]]])  # the last node belongs to no cell
    groups = {"top": 2, "bottom": 3, "left": 4}
    lines = [ref.edge_sets[g] for g in groups]
    tags = [np.full(len(e), tag) for e, tag in zip(lines, groups.values())]
    msh = meshio.Mesh(np.column_stack([pts, np.zeros(len(pts))]),
                      [("quad", ref.cells), ("line", np.vstack(lines)), ("vertex", [[len(pts) - 1]])],
                      cell_data={"gmsh:physical": [np.ones(ref.n_cells, int), np.concatenate(tags), [5]],
                                 "gmsh:geometrical": [np.ones(ref.n_cells, int), np.concatenate(tags), [5]]},
                      field_data={"body": np.array([1, 2]), "centre": np.array([5, 0]),
                                  **{g: np.array([tag, 1]) for g, tag in groups.items()}})
    msh.write(tmp_path / "body.msh", file_format="gmsh22", binary=False)
    text = re.sub(r"(?s)\[mesh\].*?\n\n", '[mesh]\nfile = "body.msh"\n\n', BLOCK)
    text = text.replace('"R", "E", "W"', '"R", "E"')
    path = _write(tmp_path, text)
    expected = "point set 'centre': 1 node(s) belong to no quadrilateral"
    for attempt in range(2):  # the second load reads the mesh from the cache
        with pytest.warns(sg.SignoriniWarning, match=re.escape(expected)):
            summary = pf.run(path, tmp_path / f"out{attempt}")
        assert summary["status"] == "converged"
        assert summary["time_wall_s"] >= summary["time_solve_s"] > 0
        assert [w for w in summary["warnings"] if expected in w], summary["warnings"]


def test_series_and_friction_columns(tmp_path):
    text = (BLOCK.replace('method = "al"', 'method = "coulomb"\nmu = 0.2')
            .replace("steps = 1", "steps = 3"))
    s = pf.run(_write(tmp_path, text, "fric.toml"), tmp_path / "out")
    assert s["status"] == "converged" and s["load_factors"] == pytest.approx([1 / 3, 2 / 3, 1])
    root = ET.parse(tmp_path / "out" / "fric.pvd").getroot()
    ds = root.findall("./Collection/DataSet")
    assert [float(d.get("timestep")) for d in ds] == pytest.approx(s["load_factors"])
    for d in ds:
        assert "displacement" in meshio.read(tmp_path / "out" / d.get("file")).point_data
    with open(tmp_path / "out" / "contact.csv") as f:
        header = next(csv.reader(f))
    assert {"status", "slip", "p_T", "dp_T_dR", "dp_N_dW"} <= set(header)


DIE = """\
[params]
E = 100.0
nu = 0.3
d = 0.2

[mesh]
type = "rectangle"
x = [0.0, 1.0]
y = [0.0, 1.0]
nx = 4
ny = 4

[material]
type = "linear_elastic"
E = "E"
nu = "nu"

[[fixed]]
set = "bottom"
component = "y"
value = "d"

[[fixed]]
set = "left"
component = 0

[[contact]]
edges = "top"
obstacle = {type = "line", point = [0.0, 1.15], normal = [0.0, -1.0]}

[solve]
steps = 2
sensitivities = ["d"]

[[response]]
name = "force"
type = "reaction"
set = "bottom"
component = 1
"""


def test_failed_run_writes_converged_increments_and_summary(tmp_path):
    """Contact starts in the second increment; one Newton iteration and no step
    cut are allowed, so it fails there (fast) after one converged increment.
    (predictor "none": the extrapolated start, a uniform 0.05 penetration of the
    flat die, is solved exactly by one iteration.)"""
    f = _write(tmp_path, DIE.replace("steps = 2", 'steps = 2\nmax_iter = 1\nmax_cuts = 0\n'
                                                  'predictor = "none"'), "die.toml")
    with pytest.raises(sg.ConvergenceError) as err:
        pf.run(f, tmp_path / "out")
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["status"] == "failed" and s["reason"] == str(err.value)
    assert s["increments"] == 1 and s["load_factors"] == [0.5]
    assert s["newton_log"][-1]["converged"] is False
    assert s["responses"]["force"]["value"] == pytest.approx(0.0, abs=1e-9)  # no contact yet
    for name in ("contact.csv", "die.vtu", "die.pvd", "die_0001.vtu"):
        assert (tmp_path / "out" / name).exists(), name
        assert name in s["outputs"]


def test_failure_without_any_increment(tmp_path):
    """A force-loaded body that does not touch the obstacle fails at once."""
    text = BLOCK.replace('centre = [0.0, "R"]', "centre = [0.0, 20.1]")
    with pytest.raises(sg.ConvergenceError):
        pf.run(_write(tmp_path, text), tmp_path / "out")
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["status"] == "failed" and s["increments"] == 0 and "not held" in s["reason"]
    assert s["outputs"] == ["summary.json"]


def test_displacement_control_reaction_response(tmp_path):
    s = pf.run(_write(tmp_path, DIE, "die.toml"), tmp_path / "out")
    r = s["responses"]["force"]
    # the die stops the block: the supports push it up (positive y reaction)
    assert r["value"] > 0 and r["sensitivities"]["d"] > 0
    h = 1e-6
    vals = [pf.run(_write(tmp_path, _set_param(DIE, "d", 0.2 + sg_ * h), "d.toml"),
                   tmp_path / "fd")["responses"]["force"]["value"] for sg_ in (1, -1)]
    assert (vals[0] - vals[1]) / (2 * h) == pytest.approx(r["sensitivities"]["d"], rel=1e-5)


# ------------------------------------------------------------ bad files

def _sub(old, new, count=1):
    def f(text):
        assert old in text, old
        return text.replace(old, new, count)
    return f


BAD = [
    # (edit of BLOCK, error type, fragment of the message)
    (_sub('E = "E"', 'Ee = "E"'), sg.InputError, "[material] unknown key 'Ee' (did you mean 'E'?); "
     "allowed: E, nu, type"),
    (_sub('nu = "nu"\n', 'nu = "nu"\nrho = 1.0\n'), sg.InputError, "[material] unknown key 'rho'"),
    (_sub('E = "E"', 'E = "Young"'), sg.UnknownParameterError, "[material] E: 'Young' is not a parameter"),
    (_sub('radius = "R"', 'radius = "RR"'), sg.UnknownParameterError,
     "[[contact]] #1 obstacle radius: 'RR' is not a parameter"),
    (_sub('"R", "E", "W"', '"R", "E", "mu"'), sg.UnknownParameterError,
     "[solve] sensitivities: 'mu' is not a parameter"),
    (_sub("[solve]", "[solver]"), sg.InputError, "unknown table or key 'solver' (did you mean [solve]?)"),
    (_sub("nx = 8", 'nx = "eight"'), sg.InputError, "[mesh] nx: expected an integer, got a string"),
    (_sub("nx = 8", "nx = 0"), sg.InputError, "[mesh] nx: must be >= 1"),
    (_sub('x = [0.0, "W"]', 'x = ["W", 0.0]'), sg.InputError, "[mesh] x: must be increasing"),
    (_sub('x = [0.0, "W"]\n', ""), sg.InputError, "[mesh] missing required key 'x'"),
    (_sub('type = "rectangle"', 'type = "disc"'), sg.InputError,
     "[mesh] type: 'disc' is not one of 'rectangle'"),
    (_sub('type = "rectangle"', 'file = "nowhere.msh"\ntype = "rectangle"'), sg.InputError,
     "give either file"),
    (_sub('type = "linear_elastic"', 'type = "linear_elastik"'), sg.InputError,
     "[material] type: 'linear_elastik' is not one of 'linear_elastic', 'neo_hooke', 'j2' "
     "(did you mean 'linear_elastic'?)"),
    (_sub("nu = 0.3", "nu = 0.6"), sg.InputError, "[material] Poisson's ratio"),
    (_sub("nu = 0.3", 'nu = "0.3"'), sg.InputError, "[params] nu: expected a number"),
    (_sub("[[fixed]]", "[fixed]"), sg.InputError, "[fixed] must be an array of tables: write [[fixed]]"),
    (_sub('component = "x"', 'component = "z"'), sg.InputError, "[[fixed]] #1 component: expected 0, 1"),
    (_sub('set = "left"', 'set = "lft"'), sg.InputError,
     "[[fixed]] #1 set: 'lft' is not a node set of the mesh"),
    (_sub('edges = "top"', 'edges = "tp"'), sg.InputError,
     "[[contact]] #1 edges: 'tp' is not an edge set of the mesh"),
    (_sub('radius = "R", ', ""), sg.InputError, "[[contact]] #1 obstacle missing required key 'radius'"),
    (_sub('type = "circle"', 'type = "sphere"'), sg.InputError,
     "[[contact]] #1 obstacle type: 'sphere' is an obstacle of 3-D problems; the mesh is 2-D, "
     "whose obstacles are 'circle', 'line', 'implicit' (line 34)"),
    (_sub('method = "al"', 'method = "penalty"'), sg.InputError, "[[contact]] #1 missing required key 'eps'"),
    (_sub('method = "al"', 'method = "al"\nmu = 0.3'), sg.InputError,
     "[[contact]] #1 mu: applies only to method = \"coulomb\""),
    (_sub('method = "al"', 'method = "coulomb"'), sg.InputError, "[[contact]] #1 missing required key 'mu'"),
    (_sub('method = "al"', 'method = "al"\neps = -1.0'), sg.InputError,
     "[[contact]] #1 the augmented-Lagrangian parameter must be positive"),
    (_sub('value = "P"', 'value = ["P", 0.0]'), sg.InputError, "[[load]] #1 value: a pressure is a scalar"),
    (_sub('type = "pressure"', 'type = "traction"'), sg.InputError,
     "[[load]] #1 value: expected a list of 2 numbers [a, b] (the mesh is 2-D)"),
    (_sub("resultant = true", 'resultant = "yes"'), sg.InputError,
     "[[load]] #1 resultant: expected true or false"),
    (_sub("steps = 1", "steps = 0"), sg.InputError, "[solve] steps: must be >= 1"),
    (_sub("steps = 1", "steps = 1\nrtol = -1e-8"), sg.InputError, "[solve] rtol: must be a non-negative"),
    (_sub("steps = 1", "steps = 1\nrtol = 2.0"), sg.InputError, "[solve] rtol: must be below 1"),
    (_sub("steps = 1", "steps = 1\nrtol = nan"), sg.InputError, "[solve] rtol: must be a non-negative"),
    (_sub('type = "max_pressure"', 'type = "max_pressure"\nset = "top"'), sg.InputError,
     "[[response]] #1 unknown key 'set'"),
    (_sub('type = "displacement"', 'type = "reaction"'), sg.InputError,
     "[[response]] #2 reaction of set 'bottom', component 1: node(s)"),
    (_sub('name = "sink"', 'name = "p_max"'), sg.InputError, "[[response]] #2 name: 'p_max' is used by two"),
    (_sub("[params]", "[params\n"), sg.InputError, "TOML syntax error"),
    (_sub("nx = 8", "nx = 8\nnx = 9"), sg.InputError, "line 15"),
    (_sub("[mesh]", "[mesh_]"), sg.InputError, "unknown table or key 'mesh_' (did you mean [mesh]?)"),
    (lambda t: t.replace('[material]\ntype = "linear_elastic"\nE = "E"\nnu = "nu"\n', ""), sg.InputError,
     "missing required table [material]"),
    (_sub("[solve]", "[output]\nvtk = true\n\n[solve]"), sg.InputError,
     "[output] unknown key 'vtk' (did you mean 'vtu'?); allowed: csv, pvd, vtu"),
]


@pytest.mark.parametrize("edit, exc, fragment", BAD, ids=[b[2][:40] for b in BAD])
def test_bad_files(tmp_path, edit, exc, fragment):
    f = _write(tmp_path, edit(BLOCK))
    with pytest.raises(exc) as err:
        pf.load(f)
    msg = str(err.value)
    assert msg.startswith(str(f) + ": "), msg
    assert fragment in msg, msg


def test_bad_mesh_file_and_missing_problem_file(tmp_path):
    text = re.sub(r"(?s)\[mesh\].*?\n\n", '[mesh]\nfile = "body.msh"\n\n', BLOCK)
    f = _write(tmp_path, text)
    with pytest.raises(sg.InputError, match=r"\[mesh\] file = 'body.msh'.*not found"):
        pf.load(f)
    (tmp_path / "body.msh").write_text("this is not a mesh\n")
    with pytest.raises(sg.InputError, match=r"\[mesh\] file = 'body.msh'.*not a readable mesh"):
        pf.load(f)
    with pytest.raises(sg.InputError, match="problem file not found"):
        pf.load(tmp_path / "missing.toml")
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00title")
    with pytest.raises(sg.InputError, match="bin.toml"):
        pf.load(tmp_path / "bin.toml")


# ------------------------------------------- [mesh] file of the wrong dimension
def _mesh_file(tmp_path, kind):
    """A mesh file the problem-file format does not take; its name."""
    from signorini.fem.mesh3d import box, tetrahedra

    hexes = box(np.linspace(0, 2, 3), np.linspace(0, 1, 2), np.linspace(-1, 0, 2))
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    if kind == "empty":
        (tmp_path / "body.msh").write_text("")
        return "body.msh"
    if kind == "text":
        (tmp_path / "body.msh").write_text("the mesh goes here\n")
        return "body.msh"
    name, cells, points = {
        "hexahedra": ("body.msh", [("hexahedron", hexes.cells), ("quad", hexes.face_sets["z1"])],
                      hexes.nodes),
        "tetrahedra": ("body.vtu", [("tetra", tetrahedra(hexes).cells)], hexes.nodes),
        "wedges": ("body.vtu", [("wedge", np.array([[0, 1, 2, 3, 4, 1]]))], pts),
        "lines": ("body.msh", [("line", np.array([[0, 1], [1, 2]]))], pts),
        "triangles": ("body.msh", [("triangle", np.array([[0, 1, 2]]))], pts[:3]),
    }[kind]
    fmt = {"file_format": "gmsh22", "binary": False} if name.endswith(".msh") else {}
    meshio.Mesh(points, cells).write(tmp_path / name, **fmt)
    return name


NOT_3D = "; [mesh] dim = 2 asks for a 2-D mesh"
BAD_MESH_FILES = [
    # (mesh file, fragments of the message after "<toml>: [mesh] file = '<name>': <path>: ")
    ("hexahedra", ["a 3-D mesh (cells: 2 hexahedron, 2 quad), where a 2-D mesh of quadrilaterals "
                   "in the z = 0 plane is expected" + NOT_3D]),
    ("tetrahedra", ["a 3-D mesh (cells: 12 tetra)", NOT_3D]),
    ("wedges", ["a 3-D mesh (cells: 1 wedge)", NOT_3D]),
    ("lines", ["no cells of a body (cells: 2 line); a mesh file needs the cells of a body"]),
    ("triangles", ["no quadrilateral cells (found ['triangle']); a 2-D mesh is made of 4-node "
                   "quadrilaterals (in gmsh: Recombine Surface)"]),
    ("empty", ["the mesh file is empty"]),
    ("text", ["not a readable mesh file"]),
]


@pytest.mark.parametrize("kind, fragments", BAD_MESH_FILES, ids=[b[0] for b in BAD_MESH_FILES])
def test_mesh_file_of_the_wrong_kind(tmp_path, kind, fragments):
    """A [mesh] file that the format does not take (3-D: not yet; no cells of a
    body, triangles, empty, not a mesh) is an InputError naming the problem file,
    the key, the mesh file and what is expected, before anything is solved."""
    name = _mesh_file(tmp_path, kind)
    f = _write(tmp_path, re.sub(r"(?s)\[mesh\].*?\n\n", f'[mesh]\nfile = "{name}"\ndim = 2\n\n', BLOCK))
    with pytest.raises(sg.InputError) as err:
        pf.load(f)
    msg = str(err.value)
    assert msg.startswith(f"{f}: [mesh] file = {name!r}: {tmp_path / name}: "), msg
    for fragment in fragments:
        assert fragment in msg, msg
    assert (NOT_3D in msg) == (kind in ("hexahedra", "tetrahedra", "wedges"))


@pytest.mark.parametrize("kind", ["hexahedra", "lines"])
def test_run_command_on_a_3d_or_cell_less_mesh_exits_2(tmp_path, capsys, kind):
    """``signorini run`` on such a file: exit code 2 and one ``signorini: error:``
    line with the message, no traceback, no output directory."""
    from signorini.app.cli import main

    name = _mesh_file(tmp_path, kind)
    f = _write(tmp_path, re.sub(r"(?s)\[mesh\].*?\n\n", f'[mesh]\nfile = "{name}"\ndim = 2\n\n', BLOCK))
    capsys.readouterr()
    assert main(["run", str(f), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    expected = NOT_3D if kind == "hexahedra" else "no cells of a body (cells: 2 line)"
    assert err.startswith(f"signorini: error: {f}: [mesh] file = {name!r}: "), err
    assert expected in err and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()
