"""One solve over MPI ranks against the serial iterative solver: whole processes.

Each row is one fresh process tree (``mpiexec -n N signorini ...`` or the plain
command), timed from spawn to exit; peak resident memory from ``wait4`` on the
launcher, which is the largest rank's (a rank is a child the launcher waits
for). Columns: wall time, peak memory of the largest process, Newton and Krylov
iterations (from ``summary.json``), the sensitivities' share, and the
communication the replicated design costs per Krylov iteration (the gathered
vector of every cycle: unknowns x 8 bytes x (N - 1) / N received per rank).

Cases (``--cases``), the ``hertz3d`` problem with the sensitivities to R and E:

* ``amg``: the serial iterative solver (``--solver amg``);
* ``petsc-amg-1``, ``petsc-amg-2``: ``--solver petsc-amg`` on 1 and 2 ranks;
* ``petsc-1``, ``petsc-2``: ``--solver petsc`` (MUMPS) on 1 and 2 ranks (at the
  size ``--direct-n-fine``; MUMPS's fill at 290k DOFs would not fit twice).

Writes ``results/mpi.csv`` (or ``--csv``) and prints the table::

    python3 benchmarks/bench_mpi.py --n-fine 12 --refine 1
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

CASES = {
    "amg": ("amg", None),
    "petsc-amg-1": ("petsc-amg", 1),
    "petsc-amg-2": ("petsc-amg", 2),
    "petsc-1": ("petsc", 1),
    "petsc-2": ("petsc", 2),
}


def launcher(n: int) -> list[str]:
    out = subprocess.run(["mpiexec", "--version"], check=False, capture_output=True,
                         text=True).stdout
    extra = ["--oversubscribe"] if ("Open MPI" in out or "OpenRTE" in out) else []
    return ["mpiexec", "-n", str(n), *extra]


def run(case: str, size: list[str], wrt: list[str], out: Path) -> dict:
    solver, ranks = CASES[case]
    signorini = shutil.which("signorini") or "signorini"
    cmd = [signorini, "hertz3d", *size, "--no-fd", "--solver", solver, "--out", str(out), "-q"]
    if wrt:
        cmd += ["--wrt", *wrt]
    if ranks is not None:
        cmd = launcher(ranks) + cmd
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    if ranks and ranks > 1:  # the ranks share the cores: one thread each
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    if status != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err[-3000:]}")
    s = json.loads((out / "summary.json").read_text())
    krylov = s.get("krylov_iterations") or []
    n = int(s.get("mesh", {}).get("dofs") or 0)
    times = s.get("timings", {})
    nr = ranks or 1
    return {"case": case, "ranks": nr, "dofs": n, "wall_s": round(wall, 2),
            "peak_mb_per_rank": round(usage.ru_maxrss / 1024),
            "newton_iterations": sum(s.get("newton_iterations", [])),
            "krylov_iterations": sum(krylov), "solves": len(krylov),
            "solve_s": round(times.get("solve_s", 0), 1),
            "sensitivities_s": round(times.get("sensitivities_s", 0), 1),
            "gathered_mb_per_iteration": round(n * 8 * (nr - 1) / nr / 1e6, 2) if n else None,
            "p0": s.get("p0", {}).get("computed")}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-fine", default="12")
    ap.add_argument("--refine", default="1")
    ap.add_argument("--direct-n-fine", default="12", help="--n-fine of the MUMPS rows (no --refine)")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--wrt", nargs="*", default=["R", "E"])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--csv", type=Path, default=HERE / "results" / "mpi.csv")
    a = ap.parse_args(argv)
    rows = []
    for _ in range(a.repeat):
        for case in a.cases:
            size = (["--n-fine", a.direct_n_fine] if case.startswith("petsc-") and
                    not case.startswith("petsc-amg") else ["--n-fine", a.n_fine, "--refine", a.refine])
            with tempfile.TemporaryDirectory() as tmp:
                row = run(case, size, a.wrt, Path(tmp) / "out")
            row["size"] = " ".join(size)
            rows.append(row)
            print(row, flush=True)
    a.csv.parent.mkdir(parents=True, exist_ok=True)
    with a.csv.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    cols = list(rows[0])
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(str(r[c]) for c in cols) + " |")


if __name__ == "__main__":
    main()
