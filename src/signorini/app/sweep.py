"""Parameter sweeps and per-mu optimisations as independent tasks on Dask.

A *sweep* runs one ``signorini`` command (``hertz``, ``hertz-friction``,
``forging``, ``optimize-forging``, ``run``) once per point of a grid of
parameter values, each point as an independent task, and collects every
point's ``summary.json`` into one table::

    from signorini.app.sweep import grid, run_sweep
    pts = grid(["R=1.0,1.1", "E=100,200"])        # 4 points, R varies slowest
    run_sweep("hertz", pts, "results/sweep", extra_args=["--no-fd"])

writes ``results/sweep/point_<k>/`` (the command's own output for point k),
``results/sweep/sweep.csv`` (one row per point, in grid order) and
``results/sweep/sweep.json`` (the grid, exit codes and full summaries).

Where the tasks run:

* by default on a :class:`distributed.LocalCluster` started for the sweep
  (``n_workers`` worker *processes*, default ``os.cpu_count()``, one thread
  each) and closed afterwards;
* ``scheduler="tcp://host:8786"``: on an existing Dask cluster (its workers
  must have ``signorini`` installed and see the output directory);
* ``sequential=True``: one after another in this process, without Dask.

Every task calls :func:`signorini.app.cli.main` with the same arguments in all
three cases, so the results are the same (tested: identical to the last bit
for ``hertz``). Each worker runs one single-threaded JAX/XLA
(:data:`WORKER_ENV`), so N workers use N cores and do not oversubscribe.

Grid names: a plain name (``R``, ``mu``, ``phi0``) is passed as
``--set NAME=VALUE``; a name starting with ``--`` is passed as that option,
``--NAME VALUE`` (e.g. ``--refine=0,1`` or, for ``optimize-forging``, which
has no ``--set``, ``--mu=0.1,0.2``).

A point that fails (exit code 1: the solve failed; 2: bad input, also
argparse usage errors) does not stop the sweep: its row has the exit code,
``status`` and ``reason`` (the summary's ``reason``, or the command's error
message) and whatever summary it wrote.

CSV columns (:func:`flatten` for the summary part), in this order: the swept
names; ``exit_code``, ``status``, ``reason``, ``dir`` (the point's output
directory relative to ``out``); then the summary's entries (``status`` and
``reason`` excepted), in first-seen order over the points:

* nested dicts are flattened with dots (``p0.computed``, ``params.R``);
* numbers, booleans, strings and ``null`` are kept as they are (floats written
  with ``repr``, so they round-trip exactly);
* a list of at most :data:`MAX_LIST_ITEMS` items that are not all strings is
  expanded by index (``newton_iterations.0``, ``loads.2.c_over_a``);
  an empty or longer list, or a list of strings (``warnings``), is reduced to its length
  (``newton_residuals.0.len``, ``warnings.len``).

The per-mu preform optimisations of ``optimize-forging`` use the same tasks
(:func:`map_tasks`), see :mod:`signorini.app.commands.optimize_forging`.
"""

from __future__ import annotations

import contextlib
import csv
import io as _io
import itertools
import json
import os
import time
from pathlib import Path

import numpy as np
from .. import timing
from ..errors import Interrupted
from ..post.atomic import atomic
from . import runner
from ..linsolve import mkl_threads, product_threads
from . import cli

#: environment of the worker processes: one thread for XLA and BLAS/OpenMP per worker
WORKER_ENV = {
    "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}

#: lists up to this length are expanded by index in the CSV; longer ones give their length
MAX_LIST_ITEMS = 4

_FIXED = ("exit_code", "status", "reason", "dir")


# --------------------------------------------------------------------------- grid

def _value(text: str):
    """'3' -> 3, '1.5' -> 1.5, anything else stays text."""
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def grid(assignments: list[str]) -> list[dict]:
    """The Cartesian product of ``NAME=v1,v2,...`` items as a list of {name: value}.

    ``NAME=start:stop:num`` gives ``num`` equally spaced values from start to stop
    (both included, as :func:`numpy.linspace`). Values that read as whole numbers
    become ints, other numbers floats. The first item varies slowest. A name given
    twice, an empty value list or a bad range is a ValueError.
    """
    names, axes = [], []
    for item in assignments:
        name, sep, values = item.partition("=")
        name = name.strip()
        if not sep or not name or not values.strip():
            raise ValueError(f"{item!r}: expected NAME=V1,V2,... or NAME=START:STOP:NUM")
        if name in names:
            raise ValueError(f"{name!r} is swept twice; give each name once")
        if ":" in values and "," not in values:
            parts = values.split(":")
            try:
                start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
                if len(parts) != 3 or num < 1:
                    raise ValueError
            except (ValueError, IndexError):
                raise ValueError(f"{item!r}: a range is START:STOP:NUM with NUM >= 1 "
                                 "points") from None

            vals = [float(v) for v in np.linspace(start, stop, num)]
        else:
            vals = [_value(v) for v in values.split(",") if v.strip()]
        if not vals:
            raise ValueError(f"{item!r}: no values")
        names.append(name)
        axes.append(vals)
    return [dict(zip(names, combo)) for combo in itertools.product(*axes)]


def point_args(command: str, point: dict, out, extra_args=()) -> list[str]:
    """The ``signorini`` argument list of one grid point."""
    args = [command, "--out", str(out), "-q"]
    for name, value in point.items():
        v = repr(value) if isinstance(value, float) else str(value)
        if name.startswith("-"):
            args += [name, v]
        else:
            args += ["--set", f"{name}={v}"]
    return args + [str(a) for a in extra_args]


# --------------------------------------------------------------------------- tasks

def single_threaded_env() -> None:
    """Before JAX is first imported in this process: one XLA/BLAS thread (a no-op
    afterwards, and for variables already set)."""
    for k, v in WORKER_ENV.items():
        os.environ.setdefault(k, v)


#: a point's record of its completed run (its arguments), beside its summary.json
POINT_RECORD = ".signorini-point.json"


def _recorded(out: Path, args: list[str]) -> dict | None:
    """The result of this point's earlier run with the same arguments, if it
    completed (a converged summary.json and the record): a re-run sweep
    continues from what was recorded instead of running the point again."""
    try:
        rec = json.loads((out / POINT_RECORD).read_text())
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    if rec.get("args") != [str(a) for a in args] or summary.get("status") != "converged":
        return None
    return {"exit_code": 0, "summary": summary, "stderr": "", "stdout": "",
            "time_s": float(rec.get("time_s", 0.0)), "kept": True}


def run_point(args: list[str], out: str, fresh: bool = False) -> dict:
    """One task: ``signorini.app.cli.main(args)`` in this process, with its output captured.

    Returns {"exit_code", "summary" (the point's summary.json or None), "stderr"
    (the last 4000 characters), "time_s"[, "kept"]}. Never raises for a failing
    point. A point that an earlier run with the same arguments completed is not
    run again (``"kept": True``), unless ``fresh``.
    """
    single_threaded_env()
    summary_path = Path(out) / "summary.json"
    if not fresh:
        kept = _recorded(Path(out), args)
        if kept is not None:
            return kept
    for stale in (summary_path, Path(out) / POINT_RECORD):  # an earlier run's, not this one's
        if stale.is_file():
            stale.unlink()
    err, std = _io.StringIO(), _io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std), mkl_threads(1), \
            product_threads(1):
        try:
            code = cli.main(list(args))
        except SystemExit as e:  # argparse usage errors
            code = e.code if isinstance(e.code, int) else 2
        except Exception as e:  # noqa: BLE001  (an unexpected error is this point's failure)
            print(f"signorini: unexpected error: {type(e).__name__}: {e}", file=err)
            code = 3
    if code in (130, 143):  # the point was interrupted (it kept its work): so is the sweep
        raise Interrupted(code - 128)
    summary = None
    if summary_path.is_file():
        try:
            summary = json.loads(summary_path.read_text())
        except (OSError, ValueError):
            summary = None
    elapsed = time.perf_counter() - t0
    if code == 0 and summary is not None:
        with atomic(Path(out) / POINT_RECORD) as tmp:
            tmp.write_text(json.dumps({"args": [str(a) for a in args], "time_s": elapsed}))
    return {"exit_code": int(code), "summary": summary, "stderr": err.getvalue()[-4000:],
            "stdout": std.getvalue()[-4000:], "time_s": elapsed}


@contextlib.contextmanager
def dask_client(scheduler=None, n_workers=None):
    """A :class:`distributed.Client`: to ``scheduler`` if given, else to a new
    LocalCluster of ``n_workers`` single-threaded worker processes (closed on exit)."""
    from distributed import Client, LocalCluster  # lazy: heavy, only Dask runs need it

    if scheduler is not None:
        with Client(scheduler) as client:
            yield client
        return
    n = int(n_workers or os.cpu_count() or 1)
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                      env=dict(WORKER_ENV)) as cluster, Client(cluster) as client:
        yield client


def map_tasks(fn, arglists: list[tuple], *, scheduler=None, n_workers=None, sequential=False,
              client=None) -> list:
    """``[fn(*a) for a in arglists]``, as independent Dask tasks unless ``sequential``.

    The results come back in the order of ``arglists``. ``client``: an open
    :class:`distributed.Client` to use (else one is made by :func:`dask_client`).
    """
    if sequential:
        return [fn(*a) for a in arglists]
    if client is not None:
        futures = [client.submit(fn, *a, pure=False) for a in arglists]
        return client.gather(futures)
    with dask_client(scheduler, n_workers) as c:
        return map_tasks(fn, arglists, client=c)


# --------------------------------------------------------------------------- table

def flatten(d, prefix: str = "") -> dict:
    """A summary as flat {column: scalar} (rules in the module docstring)."""
    out: dict = {}
    if isinstance(d, dict):
        for k, v in d.items():
            out.update(flatten(v, f"{prefix}{k}."))
        return out
    key = prefix[:-1]
    if isinstance(d, (list, tuple)):
        if d and len(d) <= MAX_LIST_ITEMS and not all(isinstance(x, str) for x in d):
            for i, v in enumerate(d):
                out.update(flatten(v, f"{prefix}{i}."))
        else:
            out[f"{key}.len"] = len(d)
        return out
    out[key] = d
    return out


def _reason(res: dict) -> str:
    s = res.get("summary") or {}
    if res["exit_code"] == 0:
        return str(s.get("reason", "")) if s.get("reason") else ""
    if s.get("reason"):
        return str(s["reason"])
    lines = [ln for ln in res.get("stderr", "").splitlines() if ln.strip()]
    errs = [ln for ln in lines if ln.startswith("signorini:") or "error" in ln.lower()]
    return (errs or lines or [f"exit code {res['exit_code']}"])[0]


def _status(res: dict) -> str:
    s = res.get("summary") or {}
    if "status" in s:
        return str(s["status"])
    return {0: "ok", 1: "failed", 2: "bad input"}.get(res["exit_code"], "error")


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return v


def rows(grid_points: list[dict], results: list[dict], dirs: list[str]) -> tuple[list[str], list[dict]]:
    """The CSV header and rows of a sweep."""
    names = list(dict.fromkeys(k for p in grid_points for k in p))
    body_cols: dict = {}
    table = []
    for p, res, d in zip(grid_points, results, dirs):
        flat = {k: v for k, v in flatten(res.get("summary") or {}).items()
                if k not in ("status", "reason")}
        for k in flat:
            body_cols.setdefault(k, None)
        table.append({**p, "exit_code": res["exit_code"], "status": _status(res),
                      "reason": _reason(res), "dir": d, **flat})
    header = names + [c for c in _FIXED if c not in names] + \
        [c for c in body_cols if c not in names and c not in _FIXED]
    return header, table


def write_csv(path, header: list[str], table: list[dict]) -> None:
    with atomic(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, restval="", extrasaction="ignore")
        w.writeheader()
        for r in table:
            w.writerow({k: _cell(v) for k, v in r.items()})


def read_csv(path) -> list[dict]:
    """``sweep.csv`` back as dicts; numbers as int/float, empty cells as None."""
    def conv(x):
        if x == "":
            return None
        return _value(x)
    with open(path, newline="") as f:
        return [{k: conv(v) for k, v in r.items()} for r in csv.DictReader(f)]


# --------------------------------------------------------------------------- sweep

def run_sweep(command: str, grid_points: list[dict], out, *, extra_args=(), scheduler=None,
              n_workers=None, sequential: bool = False, client=None, fresh: bool = False) -> Path:
    """Run ``signorini COMMAND`` at every grid point and collect the summaries.

    Point k runs ``signorini.app.cli.main([command, "--out", out/point_<k>, "-q",
    "--set", "NAME=VALUE", ..., *extra_args])`` (names starting with ``--`` are
    passed as options instead, see the module docstring), as an independent
    Dask task on a LocalCluster (default: ``n_workers`` = os.cpu_count()
    single-threaded processes), on the cluster at ``scheduler``, on an open
    ``client``, or here one after another (``sequential=True``).

    Writes ``out/sweep.csv`` and ``out/sweep.json``; returns the path of the CSV.
    Failing points are recorded (exit code, status, reason), never raised. A
    point that an earlier run of the sweep completed with the same arguments is
    taken from its directory, not run again (``kept`` in sweep.json), unless
    ``fresh``: an interrupted sweep run again continues where it stopped.
    """
    if not grid_points:
        raise ValueError("the grid has no points")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    width = max(1, len(str(len(grid_points) - 1)))
    dirs = [f"point_{k:0{width}d}" for k in range(len(grid_points))]
    arglists = [(point_args(command, p, out / d, extra_args), str(out / d), fresh)
                for p, d in zip(grid_points, dirs)]
    note = ("the points completed so far are kept in their directories: the same sweep run "
            "again continues from them")
    runner.note_run(out, note)
    t0 = time.perf_counter()
    timing.mark("solve")
    try:
        results = map_tasks(run_point, arglists, scheduler=scheduler, n_workers=n_workers,
                            sequential=sequential, client=client)
    except KeyboardInterrupt:
        runner.note_run(out, note)  # a point run here had its own
        raise
    wall = time.perf_counter() - t0
    timing.mark("output")
    header, table = rows(grid_points, results, dirs)
    csv_path = out / "sweep.csv"
    write_csv(csv_path, header, table)
    doc = {
        "command": command,
        "extra_args": [str(a) for a in extra_args],
        "mode": "sequential" if sequential else ("client" if client is not None else
                                                  (f"scheduler {scheduler}" if scheduler else
                                                   f"local cluster, {n_workers or os.cpu_count()} workers")),
        "time_wall_s": wall,
        "n_points": len(grid_points),
        "n_failed": sum(r["exit_code"] != 0 for r in results),
        "points": [{"index": k, "point": p, "dir": d, "args": a[0], "exit_code": r["exit_code"],
                    "status": _status(r), "reason": _reason(r), "time_s": r["time_s"],
                    "kept": bool(r.get("kept", False)),
                    "stderr": r["stderr"], "summary": r["summary"]}
                   for k, (p, d, a, r) in enumerate(zip(grid_points, dirs, arglists, results))],
    }
    t = timing.current()
    if t is not None:
        doc["timings"] = t.split()
    with atomic(out / "sweep.json") as tmp, open(tmp, "w") as f:
        json.dump(doc, f, indent=1, default=_json_default, allow_nan=True)
    return csv_path


def _json_default(o):
    try:

        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
    return str(o)
