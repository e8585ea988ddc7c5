"""Cost of the pieces of a Hertz solve at ~5k, 50k and 200k DOFs.

Measures per mesh: kernel evaluation + sparse assembly, bare SuperLU
factorisation of the converged tangent, one Newton iteration (assembly +
factorisation + solve), the whole solve, the DDM cost per parameter
(pseudo-load JVP + back-substitution, the factorisation being shared) and the
Newton iteration count. Prints a table and writes benchmarks/results/hertz.csv.

    python benchmarks/bench_hertz.py [--sizes small,medium,large]
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path


from _report import report

import signorini as sg
from signorini.linsolve import get_solver
from signorini.problems import hertz
from signorini.solve import model_for

MESHES = {"small": dict(n_fine=32, refine=0), "medium": dict(n_fine=24, refine=2),
          "large": dict(n_fine=24, refine=3)}
NAMES = ["R", "E", "P"]


def best(f, n=3):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def run(size: str, solver: str) -> dict:
    pb = hertz.hertz_problem(**MESHES[size])
    sg.solve(pb, sensitivities=NAMES, solver=solver)  # compile (not timed)
    t0 = time.perf_counter()
    sg.solve(pb, solver=solver)
    t_solve = time.perf_counter() - t0
    t0 = time.perf_counter()
    sol_s = sg.solve(pb, sensitivities=NAMES, solver=solver)
    t_solve_s = time.perf_counter() - t0
    inc = sol_s.increments[-1]
    m = model_for(pb)
    from signorini.params import as_jax

    params = as_jax(pb.params)
    w = inc.w
    lin = get_solver(solver)
    t_kernel = best(lambda: m.local_tangents(w, params, 1.0))
    R, blocks = m.local_tangents(w, params, 1.0)
    t_scatter = best(lambda: m.pattern.assemble(blocks))
    K = m.pattern.assemble(blocks)
    t_fac = best(lambda: lin.factorize(K), n=2)
    fac = lin.factorize(K)
    rhs = -R[m.free]
    t_bs = best(lambda: fac.solve(rhs))
    t_iter = t_kernel + t_scatter + t_fac + t_bs
    per_param = (inc.timing["pseudo_load"] + inc.timing["back_substitution"]) / len(NAMES)
    return {
        "mesh": size, "dofs": m.n_dof, "nnz": K.nnz, "newton_iterations": inc.newton.iterations,
        "kernels_s": t_kernel, "scatter_s": t_scatter, "factorization_s": t_fac,
        "back_substitution_s": t_bs, "newton_iteration_s": t_iter,
        "iteration_over_factorization": t_iter / t_fac, "solve_s": t_solve,
        "solve_with_3_sensitivities_s": t_solve_s,
        "ddm_shared_factorization_s": inc.timing["factorization"],
        "ddm_per_parameter_s": per_param, "ddm_per_parameter_over_solve": per_param / t_solve,
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="small,medium,large")
    ap.add_argument("--solver", default="superlu")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "hertz.csv"))
    args = ap.parse_args()
    rows = []
    for size in args.sizes.split(","):
        r = run(size, args.solver)
        rows.append(r)
        print(f"{size}: {r['dofs']} DOFs done", flush=True)
    report(rows, args.out)


if __name__ == "__main__":
    main()
