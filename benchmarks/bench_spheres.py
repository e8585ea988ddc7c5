"""Two elastic spheres in 3-D (``signorini spheres``, a 3-D mortar pair) against
Hertz and Cattaneo–Mindlin, and the cost of a frictional two-body increment
against the rigid sphere's (``signorini hertz3d --set mu=0.3``) of about the same size.

Each case is the whole command in a fresh process (what a user waits for,
compilation included, the program cache emptied first, or with ``--cache DIR`` the
cache kept in DIR, so that a case run twice measures an empty then a filled cache): wall time, peak
resident memory, DOFs, Newton iterations, Newton's assembly / factorisation /
solve seconds, the compile seconds, and the comparison with the theory (p0, a
in cells, c/a). Prints a table and writes benchmarks/results/spheres.csv.

    python benchmarks/bench_spheres.py [--cases frictionless,mindlin-0.5,rigid] [--csv FILE]
                                       [--cache DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _report import report

HERE = Path(__file__).parent
MU, P = 0.3, 0.1
#: case -> the command's arguments
CASES = {
    "frictionless": ["spheres"],
    "mindlin-0.25": ["spheres", "--set", f"mu={MU}", "--set", f"Q={0.25 * MU * P}", "--no-fd"],
    "mindlin-0.5": ["spheres", "--set", f"mu={MU}", "--set", f"Q={0.5 * MU * P}", "--no-fd"],
    "mindlin-0.75": ["spheres", "--set", f"mu={MU}", "--set", f"Q={0.75 * MU * P}", "--no-fd"],
    "mindlin-0.5-fine": ["spheres", "--set", f"mu={MU}", "--set", f"Q={0.5 * MU * P}", "--no-fd",
                         "--n-fine", "12"],
    # the rigid sphere with friction, 10 increments, of about the two-body half model's size
    "rigid": ["hertz3d", "--set", f"mu={MU}", "--steps", "10", "--n-fine", "10", "--no-fd"],
    # the same pair at about 100k unknowns: 107,244 (two bodies) and 112,752 (rigid)
    "mindlin-0.5-100k": ["spheres", "--set", f"mu={MU}", "--set", f"Q={0.5 * MU * P}", "--no-fd",
                         "--n-fine", "15"],
    "rigid-100k": ["hertz3d", "--set", f"mu={MU}", "--steps", "10", "--n-fine", "21", "--no-fd"],
}
# the frictional path at 264,852 unknowns with the iterative solver and three sensitivities
# (issue 50's target: <= 10 min, <= 16 GB), at the three Cattaneo-Mindlin ratios
for _r in (0.25, 0.5, 0.75):
    CASES[f"mindlin-{_r}-265k-amg"] = [
        "spheres", "--set", f"mu={MU}", "--set", f"Q={_r * MU * P}", "--no-fd", "--n-fine", "23",
        "--solver", "amg", "--wrt", "R1", "E1", "mu"]


def one(case: str, kept_cache: str | None = None) -> dict:
    with tempfile.TemporaryDirectory() as out, tempfile.TemporaryDirectory() as empty:
        cache = kept_cache or empty
        env = {**os.environ, "SIGNORINI_CACHE_DIR": cache}
        cmd = ["/usr/bin/time", "-f", "%M", sys.executable, "-m", "signorini.app.cli",
               *CASES[case], "--out", out]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"{case}: exit {r.returncode}\n{r.stderr[-2000:]}")
        rss_gb = int(r.stderr.strip().splitlines()[-1]) / 1e6
        s = json.loads((Path(out) / "summary.json").read_text())
    nt = s["newton_time_s"]
    row = {"case": case, "dofs": s["mesh"]["dofs"], "steps": s["steps"],
           "newton_its": sum(s["newton_iterations"]), "wall_s": round(wall, 1),
           "compile_s": round(s["timings"]["compile_s"], 1),
           "programs_loaded": s["timings"]["compile"]["programs_loaded"],
           "output_s": round(s["timings"]["output_s"], 1), "solve_s": round(s["time_solve_s"], 1),
           "assembly_s": round(nt["assembly"], 1), "factorization_s": round(nt["factorization"], 1),
           "newton_solve_s": round(nt["solve"], 1),
           "per_increment_s": round(s["time_solve_s"] / s["steps"], 2),
           "peak_rss_gb": round(rss_gb, 2),
           "p0_rel_error": round(s["p0"]["rel_error"], 4)}
    a = s["a"]
    row["a_error_cells"] = round(a.get("error_in_cells", float("nan")), 2)
    ca = s.get("c_over_a")
    row["c_over_a"] = round(ca["computed"], 4) if isinstance(ca, dict) else ""
    row["c_over_a_theory"] = round(ca["analytical"], 4) if isinstance(ca, dict) else ""
    fd = s.get("ddm_vs_fd_rel_diff")
    row["ddm_vs_fd_max"] = f"{max(fd.values()):.1e}" if isinstance(fd, dict) and fd else ""
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--csv", default=str(HERE / "results" / "spheres.csv"),
                    help="the CSV to write (a subset of the cases: a file of its own)")
    ap.add_argument("--cache", help="keep the program cache in this directory (default: an "
                    "empty one per case)")
    args = ap.parse_args()
    rows = []
    for case in args.cases.split(","):
        rows.append(one(case, args.cache))
        print(rows[-1], flush=True)
    report(rows, args.csv)


if __name__ == "__main__":
    main()
