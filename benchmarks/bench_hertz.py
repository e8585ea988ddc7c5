"""Cost of the one-step frictionless Hertz solve at ~5k, 56k, 225k and ~1M DOFs.

For every mesh and linear solver (``pardiso``: MKL PARDISO, what the README's
install gives on x86-64; ``superlu``: SciPy's fallback), in a fresh process
each (so that the peak memory is that run's):

* Newton iterations on the requested mesh, and those of the coarse meshes
  that start it (``signorini.multilevel``), with their cost in equivalent
  fine iterations (iterations x DOFs ratio);
* one Newton iteration (kernels + assembly + factorisation + solve, averaged
  over the iterations of the same solve started from the undeformed state)
  divided by one bare numeric factorisation of the converged tangent, and by
  that factorisation plus one checked back-substitution of one column (the
  least an iteration with a direct solver costs: what lies above it is the
  kernels, the assembly and the caches they find cold), and the kernel +
  assembly share of an iteration;
* the DDM per parameter (pseudo-load + back-substitution, the fastest of three
  solves with sensitivities) divided by the solve (the fastest of three), and
  with PARDISO how many of the DDM's solves of the finest mesh took the three
  columns one by one rather than as a block (whichever was timed faster), and
  the fastest recent PARDISO solve of one column and of three (they show the
  state of the machine, which decides the DDM's share);
* wall time of the solve (coarse levels included, compilation excluded),
  seconds per DOF, peak resident memory.

Also the cold start of ``signorini hertz --no-fd`` (imports + JIT + solve of the
default 3.6k-DOF mesh), with an empty and with a filled compilation cache.

Prints a table and writes benchmarks/results/hertz.csv (and hertz_cold_start.csv).

    python benchmarks/bench_hertz.py [--sizes 5k,56k,225k,1M] [--solvers pardiso,superlu]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _report import report, solves_by_column

#: (refine, n_fine) of each size (block 20 a0, fine zone 1.5 a0)
MESHES = {"5k": (0, 32), "56k": (2, 24), "225k": (3, 24), "1M": (4, 24)}
NAMES = ["R", "E", "P"]
HERE = Path(__file__).parent


def best(f, n=3):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def one(size: str, solver: str) -> dict:
    """Measure one (size, solver) in this process."""
    import signorini as sg
    from signorini.linsolve import get_solver
    from signorini.algorithms.coarse_to_fine import prolong, solve_coarse_to_fine
    from signorini.params import as_jax
    from signorini.problems import hertz
    from signorini.algorithms.stepping import model_for

    refine, n_fine = MESHES[size]
    opts = sg.NewtonOptions()  # rtol 1e-10 (the default, as before): 1e-11 is below the
    # round-off floor of the residual at 225k DOFs (1.9e-11, stagnation check)
    pb = hertz.hertz_problem(refine=refine, n_fine=n_fine, force_size=True)
    coarse = [hertz.hertz_problem(refine=r, n_fine=n) for r, n in hertz.coarse_levels(refine, n_fine)]
    lin = get_solver(solver)

    def run(sens):
        initial, levels = None, []
        if coarse:
            csol, levels = solve_coarse_to_fine(coarse, options=opts, solver=lin)
            initial = prolong(csol, pb)
        return sg.solve(pb, options=opts, solver=lin, wrt=sens, start=initial), levels

    run(NAMES)  # compile every level (not timed)
    # the fastest of three solves, with and without sensitivities (the DDM's own
    # times spread by up to 2.5x between identical solves on this machine)
    t_solve, t_solve_s, best_ddm = np.inf, np.inf, None
    for _ in range(3):
        t0 = time.perf_counter()
        sol, levels = run(())
        t_solve = min(t_solve, time.perf_counter() - t0)
        t0 = time.perf_counter()
        s, _ = run(NAMES)
        t_solve_s = min(t_solve_s, time.perf_counter() - t0)
        tm = s.increments[-1].timing
        if best_ddm is None or tm["pseudo_load"] + tm["back_substitution"] < best_ddm[0]:
            best_ddm = (tm["pseudo_load"] + tm["back_substitution"], s)
    sol_s = best_ddm[1]
    # the same solve from the undeformed state: its iteration count, and the cost of
    # one Newton iteration averaged over many (the last residual evaluation excluded)
    # (the fastest of three runs, against the fastest of five bare factorisations: both
    # spread by up to 25 % between runs on this machine)
    plain = min((sg.solve(pb, options=opts, solver=lin).increments[-1].newton for _ in range(3)),
                key=lambda lg: lg.time_assembly + lg.time_factorization + lg.time_solve)
    plain_its = plain.iterations
    inc = sol_s.increments[-1]
    m, p = model_for(pb), as_jax(pb.params)
    R, blocks = m.local_tangents(inc.w, p, 1.0)
    t_kernel = best(lambda: m.local_tangents(inc.w, p, 1.0))
    t_asm = best(lambda: m.pattern.assemble(blocks))
    K = m.pattern.assemble(blocks)
    sym = bool(sol_s.symmetric)
    lin.factorize(K, symmetric=sym)
    t_fac = best(lambda: lin.factorize(K, symmetric=sym), n=5)  # numeric only (analysis kept)
    # one checked back-substitution of one column (what a Newton iteration solves): with
    # the factorisation, the least a Newton iteration with a direct solver can cost
    fac = lin.factorize(K, symmetric=sym)
    rhs = -R[m.free]
    t_bsub = best(lambda: fac.solve(rhs), n=5)
    t_fac_fresh = best(lambda: get_solver(solver).factorize(K, symmetric=sym), n=1)
    its = sol.increments[-1].newton.iterations
    t_iter = (plain.time_assembly - t_kernel + plain.time_factorization + plain.time_solve) / plain_its
    per_param = (inc.timing["pseudo_load"] + inc.timing["back_substitution"]) / len(NAMES)
    coarse_equiv = sum(sum(lv["newton_iterations"]) * lv["dofs"] for lv in levels) / m.n_dof
    return {
        "mesh": size, "solver": solver, "dofs": m.n_dof, "nnz": K.nnz, "symmetric": sym,
        "newton_iterations": its, "coarse_levels": ";".join(
            f"{lv['dofs']}:{sum(lv['newton_iterations'])}" for lv in levels),
        "coarse_equivalent_iterations": coarse_equiv,
        "iterations_without_coarse_start": plain_its,
        "kernels_s": t_kernel, "assembly_s": t_asm,
        "factorization_s": t_fac, "factorization_with_analysis_s": t_fac_fresh,
        "back_substitution_s": t_bsub,
        "newton_iteration_s": t_iter, "iteration_over_factorization": t_iter / t_fac,
        "iteration_over_factorization_and_solve": t_iter / (t_fac + t_bsub),
        "kernel_assembly_share": (t_kernel + t_asm) / t_iter,
        "solve_s": t_solve, "solve_with_3_sensitivities_s": t_solve_s,
        "ddm_factorization_s": inc.timing["factorization"],
        "ddm_per_parameter_s": per_param, "ddm_per_parameter_over_solve": per_param / t_solve,
        "s_per_dof": t_solve / m.n_dof,
        **solves_by_column(lin, K.shape[0]),
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def cold_start() -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "SIGNORINI_CACHE_DIR": str(Path(d) / "cache")}
        for state in ("empty cache", "filled cache"):
            t0 = time.perf_counter()
            subprocess.run(["signorini", "hertz", "--no-fd", "-q", "--out", str(Path(d) / "out")],
                           env=env, check=True, capture_output=True)
            rows.append({"command": "signorini hertz --no-fd", "compilation_cache": state,
                         "wall_s": time.perf_counter() - t0})
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import signorini"], check=True)
    rows.append({"command": "python -c 'import signorini'", "compilation_cache": "-",
                 "wall_s": time.perf_counter() - t0})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="5k,56k,225k,1M")
    ap.add_argument("--solvers", default="pardiso,superlu")
    ap.add_argument("--skip-superlu-above", type=int, default=300_000,
                    help="do not run SuperLU above this many DOFs (its fill-in needs > 12 GB at 1M)")
    ap.add_argument("--no-cold-start", action="store_true")
    ap.add_argument("--one", nargs=2, metavar=("SIZE", "SOLVER"), help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(HERE / "results" / "hertz.csv"))
    args = ap.parse_args()
    if args.one:
        print("ROW " + json.dumps(one(*args.one)), flush=True)
        return
    rows = []
    approx = {"5k": 5e3, "56k": 5.6e4, "225k": 2.25e5, "1M": 9e5}
    for size in args.sizes.split(","):
        for solver in args.solvers.split(","):
            if solver == "superlu" and approx[size] > args.skip_superlu_above:
                rows.append({"mesh": size, "solver": solver, "note": "not run (see --skip-superlu-above)"})
                continue
            r = subprocess.run([sys.executable, __file__, "--one", size, solver], capture_output=True,
                               text=True)
            line = [ln for ln in r.stdout.splitlines() if ln.startswith("ROW ")]
            if r.returncode or not line:
                rows.append({"mesh": size, "solver": solver, "note": f"failed: {r.stderr[-300:]}"})
            else:
                rows.append(json.loads(line[0][4:]))
            print(f"{size} {solver}: done", flush=True)
    report(rows, args.out)
    if not args.no_cold_start:
        report(cold_start(), str(Path(args.out).with_name("hertz_cold_start.csv")))


if __name__ == "__main__":
    main()
