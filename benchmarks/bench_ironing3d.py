"""Ironing in 3-D (``signorini ironing3d``, a 3-D mortar pair with finite
sliding and friction) at two or three mesh sizes.

Each case is the whole command in a fresh process (what a user waits for,
compilation included; ``--cold``: the program cache emptied first, else the
user's cache, as a second run finds it): wall time, peak resident memory,
DOFs, slave nodes, increments, Newton iterations, the compile and solve
seconds, F_T/F_N at the end and over the slide, and the largest difference
between the DDM of the die force and the command's central differences of the
whole path (its default --fd-names). Prints a table and writes
benchmarks/results/ironing3d.csv.

    python benchmarks/bench_ironing3d.py [--cells 24,32] [--cold] [--no-fd]
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


def one(cells: int, cold: bool, fd: bool) -> dict:
    with tempfile.TemporaryDirectory() as out, tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, **({"SIGNORINI_CACHE_DIR": cache} if cold else {})}
        cmd = ["/usr/bin/time", "-f", "%M", sys.executable, "-m", "signorini.app.cli", "ironing3d",
               "--cells", str(cells), "--out", out, "-q"] + ([] if fd else ["--no-fd"])
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"cells {cells}: exit {r.returncode}\n{r.stderr[-2000:]}")
        rss_gb = int(r.stderr.strip().splitlines()[-1]) / 1e6
        s = json.loads((Path(out) / "summary.json").read_text())
    f = s["force_final"]
    fd_diff = s.get("ddm_vs_fd_rel_diff")
    return {"cells": cells, "dofs": s["mesh"]["dofs"], "slave_nodes": s["mesh"]["slave_nodes"],
            "steps": s["steps"], "newton_its": sum(s["newton_iterations"]),
            "wall_s": round(wall, 1), "compile_s": round(s["timings"]["compile_s"], 1),
            "solve_s": round(s["time_solve_s"], 1),
            "per_iteration_s": round(s["time_solve_s"] / sum(s["newton_iterations"]), 2),
            "peak_rss_gb": round(rss_gb, 2),
            "F_N": round(f["F_N"], 5), "F_T": round(f["F_T"], 5),
            "F_T/F_N_end": round(f["F_T"] / f["F_N"], 4),
            "F_T/F_N_slide": round(s["force_ratio_sliding"]["mean"], 4),
            "fd_names": ",".join(fd_diff) if isinstance(fd_diff, dict) else "",
            "ddm_vs_fd_max": f"{max(fd_diff.values()):.1e}" if isinstance(fd_diff, dict) else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", default="24,32")
    ap.add_argument("--cold", action="store_true", help="empty program cache in every case")
    ap.add_argument("--no-fd", action="store_true", help="skip the commands' FD checks")
    args = ap.parse_args()
    rows = []
    for c in args.cells.split(","):
        rows.append(one(int(c), args.cold, not args.no_fd))
        print(rows[-1], flush=True)
    report(rows, HERE / "results" / "ironing3d.csv")


if __name__ == "__main__":
    main()
