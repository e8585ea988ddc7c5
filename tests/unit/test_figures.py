"""Figures drawn by the helper process (signorini.post.plots): the same files as
drawn in the process, drawn in the process when the helper is gone or fails, and
the helper used by the ``signorini`` command."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from signorini.post import plots

X = np.linspace(0.0, 1.0, 50)


def draw(path, y=X ** 2):
    return plots.curves(path, [{"x": X, "y": y, "label": "a"},
                               {"x": X[::5], "y": X[::5], "label": "b", "style": "points"}],
                        xlabel="x", ylabel="y", title="t", xlim=(0, 1))


@pytest.fixture
def helper():
    assert plots.start_helper()
    yield plots._HELPER
    plots.stop_helper()


def test_the_helper_draws_the_same_file(tmp_path, helper):
    draw(tmp_path / "helper.png")
    done = plots.finish()
    assert done["helper"] and not helper.pending
    plots.stop_helper()
    draw(tmp_path / "here.png")
    assert (tmp_path / "helper.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_a_dead_helper_leaves_the_figures_to_the_process(tmp_path, helper):
    helper.proc.kill()
    helper.proc.wait()
    draw(tmp_path / "a.png")
    done = plots.finish()
    assert (tmp_path / "a.png").stat().st_size > 1000 and not done["helper"]


def test_a_figure_the_helper_cannot_draw_raises_here(tmp_path, helper):
    draw(tmp_path / "bad.png", y=X[:-1])  # x and y of different lengths
    with pytest.raises(ValueError, match="same first dimension"):
        plots.finish()
    assert not (tmp_path / "bad.png").exists()


def test_the_command_draws_with_the_helper(tmp_path):
    out = tmp_path / "h"
    r = subprocess.run([sys.executable, "-m", "signorini.app.cli", "hertz", "--no-fd", "-q",
                        "--out", str(out)], capture_output=True, text=True, timeout=600,
                       env={**os.environ})
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["timings"]["figures"]["helper"] is True
    for f in ("pressure.png", "sensitivity.png"):
        assert (out / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob(".*partial*"))
