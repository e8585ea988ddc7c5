"""Result files (signorini.post.files): a VTU with the fields and their
sensitivities, and a PVD time series of VTUs (all increments or a subset)."""

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.post import files


def test_vtu_has_fields_and_sensitivities(tmp_path):
    from signorini.problems import hertz

    pb = hertz.hertz_problem(n_fine=6, size=8)
    sol = sg.solve(pb, wrt=["R"])
    files.write_vtu(sol, tmp_path / "r.vtu")
    back = meshio.read(tmp_path / "r.vtu")
    for key in ("displacement", "ddisplacement_dR", "p_N", "dp_N_dR", "gap"):
        assert key in back.point_data, key
    assert np.allclose(back.point_data["displacement"][:, :2], sol.displacement())
    c = sol.contact()
    assert np.allclose(back.point_data["dp_N_dR"][c["node"]], c["dp_N_dR"])
    stress, dstress = sol.stress()
    assert np.allclose(back.cell_data["cauchy_stress"][0].reshape(-1, 3, 3), stress)
    assert np.allclose(back.cell_data["dcauchy_stress_dR"][0].reshape(-1, 3, 3), dstress["R"])


def test_write_pvd_series(tmp_path):
    import xml.etree.ElementTree as ET

    m = sg.rectangle(np.linspace(0, 1, 4), np.linspace(0, 1, 4))
    pb = sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0},
                    fixed=(sg.Fixed("bottom", 1), sg.Fixed("left", 0)),
                    loads=(sg.Pressure("top", "q"),))
    sol = sg.solve(pb, steps=3, wrt=["q"])
    (tmp_path / "series").mkdir()
    pvd = files.write_pvd(sol, tmp_path / "series" / "run.pvd")
    assert pvd == tmp_path / "series" / "run.pvd"
    root = ET.parse(pvd).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    ds = root.findall("./Collection/DataSet")
    assert [float(d.get("timestep")) for d in ds] == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert [d.get("file") for d in ds] == ["run_0001.vtu", "run_0002.vtu", "run_0003.vtu"]
    for i, d in enumerate(ds):
        back = meshio.read(pvd.parent / d.get("file"))
        assert np.allclose(back.point_data["displacement"][:, :2], sol.displacement(i))
        assert "ddisplacement_dq" in back.point_data
    assert sorted(p.name for p in pvd.parent.iterdir()) == [
        "run.pvd", "run_0001.vtu", "run_0002.vtu", "run_0003.vtu"]
    # a subset of increments; a bad index is an InputError
    files.write_pvd(sol, tmp_path / "last.pvd", increments=[-1])
    ds = ET.parse(tmp_path / "last.pvd").getroot().findall("./Collection/DataSet")
    assert [(d.get("file"), float(d.get("timestep"))) for d in ds] == [("last_0003.vtu", 1.0)]
    with pytest.raises(sg.InputError, match="increment 7 does not exist"):
        files.write_pvd(sol, tmp_path / "bad.pvd", increments=[7])


def test_pvd_of_two_bodies_computes_each_increment_once(tmp_path, monkeypatch):
    """A mesh of two bodies: one VTU per body and increment, each holding its
    body's nodes and cells with the solution's values there; the fields of an
    increment are computed once for all its bodies."""
    import xml.etree.ElementTree as ET

    a = sg.rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    b = sg.rectangle(np.linspace(2, 3, 4), np.linspace(0, 1, 3))
    m = sg.merge({"left": a, "right": b})
    fixed = tuple(sg.Fixed(f"{k}.{s}", d) for k in ("left", "right") for s, d in (("bottom", 1), ("left", 0)))
    pb = sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0}, fixed=fixed,
                    loads=(sg.Pressure("left.top", "q"), sg.Pressure("right.top", "q")))
    sol = sg.solve(pb, steps=2, wrt=["q"])
    calls = []
    real = files._fields
    monkeypatch.setattr(files, "_fields", lambda s, i: calls.append(i) or real(s, i))
    pvd = files.write_pvd(sol, tmp_path / "two.pvd")
    assert calls == [0, 1]
    ds = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    assert [(d.get("file"), d.get("part")) for d in ds] == [
        ("two_left_0001.vtu", "0"), ("two_right_0001.vtu", "1"),
        ("two_left_0002.vtu", "0"), ("two_right_0002.vtu", "1")]
    u = sol.displacement(1)
    for name, nodes, cells in files.bodies(sol):
        back = meshio.read(tmp_path / f"two_{name}_0002.vtu")
        assert len(back.points) == nodes.size == (9 if name == "left" else 12)
        assert len(back.cells[0].data) == cells.size
        assert np.allclose(back.points[:, :2], np.asarray(m.nodes)[nodes])
        assert np.allclose(back.point_data["displacement"][:, :2], u[nodes])
        assert np.allclose(back.point_data["ddisplacement_dq"][:, :2],
                           sol.displacement_sensitivity("q", 1)[nodes])
        assert set(back.cell_data["body"][0]) == {0 if name == "left" else 1}
        # write_vtu of one body writes the same file
        one = files.write_vtu(sol, tmp_path / f"one_{name}.vtu", 1, body=name)
        again = meshio.read(one)
        assert np.array_equal(again.point_data["displacement"], back.point_data["displacement"])
    whole = meshio.read(files.write_vtu(sol, tmp_path / "whole.vtu"))
    assert len(whole.points) == 21 and sorted(set(whole.cell_data["body"][0])) == [0, 1]
    with pytest.raises(sg.InputError, match="no body 'middle'"):
        files.write_vtu(sol, tmp_path / "bad.vtu", body="middle")


@pytest.mark.parametrize("kind, k, dim", [("quad", 4, 2), ("hexahedron", 8, 3), ("tetra", 4, 3)])
def test_vtu_writer_round_trip(tmp_path, kind, k, dim):
    """Our VTU writer (signorini.post.vtu): every array read back by meshio bit for
    bit, with its type and components; arrays of several compressed blocks and empty
    ones; a data type VTK does not name (bool) written as Float64."""
    from signorini.post import vtu

    rng = np.random.default_rng(0)
    n, nc = 5000, 3000  # the points' array spans several blocks of vtu.BLOCK bytes
    assert n * 3 * 8 > 3 * vtu.BLOCK
    points = rng.random((n, 3))
    cells = rng.integers(0, n, size=(nc, k))
    point = {"u": rng.random((n, 3)), "p_N": rng.random(n), "zeros": np.zeros(n),
             "flag": rng.random(n) > 0.5, "id": np.arange(n, dtype=np.int32)}
    cell = {"stress": [rng.random((nc, 9))], "body": np.arange(nc) % 2}
    vtu.write_unstructured(tmp_path / "a.vtu", points, kind, cells, point, cell)
    back = meshio.read(tmp_path / "a.vtu")
    assert np.array_equal(back.points, points)
    assert back.cells[0].type == kind and np.array_equal(back.cells[0].data, cells)
    for name, v in point.items():
        got = back.point_data[name]
        assert got.dtype == (np.float64 if v.dtype == bool else v.dtype), name
        assert np.array_equal(got, v), name
    assert np.array_equal(back.cell_data["stress"][0], cell["stress"][0])
    assert np.array_equal(back.cell_data["body"][0], cell["body"])
    assert back.point_data["u"].shape == (n, 3) and back.cell_data["stress"][0].shape == (nc, 9)


def test_vtu_writer_rejects_an_unknown_cell_kind(tmp_path):
    from signorini.errors import InputError
    from signorini.post import vtu

    with pytest.raises(InputError, match="wedge"):
        vtu.write_unstructured(tmp_path / "w.vtu", np.zeros((6, 3)), "wedge",
                               np.arange(6)[None], {}, {})


def test_a_series_written_as_the_solve_converges(tmp_path, monkeypatch):
    """files.Series: each increment written as the solve converges it (told by
    progress.on_increment), the .pvd listing the increments so far; complete()
    computes none of them again, writes the files write_pvd writes, and writes the
    last increment again once a shape gradient is attached."""
    import xml.etree.ElementTree as ET

    from signorini import progress
    from signorini.algorithms.stepping import last_started

    m = sg.rectangle(np.linspace(0, 1, 4), np.linspace(0, 1, 4))
    pb = sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0},
                    fixed=(sg.Fixed("bottom", 1), sg.Fixed("left", 0)),
                    loads=(sg.Pressure("top", "q"),))
    (tmp_path / "a").mkdir()
    series = files.Series(tmp_path / "a" / "run.pvd")
    listed = []

    def converged(label, n, t):
        assert label == "base" and t == pytest.approx(n / 3)
        series.add(last_started("base"))
        ds = ET.parse(series.path).getroot().findall("./Collection/DataSet")
        listed.append([d.get("file") for d in ds])

    with progress.on_increment(converged):
        sol = sg.solve(pb, steps=3, wrt=["q"], label="base")
    sg.solve(pb, steps=2, label="other")  # outside the block: not told
    assert listed == [["run_0001.vtu"], ["run_0001.vtu", "run_0002.vtu"],
                      ["run_0001.vtu", "run_0002.vtu", "run_0003.vtu"]]
    calls = []
    real = files._fields
    monkeypatch.setattr(files, "_fields", lambda s, i: calls.append(i) or real(s, i))
    assert series.complete(sol) == series.path and calls == []
    whole = files.write_pvd(sol, tmp_path / "run.pvd")
    assert whole.read_text() == series.path.read_text()
    for k in (1, 2, 3):
        a, b = (meshio.read(p / f"run_{k:04d}.vtu") for p in (tmp_path / "a", tmp_path))
        assert sorted(a.point_data) == sorted(b.point_data)
        for key in a.point_data:
            assert np.array_equal(a.point_data[key], b.point_data[key]), key
    calls.clear()
    sol.shape_gradient = np.ones((m.n_nodes, 2))
    series.complete(sol)
    assert calls == [2]
    assert "adjoint_shape_gradient" in meshio.read(tmp_path / "a" / "run_0003.vtu").point_data
