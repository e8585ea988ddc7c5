"""``signorini cylinders``: two elastic cylinders, a mortar pair between
non-matching meshes; against Hertz, and DDM = FD of two command runs with a
perturbed radius (the arcs re-meshed at the run's radius, the grid lines not)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from signorini.app.cli import main
from signorini.problems.cylinders import analytical, cylinders_problem

SMALL = ["--n-fine", "6", "-q"]


def read(out, name="contact.csv"):
    with open(out / name) as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return {k: (v if k == "status" else v.astype(float)) for k, v in cols.items()}, \
        json.loads((out / "summary.json").read_text())


@pytest.mark.slow  # 2 min; the pieces: test_cylinders_cli_outputs, the mesh test below, test_mortar's DDM = FD
def test_cylinders_cli_fd_of_two_runs_equals_the_ddm(tmp_path):
    """Frictionless, R1 = 1 against R2 = 1.5: p0 and b near Hertz's, every file
    written, the summary's own FD check below 1e-6; central differences of
    contact.csv from two runs with R1 +- 1e-4 (re-meshed at their radius) equal
    the DDM's dp_N_dR1; the upper surface's tractions balance P."""
    c, s = {}, {}
    for tag, R1 in (("0", 1.0), ("+", 1.0 + 1e-4), ("-", 1.0 - 1e-4)):
        out = tmp_path / tag
        args = ["cylinders", "--out", str(out), "--set", f"R1={R1}", "--set", "R2=1.5"] + SMALL
        assert main(args + (["--no-fd"] if tag != "0" else [])) == 0
        c[tag], s[tag] = read(out)
    for name in ("contact.csv", "contact_upper.csv", "summary.json", "pressure.png", "sensitivity.png",
                 "cylinders.vtu"):
        assert (tmp_path / "0" / name).is_file(), name
    assert np.array_equal(c["+"]["x"], c["0"]["x"])  # the grid columns do not move with R1
    an = analytical(0.1, 1.0, 1.5, 100.0, 100.0, 0.3, 0.3)
    assert s["0"]["p0"]["analytical"] == pytest.approx(an["p0"], rel=1e-12)
    assert abs(s["0"]["p0"]["rel_error"]) < 0.02 and abs(s["0"]["b"]["error_in_cells"]) <= 1.0
    assert max(s["0"]["ddm_vs_fd_rel_diff"].values()) < 1e-6
    fd = (c["+"]["p_N"] - c["-"]["p_N"]) / 2e-4
    ddm = c["0"]["dp_N_dR1"]
    inner = np.abs(c["0"]["x"]) < 0.9 * an["b"]
    err = np.max(np.abs(fd - ddm)[inner]) / np.max(np.abs(ddm[inner]))
    assert err < 1e-6
    up, _ = read(tmp_path / "0", "contact_upper.csv")
    width = np.diff(np.sort(up["x"]))
    force = np.sum(up["p_N"] * np.concatenate([[width[0] / 2], (width[:-1] + width[1:]) / 2, [width[-1] / 2]]))
    assert force == pytest.approx(0.1, rel=1e-3)


def test_cylinders_mesh_moves_smoothly_with_the_radii():
    """The nodes at R1 + h are those at R1 moved by h V_R1 + O(h^2): the design
    velocity is the exact derivative of the mesh."""
    h = 1e-4
    X = [cylinders_problem({"R1": 1.0 + s * h}, n_fine=8).mesh.nodes for s in (1, 0, -1)]
    V = cylinders_problem({}, n_fine=8).shape["R1"]
    assert np.abs((X[0] - X[2]) / (2 * h) - V).max() < 1e-6 * np.abs(V).max()
    assert np.abs(X[0] - X[1]).max() > 0


def test_cylinders_cli_outputs(tmp_path):
    """One frictionless run on a coarse mesh (6 cells across the fine zone; the 1 %
    of p0 at 16: test_mortar): every file, p0 and b near Hertz's, and the upper
    surface's tractions (from its nodal contact forces) add up to P."""
    out = tmp_path / "c"
    assert main(["cylinders", "--out", str(out), "--no-fd"] + SMALL) == 0
    for name in ("contact.csv", "contact_upper.csv", "summary.json", "pressure.png", "sensitivity.png",
                 "cylinders.vtu"):
        assert (out / name).is_file(), name
    c, s = read(out)
    assert abs(s["p0"]["rel_error"]) < 0.05 and abs(s["b"]["error_in_cells"]) <= 1.0
    assert s["p0"]["computed"] == pytest.approx(c["p_N"].max())
    up, _ = read(out, "contact_upper.csv")
    width = np.diff(np.sort(up["x"]))
    force = np.sum(up["p_N"] * np.concatenate([[width[0] / 2], (width[:-1] + width[1:]) / 2, [width[-1] / 2]]))
    assert force == pytest.approx(0.1, rel=1e-3)


@pytest.mark.slow  # 42k DOFs, ~1 min; test_mortar's frictional cylinders DDM = FD covers the code
def test_frictional_cylinders_cli_checks_its_ddm_against_fd(tmp_path):
    """With friction the summary's own FD check (the six parameters, p_N and p_T of
    contact.csv inside 0.9 b) agrees with the DDM (it compared contact.csv's DDM
    columns with the solution's own rows, in another order and with p_T of the other
    sign: 2.0 for E1, mu and Q before)."""
    out = tmp_path / "f"
    assert main(["cylinders", "--out", str(out), "--set", "mu=0.3", "--set", "Q=0.015",
                 "--steps", "6"] + SMALL) == 0
    _, s = read(out)
    assert set(s["ddm_vs_fd_rel_diff"]) == {"R1", "R2", "E1", "P", "mu", "Q"}
    assert max(s["ddm_vs_fd_rel_diff"].values()) < 1e-6, s["ddm_vs_fd_rel_diff"]


def test_mindlin_stick_zone_within_two_percent_at_refine_1(tmp_path):
    """Mindlin's partial slip: with cells of 1/32 of b (refine 1) the stick zone's
    c/b is within 2 % of sqrt(1 - Q/(mu P)) and b within one cell of Hertz's (on the
    default mesh each is resolved to one cell, 6 % of b)."""
    out = tmp_path / "m"
    assert main(["cylinders", "--out", str(out), "--no-fd", "--refine", "1", "--set", "mu=0.3",
                 "--set", "Q=0.015", "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert abs(s["c_over_b"]["rel_error"]) <= 0.02, s["c_over_b"]
    assert abs(s["b"]["error_in_cells"]) <= 1.0
