"""``signorini spheres``: two elastic spheres in 3-D against Hertz, DDM = FD of
the command's outputs (docs/theory.md §13.11)."""

import json

import numpy as np
import pytest

from signorini.app.cli import main
from signorini.problems.spheres import analytical, spheres_problem, touch_offset, grid
from signorini.errors import InputError


def test_the_command_against_hertz_and_its_sensitivities(tmp_path):
    """The default run (quarter model, 2:3 meshes): p0 within 1 % of Hertz's, the
    contact radius within one cell, DDM = central FD of the pressures for R1, R2,
    E1, E2 (--wrt: the moduli of both bodies) and P to 1e-6, and the files a user
    looks at."""
    assert main(["spheres", "--out", str(tmp_path), "--wrt", "R1", "R2", "E1", "E2", "P"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    assert abs(s["p0"]["rel_error"]) < 1e-2
    assert abs(s["a"]["error_in_cells"]) < 1.0
    assert set(s["ddm_vs_fd_rel_diff"]) == {"R1", "R2", "E1", "E2", "P"}
    assert max(s["ddm_vs_fd_rel_diff"].values()) < 1e-6
    assert s["analytical_comparison"] == {"valid": True, "why": []}  # the bodies are half-spaces
    for f in ("contact.csv", "contact_upper.csv", "pressure.png", "sensitivity.png", "spheres.vtu"):
        assert (tmp_path / f).stat().st_size > 0
    up = np.genfromtxt(tmp_path / "contact_upper.csv", delimiter=",", names=True)
    # the upper surface's nodal forces over areas: Hertz's peak within 3 % (a coarser mesh)
    assert up["p_N"].max() == pytest.approx(s["p0"]["analytical"], rel=3e-2)


def test_the_grid_and_the_touch_do_not_depend_on_the_run():
    """The grid lines and the initial overlap come from the nominal values only: a
    run at other radii and loads has the same mesh topology and nodes but for the
    caps' shape (the design velocities)."""
    a = spheres_problem()
    rest = []
    for h in (0.01, 0.005):  # the nodes move by h V + O(h^2)
        b = spheres_problem({"R1": 1.0 + h, "P": 0.2, "E2": 120.0})
        assert np.array_equal(a.mesh.cells, b.mesh.cells)
        rest.append(np.abs(b.mesh.nodes - a.mesh.nodes - h * a.shape["R1"]).max())
    assert rest[0] < 0.01**2 and rest[1] == pytest.approx(rest[0] / 4, rel=0.05)
    x1, y1, x2, y2, *_ = grid()
    assert 0 < touch_offset(x1, y1, x2, y2, 1.0, 1.0) < 0.05 * (y1[1] - y1[0])  # a rigid shift of the upper body


def test_analytical_values():
    """Hertz for two equal spheres: R = R1/2, E* = E/(2 (1 - nu^2)); Mindlin's c/a
    at Q/(mu P) = 0.25, 0.5, 0.75."""
    h = analytical(P=0.1, R1=1.0, R2=1.0, E1=100.0, E2=100.0, nu1=0.3, nu2=0.3)
    Es = 100.0 / (2 * 0.91)
    a = (3 * 0.1 * 0.5 / (4 * Es)) ** (1 / 3)
    assert h["a"] == pytest.approx(a, rel=1e-14)
    assert h["p0"] == pytest.approx(3 * 0.1 / (2 * np.pi * a**2), rel=1e-14)
    for ratio, ca in ((0.25, 0.9086), (0.5, 0.7937), (0.75, 0.6300)):
        h = analytical(P=0.1, R1=1.0, R2=1.0, E1=100.0, E2=100.0, nu1=0.3, nu2=0.3, mu=0.3,
                       Q=ratio * 0.03)
        assert h["c"] / h["a"] == pytest.approx(ca, abs=1e-4)


def test_bad_values():
    with pytest.raises(InputError, match="below mu P"):
        spheres_problem({"mu": 0.3, "Q": 0.05})
    with pytest.raises(InputError, match="too small for the grid"):
        spheres_problem({"R1": 0.3})


def test_friction_names_need_friction(tmp_path, capsys):
    assert main(["spheres", "--out", str(tmp_path), "--wrt", "R1", "Q"]) == 2
    assert "sensitivities to mu and Q need friction" in capsys.readouterr().err
