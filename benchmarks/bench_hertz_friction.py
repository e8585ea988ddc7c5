"""Frictional Hertz (paper 5.2) at ~5k and ~50k DOFs with 20 load increments.

Reports total Newton iterations, wall time of the solve without and with DDM
sensitivities for 3 parameters (R, mu, E), and the DDM part alone (shared
factorisation of the converged tangent + pseudo-loads + back-substitutions,
summed over increments). Prints a table and writes
benchmarks/results/hertz_friction.csv.

    python benchmarks/bench_hertz_friction.py [--sizes small,medium] [--steps 20]
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

from _report import report

import signorini as sg
from signorini.problems.hertz_friction import hertz_friction_problem

MESHES = {"small": dict(n_fine=32, refine=0), "medium": dict(n_fine=24, refine=2)}
NAMES = ["R", "mu", "E"]


def run(size: str, steps: int, solver: str) -> dict:
    pb = hertz_friction_problem(**MESHES[size])
    sg.solve(pb, steps=3, sensitivities=NAMES, solver=solver)  # compile (not timed)
    t0 = time.perf_counter()
    sol = sg.solve(pb, steps=steps, solver=solver)
    t_plain = time.perf_counter() - t0
    t0 = time.perf_counter()
    sol_s = sg.solve(pb, steps=steps, sensitivities=NAMES, solver=solver)
    t_sens = time.perf_counter() - t0
    ddm = sum(inc.timing["factorization"] + inc.timing["pseudo_load"] + inc.timing["back_substitution"] for inc in sol_s.increments)
    per_param = sum(inc.timing["pseudo_load"] + inc.timing["back_substitution"]
                    for inc in sol_s.increments) / len(NAMES)
    return {
        "mesh": size, "dofs": sol.model.n_dof, "increments": len(sol.increments),
        "newton_iterations_total": sum(sol.newton_iterations),
        "max_iterations_per_increment": max(sol.newton_iterations),
        "solve_s": t_plain, "solve_with_3_sensitivities_s": t_sens,
        "ddm_total_s": ddm, "ddm_per_parameter_s": per_param,
        "ddm_per_parameter_over_solve": per_param / t_plain,
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="small,medium")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--solver", default="superlu")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "hertz_friction.csv"))
    args = ap.parse_args()
    rows = []
    for size in args.sizes.split(","):
        rows.append(run(size, args.steps, args.solver))
        print(f"{size}: {rows[-1]['dofs']} DOFs done", flush=True)
    report(rows, args.out)


if __name__ == "__main__":
    main()
