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
