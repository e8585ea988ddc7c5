"""Running the ``[fit]`` of a problem file (``signorini fit FILE --out DIR``):
:func:`signorini.fit` on the file's problem and measured curves, its history
kept as it goes (an interrupt keeps it; ``resume`` continues from its last
point), and the files: ``fit.json``, ``fit_history.csv``, ``fitted.toml``,
``curves.csv`` and the figure ``fit.png`` (measured against fitted curves)."""

from __future__ import annotations

import dataclasses
import json
import math
import time
import warnings
from pathlib import Path

import numpy as np

from ...design.fit import Curve, fit_steps
from ...design.fit import fit as fit_curves
from ...errors import InputError, SignoriniWarning
from ...post import files as io
from ...post.plots import save, subplots
from ..runner import note_run, prepare_output
from .run import check_file_size
from .schema import load

__all__ = ["HISTORY", "fit"]

#: the history kept after every iteration (and read by ``resume``)
HISTORY = "fit_history.json"


def _num(v):
    v = float(v)
    return v if math.isfinite(v) else None


def _previous(out: Path, names) -> list:
    f = out / HISTORY
    if not f.exists():
        raise InputError(f"--resume: {f} not found; there is no fit to continue in {out} (run "
                         "without --resume first)")
    try:
        data = json.loads(f.read_text())
        rows = data["history"]
        if data["names"] != list(names) or not rows:
            raise ValueError("another fit's parameters")
    except (ValueError, KeyError, TypeError) as e:
        raise InputError(f"--resume: {f} is not the history of this fit ({e})") from None
    return rows


def _write_history(out: Path, names, rows: list, status: str) -> None:
    io.write_json(out / HISTORY, {"names": list(names), "status": status, "history": rows})
    cols = {"iteration": [r["iteration"] for r in rows], "F": [r["F"] for r in rows],
            "grad_norm": [r["grad_norm"] for r in rows], "solves": [r["solves"] for r in rows]}
    for i, n in enumerate(names):
        cols[n] = [r["x"][i] for r in rows]
    io.write_csv(out / "fit_history.csv", cols)


def _figure(out: Path, spec, res) -> Path:
    n = len(spec.curves)
    fig, axes = subplots(1, n, figsize=(4.6 * n, 3.6), dpi=120, squeeze=False)
    for ax, c, y in zip(axes[0], spec.curves, res.fitted):
        ax.plot(c.abscissa, c.values, "o", ms=4, mfc="none", label="measured")
        ax.plot(c.abscissa, y, "-", lw=1.5, label="fitted")
        ax.set_xlabel(c.x_label)
        name = c.response.name
        ax.set_ylabel(name if c.y_label == name else f"{name} ({c.y_label})")
        ax.grid(alpha=0.3)
        ax.legend()
    vals = ", ".join(f"{k} = {v:.6g}" for k, v in res.values.items())
    fig.suptitle(f"fit: {vals}", fontsize=9)
    fig.tight_layout()
    return save(fig, out / "fit.png")


def fit(path, out, *, solver="auto", progress=None, resume: bool = False,
        force_size: bool = False) -> dict:
    """Fit the ``[fit]`` parameters of a problem file to its measured curves.

    Args:
        path: the TOML file (with ``[fit]``; docs/problem-files.md).
        out: output directory.
        solver: linear solver of the solves.
        progress: ``progress(row)`` after every iteration (its history row).
        resume: continue the fit whose history is in ``out`` from its last point
            (the new iterations are appended to it).
        force_size: run even if the mesh is estimated not to fit in memory.

    Returns:
        The content of ``fit.json``.

    Raises:
        InputError: an invalid file, or a file without ``[fit]``.
        ConvergenceError: the solve at the start failed.
        KeyboardInterrupt: after writing the history so far.
    """
    t0 = time.perf_counter()
    problem, cfg = load(path, force_size=force_size, solver=solver)
    spec = cfg.fit
    if spec is None:
        raise InputError(f"{cfg.path}: no [fit] section; add [fit.parameters] and [[fit.curve]] "
                         "tables (docs/problem-files.md, Fits) or use signorini run")
    out = prepare_output(out)
    note_run(out, f"the fit's history so far is kept in {HISTORY} and fit_history.csv; "
                  f"signorini fit {cfg.path} --out {out} --resume continues it")
    names = list(spec.names)
    before = _previous(out, names) if resume else []
    start = dict(zip(names, before[-1]["x"])) if before else dict(spec.start)
    rows = list(before)
    offset = (before[-1]["iteration"] + 1) if before else 0

    def callback(row):
        if before and row["iteration"] == 0:
            return  # the resumed start is the last row already kept
        row = dict(row, iteration=row["iteration"] + offset - (1 if before else 0))
        rows.append(row)
        _write_history(out, names, rows, "running")
        if progress is not None:
            progress(row)

    curves = [Curve(c.response.public(), c.times, c.values, c.weights,
                    None if c.against is None else c.against.public()) for c in spec.curves]
    if spec.steps is None and all(c.against is not None for c in spec.curves):
        raise InputError(f"{cfg.path}: [fit] steps: every curve is measured against an abscissa "
                         "response, so the increments cannot come from the load factors: give "
                         "[fit] steps")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", SignoriniWarning)
            # the solves' size: the fit's increments and its parameters' sensitivities
            check_file_size(problem, dataclasses.replace(
                cfg, steps=fit_steps(curves, spec.steps), sensitivities=tuple(names)),
                force=force_size, solver=solver)
            res = fit_curves(problem, names, curves, start=start, bounds=spec.bounds, steps=spec.steps,
                             method=spec.method, gradient=spec.gradient, tol=spec.tol,
                             max_solves=spec.max_solves,
                             options=cfg.options, solver=solver, callback=callback)
    except KeyboardInterrupt:
        _write_history(out, names, rows, "interrupted")
        raise
    except InputError as e:
        if type(e) is InputError:  # found when the model is built: say which file
            raise InputError(f"{cfg.path}: {e}") from None
        raise
    _write_history(out, names, rows, "converged" if res.success else "stopped")
    said = list(dict.fromkeys([*cfg.warnings, *res.warnings, *(str(w.message) for w in caught
                                                                if issubclass(w.category, SignoriniWarning))]))
    ill = [w for w in said if any(k in w for k in ("ill-conditioned", "singular", "correlated",
                                                   "do not depend"))]
    summary = {
        "file": str(cfg.path), "title": cfg.title, "success": res.success, "message": res.message,
        "method": res.method, "names": names, "values": res.values,
        "start": dict(zip(names, before[0]["x"])) if before else res.start,
        "bounds": {n: [_num(a), _num(b)] for n, (a, b) in zip(names, res.bounds)},
        "stderr": {n: _num(v) for n, v in res.stderr.items()},
        "correlation": [[_num(v) for v in row] for row in np.asarray(res.correlation)],
        "covariance": [[_num(v) for v in row] for row in np.asarray(res.covariance)],
        "condition": _num(res.condition), "sigma": _num(res.sigma), "misfit": _num(res.misfit),
        "n_data": res.n_data, "n_solves": res.n_solves, "n_failed": res.n_failed,
        "iterations": len(rows) - 1, "resumed": bool(before), "ill_conditioned": bool(ill),
        "warnings": said,
        "curves": [{"response": c.response.name, "file": str(c.file), "points": int(c.times.size),
                    "misfit": _num(np.sum(c.weights * (np.asarray(y) - c.values) ** 2))}
                   for c, y in zip(spec.curves, res.fitted)],
        "history": [{"iteration": r["iteration"], "F": r["F"], "x": r["x"]} for r in rows],
    }
    for c, y in zip(spec.curves, res.fitted):
        first = {c.x_label: c.abscissa} if c.against is not None else {
            "t": c.times, **({c.x_label: c.abscissa} if c.x_label != "t" else {})}
        cols = {**first,
                "measured": c.values, "fitted": np.asarray(y), "weight": c.weights}
        io.write_csv(out / f"curve_{c.response.name}.csv", cols)
    (out / "fitted.toml").write_text(
        "# the fitted values (paste into [params] to run the fitted problem)\n[params]\n"
        + "".join(f"{n} = {v!r}\n" for n, v in res.values.items()))
    _figure(out, spec, res)
    summary["outputs"] = ["fit.json", HISTORY, "fit_history.csv", "fitted.toml", "fit.png"] + \
        [f"curve_{c.response.name}.csv" for c in spec.curves]
    summary["time_wall_s"] = time.perf_counter() - t0
    io.write_json(out / "fit.json", summary)
    return summary
