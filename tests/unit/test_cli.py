"""The `signorini` command, run as a user would (default mesh)."""

import csv
import json

import numpy as np
import pytest

from signorini.app.cli import main
from signorini.problems import hertz


def test_hertz_command_writes_results(tmp_path, capsys):
    out = tmp_path / "h"
    assert main(["hertz", "--out", str(out), "-q"]) == 0
    for f in ("contact.csv", "summary.json", "pressure.png", "sensitivity.png", "hertz.vtu"):
        assert (out / f).stat().st_size > 0, f
    s = json.loads((out / "summary.json").read_text())
    an = hertz.analytical(1.2, 1.0, 100.0, 0.3)
    assert np.isclose(s["p0"]["analytical"], an["p0"])  # eq. 22
    assert abs(s["p0"]["rel_error"]) < 0.01
    assert abs(s["a"]["error_in_cells"]) <= 1.0
    for name in ("R", "E", "P"):
        assert s["ddm_vs_fd_rel_diff"][name] < 1e-5
    rows = list(csv.DictReader(open(out / "contact.csv")))
    assert list(rows[0]) == ["x_ref", "x", "p_N", "dp_N_dR", "dp_N_dE", "dp_N_dP"]
    assert np.isclose(float(rows[0]["p_N"]), s["p0"]["computed"])
    assert "p0 =" in capsys.readouterr().out


def test_set_and_method_options(tmp_path):
    out = tmp_path / "p"
    assert main(["hertz", "--out", str(out), "-q", "--set", "R=2", "--method", "penalty",
                 "--no-fd"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["params"]["R"] == 2.0 and s["method"] == "penalty"
    assert np.isclose(s["a"]["analytical"], hertz.analytical(1.2, 2.0, 100.0, 0.3)["a"])
    # the penalty allows penetration p/eps: a softer support, wider contact, lower peak
    # (2.1 % low at eps = E/h here, vs 0.01 % for the augmented Lagrangian)
    assert -0.05 < s["p0"]["rel_error"] < -0.005


def test_bad_input_gives_clear_error(tmp_path, capsys):
    assert main(["hertz", "--out", str(tmp_path / "x"), "-q", "--set", "Q=1", "--no-fd"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'Q'" in err and "Traceback" not in err
    assert main(["hertz", "--out", str(tmp_path / "y"), "-q", "--set", "R=-1", "--no-fd"]) == 2
    assert "must be positive" in capsys.readouterr().err


def test_run_command_on_the_shipped_example(tmp_path, capsys):
    """`signorini run examples/block.toml`: the example of docs/problem-files.md."""
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "block.toml"
    out = tmp_path / "block"
    assert main(["run", str(example), "--out", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "converged" and s["increments"] == 2
    assert (out / "block.pvd").exists() and (out / "contact.csv").exists()
    p = s["responses"]["p_max"]
    assert p["value"] > 0 and set(p["sensitivities"]) == {"R", "E", "W"}
    assert "p_max =" in capsys.readouterr().out


def test_help_and_version(capsys):
    import pytest

    import signorini

    for argv in (["--version"], ["hertz", "--help"], ["hertz-friction", "--help"], ["run", "--help"]):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 0
    text = capsys.readouterr().out
    assert f"signorini {signorini.__version__}" in text
    assert "mu = Coulomb friction coefficient" in text  # the --set names of hertz-friction
    assert "--zone-width" in text and "(default: 20.0)" in text and "(default: 80.0)" in text
    assert ":func:" not in text and "``" not in text  # no raw reStructuredText


@pytest.mark.parametrize("command, module, names", [
    ("hertz", "hertz", "HERTZ_SET"), ("hertz-friction", "hertz_friction", "FRICTION_SET"),
    ("hertz3d", "hertz3d", "HERTZ3D_SET"), ("forging", "forging", "FORGING_SET"),
    ("forging3d", "forging3d", "FORGING3D_SET"), ("cylinders", "cylinders", "CYLINDERS_SET"),
    ("spheres", "spheres", "SPHERES_SET"), ("ironing", "ironing", "IRONING_SET"),
    ("ironing3d", "ironing3d", "IRONING3D_SET")])
def test_benchmark_commands_share_their_option_help(capsys, command, module, names):
    """--out, --set and --no-fd of every benchmark command come from one helper
    (options.command_options, options.path_options): the same words everywhere,
    and the --set help names every parameter the command accepts."""
    import importlib

    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--out DIR output directory (created if needed; must be writable)" in text
    assert "--no-fd skip the check of the DDM sensitivities by central finite differences (saves " in text
    allowed = getattr(importlib.import_module(f"signorini.app.commands.{module}"), names)
    for name in allowed:
        assert f" {name} = " in text, name


def test_old_command_name_runs_the_renamed_command_with_a_notice(capsys):
    """``optimise-forging`` is ``optimize-forging`` now (one spelling); the old name
    still runs it for a release and says so on stderr."""
    with pytest.raises(SystemExit) as e:
        main(["optimise-forging", "--help"])
    assert e.value.code == 0
    out, err = capsys.readouterr()
    assert "usage: signorini optimize-forging" in out
    assert "'optimise-forging' is now 'optimize-forging'" in err
    with pytest.raises(SystemExit):
        main(["optimize-forging", "--help"])
    assert "is now" not in capsys.readouterr().err


@pytest.mark.parametrize("bad", ["0", "-1e-10", "nan", "1", "2", "abc"])
def test_rtol_is_validated(tmp_path, capsys, bad):
    """--rtol takes a relative tolerance in (0, 1): anything else is a usage error
    (exit 2) that says what is expected, before any work."""
    with pytest.raises(SystemExit) as e:
        main(["hertz", "--out", str(tmp_path / "x"), "-q", "--no-fd", f"--rtol={bad}"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--rtol" in err and ("between 0 and 1" in err or "expected a number" in err), err
    assert not (tmp_path / "x").exists()


def test_rtol_and_max_iter_reach_newton(tmp_path):
    """--rtol and --max-iter are Newton's: a loose tolerance stops earlier (and the
    summary has each increment's relative residual and why Newton stopped); a
    problem file's [solve] values give way to them. (Between 1e-4 and 1e-11 the
    one-step Hertz takes the same iterations: the residual falls from above 1e-4
    to round-off in the iteration that finds the final contact zone.)"""
    from pathlib import Path

    runs = {}
    for rtol in ("1e-11", "0.5"):
        out = tmp_path / rtol
        assert main(["hertz", "--out", str(out), "-q", "--no-fd", "--no-coarse-start",
                     "--rtol", rtol]) == 0
        runs[rtol] = s = json.loads((out / "summary.json").read_text())
        assert s["newton_stops"] == ["rtol"]
        assert s["newton_relative_residuals"][0] <= float(rtol)
        t = s["newton_time_s"]  # where Newton's time went: all three parts measured
        assert set(t) == {"assembly", "factorization", "solve"} and all(v > 0 for v in t.values())
    assert runs["0.5"]["newton_iterations"][0] < runs["1e-11"]["newton_iterations"][0]
    # one Newton iteration is not enough: the increment is cut until the budget is spent
    out = tmp_path / "few"
    assert main(["hertz", "--out", str(out), "-q", "--no-fd", "--no-coarse-start",
                 "--max-iter", "1"]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "no convergence in 1 iterations" in s["reason"]
    example = Path(__file__).resolve().parents[2] / "examples" / "block.toml"
    out = tmp_path / "file"
    assert main(["run", str(example), "--out", str(out), "-q", "--rtol", "1e-5",
                 "--max-iter", "7"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["options"]["rtol"] == 1e-5 and s["options"]["max_iter"] == 7
    assert all(e["relative_residual"] <= 1e-5 for e in s["newton_log"] if e["converged"])
