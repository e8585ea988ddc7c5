"""``signorini hertz3d`` under refinement, as a user runs it: whole process.

Two tables, each row a fresh ``signorini hertz3d`` process (spawn to exit,
peak resident memory of the child from ``wait4``), cache of compiled programs
filled by the rows before it (the first row of a table pays the compilation):

* ``frictionless``: the 3-D quarter model at ``--n-fine`` 6, 8, 12, 16 and 19
  (89,298 DOFs: the size of the GetFEM comparison of docs/benchmarks.md; more
  with ``--sizes``), ``--no-fd``; columns: DOFs, Newton iterations,
  factorisations and Krylov iterations on a kept factor, wall
  time, peak memory, solve / sensitivity share, p0 against Hertz, and the RMS
  of Dp/DR - Hertz's over the nodes with r < 0.7 a, relative to |Dp/DR(0)|.
* ``solvers`` (``--solver-sizes``): the same frictionless runs with ``--solver
  pardiso`` and ``--solver amg`` (time, peak memory, Newton iterations).
* ``refined`` (``--refine-levels``): the default mesh refined ``--refine`` times
  (every cell halved, so the cells keep their shapes and the multigrid its
  iteration counts), with ``--refine-solvers`` (default pardiso and amg);
  a solver is skipped at the sizes beyond ``--pardiso-up-to`` DOFs' level;
  ``--friction-scale N_FINE REFINE`` adds one frictional run (mu = 0.3, 10
  increments) with the iterative solver.
* ``friction``: mu = 0.3, 10 increments, the 3-D model and ``--axisymmetric``
  at the same grid lines (``--n-fine`` 4, 8, 12): the differences between the
  two models along the x axis (p_N and the radial traction, off the axis,
  relative to the peak pressure; c/a), which must shrink under refinement.

Writes ``results/hertz3d_frictionless.csv`` and ``results/hertz3d_friction.csv``
(or ``--out-dir``) and prints both tables. Usage::

    python3 benchmarks/bench_hertz3d.py [--sizes 6 8 12 16] [--friction-sizes 4 8 12]
                                        [--solver-sizes 12 16 24]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import report  # noqa: E402

from signorini.problems.hertz3d import DEFAULTS, analytical, pressure_dR  # noqa: E402


def run(args: list[str], out: Path) -> dict:
    """One ``signorini hertz3d`` process: (wall s, peak RSS MB, summary, contact columns)."""
    cmd = [sys.executable, "-m", "signorini.app.cli", "hertz3d", "--out", str(out), "-q"] + args
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{err}")
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "contact.csv") as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    cols = {k: (v if k == "status" else v.astype(float)) for k, v in cols.items()}
    return {"wall_s": wall, "peak_MB": usage.ru_maxrss / 1024, "summary": summary, "contact": cols}


def frictionless(sizes, work: Path) -> list[dict]:
    an = analytical(DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])
    rows = []
    for n in sizes:
        r = run(["--n-fine", str(n), "--no-fd"], work / f"f{n}")
        s, c = r["summary"], r["contact"]
        inner = c["r"] < 0.7 * an["a"]
        exact = pressure_dR(c["r"][inner], DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])
        rms = np.sqrt(np.mean((c["dp_N_dR"][inner] - exact) ** 2)) / abs(an["p0"] * 2 / (3 * DEFAULTS["R"]))
        t = s.get("timings", {})
        rows.append({"n_fine": n, "dofs": s["mesh"]["dofs"], "newton_its": sum(s["newton_iterations"]),
                     # the tangents factorised (Newton's and the sensitivities'): the others
                     # were solved on a kept factorisation (docs/theory.md §10.8)
                     "factorizations": sum(s.get("factorizations", [])),
                     "kept_factor_krylov_its": sum(s.get("kept_factor_krylov_iterations", [])),
                     "wall_s": round(r["wall_s"], 2), "peak_MB": round(r["peak_MB"]),
                     "compile_s": round(t.get("compile_s", float("nan")), 2),
                     "solve_s": round(t.get("solve_s", float("nan")), 2),
                     "sensitivities_s": round(t.get("sensitivities_s", float("nan")), 2),
                     "p0_rel_error": f"{s['p0']['rel_error']:+.4f}",
                     "a_error_cells": f"{s['a']['error_in_cells']:+.2f}",
                     "dpdR_rms_rel": f"{rms:.4f}", "solver": s["solver"]})
    return rows


def solvers(sizes, work: Path) -> list[dict]:
    """The direct (PARDISO) and the iterative (AMG-GMRES) solver at the same sizes."""
    rows = []
    for n in sizes:
        for solver in ("pardiso", "amg"):
            r = run(["--n-fine", str(n), "--no-fd", "--solver", solver], work / f"s{n}{solver}")
            s, t = r["summary"], r["summary"].get("timings", {})
            rows.append({"n_fine": n, "solver": solver, "dofs": s["mesh"]["dofs"],
                         "newton_its": sum(s["newton_iterations"]), "wall_s": round(r["wall_s"], 1),
                         "peak_MB": round(r["peak_MB"]), "solve_s": round(t.get("solve_s", 0.0), 1),
                         "sensitivities_s": round(t.get("sensitivities_s", 0.0), 1),
                         "p0": f"{s['p0']['computed']:.8f}"})
    return rows


def refined(levels, solvers_, work: Path, pardiso_up_to: int, friction_scale=None,
            friction_wrt=None) -> list[dict]:
    """``--refine r`` of the default mesh with each solver; the frictional scale run
    (its sensitivities: ``friction_wrt``, else the command's four)."""
    runs = [(["--refine", str(r)], r, "frictionless", solver) for r in levels for solver in solvers_
            if not (solver == "pardiso" and r > pardiso_up_to)]
    if friction_scale:
        n, r = friction_scale
        wrt = ["--wrt", *friction_wrt] if friction_wrt else []
        runs.append((["--n-fine", str(n), "--refine", str(r), "--set", "mu=0.3", "--steps", "10",
                      *wrt], r, f"mu=0.3, 10 steps, n_fine {n}"
                     + (f", wrt {' '.join(friction_wrt)}" if friction_wrt else ""), "amg"))
    rows = []
    for args, r, case, solver in runs:
        res = run(args + ["--no-fd", "--solver", solver], work / f"r{r}{solver}{len(rows)}")
        s, t = res["summary"], res["summary"].get("timings", {})
        its = s.get("krylov_iterations", [])
        rows.append({"case": case, "refine": r, "solver": solver, "dofs": s["mesh"]["dofs"],
                     "newton_its": sum(s["newton_iterations"]), "wall_s": round(res["wall_s"], 1),
                     "peak_MB": round(res["peak_MB"]), "solve_s": round(t.get("solve_s", 0.0), 1),
                     "sensitivities_s": round(t.get("sensitivities_s", 0.0), 1),
                     "krylov_solves": len(its), "krylov_its": sum(its),
                     "krylov_max": max(its, default=0),
                     "p0": f"{s['p0']['computed']:.8f}"})
        print(rows[-1], flush=True)
    return rows


def friction(sizes, work: Path) -> list[dict]:
    rows = []
    for n in sizes:
        common = ["--n-fine", str(n), "--set", "mu=0.3", "--steps", "10", "--no-fd"]
        a = run(common, work / f"3d{n}")
        b = run(common + ["--axisymmetric"], work / f"axi{n}")
        ca, cb = a["contact"], b["contact"]
        line = np.abs(ca["y"]) < 1e-12
        ca = {k: v[line] for k, v in ca.items()}
        off = (ca["r"] > 0) & ((ca["p_N"] > 0) | (cb["p_N"] > 0))
        scale = ca["p_N"].max()
        rows.append({"n_fine": n, "dofs_3d": a["summary"]["mesh"]["dofs"],
                     "dofs_axi": b["summary"]["mesh"]["dofs"],
                     "wall_3d_s": round(a["wall_s"], 1), "wall_axi_s": round(b["wall_s"], 1),
                     "peak_3d_MB": round(a["peak_MB"]),
                     "max_dpN_rel": f"{np.max(np.abs(ca['p_N'] - cb['p_N'])[off]) / scale:.4f}",
                     "max_dpr_rel": f"{np.max(np.abs(ca['p_r'] - cb['p_r'])[off]) / scale:.4f}",
                     "c_over_a_3d": f"{a['summary']['c_over_a']:.3f}",
                     "c_over_a_axi": f"{b['summary']['c_over_a']:.3f}",
                     "p0_3d": f"{a['summary']['p0']['computed']:.4f}",
                     "p0_axi": f"{b['summary']['p0']['computed']:.4f}"})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[6, 8, 12, 16, 19])
    ap.add_argument("--friction-sizes", type=int, nargs="*", default=[4, 8, 12])
    ap.add_argument("--solver-sizes", type=int, nargs="*", default=[],
                    help="n_fine of a table of the direct against the iterative solver")
    ap.add_argument("--refine-levels", type=int, nargs="*", default=[],
                    help="--refine of the default mesh for a table of both solvers")
    ap.add_argument("--refine-solvers", nargs="*", default=["pardiso", "amg"])
    ap.add_argument("--pardiso-up-to", type=int, default=1,
                    help="the largest --refine PARDISO runs at (its factors outgrow the memory)")
    ap.add_argument("--friction-scale", type=int, nargs=2, metavar=("N_FINE", "REFINE"),
                    help="one frictional run (mu = 0.3, 10 increments) with the iterative solver")
    ap.add_argument("--friction-wrt", nargs="+", metavar="NAME",
                    help="the frictional scale run's sensitivities (default R E P mu)")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    a = ap.parse_args()
    a.out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if a.sizes:
            print("hertz3d, frictionless (whole process, --no-fd)")
            report(frictionless(a.sizes, work), a.out_dir / "hertz3d_frictionless.csv")
        if a.solver_sizes:
            print("hertz3d, frictionless: PARDISO against AMG-GMRES (whole process, --no-fd)")
            report(solvers(a.solver_sizes, work), a.out_dir / "hertz3d_solvers.csv")
        if a.refine_levels or a.friction_scale:
            print("hertz3d refined (whole process, --no-fd)")
            report(refined(a.refine_levels, a.refine_solvers, work, a.pardiso_up_to,
                           a.friction_scale, a.friction_wrt), a.out_dir / "hertz3d_refined.csv")
        if a.friction_sizes:
            print("hertz3d, mu = 0.3: the 3-D and the axisymmetric models")
            report(friction(a.friction_sizes, work), a.out_dir / "hertz3d_friction.csv")


if __name__ == "__main__":
    main()
