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
