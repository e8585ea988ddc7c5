"""``signorini fit FILE.toml --out DIR`` (issue 52 item 2): the example
examples/press_slide_fit.toml (a ball pressed into a block and slid along it,
3-D, Coulomb friction; E and mu from a synthetic force history at E = 100,
mu = 0.3) recovers the values, writes fit.json, the history and a figure, and
gives the answer of the same sg.fit called from a script; an interrupt keeps the
history and --resume continues it; a parameter the data cannot see is reported;
bad [fit] sections and CSV files get an error naming the key, the file and the line."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import signorini as sg
from signorini.app import problemfile as pf
from signorini.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "press_slide_fit.toml"
CSV = ROOT / "examples" / "press_slide_forces.csv"
TRUE = {"E": 100.0, "mu": 0.3}


def _copy(tmp_path, edit=None, csv_text=None):
    text = EXAMPLE.read_text()
    f = tmp_path / "fit.toml"
    f.write_text(edit(text) if edit else text)
    (tmp_path / CSV.name).write_text(CSV.read_text() if csv_text is None else csv_text)
    return f


def _script_fit():
    """The example written with the API: the same sg.fit call."""
    press, slide = sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)
    ball = sg.Sphere(radius="R", centre=(0.5, 0.0, "R"),
                     motion=(((0.0, 0.0, lambda p: -p["d"]), press), (("s", 0.0, 0.0), slide)))
    block = sg.box(np.linspace(0.2, 0.8, 13), np.linspace(-0.3, 0.3, 13), np.linspace(-0.3, 0, 3))
    pb = sg.Problem(block, sg.LinearElastic("E", "nu"),
                    {"E": 100.0, "nu": 0.3, "R": 0.5, "d": 0.02, "s": 0.05, "mu": 0.3, "eps": 1000.0},
                    fixed=[sg.Fixed("z0", k) for k in range(3)],
                    contact=[sg.Contact(ball, "z1", sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps"))])
    data = np.loadtxt(CSV, delimiter=",", skiprows=2)
    t, Fz, Fx = data.T
    curves = [sg.Curve(sg.responses.contact_force(component=2), t, Fz, np.full(t.size, 1 / np.abs(Fz).max() ** 2)),
              sg.Curve(sg.responses.contact_force(component=0), t, Fx, np.full(t.size, 1 / np.abs(Fx).max() ** 2))]
    return sg.fit(pb, ["E", "mu"], curves, start={"E": 75.0, "mu": 0.38},
                  bounds={"E": (10.0, 1000.0), "mu": (0.05, 0.8)}, max_solves=40,
                  options=sg.NewtonOptions(rtol=1e-12))


def test_fit_command_recovers_E_and_mu_and_equals_the_script(tmp_path, capsys):
    f = _copy(tmp_path)
    out = tmp_path / "out"
    assert main(["fit", str(f), "--out", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "converged" in printed and "E = 100" in printed
    s = json.loads((out / "fit.json").read_text())
    assert s["success"] and s["names"] == ["E", "mu"] and not s["warnings"] and not s["ill_conditioned"]
    for n, v in TRUE.items():
        assert abs(s["values"][n] / v - 1) < 1e-9, s["values"]
        assert 0 <= s["stderr"][n] < 1e-6 * v
    C = np.array(s["correlation"])
    assert C.shape == (2, 2) and np.allclose(np.diag(C), 1.0) and C[0, 1] == pytest.approx(C[1, 0])
    assert abs(C[0, 1]) < 0.9 and s["condition"] < 100
    assert s["start"] == {"E": 75.0, "mu": 0.38} and s["n_data"] == 16
    F = [r["F"] for r in s["history"]]
    assert F[0] > 1e8 * F[-1] and s["iterations"] == len(F) - 1 >= 2
    # the script's sg.fit: the same answer
    ref = _script_fit()
    for n in TRUE:
        assert s["values"][n] == pytest.approx(ref.values[n], rel=1e-10)
    assert len(s["history"]) == len(ref.history)
    # the files
    assert (out / "fit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = (out / "fit_history.csv").read_text().splitlines()
    assert rows[0] == "iteration,F,grad_norm,solves,E,mu" and len(rows) == len(F) + 1
    import tomllib
    fitted = tomllib.loads((out / "fitted.toml").read_text())["params"]
    assert fitted == pytest.approx(s["values"], rel=1e-15)
    fz = np.genfromtxt(out / "curve_Fz.csv", delimiter=",", names=True)
    np.testing.assert_allclose(fz["fitted"], fz["measured"], rtol=0, atol=1e-9 * np.abs(fz["measured"]).max())


def test_interrupt_keeps_the_history_and_resume_continues_it(tmp_path):
    f = _copy(tmp_path)
    out = tmp_path / "out"

    def stop_after_one(row):
        if row["iteration"] >= 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        pf.fit(f, out, progress=stop_after_one)
    kept = json.loads((out / "fit_history.json").read_text())
    assert kept["status"] == "interrupted" and [r["iteration"] for r in kept["history"]] == [0, 1]
    assert kept["history"][0]["x"] == [75.0, 0.38]
    seen = []
    s = pf.fit(f, out, resume=True, progress=seen.append)
    assert s["resumed"] and s["success"] and s["start"] == {"E": 75.0, "mu": 0.38}
    its = [r["iteration"] for r in s["history"]]
    assert its == list(range(len(its))) and its[:2] == [0, 1] and seen[0]["iteration"] == 2
    assert s["history"][1]["x"] == kept["history"][1]["x"]
    for n, v in TRUE.items():
        assert abs(s["values"][n] / v - 1) < 1e-9
    with pytest.raises(sg.InputError, match="--resume: .* not found"):
        pf.fit(f, tmp_path / "elsewhere", resume=True)


def test_the_adjoint_gradient_from_a_file(tmp_path):
    """gradient = "adjoint" with L-BFGS-B: the same values as the script's sg.fit
    with the same options (one backward pass per point for both parameters)."""
    f = _copy(tmp_path, lambda t: t.replace('method = "least_squares"',
                                             'method = "L-BFGS-B"\ngradient = "adjoint"'))
    s = pf.fit(f, tmp_path / "out")
    assert s["success"] and s["method"] == "L-BFGS-B"
    for n, v in TRUE.items():
        assert abs(s["values"][n] / v - 1) < 1e-6, s["values"]


def test_a_parameter_the_data_cannot_see_is_reported(tmp_path):
    """H is in [params] but in nothing of the problem: fit.json says the fit is
    ill-conditioned and why."""
    def edit(text):
        text = text.replace("eps = 1000.0 ", "eps = 1000.0\nH = 1.0 ")
        text = text.replace("max_solves = 40", "max_solves = 4")
        return text.replace("mu = { start = 0.38, bounds = [0.05, 0.8] }",
                            "mu = { start = 0.3, bounds = [0.05, 0.8] }\nH = { start = 1.0, bounds = [0.1, 10.0] }")
    f = _copy(tmp_path, edit)
    s = pf.fit(f, tmp_path / "out")
    assert s["ill_conditioned"] and s["names"] == ["E", "mu", "H"]
    assert any("do not depend on ['H']" in w for w in s["warnings"]), s["warnings"]


def _csv(rows):
    return "t,Fz,Fx\n" + "".join(f"{r}\n" for r in rows)


GOOD_ROWS = CSV.read_text().splitlines()[2:]

BAD = [
    # (edit of the file, CSV text or None, fragments of the message)
    (None, _csv(GOOD_ROWS[:3] + ["0.5,abc,0.0"] + GOOD_ROWS[4:]),
     ["[[fit.curve]] #1 press_slide_forces.csv line 5, column 'Fz': 'abc' is not a finite number"]),
    (None, _csv(GOOD_ROWS[:3] + [GOOD_ROWS[1]] + GOOD_ROWS[4:]),
     ["[[fit.curve]] #1 press_slide_forces.csv line 5, column 't': the abscissae must increase; "
      "0.25 follows 0.375"]),
    (None, "time,Fz,Fx\n0.5,1,2\n", ["[[fit.curve]] #1 x = 't': no such column"]),
    (None, _csv(["0.0,1.0,0.0", "0.5,1.0,0.0"]),
     ["[[fit.curve]] #1 x: the abscissae of press_slide_forces.csv divided by scale = 1 are load "
      "factors of the path, in (0, 1]; got 0 .. 0.5", "(line 74)"]),
    (lambda t: t.replace('response = "Fz"', 'response = "Fy"'), None,
     ["[[fit.curve]] #1 response: 'Fy' is not the name of a [[response]] (they are Fz, Fx) (line 72)"]),
    (lambda t: t.replace("E = { start = 75.0", "Young = { start = 75.0"), None,
     ["[fit.parameters] 'Young' is not a parameter", "(line 68)"]),
    (lambda t: t.replace("bounds = [10.0, 1000.0]", "bounds = [100.0, 10.0]"), None,
     ["[fit.parameters] E bounds: need low < high"]),
    (lambda t: t.replace('method = "least_squares"', 'method = "newton"'), None,
     ["[fit] method: 'newton' is not one of 'least_squares', 'L-BFGS-B' (line 64)"]),
    (lambda t: t.replace('method = "least_squares"', 'method = "least_squares"\ngradient = "adjoint"'),
     None, ['[fit] gradient: the adjoint gradient is for method = "L-BFGS-B"']),
    (lambda t: t.replace('method = "least_squares"', 'gradient = "forward"'), None,
     ["[fit] gradient: 'forward' is not one of 'ddm', 'adjoint'"]),
    (lambda t: t.replace('weight = "relative"', 'weigth = "relative"', 1), None,
     ["[[fit.curve]] #1 unknown key 'weigth' (did you mean 'weight'?)", "(line 76)"]),
    (lambda t: t.split('[[fit.curve]]\nresponse = "Fx"')[0].replace("[[fit.curve]]", "[fit.curve]"),
     None, ["[fit] curve: write each curve as a [[fit.curve]] table"]),
]


@pytest.mark.parametrize("edit, csv_text, fragments", BAD, ids=[b[2][0][:40] for b in BAD])
def test_bad_fit_sections_and_csv_files(tmp_path, edit, csv_text, fragments):
    f = _copy(tmp_path, edit, csv_text)
    with pytest.raises(sg.InputError) as err:
        pf.load(f)
    msg = str(err.value)
    assert msg.startswith(f"{f}: "), msg
    for fragment in fragments:
        assert fragment in msg, msg


def test_fit_command_on_a_file_without_fit_exits_2(tmp_path, capsys):
    shutil.copy(ROOT / "examples" / "block.toml", tmp_path / "block.toml")
    assert main(["fit", str(tmp_path / "block.toml"), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "no [fit] section" in err and "Traceback" not in err
    assert re.search(r"signorini: error: .*block.toml: no \[fit\] section", err)


def test_a_curve_against_a_displacement_response_from_a_file(tmp_path):
    """examples/block.toml under force control with a force-displacement curve
    ([[fit.curve]] abscissa = the bottom's displacement, measured between the
    increments): E recovered from 80 to 1e-6, the curve file's columns are the
    displacement (not load factors), and a missing [fit] steps is named."""
    text = (ROOT / "examples" / "block.toml").read_text().replace("nx = 32\nny = 16", "nx = 16\nny = 8")
    text = text.split("[output]")[0].replace('sensitivities = ["R", "E", "W"]', 'sensitivities = ["E"]')
    text += ('\n[[response]]\nname = "force"\ntype = "contact_force"\ncomponent = "y"\n'
             '\n[[response]]\nname = "lift"\ntype = "displacement"\nset = "bottom"\ncomponent = "y"\n')
    f = tmp_path / "block.toml"
    f.write_text(text)
    problem, cfg = pf.load(f)
    force, lift = (r.public() for r in cfg.responses[1:])
    sol = sg.solve(problem, steps=4)
    X, Y = np.array(lift.path(sol)), np.array(force.path(sol))
    xm = 0.5 * (X[:-1] + X[1:])
    (tmp_path / "fd.csv").write_text("u,F\n" + "".join(f"{a:.17g},{b:.17g}\n" for a, b in zip(xm, np.interp(xm, X, Y))))
    fit = ('\n[fit]\nsteps = 4\n[fit.parameters]\nE = { start = 80.0, bounds = [10.0, 1000.0] }\n'
           '[[fit.curve]]\nresponse = "force"\nabscissa = "lift"\nfile = "fd.csv"\nx = "u"\ny = "F"\n')
    f.write_text(text + fit)
    s = pf.fit(f, tmp_path / "out")
    assert s["success"] and abs(s["values"]["E"] / 100.0 - 1) < 1e-6, s["values"]
    assert (tmp_path / "out" / "curve_force.csv").read_text().splitlines()[0].startswith("u,measured")
    f.write_text(text + fit.replace("steps = 4\n", ""))
    with pytest.raises(sg.InputError, match=r"\[fit\] steps: every curve is measured against an abscissa"):
        pf.fit(f, tmp_path / "out2")


def test_a_fit_too_large_for_the_machine_is_refused_before_its_first_solve(tmp_path, capsys,
                                                                          monkeypatch):
    """The fit's solves are checked against the available memory before the first one,
    as a run's are (the whole mesh, 3-D, its contact multipliers), with exit 2 and
    no history written."""
    import importlib

    from signorini.errors import ResourceError

    # the module (the package's name ``run`` is its function)
    run_module = importlib.import_module("signorini.app.problemfile.run")

    seen = []

    def refuse(n_dof, **kw):
        seen.append((n_dof, kw["dim"], kw["extra"](n_dof)))  # the history's bytes
        raise ResourceError(f"refused: {n_dof:,} unknowns")

    monkeypatch.setattr(run_module, "check_size", refuse)
    f = _copy(tmp_path)
    code = main(["fit", str(f), "--out", str(tmp_path / "out"), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and "refused: 2,028 unknowns" in err, err
    # the block's 13 x 13 x 3 nodes and its 169 contact nodes' 3 multipliers; no history
    assert seen == [(3 * 13 * 13 * 3 + 3 * 169, 3, 0.0)]
    assert not (tmp_path / "out" / "fit_history.csv").exists()
