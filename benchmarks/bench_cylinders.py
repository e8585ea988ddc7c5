"""Two-body frictional contact (the two cylinders, mortar pair) against the
rigid-obstacle frictional Hertz of about the same size: the cost of an increment.

Each case in a fresh process: a first (compiling) solve with sensitivities,
then the timed warm solves of the same problem (mu = 0.3; the cylinders with
Q = mu P / 2 after P), without sensitivities and with DDM sensitivities to
R1 and mu (R and mu for the rigid one). The rigid Hertz takes P in 10
increments. The cylinders run twice: in 10 increments (P in 5, then Q in 5:
each P increment twice the rigid one's load step) and in 20 (P in 10
increments as the rigid one, then Q in 10): like with like is the P phase of
the 20-increment path. Both also run started from coarser meshes solved along
the same path (``*-guided``: solve_coarse_to_fine, the levels of
signorini.problems.hertz.coarse_levels; the time includes the coarse levels),
each compared with the rigid one started the same way. Reports DOFs, Newton iterations (all, and in the P
phase), the warm solve time per increment (all, and in the P phase: Newton's
assembly, factorisation and solve times) and per Newton iteration, the DDM
time, the peak resident memory, and the ratios of the two-body to the rigid
increment. Prints a table and writes benchmarks/results/cylinders.csv.

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
    from signorini.algorithms.coarse_to_fine import solve_coarse_to_fine
    from signorini.problems.hertz import coarse_levels

    steps, p_phase = STEPS, STEPS
    guided = kind.endswith("guided")
    if kind.startswith("two-body"):
        from signorini.problems.cylinders import cylinders_problem

        def build(refine, n_fine, force=False):
            return cylinders_problem({"mu": 0.3, "Q": 0.015}, refine=refine, n_fine=n_fine)
        r, n = 0, MESHES[size][0]
        names = ["R1", "mu"]
        steps = int(kind.split("-")[2])
        p_phase = steps // 2
    else:
        from signorini.problems.hertz_friction import hertz_friction_problem

        def build(refine, n_fine, force=False):
            return hertz_friction_problem(refine=refine, n_fine=n_fine, force_size=force)
        r, n = MESHES[size][1]
        names = ["R", "mu"]
    pb = build(r, n, True)
    coarse = [build(*lv) for lv in coarse_levels(r, n)] if guided else []

    def path(wrt=()):
        if not coarse:
            return sg.solve(pb, steps=steps, wrt=wrt), []
        return solve_coarse_to_fine(coarse + [pb], steps=steps, wrt=wrt)
    path(names)  # compiles (the DDM's programs too)
    t0 = time.perf_counter()
    sol, levels = path()
    t_solve = time.perf_counter() - t0
    t0 = time.perf_counter()
    path(names)
    t_sens = time.perf_counter() - t0
    its = sum(sol.newton_iterations)
    logs = [inc.newton for inc in sol.increments]
    newton_s = [g.time_assembly + g.time_factorization + g.time_solve for g in logs]
    return {"case": kind, "size": size, "dofs": int(sol.model.n_dof), "increments": steps,
            "newton_iterations": its, "p_phase_increments": p_phase,
            "p_phase_iterations": sum(sol.newton_iterations[:p_phase]),
            "solve_s": round(t_solve, 3),
            "per_increment_s": round(t_solve / steps, 4),
            "p_phase_newton_per_increment_s": round(sum(newton_s[:p_phase]) / p_phase, 4),
            "per_iteration_s": round(t_solve / its, 4),
            "ddm_s": round(t_sens - t_solve, 3),
            "coarse_levels": " ".join(f"{lv['dofs']}:{sum(lv['newton_iterations'])}it:"
                                      f"{lv['time_s']:.2f}s" for lv in levels[:-1]),
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
        for kind in ("rigid", "two-body-10", "two-body-20", "rigid-guided", "two-body-20-guided"):
            out = subprocess.run([sys.executable, __file__, "--one", kind, size], capture_output=True,
                                 text=True, check=True).stdout.strip().splitlines()[-1]
            pair[kind] = json.loads(out)
            rows.append(pair[kind])
            print(pair[kind], flush=True)
        for kind, row in pair.items():
            rigid = pair["rigid-guided" if kind.endswith("guided") else "rigid"]
            row["over_rigid_per_increment"] = round(row["per_increment_s"] / rigid["per_increment_s"], 2)
            row["over_rigid_p_phase_per_increment"] = round(
                row["p_phase_newton_per_increment_s"] / rigid["p_phase_newton_per_increment_s"], 2)
            row["over_rigid_per_iteration"] = round(row["per_iteration_s"] / rigid["per_iteration_s"], 2)
    report(rows, HERE / "results" / "cylinders.csv")


if __name__ == "__main__":
    main()
