"""The output helper (signorini.post.helper): figures and VTU files written by
the helper are the files written in the process; a dead helper or a job it
cannot do leaves the work to the process; the ``signorini`` command uses it."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from signorini.post import helper, plots
from signorini.post.files import _write_vtu_arrays

X = np.linspace(0.0, 1.0, 50)


def draw(path, y=X ** 2):
    return plots.curves(path, [{"x": X, "y": y, "label": "a"},
                               {"x": X[::5], "y": X[::5], "label": "b", "style": "points"}],
                        xlabel="x", ylabel="y", title="t", xlim=(0, 1))


def vtu(path):
    pts = np.random.default_rng(0).random((9, 3))
    helper.run("vtu", path, pts, "quad", np.array([[0, 1, 4, 3], [1, 2, 5, 4]]),
               {"u": pts}, {"s": [np.arange(2.0)]})


@pytest.fixture
def running():
    assert helper.start()
    yield helper._HELPER
    helper.stop()


def test_the_helper_writes_the_same_files(tmp_path, running):
    draw(tmp_path / "helper.png")
    vtu(tmp_path / "helper.vtu")
    done = helper.finish()
    assert done["used"] and done["jobs"] == 2 and not running.pending
    helper.stop()
    draw(tmp_path / "here.png")
    vtu(tmp_path / "here.vtu")
    for ext in ("png", "vtu"):
        assert (tmp_path / f"helper.{ext}").read_bytes() == (tmp_path / f"here.{ext}").read_bytes()


def test_a_dead_helper_leaves_the_work_to_the_process(tmp_path, running):
    running.proc.kill()
    running.proc.wait()
    draw(tmp_path / "a.png")
    vtu(tmp_path / "a.vtu")
    done = helper.finish()
    assert (tmp_path / "a.png").stat().st_size > 1000 and not done["used"]
    assert (tmp_path / "a.vtu").read_text().startswith("<?xml")


def test_an_abandoned_helper_ends_at_once_and_later_work_is_done_here(tmp_path, running):
    """helper.abandon (a rank's private outputs about to be removed): the helper is
    ended without doing what it still has; later jobs are done in the process."""
    draw(tmp_path / "dropped.png")
    helper.abandon()
    assert running.proc.poll() is not None and helper._HELPER is None
    vtu(tmp_path / "here.vtu")
    assert (tmp_path / "here.vtu").read_text().startswith("<?xml")
    helper.abandon()  # none left: nothing to do


def test_a_job_the_helper_cannot_do_raises_here(tmp_path, running):
    draw(tmp_path / "bad.png", y=X[:-1])  # x and y of different lengths
    with pytest.raises(ValueError, match="same first dimension"):
        helper.finish()
    assert not (tmp_path / "bad.png").exists()


def test_large_arrays_stay_in_the_process(tmp_path, running, monkeypatch):
    monkeypatch.setattr(helper, "MAX_JOB_BYTES", 100)
    vtu(tmp_path / "big.vtu")
    assert (tmp_path / "big.vtu").exists() and running.jobs == 0


def test_the_command_uses_the_helper(tmp_path):
    out = tmp_path / "h"
    r = subprocess.run([sys.executable, "-m", "signorini.app.cli", "hertz", "--no-fd", "-q",
                        "--out", str(out)], capture_output=True, text=True, timeout=600,
                       env={**os.environ})
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["timings"]["output_helper"]["used"] is True
    assert s["timings"]["output_helper"]["jobs"] == 3  # two figures and the VTU
    for f in ("pressure.png", "sensitivity.png"):
        assert (out / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "displacement" in (out / "hertz.vtu").read_text()
    assert not list(out.glob(".*partial*"))


def test_discarded_outputs_are_neither_computed_nor_written(tmp_path, running, monkeypatch):
    # a rank other than 0 under mpiexec: no figure, no VTU file, no VTU fields computed
    import signorini as sg
    from signorini.post import files

    m = sg.rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    pb = sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0},
                    fixed=(sg.Fixed("bottom", 1), sg.Fixed("left", 0)),
                    loads=(sg.Pressure("top", "q"),))
    sol = sg.solve(pb, steps=2)
    computed = []
    fields = files._fields
    monkeypatch.setattr(files, "_fields", lambda *a: computed.append(a) or fields(*a))
    helper.discard(True)
    try:
        assert helper._HELPER is None  # its helper ended
        assert draw(tmp_path / "a.png") == tmp_path / "a.png"
        vtu(tmp_path / "a.vtu")
        assert files.write_vtu(sol, tmp_path / "s.vtu") == tmp_path / "s.vtu"
        (tmp_path / "series").mkdir()
        files.write_pvd(sol, tmp_path / "series" / "run.pvd")
        helper.finish()
        assert computed == []
        assert not (tmp_path / "a.png").exists() and not (tmp_path / "a.vtu").exists()
        assert not (tmp_path / "s.vtu").exists() and not list((tmp_path / "series").glob("*.vtu"))
    finally:
        helper.discard(False)
    # and restored: written again
    files.write_vtu(sol, tmp_path / "s.vtu")
    draw(tmp_path / "a.png")
    helper.finish()
    assert len(computed) == 1 and (tmp_path / "s.vtu").exists() and (tmp_path / "a.png").exists()
