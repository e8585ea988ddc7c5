"""The scripts of examples/ run as written (docs/examples.md) and their numbers hold."""

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def run(name, tmp_path):
    return runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="example")["main"](tmp_path)


@pytest.mark.filterwarnings("ignore::signorini.SignoriniWarning")
def test_indentation_fit(tmp_path):
    out = run("indentation_fit", tmp_path)
    assert out["E"] == pytest.approx(100.0, rel=2e-3)  # 0.5 % noise on the measurement
    assert (tmp_path / "indentation_fit.png").stat().st_size > 0


def test_fit_forging(tmp_path):
    out = run("fit_forging", tmp_path)
    assert out["success"] and out["n_solves"] <= 10
    for n, true in out["truth"].items():  # 1 % noise, seed 0: within two standard errors
        assert abs(out["values"][n] - true) <= 2 * out["stderr"][n]
        assert 0.002 < out["stderr"][n] / true < 0.05  # SE ~ 2.5 % of sigma_y, 1.2 % of H
    assert 0.5 < out["sigma"] < 1.5  # the weights are 1 / the noise's variance
    assert (tmp_path / "fit_forging.png").stat().st_size > 0


@pytest.mark.filterwarnings("ignore::signorini.SignoriniWarning")
def test_press_then_slide(tmp_path):
    out = run("press_then_slide", tmp_path)
    assert out["ratio"] == pytest.approx(0.3, rel=2e-2)  # sliding: drag ~ mu load
    assert out["dF_x"] == pytest.approx(-out["F_z"], rel=2e-2)
    assert (tmp_path / "press_then_slide.png").stat().st_size > 0


@pytest.mark.filterwarnings("ignore::signorini.SignoriniWarning")
def test_two_body_design(tmp_path):
    out = run("two_body_design", tmp_path)
    assert out["peak"] == pytest.approx(out["target"], rel=1e-6)
    assert out["R2"] == pytest.approx(out["R2_hertz"], rel=0.02)  # 1.469 against Hertz's 1.486
    assert (tmp_path / "two_body_design.png").stat().st_size > 0
