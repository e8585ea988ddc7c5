"""``signorini forging3d`` under refinement, as a user runs it: whole process.

Each row a fresh ``signorini forging3d --mesh NxN`` process (spawn to exit, peak
resident memory of the child from ``wait4``; the cache of compiled programs
filled by the rows before), 20 increments, ``--no-fd`` except where
``--fd`` names the mesh: DOFs, Newton iterations, wall time and its parts
(compile, solve, sensitivities: the DDM of five parameters after every
increment), F and its five DDM derivatives, the volume ratio against the
elastic estimate, the largest plastic strain.

Writes ``results/forging3d.csv`` (or ``--out-dir``) and prints the table. Usage::

    python3 benchmarks/bench_forging3d.py [--meshes 4 6 8 10] [--fd 4]
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import report  # noqa: E402


def run(args: list[str], out: Path) -> dict:
    cmd = [sys.executable, "-m", "signorini.app.cli", "forging3d", "--out", str(out), "-q"] + args
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr.read().decode()}")
    return {"wall_s": wall, "peak_MB": usage.ru_maxrss / 1024,
            "summary": json.loads((out / "summary.json").read_text())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=int, nargs="*", default=[4, 6, 8, 10])
    ap.add_argument("--fd", type=int, nargs="*", default=[4],
                    help="meshes whose run also checks the DDM by central differences")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.meshes:
            args = ["--mesh", f"{n}x{n}"] + ([] if n in a.fd else ["--no-fd"])
            r = run(args, Path(tmp) / f"m{n}")
            s, t = r["summary"], r["summary"].get("timings", {})
            rel = s["ddm_vs_fd_rel_diff"]
            rows.append({
                "mesh": f"{n}x{n}", "dofs": s["mesh"]["dofs"], "newton_its": sum(s["newton_iterations"]),
                "wall_s": round(r["wall_s"], 1), "peak_MB": round(r["peak_MB"]),
                "compile_s": round(t.get("compile_s", 0.0), 1), "solve_s": round(t.get("solve_s", 0.0), 1),
                "sensitivities_s": round(t.get("sensitivities_s", 0.0), 1),
                "F": f"{s['F']:.6g}", **{f"dF_d{k}": f"{v:.5e}" for k, v in s["dF_ddm"].items()},
                "max_ddm_vs_fd": f"{max(rel.values()):.1e}" if isinstance(rel, dict) else "",
                "volume_ratio": f"{s['volume']['ratio']:.5f}",
                "elastic_estimate": f"{s['volume']['elastic_estimate']:.5f}",
                "max_plastic_strain": f"{s['max_equivalent_plastic_strain']:.3f}"})
    print("forging3d, 20 increments (whole process)")
    report(rows, a.out_dir / "forging3d.csv")


if __name__ == "__main__":
    main()
