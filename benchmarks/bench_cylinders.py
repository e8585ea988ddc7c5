"""Two-body frictional contact (the two cylinders, mortar pair) against the
rigid-obstacle frictional Hertz of about the same size: the cost of an increment.

Each case in a fresh process: a first (compiling) solve with sensitivities,
then the timed warm solves of the same problem (10 increments, mu = 0.3; the cylinders with
Q = mu P / 2 after P), without sensitivities and with DDM sensitivities to
R1 and mu (R and mu for the rigid one). Reports DOFs, Newton iterations, the
warm solve time per increment and per Newton iteration, the DDM time, the
peak resident memory, and the ratio of the two-body to the rigid increment.
Prints a table and writes benchmarks/results/cylinders.csv.

    python benchmarks/bench_cylinders.py [--sizes 10k,60k]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

from _report import report

#: size -> (cylinders n_fine, rigid Hertz (refine, n_fine)), about the same DOFs
MESHES = {"10k": (24, (0, 36)), "60k": (88, (2, 18))}
STEPS = 10
HERE = Path(__file__).parent


def one(kind: str, size: str) -> dict:
    import signorini as sg
    if kind == "two-body":
        from signorini.problems.cylinders import cylinders_problem
        pb = cylinders_problem({"mu": 0.3, "Q": 0.015}, n_fine=MESHES[size][0])
        names = ["R1", "mu"]
    else:
        from signorini.problems.hertz_friction import hertz_friction_problem
        r, n = MESHES[size][1]
        pb = hertz_friction_problem(refine=r, n_fine=n, force_size=True)
        names = ["R", "mu"]
    sg.solve(pb, steps=STEPS, wrt=names)  # compiles (the DDM's programs too)
    t0 = time.perf_counter()
    sol = sg.solve(pb, steps=STEPS)
    t_solve = time.perf_counter() - t0
    t0 = time.perf_counter()
    sg.solve(pb, steps=STEPS, wrt=names)
    t_sens = time.perf_counter() - t0
    its = sum(sol.newton_iterations)
    return {"case": kind, "size": size, "dofs": int(sol.model.n_dof), "increments": STEPS,
            "newton_iterations": its, "solve_s": round(t_solve, 3),
            "per_increment_s": round(t_solve / STEPS, 4), "per_iteration_s": round(t_solve / its, 4),
            "ddm_s": round(t_sens - t_solve, 3),
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10k,60k")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(one(*a.one)))
        return
    rows = []
    for size in a.sizes.split(","):
        pair = {}
        for kind in ("rigid", "two-body"):
            out = subprocess.run([sys.executable, __file__, "--one", kind, size], capture_output=True,
                                 text=True, check=True).stdout.strip().splitlines()[-1]
            pair[kind] = json.loads(out)
            rows.append(pair[kind])
            print(pair[kind], flush=True)
        r = pair["two-body"]["per_increment_s"] / pair["rigid"]["per_increment_s"]
        it = pair["two-body"]["per_iteration_s"] / pair["rigid"]["per_iteration_s"]
        for kind in pair:
            pair[kind]["two_body_over_rigid_per_increment"] = round(r, 2)
            pair[kind]["two_body_over_rigid_per_iteration"] = round(it, 2)
    report(rows, HERE / "results" / "cylinders.csv")


if __name__ == "__main__":
    main()
