"""docs/tutorial.md runs as written, and its numbers hold.

The ```python blocks of the tutorial are executed in order, in one namespace,
inside a temporary working directory (they write ``block.msh`` and
``block.vtu``). The tests then check the results independently of the
tutorial's own asserts: the mesh file and its named sets, the Signorini
conditions (docs/theory.md §2.5), the DDM sensitivities against central finite
differences (§9) and two exact sensitivities, and that the outputs quoted in
the ```text blocks are what the code prints.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import warnings
from pathlib import Path

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.fem.mesh import signed_jacobians
from signorini.fem.meshfile import read_mesh

TUTORIAL = Path(__file__).resolve().parents[2] / "docs" / "tutorial.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```[ \t]*$", re.S | re.M)


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """(language, code) of every fenced block, in order."""
    return [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]


def python_blocks(text: str) -> list[str]:
    return [code for lang, code in fenced_blocks(text) if lang == "python"]


@pytest.fixture(scope="module")
def tutorial(tmp_path_factory):
    """Run the tutorial; returns (namespace, working dir, printed output per block,
    warnings raised by signorini)."""
    blocks = fenced_blocks(TUTORIAL.read_text())
    workdir = tmp_path_factory.mktemp("tutorial")
    ns = {"__name__": "tutorial"}
    printed = []  # (python block output, the ```text block right after it or None)
    old = os.getcwd()
    os.chdir(workdir)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for k, (lang, code) in enumerate(blocks):
                if lang != "python":
                    continue
                out = io.StringIO()
                with contextlib.redirect_stdout(out):
                    exec(compile(code, f"{TUTORIAL.name}, python block {len(printed) + 1}", "exec"), ns)
                follows = blocks[k + 1][1] if k + 1 < len(blocks) and blocks[k + 1][0] == "text" else None
                printed.append((out.getvalue(), follows))
    finally:
        os.chdir(old)
    for w in caught:  # past the recording: pyproject.toml's filters decide (ours are errors)
        if issubclass(w.category, DeprecationWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    ours = [w for w in caught if type(w.message).__name__ == "SignoriniWarning"]
    return ns, workdir, printed, ours


def test_tutorial_has_code_and_quoted_output():
    blocks = fenced_blocks(TUTORIAL.read_text())
    assert len(python_blocks(TUTORIAL.read_text())) >= 8
    assert sum(lang == "text" for lang, _ in blocks) >= 5


def test_mesh_file_read_with_named_edge_sets(tutorial):
    ns, workdir, _, _ = tutorial
    path = workdir / "block.msh"
    assert path.read_text().startswith("$MeshFormat\n2.2 0 8\n")
    raw = meshio.read(path)
    assert set(raw.field_data) == {"bottom", "top", "left", "block"}  # gmsh $PhysicalNames
    mesh = read_mesh(path)
    xs, ys = ns["xs"], ns["ys"]
    assert mesh.n_nodes == len(xs) * len(ys)
    assert mesh.n_cells == (len(xs) - 1) * (len(ys) - 1)
    assert (signed_jacobians(mesh.nodes, mesh.cells) > 0).all()
    # each named line group is a boundary edge set, oriented with the body on its
    # left: the outward normal (dy, -dx) of every top edge points up, of every
    # bottom edge down, of every left edge towards -x
    for name, outward in (("top", (0, 1)), ("bottom", (0, -1)), ("left", (-1, 0))):
        e = mesh.edge_set(name)
        d = mesh.nodes[e[:, 1]] - mesh.nodes[e[:, 0]]
        n = np.column_stack([d[:, 1], -d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
        assert np.allclose(n, outward), name
    assert np.allclose(mesh.nodes[mesh.node_set("top"), 1], 0.0)
    assert len(mesh.node_set("top")) == len(xs)
    assert np.allclose(np.sort(mesh.nodes[mesh.node_set("left"), 1]), ys)


def test_solution_converged_without_warnings(tutorial):
    ns, _, _, ours = tutorial
    sol = ns["sol"]
    assert sol.status == "converged" and len(sol.increments) == 1
    res = sol.increments[-1].newton.residuals
    assert res[-1] <= 1e-12 * res[0]
    assert not ours, [str(w.message) for w in ours]


def test_signorini_conditions(tutorial):
    """AL at convergence (theory §2.5): g >= 0, p_N >= 0, g p_N = 0 at every node."""
    ns, _, _, _ = tutorial
    c = ns["sol"].contact()
    p0 = c["p_N"].max()
    closed = c["p_N"] > 0
    assert closed.sum() >= 10  # a resolved contact zone, not a point
    assert (~closed).sum() >= 10  # and a free part of the face
    assert c["gap"].min() >= -1e-12 * ns["problem"].params["d"]
    assert c["p_N"].min() >= -1e-12 * p0
    assert np.abs(c["gap"] * c["p_N"]).max() <= 1e-12 * p0 * ns["problem"].params["d"]
    assert np.abs(c["gap"][closed]).max() <= 1e-12 * ns["problem"].params["d"]
    # the cylinder moved down by d and touches the block at the symmetry node
    x0 = np.argmin(c["x_ref"][:, 0])
    assert c["x_ref"][x0, 0] == 0.0
    assert np.isclose(c["x"][x0, 1], -ns["problem"].params["d"], rtol=1e-10)


def test_exact_sensitivities(tutorial):
    """Displacement control, linear elasticity: p_N is proportional to E, so
    Dp_N/DE = p_N / E; the AL solution does not depend on eps (theory §2.5)."""
    ns, _, _, _ = tutorial
    c = ns["sol"].contact()
    E, eps = ns["problem"].params["E"], ns["problem"].params["eps"]
    p0 = c["p_N"].max()
    assert np.abs(c["dp_N_dE"] - c["p_N"] / E).max() <= 1e-10 * p0 / E
    assert np.abs(c["dp_N_deps"]).max() * eps <= 1e-10 * p0
    assert np.isclose(ns["dF"]["E"], ns["F"] / E, rtol=1e-10)


def test_ddm_equals_central_fd_in_tutorial(tutorial):
    """The tutorial's own FD results: force and pressures to 1e-6 relative."""
    ns, _, _, _ = tutorial
    c = ns["c"]
    assert set(ns["fd"]) == {"R", "E", "d", "H"}
    for n, fd in ns["fd"].items():
        ddm = np.r_[ns["dF"][n], c[f"dp_N_d{n}"]]
        assert abs(ddm[0]) > 1e-3 * abs(ns["F"]) / max(abs(ns["problem"].params[n]), 1.0), n
        assert abs(fd[0] - ddm[0]) <= 1e-6 * abs(ddm[0]), n
        assert np.abs(fd[1:] - ddm[1:]).max() <= 1e-6 * np.abs(ddm[1:]).max(), n


def test_ddm_equals_central_fd_independent_step(tutorial):
    """Our own FD of the shape parameter H with a different step (relative 1e-5,
    inside the active-set bound): DDM of the pressures, the gaps and the
    displacements of the top face to 1e-6 relative."""
    ns, _, _, _ = tutorial
    problem, sol, tight = ns["problem"], ns["sol"], ns["tight"]
    top = problem.mesh.node_set("top")

    def q(s):
        c = s.contact()
        return np.concatenate([c["p_N"], c["gap"], s.displacement()[top].ravel()])

    h = 1e-5 * problem.params["H"]
    fd = sg.finite_difference(problem, "H", q, step=h, options=tight)
    c = sol.contact()
    ddm_parts = [c["dp_N_dH"], c["dgap_dH"], sol.displacement_sensitivity("H")[top].ravel()]
    fd_parts = np.split(fd, np.cumsum([len(p) for p in ddm_parts])[:-1])
    for ddm, f in zip(ddm_parts, fd_parts):
        assert np.abs(ddm).max() > 0
        assert np.abs(f - ddm).max() <= 1e-6 * np.abs(ddm).max()


def test_active_set_bound_predicts_the_bad_step(tutorial):
    """The tutorial's step safety bound is real: its steps are inside it, and the
    deliberately bad step for d (outside it) gives a wrong difference."""
    ns, _, _, _ = tutorial
    c = ns["c"]
    for n, h in ns["steps"].items():
        assert h < 0.1 * ns["largest_safe_step"](c, n)
    h_safe = ns["largest_safe_step"](c, "d")
    assert ns["h_bad"] > h_safe
    bad = np.abs(ns["fd_bad"][1:] - c["dp_N_dd"]).max() / np.abs(c["dp_N_dd"]).max()
    assert bad > 0.05


def test_vtu_holds_fields_and_sensitivities(tutorial):
    ns, workdir, _, _ = tutorial
    back = meshio.read(workdir / "block.vtu")
    sol, c = ns["sol"], ns["c"]
    for name in ("R", "E", "d", "H"):
        assert f"dp_N_d{name}" in back.point_data
        assert np.allclose(back.point_data[f"dp_N_d{name}"][c["node"]], c[f"dp_N_d{name}"])
    assert np.allclose(back.point_data["displacement"][:, :2], sol.displacement())


_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _tokens(text: str):
    """Split printed text into words and numbers."""
    out, pos = [], 0
    for m in _NUMBER.finditer(text):
        out += text[pos:m.start()].split()
        out.append(float(m.group()))
        pos = m.end()
    return out + text[pos:].split()


def test_quoted_output_is_what_the_code_prints(tutorial):
    """Every ```text block that follows a python block matches its output: same
    words, numbers within 1e-3 relative, except round-off-level numbers (both
    below 1e-6 in magnitude: residuals, FD differences, zero sensitivities)."""
    _, _, printed, _ = tutorial
    compared = 0
    for out, quoted in printed:
        if quoted is None:
            continue
        compared += 1
        got, want = _tokens(out), _tokens(quoted)
        assert len(got) == len(want), (out, quoted)
        for g, w in zip(got, want):
            if isinstance(w, float) and isinstance(g, float):
                if abs(w) < 1e-6 and abs(g) < 1e-6:
                    continue
                assert g == pytest.approx(w, rel=1e-3, abs=0), (out, quoted)
            else:
                assert g == w, (out, quoted)
    assert compared >= 5
