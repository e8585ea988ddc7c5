"""Mesh input (signorini.fem.meshfile): gmsh and other meshio formats read into
quadrilateral meshes with named edge and node sets, or 3-D meshes of hexahedra or
tetrahedra with named face and node sets, by one reader; clear errors for
missing, empty, garbage, non-planar, triangle-only or wrong-dimension files."""

import meshio
import numpy as np
import pytest

import signorini as sg
from signorini.fem.mesh import signed_jacobians
from signorini.fem.meshfile import read_mesh, read_mesh_3d


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
    assert (signed_jacobians(m.nodes, m.cells) > 0).all()
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


# ------------------------------------------------------------- read_mesh errors

def test_read_missing_file(tmp_path):
    with pytest.raises(sg.InputError, match=r"nowhere\.msh: mesh file not found.*check the file name"):
        read_mesh(tmp_path / "nowhere.msh")


def test_read_empty_file(tmp_path):
    (tmp_path / "empty.msh").write_text("")
    with pytest.raises(sg.InputError, match=r"empty\.msh: the mesh file is empty; write the mesh again"):
        read_mesh(tmp_path / "empty.msh")


@pytest.mark.parametrize("name, content", [
    ("garbage.msh", b"this is not a mesh\n1 2 3\n"),
    ("garbage.vtu", b"<VTKFile>broken"),
    ("garbage.vtk", b"\x00\x01\x02 binary junk"),
    ("truncated.msh", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n"),
])
def test_read_garbage_file(tmp_path, capfd, name, content):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(sg.InputError) as err:
        read_mesh(tmp_path / name)
    msg = str(err.value)
    assert msg.startswith(str(tmp_path / name)) and "not a readable mesh file" in msg, msg
    assert "gmsh" in msg  # says what to do
    out, errtext = capfd.readouterr()
    assert "Error" not in out + errtext  # meshio's console output is captured, not printed


def test_read_unknown_extension_and_directory(tmp_path):
    (tmp_path / "body.geo").write_text("Point(1) = {0, 0, 0};\n")
    with pytest.raises(sg.InputError, match=r"body\.geo: unknown mesh file extension '\.geo'.*\.msh"):
        read_mesh(tmp_path / "body.geo")
    (tmp_path / "d.msh").mkdir()
    with pytest.raises(sg.InputError, match="is a directory"):
        read_mesh(tmp_path / "d.msh")


def test_read_rejects_non_planar(tmp_path):
    m = sg.rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    meshio.Mesh(np.column_stack([m.nodes, m.nodes[:, 0]]), [("quad", m.cells)]).write(
        tmp_path / "tilted.vtu")
    with pytest.raises(sg.InputError, match="not planar"):
        read_mesh(tmp_path / "tilted.vtu")


def test_read_drops_orphan_nodes_and_merges_group_blocks(tmp_path):
    """gmsh writes a node for every geometry point (e.g. an arc centre) and one
    cell block per curve; unused nodes are dropped and a physical group made of
    several curves becomes one set."""
    m = sg.rectangle(np.linspace(0, 2, 5), np.linspace(0, 1, 3))
    pts = np.vstack([[[5.0, 5.0]], m.nodes])  # orphan node 0, all others shifted by one
    top = m.edge_sets["top"] + 1
    mesh = meshio.Mesh(np.column_stack([pts, np.zeros(len(pts))]),
                       [("quad", m.cells + 1), ("line", top[:2]), ("line", top[2:]), ("vertex", [[0]])],
                       cell_data={"gmsh:physical": [np.ones(m.n_cells, int), [2, 2], [2, 2], [5]],
                                  "gmsh:geometrical": [np.ones(m.n_cells, int), [1, 1], [2, 2], [3]]},
                       field_data={"block": np.array([1, 2]), "top": np.array([2, 1]),
                                   "centre": np.array([5, 0])})
    mesh.write(tmp_path / "arc.msh", file_format="gmsh22", binary=False)
    assert len(meshio.read(tmp_path / "arc.msh").points) == m.n_nodes + 1
    with pytest.warns(sg.SignoriniWarning, match="point set 'centre': 1 node"):
        r = read_mesh(tmp_path / "arc.msh")
    assert r.n_nodes == m.n_nodes and np.allclose(r.nodes, m.nodes)
    assert {tuple(e) for e in r.edge_set("top")} == {tuple(e) for e in m.edge_set("top")}
    assert set(r.node_set("top")) == set(m.node_set("top"))
    assert "centre" not in r.node_sets  # its only node is not part of the body
    # an edge set off the body is an error
    mesh.cells.append(meshio.CellBlock("line", np.array([[0, 1]])))
    mesh.cell_data = {k: v + [np.array([6])] for k, v in mesh.cell_data.items()}
    mesh.field_data["spoke"] = np.array([6, 1])
    mesh.write(tmp_path / "arc.msh", file_format="gmsh22", binary=False)
    with pytest.raises(sg.InputError, match="edge set 'spoke' has nodes that belong to no quadrilateral"):
        read_mesh(tmp_path / "arc.msh")


# ------------------------------------------------------------------ 3-D meshes
def _write_gmsh_3d(path, tets=False, flip=False, inner_face=False):
    from signorini.fem.mesh3d import box, tetrahedra

    m = box(np.linspace(0, 2, 4), np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    if tets:
        m = tetrahedra(m)
    face = "triangle" if tets else "quad"
    vol = "tetra" if tets else "hexahedron"
    cells = m.cells[:, [0, 2, 1, 3]] if (flip and tets) else (
        m.cells[:, [4, 5, 6, 7, 0, 1, 2, 3]] if flip else m.cells)
    top = m.face_sets["z1"][:, ::-1]  # written inward on purpose
    faces = np.vstack([top, m.face_sets["x0"]])
    tags = np.r_[np.full(len(top), 2), np.full(len(m.face_sets["x0"]), 3)]
    if inner_face:
        c = m.cells[0]
        faces = np.vstack([faces, c[[1, 2, 6, 5]] if not tets else [[c[0], c[2], c[3]]]])
        tags = np.r_[tags, 3]
    mesh = meshio.Mesh(m.nodes, [(vol, cells), (face, faces)],
                       cell_data={"gmsh:physical": [np.ones(len(cells), int), tags],
                                  "gmsh:geometrical": [np.ones(len(cells), int), tags]},
                       field_data={"part": np.array([1, 3]), "top": np.array([2, 2]),
                                   "left": np.array([3, 2])})
    mesh.write(path, file_format="gmsh22", binary=False)
    return m


@pytest.mark.parametrize("tets", [False, True])
@pytest.mark.parametrize("flip", [False, True])
def test_read_gmsh_3d_with_face_sets(tmp_path, tets, flip):
    """Hexahedra or tetrahedra (cells of negative volume renumbered), physical
    surfaces as outward face sets and node sets, the volume group as a node set."""
    from signorini.fem.mesh3d import Mesh3D, cell_jacobians

    ref = _write_gmsh_3d(tmp_path / "m.msh", tets=tets, flip=flip)
    m = read_mesh(tmp_path / "m.msh")
    assert isinstance(m, Mesh3D) and m.n_cells == ref.n_cells and np.allclose(m.nodes, ref.nodes)
    assert (cell_jacobians(m.nodes, m.cells) > 0).all()
    key = lambda faces: {tuple(np.roll(f, -int(np.argmin(f)))) for f in faces}
    assert key(m.face_set("top")) == key(ref.face_set("z1"))  # outward, as the cells own them
    assert key(m.face_set("left")) == key(ref.face_set("x0"))
    assert set(m.node_set("top")) == set(ref.node_set("z1"))
    assert len(m.node_set("part")) == m.n_nodes


def test_read_gmsh_3d_errors(tmp_path):
    _write_gmsh_3d(tmp_path / "bad.msh", inner_face=True)
    with pytest.raises(sg.InputError, match="face set 'left'.*not on the boundary"):
        read_mesh(tmp_path / "bad.msh")
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    meshio.Mesh(pts, [("tetra", np.array([[0, 1, 2, 3]])), ("wedge", np.array([[0, 1, 2, 3, 4, 1]]))]
                ).write(tmp_path / "wedge.msh", file_format="gmsh22", binary=False)
    with pytest.raises(sg.InputError, match=r"unsupported cell types \['wedge'\]"):
        read_mesh(tmp_path / "wedge.msh")


def test_connected_parts_are_scipys_connected_components():
    """The bodies of a mesh (signorini.fem.mesh.parts) come from our own connected
    components: the same partition as scipy.sparse.csgraph's on random cell sets
    (several parts, isolated nodes, cells of 4 and 8 nodes), and boundary edges
    are those in exactly one cell."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from signorini.fem.mesh import _components

    rng = np.random.default_rng(3)
    for _ in range(300):
        n, k = int(rng.integers(2, 80)), int(rng.choice([4, 8]))
        cells = rng.integers(0, n, size=(int(rng.integers(1, 25)), k))
        ours = _components(cells, n)
        g = sp.coo_matrix((np.ones(cells.size * k), (np.repeat(cells, k, axis=1).ravel(),
                                                      np.tile(cells, (1, k)).ravel())), shape=(n, n))
        count, ref = connected_components(g, directed=False)
        assert len(np.unique(ours)) == count
        pairs = set(zip(ours.tolist(), ref.tolist()))
        assert len(pairs) == count  # one of ours per one of theirs
        assert np.all(ours <= np.arange(n)) and np.all(ours[ours] == ours)  # labelled by a member
    m = sg.rectangle(np.linspace(0, 1, 5), np.linspace(0, 2, 4))
    e = m.boundary_edges()
    assert len(e) == 2 * (4 + 3)
    count = {}
    for c in m.cells:
        for a, b in zip(c, np.roll(c, -1)):
            count[frozenset((a, b))] = count.get(frozenset((a, b)), 0) + 1
    assert {frozenset(x) for x in e.tolist()} == {s for s, v in count.items() if v == 1}


# ------------------------------------------------- a mesh of the wrong dimension
def _wrong_file(tmp_path, kind):
    """A file of one kind (a 2-D or 3-D mesh, a mesh without body cells, an empty
    or a non-mesh file); its path."""
    from signorini.fem.mesh3d import box, tetrahedra

    quads = sg.rectangle(np.linspace(0, 2, 5), np.linspace(0, 1, 3))
    hexes = box(np.linspace(0, 2, 3), np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    name, cells, points = {
        "quad": ("quads.msh", [("quad", quads.cells), ("line", quads.edge_sets["top"])],
                 np.column_stack([quads.nodes, np.zeros(quads.n_nodes)])),
        "triangle": ("triangles.msh", [("triangle", np.array([[0, 1, 2]]))], pts[:3]),
        "planar": ("planar.vtu", [("quad", quads.cells)], quads.nodes),  # x, y only
        "hexahedron": ("hexahedra.msh", [("hexahedron", hexes.cells)], hexes.nodes),
        "tetra": ("tetrahedra.vtu", [("tetra", tetrahedra(hexes).cells)], hexes.nodes),
        "wedge": ("wedge.vtu", [("wedge", np.array([[0, 1, 2, 3, 4, 1]]))], pts),
        "tetra10": ("tetra10.vtu", [("tetra10", np.array([[0, 1, 2, 3, 4, 0, 1, 2, 3, 4]]))], pts),
        "line": ("lines.msh", [("line", np.array([[0, 1], [1, 2]]))], pts),
        "vertex": ("points.msh", [("vertex", np.array([[0], [1]]))], pts),
        "none": ("no_cells.msh", [], pts),
    }.get(kind, (None, None, None))
    if kind == "empty":
        (tmp_path / "empty.msh").write_text("")
        return tmp_path / "empty.msh"
    if kind == "text":
        (tmp_path / "notes.msh").write_text("a mesh will be here\n")
        return tmp_path / "notes.msh"
    path = tmp_path / name
    fmt = {"file_format": "gmsh22", "binary": False} if name.endswith(".msh") else {}
    meshio.Mesh(points, cells).write(path, **fmt)
    return path


def _read(kind, path):
    return read_mesh_3d(path) if kind == "3d" else read_mesh(path, dim=2) if kind == "2d" \
        else read_mesh(path)


WRONG = [
    # (file, reader: "3d" read_mesh_3d | "2d" read_mesh(dim=2) | "any" read_mesh, fragment, its dim)
    ("quad", "3d", "a 2-D mesh (cells: 8 quad, 4 line; no volume cells), where a 3-D mesh of "
                   "hexahedra or tetrahedra is expected; read a 2-D mesh with read_mesh", 2),
    ("triangle", "3d", "a 2-D mesh (cells: 1 triangle; no volume cells), where a 3-D mesh", 2),
    ("planar", "3d", "a 2-D mesh (cells: 8 quad; no volume cells)", 2),
    ("hexahedron", "2d", "a 3-D mesh (cells: 2 hexahedron), where a 2-D mesh of quadrilaterals in "
                         "the z = 0 plane is expected", 3),
    ("tetra", "2d", "a 3-D mesh (cells: 12 tetra), where a 2-D mesh", 3),
    ("wedge", "2d", "a 3-D mesh (cells: 1 wedge)", 3),
    ("wedge", "any", "no hexahedra or tetrahedra (found ['wedge']); signorini reads 3-D meshes of "
                     "8-node hexahedra or 4-node tetrahedra", None),
    ("tetra10", "3d", "no hexahedra or tetrahedra (found ['tetra10'])", None),
    ("line", "any", "no cells of a body (cells: 2 line); a mesh file needs the cells of a body", None),
    ("line", "3d", "no cells of a body (cells: 2 line)", None),
    ("vertex", "2d", "no cells of a body (cells: 2 vertex)", None),
    ("none", "3d", "no cells at all; a mesh file needs the cells of a body", None),
    ("empty", "3d", "the mesh file is empty; write the mesh again", None),
    ("text", "3d", "not a readable mesh file", None),
]


@pytest.mark.parametrize("kind, reader, fragment, dim", WRONG,
                         ids=[f"{k}-{r}" for k, r, _, _ in WRONG])
def test_wrong_dimension_or_no_body_is_a_clear_error(tmp_path, capfd, kind, reader, fragment, dim):
    """A 2-D file given to the 3-D reader, a 3-D file where a 2-D mesh is asked for,
    a file without the cells of a body, an empty or a non-mesh file: an InputError
    that names the file, what it holds and what is expected (no IndexError from
    deep inside the reader, nothing printed by meshio)."""
    path = _wrong_file(tmp_path, kind)
    capfd.readouterr()  # what meshio said writing it
    with pytest.raises(sg.InputError) as err:
        _read(reader, path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: "), msg
    assert fragment in msg, msg
    assert getattr(err.value, "dim", None) == dim
    assert capfd.readouterr() == ("", "")  # meshio's console output is captured


@pytest.mark.parametrize("kind, dim, cls", [("quad", 2, "Mesh"), ("planar", 2, "Mesh"),
                                            ("hexahedron", 3, "Mesh3D"), ("tetra", 3, "Mesh3D")])
def test_the_right_dimension_reads(tmp_path, kind, dim, cls):
    """The same files read by the reader of their dimension, and by read_mesh
    without one."""
    path = _wrong_file(tmp_path, kind)
    a = read_mesh_3d(path) if dim == 3 else read_mesh(path, dim=2)
    b = read_mesh(path)
    assert type(a).__name__ == type(b).__name__ == cls
    np.testing.assert_array_equal(a.cells, b.cells)


@pytest.mark.parametrize("tets", [False, True])
def test_one_public_reader_for_2d_and_3d_files(tmp_path, tets):
    """``signorini.read_mesh`` reads a 2-D file into a Mesh and a 3-D file into a
    Mesh3D by the file's cells; ``dim=`` demands one and gives the same mesh;
    ``read_mesh_3d`` is ``read_mesh(dim=3)``: same cells, nodes, face and node sets."""
    assert sg.read_mesh is read_mesh
    _write_gmsh(tmp_path / "flat.msh")
    _write_gmsh_3d(tmp_path / "solid.msh", tets=tets)
    flat, solid = sg.read_mesh(tmp_path / "flat.msh"), sg.read_mesh(tmp_path / "solid.msh")
    assert type(flat) is sg.Mesh and type(solid) is sg.Mesh3D
    assert flat.nodes.shape[1] == 2 and solid.nodes.shape[1] == 3
    assert solid.cells.shape[1] == (4 if tets else 8)
    for path, mesh, dim in ((tmp_path / "flat.msh", flat, 2), (tmp_path / "solid.msh", solid, 3)):
        readers = [sg.read_mesh(path, dim=dim)] + ([read_mesh_3d(path)] if dim == 3 else [])
        for again in readers:
            assert type(again) is type(mesh)
            np.testing.assert_array_equal(again.nodes, mesh.nodes)
            np.testing.assert_array_equal(again.cells, mesh.cells)
            assert sorted(again.node_sets) == sorted(mesh.node_sets)
            for name in mesh.node_sets:
                np.testing.assert_array_equal(again.node_set(name), mesh.node_set(name))
        with pytest.raises(sg.InputError) as err:
            sg.read_mesh(path, dim=5 - dim)
        assert err.value.dim == dim
    assert sorted(solid.face_sets) == ["left", "top"] and sorted(flat.edge_sets) == ["bottom", "top"]
    with pytest.raises(sg.InputError, match="dim must be 2, 3 or None"):
        sg.read_mesh(tmp_path / "flat.msh", dim=1)


def _mixed_file(path, shared=False, mixed_set=False):
    """A hexahedral block and a tetrahedral one beside it (x in [1.5, 2.5]; with
    ``shared`` touching it at x = 1, sharing its nodes) in one gmsh file, their
    contact faces named "hex_right" and "tet_left" ("both" when ``mixed_set``)."""
    from signorini.fem.mesh3d import box, tetrahedra

    h = box(np.linspace(0, 1, 3), np.linspace(0, 1, 3), np.linspace(0, 1, 2))
    t = tetrahedra(box(np.linspace(1 if shared else 1.5, 2.5, 3), np.linspace(0, 1, 3),
                       np.linspace(0, 1, 2)))
    off = len(h.nodes)
    tets = t.cells + off
    if shared:  # the tetrahedra's nodes at x = 1 are the hexahedra's
        own = {tuple(x.round(9)): i for i, x in enumerate(h.nodes)}
        alias = np.array([own.get(tuple(x.round(9)), off + i) for i, x in enumerate(t.nodes)])
        tets = alias[t.cells]
    quads, tris = h.face_sets["x1"], t.face_sets["x0"] + off
    tag_q, tag_t = 2, 2 if mixed_set else 3
    meshio.Mesh(np.vstack([h.nodes, t.nodes]),
                [("hexahedron", h.cells), ("tetra", tets), ("quad", quads), ("triangle", tris)],
                cell_data={"gmsh:physical": [np.full(len(h.cells), 5), np.full(len(tets), 6),
                                             np.full(len(quads), tag_q), np.full(len(tris), tag_t)],
                           "gmsh:geometrical": [np.full(len(h.cells), 5), np.full(len(tets), 6),
                                                np.full(len(quads), 2), np.full(len(tris), 3)]},
                field_data={"hex_right": np.array([2, 2]), "tet_left": np.array([3, 2]),
                            "hexes": np.array([5, 3]), "tets": np.array([6, 3])}
                ).write(path, file_format="gmsh22", binary=False)
    return h, t


def test_read_gmsh_3d_mixed(tmp_path):
    """A file of hexahedra and tetrahedra in bodies of their own: a mixed mesh
    (hexahedra first, each kind's cells and face sets as in files of one kind)."""
    h, t = _mixed_file(tmp_path / "mixed.msh")
    m = read_mesh(tmp_path / "mixed.msh")
    assert m.mixed and m.cells.shape == (h.n_cells + t.n_cells, 8)
    (hexa, ih), (tet, it) = m.groups()
    assert (hexa.name, len(ih), tet.name, len(it)) == ("hexahedron", h.n_cells, "tetra", t.n_cells)
    assert np.array_equal(m.cells[it, 4:], np.repeat(m.cells[it, :1], 4, axis=1))
    assert m.face_set("hex_right").shape == (len(h.face_sets["x1"]), 4)
    assert m.face_set("tet_left").shape == (len(t.face_sets["x0"]), 3)
    assert len(m.node_set("hexes")) == h.n_nodes and len(m.node_set("tets")) == t.n_nodes


def test_read_gmsh_3d_mixed_errors(tmp_path):
    _mixed_file(tmp_path / "joined.msh", shared=True)
    with pytest.raises(sg.InputError, match="joins hexahedra and tetrahedra.*pyramids"):
        read_mesh(tmp_path / "joined.msh")
    _mixed_file(tmp_path / "set.msh", mixed_set=True)
    with pytest.raises(sg.InputError, match="'hex_right' has triangles and quadrilaterals"):
        read_mesh(tmp_path / "set.msh")
