"""The size guard as a user meets it: how long each command takes to refuse an
absurd size, and how much memory it uses while refusing.

Each command of ``signorini`` that builds a mesh is run once per row as a fresh
process (``subprocess``), with options that ask for a mesh far beyond the
machine, timed from before the spawn to the return of ``wait4`` (Python start-up
and imports included: the whole wait), its peak resident memory from
``wait4``'s ``ru_maxrss``. Every row must end with exit code 2 and the refusal's
message (the estimate, what is available, the largest size that fits)::

    python3 benchmarks/bench_guards.py [--out benchmarks/results/guards.csv]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _report import report

HUGE_TOML = """[params]
E = 100.0
[mesh]
type = "rectangle"
x = [0.0, 1.0]
y = [0.0, 1.0]
nx = 100000
ny = 100000
[material]
type = "linear_elastic"
E = "E"
nu = 0.3
"""

#: command -> the options of an absurd size ({toml}: a problem file of 10^10 cells)
ROWS = {
    "hertz": ["--refine", "9"],
    "hertz-friction": ["--refine", "9"],
    "hertz3d": ["--n-fine", "400"],
    "hertz3d --axisymmetric": ["--axisymmetric", "--refine", "12"],
    "forging": ["--mesh", "3000x6000"],
    "forging3d": ["--mesh", "300x600"],
    "cylinders": ["--refine", "6"],
    "ironing": ["--refine", "3"],
    "optimize-forging": ["--mesh", "3000x6000"],
    "run": ["{toml}"],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "guards.csv"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        toml = Path(tmp) / "huge.toml"
        toml.write_text(HUGE_TOML)
        for label, opts in ROWS.items():
            name = label.split()[0]
            cmd = [sys.executable, "-m", "signorini.app.cli", name,
                   *[o.format(toml=toml) for o in opts], "--out", str(Path(tmp) / "o"), "-q"]
            t0 = time.perf_counter()
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 cwd=tmp)
            _, status, usage = os.wait4(p.pid, 0)
            wall = time.perf_counter() - t0
            err = p.stderr.read()
            p.stderr.close()
            p.stdout.close()
            need = re.search(r"([\d,]+) unknowns and needs an estimated ([\d.e+]+) GB", err)
            most = re.search(r"the largest that fits is about ([\d,]+) unknowns", err)
            rows.append({"command": f"signorini {label.split()[0]} {' '.join(opts)}".replace(
                             "{toml}", "huge.toml"),
                         "exit_code": os.waitstatus_to_exitcode(status),
                         "unknowns": need.group(1) if need else "",
                         "estimate_GB": need.group(2) if need else "",
                         "largest_fitting": most.group(1) if most else "",
                         "wall_s": round(wall, 2),
                         "peak_rss_MB": round(usage.ru_maxrss / 1024, 1)})
    report(rows, args.out, width=14)


if __name__ == "__main__":
    main()
