"""The validity warnings of the contact commands (signorini.app.validity): a
contact zone too large for the curvature radius, the fine mesh zone or the
body, or reaching the edge of a face, and too few closed nodes, in 2-D,
axisymmetric and 3-D, rigid and two-body; each lands in summary.json and marks
the printed comparison with the analytical solution not valid. Small meshes:
each run takes a few seconds."""

from __future__ import annotations

import json
import types

import pytest

from signorini.app import validity
from signorini.app.cli import main
from signorini.errors import SignoriniWarning

RADIUS = "exceeds 0.3 R"
ZONE = "extends beyond the fine mesh zone"
BLOCK = "so the block is no longer a half-space"
FEW = validity.TOO_FEW
#: the family, to find its members among a run's warnings
FAMILY = (RADIUS, ZONE, "no longer a half-space", "no longer half-spaces", "reaches the edge of", FEW)

H3D = ["hertz3d", "--n-fine", "4", "--block", "6"]
CYL = ["cylinders", "--n-fine", "6"]
IRON = ["ironing", "--cells", "24", "--steps", "12", "--set", "s=0.5"]

#: command line -> fragments of the warnings it must give
CASES = {
    "hertz-radius": (["hertz", "--set", "P=10"], ["contact half-width a = ", RADIUS]),
    "hertz-zone": (["hertz", "--zone-width", "0.5"], [ZONE, "(--zone-width)"]),
    "hertz-block": (["hertz", "--block", "3"], ["of the block width", BLOCK, "(--block)"]),
    "hertz-few-nodes": (["hertz", "--set", "P=0.01"], [FEW]),
    "hertz-friction-block": (["hertz-friction", "--block", "3", "--steps", "3"], [BLOCK]),
    "hertz3d-radius": (H3D + ["--set", "P=4"], ["contact radius a = ", RADIUS]),
    "hertz3d-zone": (H3D + ["--zone-width", "0.5"], [ZONE]),
    "hertz3d-block": (["hertz3d", "--n-fine", "4", "--block", "3"],
                      ["of the block width and depth", BLOCK]),
    "axisymmetric-few-nodes": (H3D + ["--axisymmetric"], [FEW]),
    "axisymmetric-zone": (["hertz3d", "--axisymmetric", "--zone-width", "0.5"], [ZONE]),
    "cylinders-radius": (CYL + ["--set", "P=2.5"], ["contact half-width b = ", RADIUS, "R1 R2/(R1 + R2)"]),
    "cylinders-zone": (CYL + ["--set", "P=0.4"], ["(b = ", ZONE, "--set P="]),
    "cylinders-bodies": (CYL + ["--set", "P=1.6"], ["of each body's half-width and depth",
                                                    "so the bodies are no longer half-spaces"]),
    "cylinders-few-nodes": (CYL + ["--set", "P=0.01"], [FEW]),
    "ironing-die-edge": (IRON + ["--set", "d=0.25"], ["reaches the edge of the die's rounded face",
                                                      "--set d="]),
}

#: meshes like the defaults' (or the defaults): no validity warning
VALID = {
    "hertz": ["hertz"],
    "hertz-friction": ["hertz-friction"],
    "hertz3d": ["hertz3d", "--n-fine", "6", "--block", "6"],
    "axisymmetric": ["hertz3d", "--axisymmetric"],  # the default mesh
    "cylinders": ["cylinders", "--n-fine", "12"],
    # the default (96 cells, 50 increments) takes a minute; half its cells keep 10 closed nodes
    "ironing": ["ironing", "--cells", "48", "--steps", "12", "--set", "s=0.5", "--set", "d=0.12"],
}


def run(tmp_path, capsys, args):
    out = tmp_path / "out"
    assert main(args + ["--out", str(out), "--no-fd", "-q"]) == 0
    return json.loads((out / "summary.json").read_text()), capsys.readouterr().out


@pytest.mark.timeout(300)
@pytest.mark.parametrize("case", list(CASES))
def test_validity_warning_lands_in_summary_and_marks_the_comparison(tmp_path, capsys, case):
    args, fragments = CASES[case]
    s, printed = run(tmp_path, capsys, args)
    for f in fragments:
        assert any(f in w for w in s["warnings"]), (f, s["warnings"])
    ours = [w for w in s["warnings"] if any(f in w for f in FAMILY)]
    if args[0] == "ironing":  # no analytical solution to compare with
        assert "analytical_comparison" not in s
    else:
        assert s["analytical_comparison"]["valid"] is False
        assert s["analytical_comparison"]["why"] and set(s["analytical_comparison"]["why"]) == set(ours)
        assert validity.NOT_VALID in printed


@pytest.mark.timeout(300)
@pytest.mark.parametrize("name", list(VALID))
def test_default_like_runs_have_no_validity_warning(tmp_path, capsys, name):
    s, printed = run(tmp_path, capsys, VALID[name])
    assert not [w for w in s["warnings"] if any(f in w for f in FAMILY)], s["warnings"]
    if name != "ironing":
        assert s["analytical_comparison"] == {"valid": True, "why": []}
        assert "not valid" not in printed


def _solution(*warnings):
    return types.SimpleNamespace(warnings=list(warnings), label=None)


def test_check_issues_each_limit_once_and_returns_the_family():
    few = f"contact 'top': the contact zone holds only 3 {FEW}; refine"
    sol = _solution("something else", few)
    limits = [validity.fine_zone(1.0), validity.half_space(3.0),
              validity.edge(2.0, 0.5, "the die's face", ", so its corners press", "press less")]
    with pytest.warns(SignoriniWarning):
        got = validity.check(sol, 1.6, limits, radius=5.0)
    # 1.6 > 0.3 x 5.0 (radius), > 1.0 (zone), > 0.25 x 3.0 (half-space), > 2.0 - 0.5 (edge)
    assert got[0] == few and len(got) == 5
    assert RADIUS in got[1] and ZONE in got[2] and "53% of the block width 3" in got[3]
    assert "reaches the edge of the die's face (at 2" in got[4]
    assert sol.warnings == ["something else", few] + got[1:]
    assert validity.check(sol, 1.6, limits, radius=5.0) == got  # again: nothing added
    assert sol.warnings == ["something else", few] + got[1:]
    assert validity.comparison(got) == {"valid": False, "why": got}
    assert validity.note({"analytical_comparison": validity.comparison(got)}) == validity.NOT_VALID


def test_check_within_every_limit_warns_nothing():
    sol = _solution()
    limits = [validity.fine_zone(1.0), validity.half_space(4.0),
              validity.edge(2.0, 0.5, "the die's face", "", "")]
    assert validity.check(sol, 0.99, limits, radius=3.4) == []
    assert validity.check(sol, 0.99, limits) == []  # no radius: no comparison with Hertz
    assert sol.warnings == []
    assert validity.comparison([]) == {"valid": True, "why": []}
    assert validity.note({"analytical_comparison": validity.comparison([])}) == ""
    assert validity.note({}) == ""


@pytest.mark.timeout(300)
def test_a_problem_files_contact_reaching_the_end_of_its_surface_warns(tmp_path, capsys):
    """examples/block.toml (a half model: its surface's end on the symmetry line is
    the contact's centre) warns of nothing; under 30 times the load its contact
    zone reaches the far end of the block's top, and summary.json says so."""
    from pathlib import Path

    example = Path(__file__).parents[2] / "examples" / "block.toml"
    heavy = tmp_path / "heavy.toml"
    heavy.write_text(example.read_text().replace("P = 2.0", "P = 60.0"))
    for path, expect in ((example, False), (heavy, True)):
        out = tmp_path / path.stem
        assert main(["run", str(path), "--out", str(out), "-q"]) == 0
        s = json.loads((out / "summary.json").read_text())
        said = [w for w in s["warnings"] if "reaches the end of the contact surface" in w]
        assert bool(said) == expect, s["warnings"]
        if expect:
            assert len(said) == 1 and "(2.0, 0.0)" in said[0]
    capsys.readouterr()
