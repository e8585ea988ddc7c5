"""The time split of a run (signorini.timing) and its place in summary.json."""

import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from signorini import timing
from signorini.app.cli import main

ROOT = Path(__file__).resolve().parents[2]

PARTS = ("imports_s", "compile_s", "solve_s", "sensitivities_s", "output_s", "other_s")


def _sum(split):
    return sum(split.get(k, 0.0) for k in PARTS)


def test_parts_are_disjoint_and_add_up_to_the_total():
    t = timing.Timings()
    t.mark("solve")
    time.sleep(0.05)
    with t.phase("sensitivities"):  # nested in the solve: booked here, not there
        time.sleep(0.04)
        # a program JAX has never seen (a fresh closure): traced and compiled here
        scale = float(np.random.default_rng().uniform(1, 2))
        jax.jit(lambda x: jnp.sin(scale * x) ** 2)(jnp.ones(5)).block_until_ready()
    t.mark("output")
    time.sleep(0.03)
    t.mark(None)
    time.sleep(0.02)
    s = t.split()
    assert _sum(s) == pytest.approx(s["total_s"], rel=1e-9, abs=1e-9)
    assert s["compile"]["programs"] >= 1 and s["compile_s"] > 0
    assert s["compile"]["trace_s"] > 0 and s["compile"]["xla_s"] > 0
    assert s["compile_s"] <= sum(v for k, v in s["compile"].items() if k.endswith("_s")) + 1e-9
    assert 0.05 <= s["solve_s"] < 0.05 + 0.04  # the nested phase is not in it
    assert 0.04 <= s["sensitivities_s"] + s["compile_s"]
    assert s["sensitivities_s"] >= 0.04 - 1e-3
    assert 0.03 <= s["output_s"] < 0.03 + 0.02
    assert s["other_s"] >= 0.02
    assert "imports_s" not in s


def test_imports_count_from_the_process_start():
    start = timing.process_start()
    assert start is not None and 0 < time.time() - start < 3600  # this process is alive
    t = timing.Timings(imports_from=start)
    s = t.split()
    assert s["imports_s"] == pytest.approx(t.start - start)
    assert _sum(s) == pytest.approx(s["total_s"])


def test_a_run_within_a_run_books_into_the_outer_one():
    with timing.recording() as outer:
        with timing.recording() as inner:
            assert inner is outer and timing.current() is outer
        with timing.recording(fresh=True) as own:
            assert own is not outer and timing.current() is own
        assert timing.current() is outer
    assert timing.current() is None
    timing.mark("solve")  # without a current Timings: nothing to book, no error
    with timing.phase("solve"):
        pass


def test_cli_summary_has_the_split(tmp_path):
    assert main(["hertz", "--out", str(tmp_path), "-q", "--no-fd", "--no-coarse-start"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())["timings"]
    assert "imports_s" not in s  # main() called from Python: no process start to count from
    assert _sum(s) == pytest.approx(s["total_s"], rel=1e-9, abs=1e-9)
    assert s["solve_s"] > 0 and s["output_s"] > 0 and s["sensitivities_s"] > 0  # DDM per increment


def test_a_problem_files_summary_has_the_split(tmp_path):
    """`signorini run` records its own run (the same split as the commands')."""
    from signorini.app import problemfile as pf

    s = pf.run(ROOT / "examples" / "block.toml", tmp_path)["timings"]
    assert _sum(s) == pytest.approx(s["total_s"], rel=1e-9, abs=1e-9)
    assert s["solve_s"] > 0 and s["output_s"] > 0
