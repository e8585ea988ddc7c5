"""Mesh input (gmsh via meshio) and result output."""

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.io import read_mesh


def _write_gmsh(path, flip_cells=False, interior_line=False):
    m = sg.rectangle(np.linspace(0, 2, 5), np.linspace(0, 1, 3))
    cells = m.cells[:, ::-1] if flip_cells else m.cells
    top = m.edge_sets["top"][:, ::-1]  # written in the "wrong" direction on purpose
    lines = np.vstack([top, m.edge_sets["bottom"]])
    tags = np.r_[np.full(len(top), 2), np.full(len(m.edge_sets["bottom"]), 3)]
    if interior_line:
        lines = np.vstack([lines, [[6, 7]]])
        tags = np.r_[tags, 3]
    mesh = meshio.Mesh(np.column_stack([m.nodes, np.zeros(m.n_nodes)]),
                       [("quad", cells), ("line", lines)],
                       cell_data={"gmsh:physical": [np.ones(len(cells), int), tags],
                                  "gmsh:geometrical": [np.ones(len(cells), int), tags]},
                       field_data={"block": np.array([1, 2]), "top": np.array([2, 1]),
                                   "bottom": np.array([3, 1])})
    mesh.write(path, file_format="gmsh22", binary=False)
    return m


@pytest.mark.parametrize("flip", [False, True])
def test_read_gmsh_quads_and_named_edge_sets(tmp_path, flip):
    ref = _write_gmsh(tmp_path / "m.msh", flip_cells=flip)
    m = read_mesh(tmp_path / "m.msh")
    assert m.n_cells == ref.n_cells and m.n_nodes == ref.n_nodes
    assert np.allclose(m.nodes, ref.nodes)
    # cells are counter-clockwise after reading, whatever the file's order
    assert (sg.mesh.signed_jacobians(m.nodes, m.cells) > 0).all()
    # edge sets oriented with the body on the left (as the generator's), node sets alike
    assert {tuple(e) for e in m.edge_set("top")} == {tuple(e) for e in ref.edge_set("top")}
    assert set(m.node_set("bottom")) == set(ref.node_set("bottom"))


def test_read_rejects_interior_edge_set(tmp_path):
    _write_gmsh(tmp_path / "bad.msh", interior_line=True)
    with pytest.raises(sg.InputError, match="not on the boundary"):
        read_mesh(tmp_path / "bad.msh")


def test_read_rejects_triangles(tmp_path):
    meshio.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), [("triangle", np.array([[0, 1, 2]]))]
                ).write(tmp_path / "t.msh", file_format="gmsh22", binary=False)
    with pytest.raises(sg.InputError, match="no quadrilateral cells"):
        read_mesh(tmp_path / "t.msh")


def test_vtu_has_fields_and_sensitivities(tmp_path):
    from signorini.problems import hertz

    pb = hertz.hertz_problem(n_fine=6, size=8)
    sol = sg.solve(pb, sensitivities=["R"])
    sg.io.write_vtu(sol, tmp_path / "r.vtu")
    back = meshio.read(tmp_path / "r.vtu")
    for key in ("displacement", "ddisplacement_dR", "p_N", "dp_N_dR", "gap"):
        assert key in back.point_data, key
    assert np.allclose(back.point_data["displacement"][:, :2], sol.displacement())
    c = sol.contact()
    assert np.allclose(back.point_data["dp_N_dR"][c["node"]], c["dp_N_dR"])
    stress, dstress = sol.stress()
    assert np.allclose(back.cell_data["cauchy_stress"][0].reshape(-1, 3, 3), stress)
    assert np.allclose(back.cell_data["dcauchy_stress_dR"][0].reshape(-1, 3, 3), dstress["R"])
