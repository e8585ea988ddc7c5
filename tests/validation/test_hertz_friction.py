"""The frictional Hertz benchmark (paper 5.2): the stick zone and the normalised
pressure are self-similar at P1, P2, P3, and the ``hertz-friction`` command
writes its tables, figures and summary."""

import json

import numpy as np

import signorini as sg
from signorini.app.cli import main
from signorini.problems import hertz, hertz_friction as hf

STEPS = 6  # P1, P2, P3 = increments 1, 3, 5


def test_frictional_hertz_self_similar():
    """Paper 5.2 (default mesh, 6 increments): c/a the same at P1, P2, P3 within one
    element spacing h (|c_i - kappa a_i| <= h for one kappa), and p_N / p0_i against
    x / a_i the same curve within 2 % of p0 (eq. 22 for p0_i, a_i)."""
    pb = hf.hertz_friction_problem()
    h = hertz.fine_cell_size(pb)
    sol = sg.solve(pb, steps=STEPS, options=sg.NewtonOptions(rtol=1e-10))
    a, c, curves = [], [], []
    for k in hf.load_increments(sol):
        cont = sol.contact(k)
        ak, ck = hf.zones(cont)
        a.append(ak)
        c.append(ck)
        an = hertz.analytical(pb.params["P"] * sol.increments[k].t, 10.0, 100.0, 0.3)
        curves.append((cont["x_ref"][:, 0] / an["a"], cont["p_N"] / an["p0"]))
    a, c = np.array(a), np.array(c)
    kappa = np.linspace(0.2, 1.0, 8001)
    dev = min(np.max(np.abs(c - kap * a)) for kap in kappa)
    print("c/a at P1, P2, P3:", np.round(c / a, 3), f"minimax deviation {dev / h:.2f} h")
    assert dev <= h
    x3, p3 = curves[2]
    for x, p in curves[:2]:
        m = x < 1.0
        assert np.max(np.abs(p[m] - np.interp(x[m], x3, p3))) <= 0.02


def test_hertz_friction_command(tmp_path, capsys):
    out = tmp_path / "hf"
    assert main(["hertz-friction", "--out", str(out), "-q", "--steps", "3", "--no-fd",
                 "--set", "mu=0.5"]) == 0
    for i in (1, 2, 3):
        head = (out / f"contact_P{i}.csv").read_text().splitlines()[0]
        assert head == "x_ref,x,p_N,p_T,dp_N_dR,dp_T_dR,dp_N_dmu,dp_T_dmu,dp_N_dE,dp_T_dE,status"
    for f in ("pressure.png", "friction.png", "normalised.png", "normalised_sensitivity.png"):
        assert (out / f).stat().st_size > 0
    import meshio

    vtu = meshio.read(out / "hertz_friction_P3.vtu")
    status = vtu.point_data["contact_status"]
    assert {1.0, 2.0} <= set(np.unique(status))  # stick and slip nodes at P3
    assert "dp_T_dR" in vtu.point_data and "slip_increment" in vtu.point_data
    s = json.loads((out / "summary.json").read_text())
    assert s["params"]["mu"] == 0.5 and len(s["newton_iterations"]) == 3
    assert all(0 < ca < 1 for ca in s["c_over_a"])
    assert "c/a" in capsys.readouterr().out
    assert main(["hertz-friction", "--out", str(out), "-q", "--steps", "4"]) == 2
    assert "multiple of 3" in capsys.readouterr().err
