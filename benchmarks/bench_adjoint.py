"""Adjoint against DDM gradients: cost against the number of parameters, and
the memory of the adjoint's backward pass.

Two path-dependent problems, one scalar response each (``signorini.gradient``):

* ``hertz``: frictional Hertz, ``hertz_friction_problem(refine=2, n_fine=18)``
  (~60k DOFs; ``--small``: ``refine=0, n_fine=24``, ~5k DOFs), 10 increments,
  response ``hertz.contact_work`` summed over all increments,
  ``NewtonOptions(rtol=1e-10)``;
* ``forging``: forging 10x20, 50 increments, ``forging.options()``, response
  ``forging.objective`` of the lateral nodes at the last increment.

Parameter counts 1, 5, 50 and "all nodes". The scalar parameters are the
problem's own names first (Hertz: R, mu, E, P, nu, bump, eps, eps_t; forging:
phi0..phi4, mu, sigma_y), then one-hot nodal shape parameters ``x<k>`` (the
design velocity moves one coordinate of one node; nominal value 0, nodes taken
by distance from where the response is sensitive) up to the count. "All nodes"
is the adjoint with ``["nodes"]`` (2 x n_nodes coordinates); the DDM is not run
there: its time is extrapolated linearly from the measured ones (a + b n, least
squares over 1, 5, 50) and flagged ``ddm_extrapolated``.

Timing table (``adjoint.csv``), one row per (problem, count); the DDM and the
adjoint of a row run in two fresh processes, so that each peak RSS is its own.
In each process every measurement runs once to compile (JIT; the persistent
cache may already hold the kernels) and then ``--repeat`` times (default 2),
the fastest run kept, so **compile time is excluded**. Columns:

* ``forward_s``: a plain ``signorini.solve`` (no sensitivities, same steps,
  options and solver), measured in the adjoint's process (``forward_ddm_s``: in
  the DDM's process);
* ``ddm_s``: the DDM's ``timing["gradient"]`` (factorisation of each converged
  tangent, pseudo-loads, back-substitutions, response JVPs and, since this
  benchmark found it missing, the update of the history sensitivities);
  ``ddm_wall_extra_s``: wall time of ``gradient(method=DDM())`` minus the plain
  solve; ``ddm_fwd_part_s``: the DDM's ``timing["forward"]`` (the rows in
  results/ were measured before that fix: there the history-sensitivity update,
  ~0.9 s of forging at 50 parameters, is in ``ddm_fwd_part_s``);
* ``adjoint_backward_s``: the adjoint's ``timing["gradient"]`` (the backward
  pass alone), ``adjoint_forward_s`` its forward solve (``timing["forward"]``);
* ``backward_over_forward`` = adjoint_backward_s / forward_s, ``ddm_over_forward``
  = ddm_s / forward_ddm_s;
* ``peak_rss_ddm_MB``, ``peak_rss_adjoint_MB``: ``ru_maxrss`` of each process
  (at 50 it includes the model's cost of the one-hot design velocity fields:
  measured 1.33 GB against 0.71 GB for a plain solve of the 60k Hertz model);
* checks that the numbers are those of the same gradient. In the DDM's
  process, after its peak RSS is read, the adjoint runs on the DDM's own
  converged solution (``gradient(..., solution=...)``): ``max_rel_diff`` = max
  over the scalar parameters of |adjoint - DDM| / max |DDM| (the measure of
  tests/unit/test_adjoint.py), ``max_comp_rel_diff`` componentwise
  (|adjoint - DDM| / max(|DDM|, 1e-3 max |DDM|)), ``value_rel_diff`` of G;
  ``nodes_rel_diff``: ``grad["nodes"]`` at the one-hot nodes against the DDM
  of the one-hot parameters (50 row: same solution; "all nodes" row: the timed
  all-nodes adjoint against the 50 row's DDM); ``xproc_rel_diff``: the timed
  adjoint against the timed DDM (two processes, two solves);
* ``other_cpu``: CPU cores used by other processes during the timed runs
  (machine busy time minus this process's; the larger of the two processes):
  on 2 cores, much above 0.1 means the times are contended.

Memory table (``adjoint_memory.csv``): the all-nodes adjoint in three
configurations, each in its own process (one run, not warmed: the peak is that
of the configuration, JIT included; ``rss_before_MB`` is the peak after
importing and building the problem): default (``factors="recompute"``,
``checkpoint=1``), ``checkpoint=5``, ``factors="store"``; with
``memory["per_increment"]``, states and factors kept, forward and backward
times, and the relative difference of the nodal gradient from the default one.

After the tables: whether the all-nodes backward pass costs at most 2 forward
solves, and the crossover count n at which the adjoint becomes cheaper than the
DDM, from straight-line fits a + b n over 1, 5, 50 of DDM ``timing["gradient"]``
against the adjoint backward pass, and of the wall times over the plain solve.

    python benchmarks/bench_adjoint.py --small          # ~5k-DOF Hertz, a few minutes
    python benchmarks/bench_adjoint.py                  # ~60k-DOF Hertz, longer
        [--problems hertz,forging] [--counts 1,5,50,nodes] [--repeat 2] [--no-memory | --memory-only]
        [--solver auto]

Writes benchmarks/results/adjoint.csv and adjoint_memory.csv (``--small``:
adjoint_small.csv and adjoint_memory_small.csv); the rows of a problem not in
``--problems`` are kept from the file as they were.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _report import report

HERE = Path(__file__).parent
RESULTS = HERE / "results"
COUNTS = ("1", "5", "50", "nodes")
OWN = {"hertz": ["R", "mu", "E", "P", "nu", "bump", "eps", "eps_t"],
       "forging": ["phi0", "phi1", "phi2", "phi3", "phi4", "mu", "sigma_y"]}
#: the one-hot shape parameters move the nodes nearest to this point first:
#: Hertz, the first contact point (top centre); forging, the corner of the
#: billet's free surface under the die (where the bulge folds onto it)
HOT = {"hertz": (0.0, 0.0), "forging": (0.7, 1.0)}
MEMORY_CONFIGS = {"default": {}, "checkpoint=5": {"checkpoint": 5}, "factors=store": {"factors": "store"}}


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class OtherCpu:
    """CPU cores used by *other* processes over an interval: busy time of the
    machine (/proc/stat) minus this process's own CPU time, over the wall time
    (the load average is no measure here: it counts this process's own threads)."""

    def __init__(self):
        self.t0, self.busy0, self.own0 = time.perf_counter(), self._busy(), self._own()

    @staticmethod
    def _busy() -> float:
        try:
            with open("/proc/stat") as f:
                v = [int(x) for x in f.readline().split()[1:]]
        except OSError:
            return float("nan")
        idle = v[3] + (v[4] if len(v) > 4 else 0)
        return (sum(v[:8]) - idle) / os.sysconf("SC_CLK_TCK")

    @staticmethod
    def _own() -> float:
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    def cores(self) -> float:
        wall = time.perf_counter() - self.t0
        return max(0.0, (self._busy() - self.busy0 - (self._own() - self.own0)) / wall)


# ------------------------------------------------------------------ problems
def setup(name: str, small: bool):
    """(problem, response, gradient keyword arguments) of a benchmark problem."""
    import signorini as sg
    from signorini.problems import forging, hertz
    from signorini.problems.hertz_friction import hertz_friction_problem

    if name == "hertz":
        pb = hertz_friction_problem(refine=0, n_fine=24) if small else \
            hertz_friction_problem(refine=2, n_fine=18)
        kw = dict(steps=10, increments="all", options=sg.NewtonOptions(rtol=1e-10))
        return pb, hertz.contact_work, kw
    if name == "forging":
        pb = forging.forging_problem(mesh=(10, 20))
        nodes = forging.lateral_nodes(pb)
        # one response object per process: the compiled VJPs/JVPs are cached by its identity
        return pb, (lambda m: forging.objective(m, nodes)), dict(steps=50, increments="last",
                                                                 options=forging.options())
    raise SystemExit(f"unknown problem {name!r}")


def one_hot(name: str, pb, k: int) -> list[tuple[int, int]]:
    """(node, component) of k one-hot shape parameters: nodes by distance from HOT, x then y."""
    x = pb.mesh.nodes
    order = np.argsort(np.hypot(x[:, 0] - HOT[name][0], x[:, 1] - HOT[name][1]), kind="stable")
    return [(int(order[i // 2]), i % 2) for i in range(k)]


def with_parameters(name: str, pb, count: int):
    """(problem, names, [(node, component)] of the one-hot parameters): the first
    ``count`` own names, then one-hot nodal shape parameters x0, x1, ..."""
    import dataclasses

    own = OWN[name][:count]
    extra = one_hot(name, pb, count - len(own))
    if not extra:
        return pb, own, []
    shape, params, nominal = dict(pb.shape), dict(pb.params), dict(pb.shape_nominal)
    for k, (n, c) in enumerate(extra):
        V = np.zeros_like(pb.mesh.nodes)
        V[n, c] = 1.0
        shape[f"x{k}"], params[f"x{k}"], nominal[f"x{k}"] = V, 0.0, 0.0
    pb = dataclasses.replace(pb, shape=shape, params=params, shape_nominal=nominal)
    return pb, own + [f"x{k}" for k in range(len(extra))], extra


# ------------------------------------------------------------- measurements
def measure(name: str, count: str, mode: str, small: bool, solver: str, repeat: int) -> dict:
    """One process: plain solve and gradient(mode), each run once to compile, then
    ``repeat`` more times, the fastest kept."""
    import gc

    import signorini as sg
    from signorini import Adjoint
    from signorini.design.gradient import gradient
    from signorini.sensitivity.methods import method_named

    base, response, kw = setup(name, small)
    if count == "nodes":
        pb, names, extra = base, ["nodes"], []
    else:
        pb, names, extra = with_parameters(name, base, int(count))
    opts = dict(kw)
    increments = opts.pop("increments")

    def forward():
        t0 = time.perf_counter()
        sol = sg.solve(pb, solver=solver, **opts)
        return time.perf_counter() - t0, sol

    def grad():
        t0 = time.perf_counter()
        g = gradient(pb, response, names, method=method_named(mode), increments=increments, solver=solver,
                     **opts)
        return time.perf_counter() - t0, g

    other, g = None, None
    best_fwd = best = None
    for k in range(1 + repeat):  # the first run of each compiles; the others are timed
        if k == 1:
            other = OtherCpu()
        del g  # one solution alive at a time (peak RSS)
        gc.collect()
        t_fwd, sol = forward()
        its = sum(sol.newton_iterations)
        del sol
        gc.collect()
        t_wall, g = grad()
        if k and (best_fwd is None or t_fwd < best_fwd):
            best_fwd = t_fwd
        if k and (best is None or g.timing["gradient"] < best[1]["gradient"]):
            best = (t_wall, {k_: v for k_, v in g.timing.items() if isinstance(v, (int, float))})
    row = {"problem": name, "count": count, "mode": mode, "dofs": int(g.solution.model.n_dof),
           "n_nodes": int(pb.mesh.nodes.shape[0]), "increments": len(g.solution.increments),
           "newton_its": its, "forward_s": best_fwd, "gradient_wall_s": best[0], "timing": best[1],
           "memory": g.memory, "value": g.value, "peak_rss_MB": rss_mb(),
           "other_cpu": other.cores() if other else float("nan"),
           "warnings": [w[:120] for w in g.warnings],
           "grad": {n: float(v) for n, v in g.grad.items() if n != "nodes"},
           "one_hot": extra}
    if count == "nodes":
        # the nodal gradient at the nodes the 50-parameter rows move (for the check)
        ref = one_hot(name, pb, 50 - len(OWN[name]))
        row["nodes_at_one_hot"] = [float(g["nodes"][n, c]) for n, c in ref]
    if mode == "ddm":
        # check (after the peak RSS is read): the adjoint on the DDM's own converged
        # solution, for the same names and, with one-hot parameters, every nodal
        # coordinate (its entries at the one-hot nodes are their DDM derivatives)
        chk = gradient(pb, response, names + (["nodes"] if extra else []), method=Adjoint(),
                       increments=increments, solver=solver, solution=g.solution, **opts)
        row["check_value"] = chk.value
        row["check_grad"] = {n: float(v) for n, v in chk.grad.items() if n != "nodes"}
        row["check_nodes"] = [float(chk["nodes"][n, c]) for n, c in extra]
    return row


def measure_memory(name: str, config: str, small: bool, solver: str, out: str) -> dict:
    """One process, one run: the all-nodes adjoint in one memory configuration."""
    from signorini import Adjoint
    from signorini.design.gradient import gradient

    pb, response, kw = setup(name, small)
    before, other = rss_mb(), OtherCpu()
    t0 = time.perf_counter()
    g = gradient(pb, response, ["nodes"], method=Adjoint(**MEMORY_CONFIGS[config]), solver=solver, **kw)
    wall = time.perf_counter() - t0
    np.save(out, g["nodes"])
    return {"problem": name, "config": config, "dofs": int(g.solution.model.n_dof),
            "increments": len(g.solution.increments),
            "per_increment_kB": g.memory["per_increment"] / 1024,
            "states_kept": g.memory["states_kept"], "factors_kept": g.memory["factors_kept"],
            "rss_before_MB": before, "peak_rss_MB": rss_mb(), "forward_s": g.timing["forward"],
            "backward_s": g.timing["gradient"], "factorizations": g.timing["factorizations"],
            "wall_s_with_jit": wall, "other_cpu": other.cores()}


def subprocess_row(args: list[str]) -> dict:
    r = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True)
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("ROW ")]
    if r.returncode or not line:
        return {"error": r.stderr[-600:]}
    return json.loads(line[0][4:])


# ------------------------------------------------------------------ analysis
def fit(ns, ts):
    """Least-squares a + b n."""
    b, a = np.polyfit(np.asarray(ns, float), np.asarray(ts, float), 1)
    return a, b


def rel_diff(a: dict, d: dict) -> tuple[float, float]:
    """Over the common names: (max_k |a_k - d_k| / max_k |d_k| (as tests/unit/test_adjoint.py),
    max_k |a_k - d_k| / max(|d_k|, 1e-3 max|d|) (componentwise, tiny components floored))."""
    common = [n for n in a if n in d]
    if not common:
        return float("nan"), float("nan")
    av, dv = np.array([a[n] for n in common]), np.array([d[n] for n in common])
    err, top = np.abs(av - dv), np.abs(dv).max()
    return float(err.max() / top), float(np.max(err / np.maximum(np.abs(dv), 1e-3 * top)))


def table_rows(name: str, runs: dict) -> tuple[list[dict], dict]:
    """Rows of the timing table for one problem and the crossover summary."""
    rows = []
    measured, wall = {}, {}  # n -> DDM timing["gradient"]; n -> (DDM, adjoint) wall minus plain solve
    for count in [c for c in COUNTS if ("adjoint", c) in runs or ("ddm", c) in runs]:
        a, d = runs.get(("adjoint", count)), runs.get(("ddm", count))
        if a and "error" in a:
            rows.append({"problem": name, "params": count, "note": "adjoint failed: " + a["error"][-200:]})
            continue
        if d and "error" in d:
            rows.append({"problem": name, "params": count, "note": "ddm failed: " + d["error"][-200:]})
            continue
        n = 2 * a["n_nodes"] if count == "nodes" else int(count)
        row = {"problem": name, "dofs": a["dofs"], "params": n if count != "nodes" else f"nodes({n})",
               "forward_s": a["forward_s"]}
        if d:
            measured[n] = d["timing"]["gradient"]
            wall[n] = (d["gradient_wall_s"] - d["forward_s"], a["gradient_wall_s"] - a["forward_s"])
            row.update({"forward_ddm_s": d["forward_s"], "ddm_s": d["timing"]["gradient"],
                        "ddm_extrapolated": False,
                        "ddm_fwd_part_s": d["timing"]["forward"],
                        "ddm_wall_extra_s": d["gradient_wall_s"] - d["forward_s"]})
        row.update({"adjoint_backward_s": a["timing"]["gradient"],
                    "adjoint_forward_s": a["timing"]["forward"],
                    "backward_over_forward": a["timing"]["gradient"] / a["forward_s"]})
        if d:
            row["ddm_over_forward"] = d["timing"]["gradient"] / d["forward_s"]
            row["peak_rss_ddm_MB"] = d["peak_rss_MB"]
            # adjoint on the DDM's solution against the DDM (same converged path)
            row["max_rel_diff"], row["max_comp_rel_diff"] = rel_diff(d["check_grad"], d["grad"])
            row["value_rel_diff"] = abs(d["check_value"] - d["value"]) / abs(d["value"])
            if d["check_nodes"]:
                k = len(d["check_nodes"])
                row["nodes_rel_diff"] = rel_diff({f"x{i}": v for i, v in enumerate(d["check_nodes"])},
                                                 {f"x{i}": d["grad"][f"x{i}"] for i in range(k)})[0]
            # the timed adjoint (its own process and solve) against the DDM
            row["xproc_rel_diff"] = rel_diff(a["grad"], d["grad"])[0]
        row["peak_rss_adjoint_MB"] = a["peak_rss_MB"]
        row["adj_factorizations"] = a["timing"].get("factorizations")
        row["warnings"] = len(a["warnings"]) + (len(d["warnings"]) if d else 0)
        row["other_cpu"] = max(a["other_cpu"], d["other_cpu"]) if d else a["other_cpu"]
        row["_n"] = n
        rows.append(row)
    summary = {"problem": name}
    if len(measured) >= 2:
        ns = sorted(measured)
        A, B = fit(ns, [measured[n] for n in ns])
        summary["ddm_fit"] = (A, B)
        for row in rows:
            if "_n" in row and "ddm_s" not in row:  # all nodes: extrapolated
                t = A + B * row["_n"]
                row.update({"ddm_s": t, "ddm_extrapolated": True,
                            "ddm_over_forward": t / row["forward_s"]})
        adj = [(r["_n"], r["adjoint_backward_s"]) for r in rows if "_n" in r and r.get("ddm_extrapolated") is False]
        if len(adj) >= 2:
            C, D = fit(*zip(*adj))
            summary["adjoint_fit"] = (C, D)
            summary["crossover"] = (C - A) / (B - D) if B > D else float("inf")
        # the same from wall times (gradient() minus the plain solve in the same process):
        # counts the DDM's history-sensitivity update and the adjoint's extra forward work
        (A2, B2), (C2, D2) = fit(ns, [wall[n][0] for n in ns]), fit(ns, [wall[n][1] for n in ns])
        summary["wall_fits"] = (A2, B2, C2, D2)
        summary["crossover_wall"] = (C2 - A2) / (B2 - D2) if B2 > D2 else float("inf")
    nodes = runs.get(("adjoint", "nodes"))
    d50 = runs.get(("ddm", "50"))
    for row in rows:
        if str(row.get("params", "")).startswith("nodes") and nodes and d50 and "error" not in d50 \
                and "nodes_at_one_hot" in nodes:
            k = len(OWN[name])
            ddm = {f"x{i}": d50["grad"][f"x{i}"] for i in range(len(nodes["nodes_at_one_hot"]))}
            adj = {f"x{i}": v for i, v in enumerate(nodes["nodes_at_one_hot"])}
            row["nodes_rel_diff"] = row["xproc_rel_diff"] = rel_diff(adj, ddm)[0]
            assert len(ddm) == 50 - k
    for row in rows:
        row.pop("_n", None)
    return rows, summary


def compact(rows: list[dict], repeat: int) -> None:
    """The key columns of the timing table (the CSV has them all)."""
    cols = [("problem", "problem", "s"), ("params", "params", "s"), ("forward_s", "forward s", ".3f"),
            ("ddm_s", "DDM s", ".3f"), ("adjoint_backward_s", "adj. bwd s", ".3f"),
            ("backward_over_forward", "bwd/fwd", ".2f"), ("ddm_over_forward", "DDM/fwd", ".2f"),
            ("peak_rss_ddm_MB", "RSS DDM MB", ".0f"), ("peak_rss_adjoint_MB", "RSS adj MB", ".0f"),
            ("max_rel_diff", "adj-DDM rel", ".1e"), ("other_cpu", "other cpu", ".2f")]
    print(f"\nSummary (seconds after JIT, fastest of {repeat}; DDM s marked * = extrapolated, not run)")
    print(" | ".join(f"{h:>12s}" for _, h, _ in cols))
    for r in rows:
        out = []
        for k, _, fmt in cols:
            v = r.get(k, "")
            txt = format(v, fmt) if isinstance(v, (int, float)) and not isinstance(v, bool) and fmt != "s" \
                else str(v)
            if k == "ddm_s" and r.get("ddm_extrapolated"):
                txt = format(v, ".4g") + "*"
            out.append(f"{txt:>12s}")
        print(" | ".join(out))


# ---------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--small", action="store_true", help="~5k-DOF Hertz (refine 0, n_fine 24)")
    ap.add_argument("--problems", default="hertz,forging")
    ap.add_argument("--counts", default=",".join(COUNTS))
    ap.add_argument("--no-memory", action="store_true", help="skip the memory configurations")
    ap.add_argument("--memory-only", action="store_true", help="only the memory configurations")
    ap.add_argument("--solver", default="auto")
    ap.add_argument("--repeat", type=int, default=2, help="timed runs after the compiling one (fastest kept)")
    ap.add_argument("--one", nargs=3, metavar=("PROBLEM", "COUNT", "MODE"), help=argparse.SUPPRESS)
    ap.add_argument("--mem", nargs=3, metavar=("PROBLEM", "CONFIG", "NPY"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    small = ["--small"] if args.small else []
    if args.one:
        print("ROW " + json.dumps(measure(*args.one, args.small, args.solver, args.repeat)), flush=True)
        return
    if args.mem:
        print("ROW " + json.dumps(measure_memory(*args.mem[:2], args.small, args.solver, args.mem[2])),
              flush=True)
        return

    suffix = "_small" if args.small else ""
    counts = args.counts.split(",")
    rows, summaries, mem_rows = [], [], []
    for name in args.problems.split(","):
        runs = {}
        for count in ([] if args.memory_only else counts):
            for mode in ("ddm", "adjoint"):
                if mode == "ddm" and count == "nodes":
                    continue
                t0 = time.perf_counter()
                r = subprocess_row(["--one", name, count, mode, "--solver", args.solver,
                                    "--repeat", str(args.repeat), *small])
                runs[(mode, count)] = r
                msg = r.get("error", "")[-300:] or (
                    f"gradient {r['timing']['gradient']:.3f} s, forward {r['forward_s']:.3f} s, "
                    f"{r['dofs']} DOFs, other processes {r['other_cpu']:.2f} cores")
                print(f"{name} {count:>5s} {mode:7s}: {msg} ({time.perf_counter() - t0:.0f} s for the run)",
                      flush=True)
        if runs:
            r, s = table_rows(name, runs)
            rows += r
            summaries.append(s)
        if not args.no_memory:
            with tempfile.TemporaryDirectory() as tmp:
                grads = {}
                for config in MEMORY_CONFIGS:
                    npy = str(Path(tmp) / f"{config}.npy")
                    m = subprocess_row(["--mem", name, config, npy, "--solver", args.solver, *small])
                    if "error" not in m:
                        grads[config] = np.load(npy)
                        g0 = grads.get("default")
                        if g0 is not None:
                            m["rel_diff_from_default"] = float(np.abs(grads[config] - g0).max() /
                                                               np.abs(g0).max())
                    else:
                        m = {"problem": name, "config": config, "note": m["error"][-200:]}
                    mem_rows.append(m)
                    print(f"{name} memory {config}: done", flush=True)

    if rows:
        print(f"\nTiming, seconds: fastest of {args.repeat} runs after a compiling one in each process "
              "(JIT compile time excluded); DDM at 'nodes' extrapolated (a + b n) where ddm_extrapolated")
        report(_keep_other_problems(rows, RESULTS / f"adjoint{suffix}.csv"),
               RESULTS / f"adjoint{suffix}.csv", width=10)
        compact(rows, args.repeat)
    for r in rows:
        if str(r.get("params", "")).startswith("nodes") and "backward_over_forward" in r:
            v = r["backward_over_forward"]
            print(f"{r['problem']}: adjoint backward for every nodal coordinate = {v:.2f} x the forward "
                  f"solve ({'<=' if v <= 2 else '>'} 2)")
    for s in summaries:
        if "crossover" in s:
            (A, B), (C, D) = s["ddm_fit"], s["adjoint_fit"]
            print(f"{s['problem']}: DDM gradient {A:.3g} + {B:.3g} n s, adjoint backward {C:.3g} + "
                  f"{D:.3g} n s -> adjoint cheaper above n = {s['crossover']:.2f} parameters")
            A2, B2, C2, D2 = s["wall_fits"]
            print(f"{s['problem']}: by wall time over the plain solve: DDM {A2:.3g} + {B2:.3g} n s, "
                  f"adjoint {C2:.3g} + {D2:.3g} n s -> adjoint cheaper above n = "
                  f"{s['crossover_wall']:.2f} parameters")
    if mem_rows:
        print("\nMemory of the all-nodes adjoint (one run per process, JIT included)")
        report(_keep_other_problems(mem_rows, RESULTS / f"adjoint_memory{suffix}.csv"),
               RESULTS / f"adjoint_memory{suffix}.csv", width=10)


def _keep_other_problems(rows: list[dict], path: Path) -> list[dict]:
    """``rows`` with the rows of ``path`` for the problems not measured in this run
    (``--problems hertz`` re-measures Hertz and keeps the forging rows), in the
    file's order of problems."""
    if not path.exists():
        return rows
    with open(path, newline="") as f:
        old = list(csv.DictReader(f))
    ran = {r["problem"] for r in rows}
    order = list(dict.fromkeys([r["problem"] for r in old] + [r["problem"] for r in rows]))
    merged = [r for name in order
              for r in (rows if name in ran else old) if r["problem"] == name]
    return merged


if __name__ == "__main__":
    main()
