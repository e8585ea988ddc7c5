"""The ``signorini`` command as a user waits for it: whole process, spawn to exit.

Every command of ``signorini --help`` at its defaults, plus ``hertz --refine 2
--no-fd`` (56k DOFs); each run is a fresh process (``subprocess``), timed by the
wall clock from before the spawn to the return of ``wait4`` (Python start-up,
imports, JAX tracing and XLA compilation, solve, sensitivities, FD checks,
figures and files: everything). The command lines (``--out`` is a new temporary
directory per run; the child's working directory is a temporary one too)::

    hertz               signorini hertz --out OUT
    hertz-refine2       signorini hertz --out OUT --refine 2 --no-fd
    hertz-friction      signorini hertz-friction --out OUT
    forging             signorini forging --out OUT
    optimize-forging    signorini optimize-forging --out OUT
    sweep               signorini sweep --out OUT hertz --set R=1,1.5,2,2.5 -- --no-fd
    run                 signorini run --out OUT examples/block.toml

``sweep`` has no grid of its own: 4 points of ``hertz --no-fd`` (the example of
``signorini sweep --help``), on its default scheduler (a local Dask cluster of
os.cpu_count() single-threaded workers). ``run`` needs a problem file: the
first ``examples/*.toml`` (skipped with a note if there is none).
``optimize-forging`` at its defaults is three BFGS optimisations (mu = 0.1,
0.2, 0.3, up to 50 iterations, each evaluation a 50-increment forging solve
with DDM): by far the longest row (``--timeout`` stops a run).

Two states of the caches of compiled programs (``SIGNORINI_CACHE_DIR``: JAX's
compilation cache and signorini's kept programs, see ``signorini/_jax.py`` and
``signorini/_programs.py``), both measured:

* ``empty``: ``SIGNORINI_CACHE_DIR`` a fresh, empty directory for every run
  (every kernel traced and compiled by XLA);
* ``filled``: one directory per command, filled by one untimed warm-up run of
  the same command line, shared by the timed runs (the kept programs are
  loaded; what is not kept is traced and read from JAX's cache).

``--signorini`` runs another installation or checkout (e.g. a script running
``PYTHONPATH=OLD/src python3 -m signorini.app.cli "$@"``) for before/after tables;
``--commit`` names its commit in the CSV. ``--against`` (with ``--against-commit``)
measures a second one in the same benchmark, alternating: run k of each, one
after the other, each with caches of its own; the machine's speed drifts by
10-20 % within an hour here, and alternating runs see the same drift.

Other caches are not controlled: Python's bytecode and the OS's file cache are
warm after the first run of the benchmark.

Per run (``cli_runs.csv``): wall time, exit code, the status of summary.json,
every timing entry of ``OUT/summary.json`` (top-level keys containing "time"
with a number, e.g. ``time_solve_s``, ``time_wall_s``, and every number of a
top-level ``timings`` object as ``timings.<key>``; ``sweep`` writes no
summary.json: its ``sweep.json`` is read instead), the DOFs (``mesh.dofs``;
for ``sweep`` those of its points), the size of the compilation cache after the
run, and the peak RSS from ``wait4``: the largest resident set of the child or
of any descendant it waited for (for ``sweep`` and ``optimize-forging``: the
largest single process, the Dask workers are not summed). Per command and cache
state (``cli.csv`` and the printed Markdown table): median, min and max of the
wall time over ``--runs`` runs (successful runs only; failures are counted in
``failed``), the median of each timing entry, the largest peak RSS, the DOFs;
with the date, the git commit (``+dirty`` when src/ has uncommitted changes),
the CPU count, and the Python, JAX and signorini versions.

    python benchmarks/bench_cli.py [--runs 5] [--commands hertz,sweep,...] [--out-dir benchmarks/results]
    python benchmarks/bench_cli.py --quick --out-dir /tmp/bench_cli_smoke   # 1 run of hertz: a smoke test
"""

from __future__ import annotations

import argparse
import csv
import datetime
import importlib.metadata
import json
import os
import platform
import shutil
import signal
import statistics
import subprocess
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"
CACHES = ("empty", "filled")
#: points of the sweep row: hertz at R = 1, 1.5, 2, 2.5 mm, without the FD check
SWEEP_POINTS = "R=1,1.5,2,2.5"


def _example() -> Path | None:
    files = sorted((ROOT / "examples").glob("*.toml"))
    return files[0] if files else None


def commands() -> dict[str, list[str] | str]:
    """name -> the arguments after ``signorini`` (``{out}`` where --out's value goes),
    or a note saying why the command cannot be run."""
    ex = _example()
    return {
        "hertz": ["hertz", "--out", "{out}"],
        "hertz-refine2": ["hertz", "--out", "{out}", "--refine", "2", "--no-fd"],
        "hertz-friction": ["hertz-friction", "--out", "{out}"],
        "forging": ["forging", "--out", "{out}"],
        "optimize-forging": ["optimize-forging", "--out", "{out}"],
        "sweep": ["sweep", "--out", "{out}", "hertz", "--set", SWEEP_POINTS, "--", "--no-fd"],
        "run": ["run", "--out", "{out}", str(ex)] if ex else "skipped: no examples/*.toml problem file",
    }


def shown(argv: list[str]) -> str:
    """The command line as a user types it (OUT for the output directory, paths
    relative to the repository)."""
    def one(a):
        if a == "{out}":
            return "OUT"
        p = Path(a)
        return str(p.relative_to(ROOT)) if p.is_absolute() and ROOT in p.parents else a
    return "signorini " + " ".join(one(a) for a in argv)


# --------------------------------------------------------------------------- one run

def _dir_mb(d: Path) -> float:
    if not d.is_dir():
        return 0.0
    return sum(f.stat().st_size for f in d.rglob("*") if f.is_file()) / 2**20


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def is_timing(key: str) -> bool:
    """A column of :func:`timings_of` ("timings" does not contain "time")."""
    return "time" in key or key.startswith("timings.")


def timings_of(summary: dict) -> dict:
    """The timing entries of a summary: top-level numbers under a key containing
    "time", and every number of a top-level ``timings`` object (nested objects
    flattened with dots), as ``timings.<key>``."""
    out = {k: v for k, v in summary.items() if "time" in k and k != "timings" and _number(v)}

    def walk(d, prefix):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            elif _number(v):
                out[f"{prefix}{k}"] = v
    if isinstance(summary.get("timings"), dict):
        walk(summary["timings"], "timings.")
    return out


def dofs_of(summary: dict):
    """``mesh.dofs`` of a summary; for a sweep's sweep.json, its points' (one
    number if all equal, else "a;b;...")."""
    mesh = summary.get("mesh")
    if isinstance(mesh, dict) and _number(mesh.get("dofs")):
        return int(mesh["dofs"])
    found = []
    for p in summary.get("points") or []:
        d = dofs_of((p or {}).get("summary") or {})
        if d != "" and d not in found:
            found.append(d)
    return found[0] if len(found) == 1 else ";".join(map(str, found))


def run_once(exe: str, argv: list[str], work: Path, cache: Path, timeout: float | None) -> dict:
    """Spawn ``exe argv`` once with SIGNORINI_CACHE_DIR=cache and --out work/out;
    wall time spawn -> exit, peak RSS (wait4) and what summary.json says."""
    out = work / "out"
    work.mkdir(parents=True, exist_ok=True)
    args = [exe] + [str(out) if a == "{out}" else a for a in argv]
    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(cache)}
    timed_out = threading.Event()
    with open(work / "stdout.txt", "wb") as so, open(work / "stderr.txt", "wb") as se:
        t0 = time.perf_counter()
        p = subprocess.Popen(args, stdout=so, stderr=se, stdin=subprocess.DEVNULL, env=env, cwd=work,
                             start_new_session=True)  # its own process group: a timeout ends it all

        def kill():
            timed_out.set()
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        timer = threading.Timer(timeout, kill) if timeout else None
        if timer:
            timer.start()
        os.waitid(os.P_PID, p.pid, os.WEXITED | os.WNOWAIT)  # exited, not yet reaped
        wall = time.perf_counter() - t0
        if timer:
            timer.cancel()
        try:  # what is left of the run's process group (e.g. Dask workers of a killed parent);
            os.killpg(p.pid, signal.SIGKILL)  # its leader, unreaped, keeps the group id ours
        except (ProcessLookupError, PermissionError):
            pass
        _, status, ru = os.wait4(p.pid, 0)  # reap: the rusage of the child and its waited-for descendants
    p.returncode = code = os.waitstatus_to_exitcode(status)
    row = {"wall_s": wall, "exit_code": code, "peak_rss_MB": ru.ru_maxrss / 1024,
           "cache_MB": _dir_mb(cache)}
    summary, source = None, ""
    for name in ("summary.json", "sweep.json"):
        f = out / name
        if f.is_file():
            try:
                summary, source = json.loads(f.read_text()), name
            except (OSError, ValueError) as e:
                source = f"{name} unreadable: {e}"
            break
    row["status"] = (summary or {}).get("status", "") if isinstance(summary, dict) else ""
    row["summary_file"] = source
    row["dofs"] = dofs_of(summary) if isinstance(summary, dict) else ""
    row.update(timings_of(summary) if isinstance(summary, dict) else {})
    note = ""
    if timed_out.is_set():
        note = f"killed after the --timeout of {timeout:g} s"
    elif code != 0:
        err = (work / "stderr.txt").read_text(errors="replace").strip().splitlines()
        note = f"exit code {code}: " + (err[-1][:300] if err else "(no stderr)")
    row["note"] = note
    return row


# --------------------------------------------------------------------------- a command

def measure(name: str, argv: list[str], exes: list[tuple[str, str]], runs: int, caches, timeout,
            log) -> list[dict]:
    """Every timed run of one command, in both cache states; with several
    executables ``(exe, commit)``, run k of each one after the other (alternating,
    so that a change of the machine's speed during the benchmark hits all alike),
    each with caches of its own."""
    rows = []
    with tempfile.TemporaryDirectory(prefix=f"bench_cli_{name}_") as tmp:
        tmp = Path(tmp)
        for state in caches:
            shared = {}
            if state == "filled":
                for j, (exe, code) in enumerate(exes):
                    shared[j] = tmp / f"filled_cache_{j}"
                    w = run_once(exe, argv, tmp / "warmup", shared[j], timeout)
                    log(f"{name:17s} filled  warm-up  {w['wall_s']:8.2f} s  (untimed; {code}; exit "
                        f"{w['exit_code']}, cache {w['cache_MB']:.1f} MB)")
            for k in range(runs):
                for j, (exe, code) in enumerate(exes):
                    work = tmp / f"{state}_{k}_{j}"
                    cache = tmp / f"empty_cache_{k}_{j}" if state == "empty" else shared[j]
                    r = run_once(exe, argv, work, cache, timeout)
                    rows.append({"command": name, "command_line": shown(argv), "cache": state,
                                 "run": k + 1, "commit": code, "executable": exe, **r})
                    log(f"{name:17s} {state:7s} run {k + 1}/{runs} {r['wall_s']:8.2f} s  exit "
                        f"{r['exit_code']}  peak RSS {r['peak_rss_MB']:.0f} MB  ({code})"
                        + (f"  {r['note']}" if r["note"] else ""))
                    shutil.rmtree(work, ignore_errors=True)  # disk: a forging output is ~10s of MB
                    if state == "empty":
                        shutil.rmtree(cache, ignore_errors=True)
    return rows


def summarise(rows: list[dict], meta: dict) -> dict:
    """The row of one command and cache state."""
    ok = [r for r in rows if r["exit_code"] == 0]
    walls = [r["wall_s"] for r in ok]
    first = rows[0]
    out = {"command": first["command"], "command_line": first["command_line"], "cache": first["cache"],
           "runs": len(ok), "failed": len(rows) - len(ok),
           "median_s": statistics.median(walls) if walls else "",
           "min_s": min(walls) if walls else "", "max_s": max(walls) if walls else ""}
    keys = list(dict.fromkeys(k for r in ok for k in r if is_timing(k)))
    for k in keys:
        vals = [r[k] for r in ok if _number(r.get(k))]
        out[f"median_{k}"] = statistics.median(vals) if vals else ""
    out["peak_rss_MB"] = max((r["peak_rss_MB"] for r in ok), default="")
    out["median_cache_MB"] = statistics.median([r["cache_MB"] for r in ok]) if ok else ""
    dofs = list(dict.fromkeys(r["dofs"] for r in ok if r["dofs"] != ""))
    out["dofs"] = dofs[0] if len(dofs) == 1 else ";".join(map(str, dofs))
    notes = list(dict.fromkeys(r["note"] for r in rows if r["note"]))
    out["note"] = " | ".join(notes)
    return {**meta, **out, "commit": first.get("commit", meta.get("commit")),
            "executable": first.get("executable", meta.get("executable"))}


# --------------------------------------------------------------------------- output

def metadata(exe: str, commit: str | None = None) -> dict:
    def git(*a):
        try:
            return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True,
                                  check=True).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            return ""
    if commit is None:  # this checkout's code
        commit = git("rev-parse", "--short", "HEAD")
        if commit and git("status", "--porcelain", "--untracked-files=no", "--", "src"):
            commit += "+dirty"  # the measured code is not exactly the commit's

    def version(pkg):
        try:
            return importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            return ""
    return {"date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": commit,
            "cpu_count": os.cpu_count(), "usable_cpus": len(os.sched_getaffinity(0)),
            "python": platform.python_version(), "jax": version("jax"), "signorini": version("signorini"),
            "executable": exe}


def write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, restval="")
        w.writeheader()
        w.writerows(rows)
    print(f"written {path}")


def markdown(rows: list[dict]) -> str:
    parts = list(dict.fromkeys(k for r in rows for k in r if k.startswith("median_") and
                               is_timing(k[len("median_"):])))

    def f(v):
        if not isinstance(v, float):
            return "" if v is None else str(v)
        return f"{v:.3g}" if abs(v) < 1 else f"{v:.2f}"
    head = ["command", "code", "cache", "runs", "median s", "min s", "max s"] + \
        [p[len("median_"):] + " (median)" for p in parts] + ["peak RSS MB", "DOFs"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for r in rows:
        runs = f"{r['runs']}" + (f" ({r['failed']} failed)" if r["failed"] else "")
        cells = [f"`{r['command_line']}`", str(r.get("commit", "")), r["cache"], runs,
                 f(r["median_s"]), f(r["min_s"]),
                 f(r["max_s"])] + [f(r.get(p, "")) for p in parts] + \
            [f"{r['peak_rss_MB']:.0f}" if r["peak_rss_MB"] != "" else "", str(r["dofs"])]
        lines.append("| " + " | ".join(cells) + " |")
    notes = [f"* `{r['command_line']}` ({r['cache']}): {r['note']}" for r in rows if r.get("note")]
    return "\n".join(lines + ([""] + notes if notes else []))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    names = list(commands())
    ap.add_argument("--runs", type=int, default=5, help="timed runs per command and cache state (default 5)")
    ap.add_argument("--commands", default=",".join(names),
                    help=f"comma-separated subset of {','.join(names)} (default: all)")
    ap.add_argument("--caches", default=",".join(CACHES), help="empty,filled (default: both)")
    ap.add_argument("--out-dir", default=str(RESULTS), help="where cli.csv and cli_runs.csv go "
                    "(default: benchmarks/results)")
    ap.add_argument("--quick", action="store_true", help="smoke test: --runs 1 --commands hertz")
    ap.add_argument("--timeout", type=float, default=3600.0,
                    help="seconds before a run is killed and recorded as failed (0: none; default 3600)")
    ap.add_argument("--signorini", default=shutil.which("signorini"),
                    help="the executable (default: signorini on PATH, %(default)s)")
    ap.add_argument("--commit", default=None,
                    help="the commit of the code --signorini runs, for the CSV (default: this "
                         "checkout's HEAD, +dirty with uncommitted changes in src/)")
    ap.add_argument("--against", default=None,
                    help="a second executable (e.g. another checkout's, as for --signorini), run "
                         "alternately with the first: run k of each one after the other")
    ap.add_argument("--against-commit", default="against", help="the commit --against runs")
    args = ap.parse_args()
    if args.quick:
        args.runs, args.commands = 1, "hertz"
    if not args.signorini:
        ap.error("no signorini command on PATH (pip install -e .), or give --signorini")
    chosen = [c.strip() for c in args.commands.split(",") if c.strip()]
    caches = [c.strip() for c in args.caches.split(",") if c.strip()]
    bad = [c for c in chosen if c not in names] + [c for c in caches if c not in CACHES]
    if bad or args.runs < 1:
        ap.error(f"unknown command/cache state {bad} (commands: {names}; caches: {list(CACHES)})"
                 if bad else "--runs must be >= 1")
    meta = metadata(args.signorini, args.commit)

    def log(msg):
        print(msg, flush=True)
    table = commands()
    all_runs, summary = [], []
    for name in chosen:
        argv = table[name]
        if isinstance(argv, str):
            log(f"{name}: {argv}")
            summary.append({"command": name, "command_line": f"signorini {name}", "cache": "-", "runs": 0,
                            "failed": 0, "median_s": "", "min_s": "", "max_s": "", "peak_rss_MB": "",
                            "dofs": "", "note": argv, **meta})
            continue
        exes = [(args.signorini, meta["commit"])]
        if args.against:
            exes.append((args.against, args.against_commit))
        runs = measure(name, argv, exes, args.runs, caches, args.timeout or None, log)
        all_runs += [{**meta, **r} for r in runs]
        for state in caches:
            for _, code in exes:
                summary.append(summarise([r for r in runs if r["cache"] == state
                                          and r["commit"] == code], meta))
    print()
    print(f"signorini {meta['signorini']} at {meta['commit']}, {meta['date']}, {meta['cpu_count']} CPUs, "
          f"Python {meta['python']}, JAX {meta['jax']}; {args.runs} run(s) each, wall clock spawn -> exit")
    print()
    print(markdown(summary))
    print()
    out = Path(args.out_dir)
    write_csv(out / "cli.csv", summary)
    write_csv(out / "cli_runs.csv", all_runs)


if __name__ == "__main__":
    main()
