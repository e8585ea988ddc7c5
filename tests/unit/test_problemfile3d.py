"""Problem files in 3-D and with several bodies (issue 52 item 1): every example of
docs/problem-files.md runs; two-body files (2-D and 3-D) give the API script's
solution to round-off; implicit surfaces are parsed safely; bad files get an
error naming the key and its line."""

import re
from pathlib import Path

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.app import problemfile as pf
from signorini.app.problemfile.expr import parse

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "problem-files.md").read_text()
EXAMPLES = re.findall(r"```toml\n(.*?)```", DOC, re.S)


def _title(text):
    return re.search(r'title = "(.*?)"', text).group(1)


def _write(tmp_path, text, name="problem.toml"):
    f = tmp_path / name
    f.write_text(text)
    return f


def _example(start):
    (text,) = [e for e in EXAMPLES if _title(e).startswith(start)]
    return text


def _same(sol, ref, names):
    """Displacements and their sensitivities equal to round-off."""
    u, v = sol.displacement(), ref.displacement()
    scale = np.abs(v).max()
    np.testing.assert_allclose(u, v, rtol=0, atol=1e-12 * scale)
    for n in names:
        du, dv = sol.displacement_sensitivity(n), ref.displacement_sensitivity(n)
        np.testing.assert_allclose(du, dv, rtol=0, atol=1e-10 * max(np.abs(dv).max(), 1e-300))


# ------------------------------------------------------------- the docs' examples
#: the docs' examples by title -> the test that runs it
RUN_BY = {
    "block on a cylinder": "test_cli.py::test_run_command_on_the_shipped_example (examples/block.toml)",
    "a ball, given as an implicit surface": "test_implicit_ball_example_equals_the_api_script_with_a_sphere",
    "a neo-Hookean pad pressed onto an elastic base": "test_two_bodies_2d_file_equals_the_api_script",
    "a block pressed onto a base": "test_two_bodies_3d_file_equals_the_api_script",
    "ball pressed into a block, then slid along it": "test_fit_command.py (examples/press_slide_fit.toml)",
}


def test_every_example_of_the_docs_is_a_file_that_is_run(tmp_path):
    """Each ```toml block of docs/problem-files.md loads, and is run by the test
    named for it (each once: they compile their own programs); the first is
    examples/block.toml and the fit example examples/press_slide_fit.toml, verbatim."""
    assert len(EXAMPLES) == len(RUN_BY)
    for k, text in enumerate(EXAMPLES):
        (title,) = [t for t in RUN_BY if _title(text).startswith(t)]
        if "[fit]" in text:
            example = ROOT / "examples" / "press_slide_fit.toml"
            assert text == example.read_text(), "the docs' fit example is examples/press_slide_fit.toml"
            problem, cfg = pf.load(example)
            assert cfg.fit.names == ("E", "mu") and cfg.dim == 3
            continue
        if title == "block on a cylinder":
            assert text == (ROOT / "examples" / "block.toml").read_text()
        problem, cfg = pf.load(_write(tmp_path, text, f"doc{k}.toml"))
        assert problem.mesh.n_nodes > 0 and cfg.responses


def test_implicit_ball_example_equals_the_api_script_with_a_sphere(tmp_path):
    """The docs' implicit ball (an expression of x, y, z and R), pressed and then
    slid along a Table, gives the solution of the API script with sg.Sphere to
    round-off (the expression's gap, normal and their derivatives are the
    sphere's); at the end the drag is nearly mu times the load (sliding)."""
    s = pf.run(_write(tmp_path, _example("a ball, given as an implicit")), tmp_path / "out")
    load, drag = s["responses"]["load"]["value"], s["responses"]["drag"]["value"]
    assert load < 0 and 0.95 * 0.2 < drag / -load <= 0.2 * (1 + 1e-9)
    block = sg.box(np.linspace(0.2, 0.8, 9), np.linspace(0.2, 0.8, 9), np.linspace(-0.3, 0, 3))
    ball = sg.Sphere(radius="R", centre=(0.5, 0.5, "R"),
                     motion=(((0.0, 0.0, lambda p: -p["d"]), sg.Ramp(0.0, 0.5)),
                             (("s", 0.0, 0.0), sg.Table((0.5, 1.0), (0.0, 1.0)))))
    pb = sg.Problem(block, sg.LinearElastic("E", "nu"),
                    {"E": 100.0, "nu": 0.3, "R": 0.5, "d": 0.03, "s": 0.05, "mu": 0.2},
                    fixed=[sg.Fixed("z0", k) for k in range(3)],
                    contact=[sg.Contact(ball, "z1", sg.Coulomb(mu="mu", eps_n=1000.0,
                                                               eps_t=1000.0))])
    ref = sg.solve(pb, steps=4, wrt=["R", "mu"])
    for name, comp in (("load", 2), ("drag", 0)):
        v, d = sg.responses.contact_force(component=comp).of(ref)
        got = s["responses"][name]
        assert got["value"] == pytest.approx(v, rel=1e-10)
        for n in ("R", "mu"):
            assert got["sensitivities"][n] == pytest.approx(d[n], rel=1e-8)
    assert s["responses"]["area"]["value"] == pytest.approx(sg.responses.contact_area().of(ref)[0],
                                                            rel=1e-12)


# ------------------------------------------------------ two bodies: file = script
def test_two_bodies_2d_file_equals_the_api_script(tmp_path):
    f = _write(tmp_path, _example("a neo-Hookean pad"))
    problem, cfg = pf.load(f)
    sol = sg.solve(problem, steps=cfg.steps, wrt=list(cfg.sensitivities), options=cfg.options)

    base = sg.rectangle(np.linspace(0.0, 1.0, 13), np.linspace(-0.5, 0.0, 4))
    pad = sg.rectangle(np.linspace(0.25, 0.75, 11), np.linspace(0.0, 0.25, 3))
    pb = sg.Problem(
        sg.merge({"base": base, "pad": pad}),
        sg.Bodies({"base": sg.LinearElastic("E1", "nu"), "pad": sg.NeoHooke("E2", "nu")}),
        {"E1": 100.0, "E2": 200.0, "nu": 0.3, "P": 2.0},
        fixed=[sg.Fixed("base.bottom", 0), sg.Fixed("base.bottom", 1), sg.Fixed("pad.top", 0)],
        loads=[sg.Pressure("pad.top", "P")],
        contact=[sg.pair("pad.bottom", "base.top", sg.AugmentedLagrangian(800.0))])
    ref = sg.solve(pb, steps=2, wrt=["E1", "E2", "P"], options=sg.NewtonOptions(rtol=1e-12))
    assert sol.newton_iterations == ref.newton_iterations
    _same(sol, ref, ["E1", "E2", "P"])
    s = pf.run(f, tmp_path / "out")
    F, dF = sg.responses.contact_force(component=1).of(ref)
    assert F == pytest.approx(2.0 * 0.5, rel=1e-10)  # the pressure's resultant on the pad
    assert s["responses"]["F"]["value"] == pytest.approx(F, rel=1e-12)
    assert s["responses"]["F"]["sensitivities"]["P"] == pytest.approx(dF["P"], rel=1e-10)
    sink = sg.responses.displacement("pad.top", 1).of(ref)
    assert s["responses"]["sink"]["value"] == pytest.approx(sink[0], rel=1e-12)


def test_two_bodies_3d_file_equals_the_api_script(tmp_path):
    f = _write(tmp_path, _example("a block pressed onto a base"))
    problem, cfg = pf.load(f)
    assert cfg.dim == 3
    sol = sg.solve(problem, steps=cfg.steps, wrt=list(cfg.sensitivities), options=cfg.options)
    base = sg.box(np.linspace(0, 1, 4), np.linspace(0, 1, 4), np.linspace(-0.4, 0, 2))
    block = sg.box(np.linspace(0.25, 0.75, 4), np.linspace(0.25, 0.75, 4), np.linspace(0, 0.25, 2))
    pb = sg.Problem(
        sg.merge({"base": base, "block": block}),
        sg.Bodies({"base": sg.LinearElastic("E1", "nu"), "block": sg.LinearElastic("E2", "nu")}),
        {"E1": 100.0, "E2": 200.0, "nu": 0.3, "P": 2.0},
        fixed=[*(sg.Fixed("base.z0", k) for k in range(3)), sg.Fixed("block.z1", 0),
               sg.Fixed("block.z1", 1)],
        loads=[sg.Pressure("block.z1", "P")],
        contact=[sg.pair("block.z0", "base.z1", sg.AugmentedLagrangian(800.0))])
    ref = sg.solve(pb, wrt=["E2", "P"], options=sg.NewtonOptions(rtol=1e-12))
    _same(sol, ref, ["E2", "P"])
    s = pf.run(f, tmp_path / "out")
    F, dF = sg.responses.contact_force(component=2).of(ref)
    assert F == pytest.approx(2.0 * 0.25, rel=1e-10)
    assert s["responses"]["F"]["value"] == pytest.approx(F, rel=1e-12)
    assert s["responses"]["F"]["sensitivities"]["P"] == pytest.approx(dF["P"], rel=1e-10)
    assert s["mesh"]["dofs"] == ref.model.n_dof
    # adjoint = true: the gradient w.r.t. every parameter by one adjoint pass = DDM's
    adj = s["responses"]["F"]["adjoint"]
    assert set(adj) == {"E1", "E2", "nu", "P"}
    assert adj["P"] == pytest.approx(dF["P"], rel=1e-10)
    assert abs(adj["E2"]) < 1e-12 and abs(adj["E1"]) < 1e-12  # a pressure's resultant


def test_bodies_named_by_the_physical_volumes_of_a_gmsh_file(tmp_path):
    """[[body]] without a mesh: the bodies are physical volumes of one 3-D file,
    its physical surfaces face sets; the file's problem = the script's."""
    whole = sg.box(np.linspace(0, 1, 3), np.linspace(0, 1, 3), np.linspace(-0.5, 0.5, 3))
    X = whole.nodes
    low = X[whole.cells].mean(axis=1)[:, 2] < 0  # the lower layer of cells, then the upper
    quads = [whole.face_sets["z0"], whole.face_sets["z1"]]
    cells = [("hexahedron", whole.cells[low]), ("hexahedron", whole.cells[~low])] + \
        [("quad", q) for q in quads]
    tags = [np.full(len(c[1]), k + 1) for k, c in enumerate(cells)]
    m = meshio.Mesh(X, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                    field_data={"lower": np.array([1, 3]), "upper": np.array([2, 3]),
                                "bottom": np.array([3, 2]), "top": np.array([4, 2])})
    m.write(tmp_path / "two.msh", file_format="gmsh22", binary=False)
    text = """
[params]
E1 = 100.0
E2 = 50.0
nu = 0.3

[mesh]
file = "two.msh"

[[body]]
name = "lower"
material = { type = "linear_elastic", E = "E1", nu = "nu" }

[[body]]
name = "upper"
material = { type = "linear_elastic", E = "E2", nu = "nu" }

[[fixed]]
set = "bottom"
component = "x"

[[fixed]]
set = "bottom"
component = "y"

[[fixed]]
set = "bottom"
component = "z"

[[load]]
type = "traction"
faces = "top"
value = [0.0, 0.0, -1.0]
"""
    problem, _ = pf.load(_write(tmp_path, text))
    sol = sg.solve(problem, wrt=["E2"])
    mesh = sg.read_mesh(tmp_path / "two.msh")
    pb = sg.Problem(mesh, sg.Bodies({"lower": sg.LinearElastic("E1", "nu"),
                                     "upper": sg.LinearElastic("E2", "nu")}),
                    {"E1": 100.0, "E2": 50.0, "nu": 0.3},
                    fixed=[sg.Fixed("bottom", k) for k in range(3)],
                    loads=[sg.Traction("top", (0.0, 0.0, -1.0))])
    _same(sol, sg.solve(pb, wrt=["E2"]), ["E2"])


# ------------------------------------------------------------- expressions
def test_expressions_are_checked_not_evaluated():
    e = parse("sqrt(x^2 + y**2 + z^2) - R", ("x", "y", "z"), {"R": 1.0, "d": 0.1})
    assert e.names == ("R",)
    assert float(e.distance()(np.array([3.0, 4.0, 0.0]), {"R": 1.0})) == 4.0
    assert float(parse("-2*d + pi", (), {"d": 0.5}).of_params()({"d": 0.5})) == pytest.approx(np.pi - 1)
    for text, fragment in [
        ("__import__('os').system('true')", "the call of \"__import__('os').system\" is not allowed"),
        ("__import__('os')", "the call of '__import__' is not allowed"),
        ("x.real", "Attribute ('x.real') is not allowed"),
        ("open('f')", "the call of 'open' is not allowed"),
        ("w + 1", "unknown name 'w'"),
        ("x if y else z", "IfExp"),
        ("x < 1", "Compare"),
        ("'a' * 3", "the constant 'a'"),
        ("sin(x, y)", "sin takes 1 argument(s)"),
        ("x +", "not an arithmetic expression"),
        ("(lambda: 1)()", "the call of"),
    ]:
        with pytest.raises(sg.InputError, match=re.escape(fragment)):
            parse(text, ("x", "y", "z"), {"R": 1.0})


# ------------------------------------------------------------- bad files
BOX = """\
[params]
E = 100.0
nu = 0.3
R = 0.5
d = 0.01

[mesh]
type = "box"
x = [0.0, 1.0]
y = [0.0, 1.0]
z = [-0.5, 0.0]
nx = 2
ny = 2
nz = 1

[material]
type = "linear_elastic"
E = "E"
nu = "nu"

[[fixed]]
set = "z0"
component = "z"

[[contact]]
faces = "z1"
obstacle = { type = "sphere", radius = "R", centre = [0.5, 0.5, "R"], motion = [0.0, 0.0, "-d"] }

[solve]
steps = 1
"""


def _sub(old, new):
    def f(text):
        assert old in text, old
        return text.replace(old, new, 1)
    return f


BAD = [
    (_sub("nz = 1", "nz = 1\nnw = 2"), "[mesh] unknown key 'nw'", 15),
    (_sub("nz = 1", 'nz = "one"'), "[mesh] nz: expected an integer, got a string ('one')", 14),
    (_sub('faces = "z1"', 'faces = "top"'), "[[contact]] #1 faces: 'top' is not a face set of the "
     "mesh; the mesh has x0, x1, y0, y1, z0, z1", 26),
    (_sub('faces = "z1"', 'edges = "z1"'), "[[contact]] #1 edges: the mesh is 3-D: name its "
     "boundary set with faces = ", 26),
    (_sub('component = "z"', 'component = "w"'), "[[fixed]] #1 component: expected 0, 1, 2, \"x\", "
     "\"y\", \"z\" (the mesh is 3-D)", 23),
    (_sub('centre = [0.5, 0.5, "R"]', 'centre = [0.5, "R"]'), "[[contact]] #1 obstacle centre: "
     "expected a list of 3 numbers [a, b, c] (the mesh is 3-D), got an array of length 2", 27),
    (_sub('type = "sphere"', 'type = "circle"'), "[[contact]] #1 obstacle type: 'circle' is an "
     "obstacle of 2-D problems; the mesh is 3-D", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "sqrt(x^2 + y^2 + w^2) - R"'),
     "[[contact]] #1 obstacle expression: 'sqrt(x^2 + y^2 + w^2) - R': unknown name 'w'", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "R - 1"'),
     "[[contact]] #1 obstacle expression: 'R - 1' is not a function of x, y, z", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "__import__(\'os\').getcwd()"'),
     "expression: \"__import__('os').getcwd()\": the call of \"__import__('os').getcwd\" is not "
     "allowed in an expression", 27),
    (_sub('motion = [0.0, 0.0, "-d"]', 'motion = [{ vector = [0.0, 0.0, "-d"], ramp = [0.5, 0.2] }]'),
     "[[contact]] #1 obstacle motion[0] ramp: Ramp(start, end) needs", 27),
    (_sub('"-d"', '"-dd"'), "[[contact]] #1 obstacle motion[2]: '-dd': unknown name 'dd'", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "log(-1) + z"'),
     "[[contact]] #1 obstacle the expression is nan at the point origin + (1, 1, 1)", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "z + 9**9**9**9"'),  # a power of integers: no hang
     "[[contact]] #1 obstacle 'z + 9**9**9**9' cannot be evaluated: OverflowError", 27),
    (_sub('type = "sphere", radius = "R", centre = [0.5, 0.5, "R"]',
          'type = "implicit", expression = "1/0 + z"'),
     "[[contact]] #1 obstacle '1/0 + z' cannot be evaluated: ZeroDivisionError", 27),
    (_sub('type = "linear_elastic"', 'type = "j2"'), "[material] missing required key 'sigma_y'", 16),
    (_sub("[solve]", "[[pair]]\nslave = \"z1\"\nmaster = \"z1\"\n\n[solve]"),
     "[[pair]] #1 master: the slave and master surfaces are both 'z1'", 31),
    (_sub('[mesh]\ntype = "box"', '[mesh]\ndim = 2\ntype = "box"'), "[mesh] unknown key 'dim'", 8),
]


@pytest.mark.parametrize("edit, fragment, line", BAD, ids=[b[1][:40] for b in BAD])
def test_bad_3d_files(tmp_path, edit, fragment, line):
    """Each bad file: an InputError naming the file, the key and its line."""
    f = _write(tmp_path, edit(BOX))
    with pytest.raises(sg.InputError) as err:
        pf.load(f)
    msg = str(err.value)
    assert msg.startswith(f"{f}: ") and fragment in msg, msg
    assert msg.endswith(f"(line {line})"), msg


def test_mesh_of_the_wrong_dimension(tmp_path):
    """A 2-D mesh file where [mesh] dim = 3 asks for 3-D, and bodies of both dimensions."""
    rect = sg.rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    meshio.Mesh(np.column_stack([rect.nodes, np.zeros(rect.n_nodes)]), [("quad", rect.cells)]).write(
        tmp_path / "flat.msh", file_format="gmsh22", binary=False)
    text = re.sub(r'(?s)\[mesh\].*?\n\n', '[mesh]\nfile = "flat.msh"\ndim = 3\n\n', BOX)
    with pytest.raises(sg.InputError) as err:
        pf.load(_write(tmp_path, text))
    assert "[mesh] file = 'flat.msh'" in str(err.value) and "2-D" in str(err.value), err.value
    two = """
[[body]]
name = "a"
mesh = { type = "box", x = [0, 1], y = [0, 1], z = [0, 1], nx = 1, ny = 1, nz = 1 }
material = { type = "linear_elastic", E = 1.0, nu = 0.3 }

[[body]]
name = "b"
mesh = { type = "rectangle", x = [0, 1], y = [1, 2], nx = 1, ny = 1 }
material = { type = "linear_elastic", E = 1.0, nu = 0.3 }
"""
    with pytest.raises(sg.InputError, match=r"\[\[body\]\] the bodies' meshes must all be 2-D or all "
                                            r"3-D; got a 3-D, b 2-D"):
        pf.load(_write(tmp_path, two, "two.toml"))


def test_run_command_on_a_bad_3d_file_exits_2_without_traceback(tmp_path, capsys):
    from signorini.app.cli import main

    f = _write(tmp_path, _sub('faces = "z1"', 'faces = "top"')(BOX))
    assert main(["run", str(f), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "is not a face set of the mesh" in err and "(line 26)" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------- 2-D implicit, paths
STRIP = """\
[params]
E = 100.0
nu = 0.3
R = 5.0
d = 0.02

[mesh]
type = "rectangle"
x = [-1.0, 1.0]
y = [-1.0, 0.0]
nx = 16
ny = 4

[material]
type = "linear_elastic"
E = "E"
nu = "nu"

[[fixed]]
set = "bottom"
component = "x"

[[fixed]]
set = "bottom"
component = "y"

[[contact]]
edges = "top"
eps = 400.0
obstacle = { type = "circle", radius = "R", centre = [0.0, "R"], motion = [0.0, "-d"] }

[solve]
sensitivities = ["R", "d"]
rtol = 1e-12
"""


def test_2d_implicit_circle_equals_the_circle(tmp_path):
    """In 2-D an implicit surface is an expression of x, y: a circle written as one
    gives the Circle's solution and sensitivities to round-off."""
    implicit = STRIP.replace('type = "circle", radius = "R", centre = [0.0, "R"]',
                             'type = "implicit", expression = "hypot(x, y) - R", origin = [0.0, "R"]')
    sols = []
    for k, text in enumerate((STRIP, implicit)):
        problem, cfg = pf.load(_write(tmp_path, text, f"s{k}.toml"))
        sols.append(sg.solve(problem, wrt=list(cfg.sensitivities), options=cfg.options))
    assert isinstance(problem.contact[0].obstacle, sg.Implicit)
    assert (sols[0].contact()["p_N"] > 0).sum() >= 3
    _same(sols[1], sols[0], ["R", "d"])


def test_2d_implicit_with_friction_is_refused(tmp_path):
    text = STRIP.replace('type = "circle", radius = "R", centre = [0.0, "R"]',
                         'type = "implicit", expression = "hypot(x, y) - R", origin = [0.0, "R"]')
    text = text.replace("eps = 400.0", 'eps = 400.0\nmethod = "coulomb"\nmu = 0.2')
    f = _write(tmp_path, text)
    with pytest.raises(sg.InputError) as err:
        pf.load(f)
    assert str(err.value) == (f"{f}: [[contact]] #1 method: a 2-D implicit obstacle takes frictionless "
                              "laws only (\"al\", \"penalty\"): Coulomb friction in 2-D needs a circle "
                              "or a line (line 30)")


def test_paths_rotations_and_a_displacement_abscissa_are_read(tmp_path):
    """A support along a table, an obstacle's rotation legs, and a fit curve against
    a displacement d t (scale = d) become the library's objects and load factors."""
    text = BOX.replace('component = "z"', 'component = "z"\nvalue = "-d"\n'
                       'table = { times = [0.0, 0.5, 1.0], values = [0.0, 1.0, 0.0] }')
    text = text.replace('motion = [0.0, 0.0, "-d"]',
                        'rotation = [{ vector = [0.0, 0.0, 0.1], ramp = [0.5, 1.0] }]')
    problem, cfg = pf.load(_write(tmp_path, text))
    (fx,) = problem.fixed
    assert fx.ramp == sg.Table((0.0, 0.5, 1.0), (0.0, 1.0, 0.0)) and callable(fx.value)
    assert fx.value({"d": 0.01}) == -0.01
    ob = problem.contact[0].obstacle
    assert ob.rotation == (((0.0, 0.0, 0.1), sg.Ramp(0.5, 1.0)),)
    (tmp_path / "f.csv").write_text("depth,F\n0.0025,1.0\n0.005,2.0\n0.01,3.0\n")
    text += """
[[response]]
name = "F"
type = "contact_force"
component = "z"

[fit.parameters]
E = { start = 80.0 }

[[fit.curve]]
response = "F"
file = "f.csv"
x = "depth"
y = "F"
scale = 0.01
"""
    problem, cfg = pf.load(_write(tmp_path, text))
    (c,) = cfg.fit.curves
    np.testing.assert_allclose(c.times, [0.25, 0.5, 1.0], rtol=1e-15)
    assert cfg.fit.start == {"E": 80.0} and cfg.fit.bounds == {"E": (-np.inf, np.inf)}


def test_tetrahedra_and_j2_bodies_are_read(tmp_path):
    text = BOX.replace("nz = 1", "nz = 1\ntetrahedra = true").replace(
        '[material]\ntype = "linear_elastic"\nE = "E"\nnu = "nu"',
        '[material]\ntype = "j2"\nE = "E"\nnu = "nu"\nsigma_y = 2.0\nH = 1.0')
    problem, _ = pf.load(_write(tmp_path, text))
    assert problem.mesh.n_cells == 6 * 4 and problem.mesh.cells.shape[1] == 4
    assert problem.material == sg.J2Plasticity("E", "nu", 2.0, 1.0)
    assert set(problem.mesh.face_sets) == {"x0", "x1", "y0", "y1", "z0", "z1"}


def test_the_size_guard_of_a_3d_file_counts_3d_fill_and_the_history(tmp_path, monkeypatch):
    """A 3-D file is estimated with the 3-D model (a sparse LU of a 3-D mesh fills in
    much faster: 60^3 cells, 680k unknowns, 20 GB against 4.6 GB with the 2-D model,
    refused with 16 GB available while the mesh is read), and a J2 body's history,
    kept for every increment and sensitivity, counts: 20^3 J2 cells over 200 steps
    with 3 sensitivities keep 4.1 GB, refused with 4 GB available, 2 steps pass."""
    import dataclasses

    from signorini.app.problemfile.run import check_file_size
    from signorini.errors import ResourceError
    from signorini.linsolve import memory as m

    big = _sub("nx = 2\nny = 2\nnz = 1", "nx = 60\nny = 60\nnz = 60")(BOX)
    assert m.estimated_peak_memory(3 * 61**3, "pardiso", dim=2) < 0.85 * 16 * m.GB
    monkeypatch.setattr(m, "available_memory", lambda: 16.0 * m.GB)
    with pytest.raises(ResourceError, match="680,943 unknowns"):
        pf.load(_write(tmp_path, big), solver="pardiso")
    j2 = _sub("nx = 2\nny = 2\nnz = 1", "nx = 20\nny = 20\nnz = 20")(
        _sub('[material]\ntype = "linear_elastic"\nE = "E"\nnu = "nu"',
             '[material]\ntype = "j2"\nE = "E"\nnu = "nu"\nsigma_y = 2.0\nH = 1.0')(BOX))
    many = _sub("steps = 1", 'steps = 200\nsensitivities = ["E", "nu", "R"]')(j2)
    monkeypatch.setattr(m, "available_memory", lambda: 4.0 * m.GB)
    with pytest.raises(ResourceError, match="or fewer steps"):
        pf.run(_write(tmp_path, many, "many.toml"), tmp_path / "many", solver="pardiso")
    assert not (tmp_path / "many" / "summary.json").exists()
    few = _sub("steps = 1", 'steps = 2\nsensitivities = ["E", "nu", "R"]')(j2)
    problem, cfg = pf.load(_write(tmp_path, few, "few.toml"), solver="pardiso")
    est = check_file_size(problem, cfg, solver="pardiso")
    # 8 Gauss points x 10 values x 8 bytes a cell, for the state and 3 sensitivities
    per_step = 8 * 10 * 8 * 8000 * (1 + 3)
    one = check_file_size(problem, dataclasses.replace(cfg, steps=1), solver="pardiso")
    assert est - one == pytest.approx(per_step, rel=1e-12)
    assert m.estimated_peak_memory(3 * 21**3, "pardiso", dim=3) < one < est < 0.85 * 4 * m.GB
