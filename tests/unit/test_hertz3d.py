"""``signorini hertz3d``: the sphere on a block in 3-D and in the axisymmetric
model, against Hertz, DDM = FD from two command runs, and the two models
against each other with friction."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from signorini.app.cli import main
from signorini.problems.hertz3d import analytical, grid, hertz3d_problem

SMALL = ["--n-fine", "4", "--block", "6", "-q"]


def read(out):
    with open(out / "contact.csv") as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return {k: (v if k == "status" else v.astype(float)) for k, v in cols.items()}, \
        json.loads((out / "summary.json").read_text())


def test_hertz3d_cli_fd_of_two_runs_equals_the_ddm(tmp_path):
    """Frictionless: p0 and a near Hertz's on a coarse mesh, every file written;
    central differences of contact.csv from two runs with R +- dR (the mesh is
    sized by the nominal values only) equal the DDM's dp_N_dR."""
    c, s = {}, {}
    for tag, R in (("0", 1.0), ("+", 1.0 + 1e-5), ("-", 1.0 - 1e-5)):
        out = tmp_path / tag
        args = ["hertz3d", "--out", str(out), "--set", f"R={R}"] + SMALL + (["--no-fd"] if tag != "0" else [])
        assert main(args) == 0
        c[tag], s[tag] = read(out)
    for name in ("contact.csv", "summary.json", "pressure.png", "sensitivity.png", "hertz3d.vtu"):
        assert (tmp_path / "0" / name).is_file(), name
    assert np.array_equal(c["+"]["r"], c["0"]["r"])
    an = analytical(0.1, 1.0, 100.0, 0.3)
    assert s["0"]["p0"]["analytical"] == pytest.approx(an["p0"], rel=1e-12)
    assert abs(s["0"]["p0"]["rel_error"]) < 0.05 and abs(s["0"]["a"]["error_in_cells"]) < 1.0
    assert max(s["0"]["ddm_vs_fd_rel_diff"].values()) < 1e-6
    fd = (c["+"]["p_N"] - c["-"]["p_N"]) / 2e-5
    inner = c["0"]["r"] < 0.9 * an["a"]
    ddm = c["0"]["dp_N_dR"]
    assert np.max(np.abs(fd - ddm)[inner]) < 1e-6 * np.max(np.abs(ddm))


def test_hertz3d_friction_3d_and_axisymmetric_models_agree(tmp_path):
    """With mu = 0.3 along 6 increments: along the x axis the 3-D quarter model
    and the axisymmetric model give the same stick/slip zones, and pressures and
    radial tractions within the discretisation error (off the axis, where the
    axisymmetric nodal area degenerates); hardly any circumferential traction."""
    runs = {}
    for model in ("3d", "axi"):
        out = tmp_path / model
        args = ["hertz3d", "--out", str(out), "--set", "mu=0.3", "--steps", "6", "--no-fd", "--block", "5",
                "--n-fine", "8", "-q"]  # the same grid lines (the axisymmetric default is finer)
        assert main(args + (["--axisymmetric"] if model == "axi" else [])) == 0
        runs[model] = read(out)
    (a, sa), (b, sb) = runs["3d"], runs["axi"]
    line = np.abs(a["y"]) < 1e-12
    a = {k: v[line] for k, v in a.items()}
    assert np.array_equal(a["x"], b["x"])
    assert list(a["status"]) == list(b["status"]) and {"stick", "slip"} <= set(a["status"])
    off_axis = (a["r"] > 0) & (a["p_N"] > 0)
    scale = a["p_N"].max()
    assert np.max(np.abs(a["p_N"] - b["p_N"])[off_axis]) < 0.03 * scale
    assert np.max(np.abs(a["p_r"] - b["p_r"])[off_axis]) < 0.03 * scale
    assert np.max(np.abs(a["p_r"])) > 0.1 * 0.3 * scale  # friction acts
    # the Cartesian mesh is not axisymmetric: a small circumferential traction off the axes
    full = runs["3d"][0]
    assert np.max(np.abs(full["p_theta"])) < 0.1 * np.max(np.abs(full["p_r"]))
    assert np.all(full["p_theta"][line] == 0.0)
    assert sa["c_over_a"] == pytest.approx(sb["c_over_a"], abs=0.05)


def test_hertz3d_problem_is_sized_by_nominal_values_and_named_errors():
    a = hertz3d_problem({"R": 1.3}, n_fine=4, size=6.0)
    b = hertz3d_problem({}, n_fine=4, size=6.0)
    assert np.array_equal(a.mesh.nodes, b.mesh.nodes)
    xs, zs, a0 = grid(n_fine=4, size=6.0)
    assert xs[-1] == pytest.approx(6.0 * a0) and zs[0] == pytest.approx(-6.0 * a0)
    from signorini.errors import InputError, UnknownParameterError
    with pytest.raises(UnknownParameterError, match="unknown parameter 'Q'"):
        hertz3d_problem({"Q": 1.0})
    with pytest.raises(InputError, match="mu=-0.1"):
        hertz3d_problem({"mu": -0.1})


def test_hertz3d_coarse_start_changes_only_the_first_iterate(tmp_path, monkeypatch):
    """From a coarser mesh's solution, interpolated in 3-D (tetrahedral linear
    interpolation of the displacements, the nearest surface nodes' multipliers),
    Newton needs fewer iterations and reaches the same pressures and sensitivities."""
    from signorini.app.commands import hertz3d as cmd
    from signorini.problems import hertz
    monkeypatch.setattr(hertz, "MIN_GUIDED_DOFS", 0)
    kw = dict(n_fine=8, size=5.0, fd_check=False)
    guided = cmd.run(tmp_path / "g", **kw)
    plain = cmd.run(tmp_path / "p", coarse_start=False, **kw)
    assert guided["coarse_start"][0]["dofs"] < guided["mesh"]["dofs"]
    assert sum(guided["newton_iterations"]) < sum(plain["newton_iterations"])
    a, _ = read(tmp_path / "g")
    b, _ = read(tmp_path / "p")
    for f in ("p_N", "dp_N_dR", "dp_N_dP"):
        assert np.allclose(a[f], b[f], rtol=0, atol=1e-8 * np.abs(b[f]).max()), f


def test_hertz3d_wrt_selects_the_sensitivities(tmp_path):
    """--wrt: only the named parameters' columns, FD checks and figures, the same
    values as the default run's columns of those parameters."""
    out_all, out_two = tmp_path / "all", tmp_path / "two"
    assert main(["hertz3d", "--out", str(out_all), "--no-fd"] + SMALL) == 0
    assert main(["hertz3d", "--out", str(out_two), "--wrt", "P", "E", "P"] + SMALL) == 0
    a, _ = read(out_all)
    b, s = read(out_two)
    assert {k for k in b if k.startswith("dp_N_d")} == {"dp_N_dP", "dp_N_dE"}
    assert set(s["ddm_vs_fd_rel_diff"]) == {"P", "E"} and max(s["ddm_vs_fd_rel_diff"].values()) < 1e-6
    for k in ("dp_N_dP", "dp_N_dE"):
        assert np.max(np.abs(a[k] - b[k])) <= 1e-9 * np.max(np.abs(a[k]))
    assert not (out_two / "sensitivity.png").exists()  # its curve is dp_N/dR
    with pytest.raises(SystemExit):
        main(["hertz3d", "--out", str(tmp_path / "bad"), "--wrt", "Q"] + SMALL)
