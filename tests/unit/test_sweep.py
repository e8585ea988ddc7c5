"""signorini.sweep: grid parsing, the CSV, and a hertz sweep on a two-worker
local Dask cluster identical to the sequential run, with a failing point."""

import json
import math

import pytest

from signorini.app.sweep import flatten, grid, point_args, read_csv, run_sweep

distributed = pytest.importorskip("distributed")

HERTZ_FAST = ["--no-fd", "--block", "10"]


def test_grid_product_and_types():
    pts = grid(["R=1.0,1.1", "E=100,200", "--refine=0"])
    assert pts == [{"R": 1.0, "E": 100, "--refine": 0}, {"R": 1.0, "E": 200, "--refine": 0},
                   {"R": 1.1, "E": 100, "--refine": 0}, {"R": 1.1, "E": 200, "--refine": 0}]
    assert grid(["P=1:2:3"]) == [{"P": 1.0}, {"P": 1.5}, {"P": 2.0}]
    assert grid([]) == [{}]
    for bad in (["R"], ["R="], ["=1"], ["R=1", "R=2"], ["P=1:2"], ["P=1:2:0"]):
        with pytest.raises(ValueError):
            grid(bad)


def test_point_args_and_flatten():
    args = point_args("optimize-forging", {"--mu": 0.1, "R": 0.1 + 0.2}, "o", ["--maxiter", 2])
    assert args == ["optimize-forging", "--out", "o", "-q", "--mu", "0.1", "--set",
                    f"R={0.1 + 0.2!r}", "--maxiter", "2"]
    flat = flatten({"a": {"b": 1.5, "c": [1, 2]}, "w": ["x", "y"], "e": [], "long": list(range(9)),
                    "loads": [{"c": 0.1}], "s": "txt", "n": None})
    assert flat == {"a.b": 1.5, "a.c.0": 1, "a.c.1": 2, "w.len": 2, "e.len": 0, "long.len": 9,
                    "loads.0.c": 0.1, "s": "txt", "n": None}


def _numeric(rows):
    """The numeric cells of the table, except timings."""
    return [{k: v for k, v in r.items() if isinstance(v, (int, float)) and "time" not in k and not k.startswith("timings.")}
            for r in rows]


def test_hertz_sweep_two_workers_equals_sequential(tmp_path):
    pts = grid(["R=1.0,1.1"]) + [{"R": 1.0, "nu": 0.7}]  # the last point is bad input
    seq = run_sweep("hertz", pts, tmp_path / "seq", extra_args=HERTZ_FAST, sequential=True)
    par = run_sweep("hertz", pts, tmp_path / "par", extra_args=HERTZ_FAST, n_workers=2)
    a, b = read_csv(seq), read_csv(par)
    assert len(a) == len(b) == 3
    assert [r["exit_code"] for r in a] == [r["exit_code"] for r in b] == [0, 0, 2]
    assert [r["status"] for r in b] == ["converged", "converged", "bad input"]
    assert "Poisson" in b[2]["reason"] and b[2]["nu"] == 0.7
    assert b[1]["R"] == 1.1 and b[1]["params.R"] == 1.1 and b[0]["dir"] == "point_0"
    na, nb = _numeric(a), _numeric(b)
    assert na == nb  # bitwise: the same calls, in other processes
    assert math.isfinite(b[1]["p0.computed"]) and b[0]["p0.computed"] != b[1]["p0.computed"]
    doc = json.loads((tmp_path / "par" / "sweep.json").read_text())
    assert doc["n_failed"] == 1 and doc["points"][2]["summary"] is None
    assert doc["points"][0]["summary"]["params"]["R"] == 1.0
    assert (tmp_path / "par" / "point_1" / "contact.csv").is_file()


def test_sweep_command_sequential(tmp_path, capsys):
    """`signorini sweep hertz --set R=1,1.2 --sequential -- --no-fd --block 10`: one row
    per point, the mesh never follows R (same DOFs), R recorded as swept."""
    from signorini.app.cli import main

    out = tmp_path / "sw"
    assert main(["sweep", "hertz", "--out", str(out), "--set", "R=1,1.2", "--sequential", "-q",
                 "--", "--no-fd", "--block", "10"]) == 0
    table = read_csv(out / "sweep.csv")
    assert [float(r["R"]) for r in table] == [1.0, 1.2]
    assert len({r["mesh.dofs"] for r in table}) == 1
    assert "2 points, 0 failed" in capsys.readouterr().out
    assert main(["sweep", "hertz", "--out", str(out), "--set", "R", "--sequential"]) == 2


def test_a_sweep_run_again_continues_from_what_was_recorded(tmp_path):
    """Run again, a sweep takes the points an earlier run completed (same
    arguments) from their directories and runs only the others: here the point
    that failed and a point whose directory lost its summary (as after an
    interrupted run); --fresh (fresh=True) runs every point again, to the same
    results."""
    pts = grid(["R=1.0,1.1,1.2"]) + [{"R": 1.0, "nu": 0.7}]  # the last point is bad input
    out = tmp_path / "sw"
    first = json.loads(_sweep_json(run_sweep("hertz", pts, out, extra_args=HERTZ_FAST,
                                             sequential=True)))
    (out / "point_2" / "summary.json").unlink()
    again = json.loads(_sweep_json(run_sweep("hertz", pts, out, extra_args=HERTZ_FAST,
                                             sequential=True)))
    assert [p["kept"] for p in again["points"]] == [True, True, False, False]
    assert [p["exit_code"] for p in again["points"]] == [0, 0, 0, 2]
    for p, q in zip(first["points"][:3], again["points"][:3]):
        assert p["summary"]["p0"] == q["summary"]["p0"]
    fresh = json.loads(_sweep_json(run_sweep("hertz", pts, out, extra_args=HERTZ_FAST,
                                             sequential=True, fresh=True)))
    assert not any(p["kept"] for p in fresh["points"])
    assert [p["summary"]["p0"] for p in fresh["points"][:3]] == \
        [p["summary"]["p0"] for p in again["points"][:3]]


def _sweep_json(csv_path):
    return (csv_path.parent / "sweep.json").read_text()
