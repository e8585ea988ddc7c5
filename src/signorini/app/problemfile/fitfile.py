"""The ``[fit]`` section of a problem file: the parameters to identify (start
values, bounds), the measured curves (CSV files) and the optimiser's settings
(the schema: docs/problem-files.md, "Fits")."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...design.fit import GRADIENTS, METHODS, TIME_TOL
from ...errors import InputError, UnknownParameterError
from .reader import Reader, Table, kind

__all__ = ["FitSpec", "MeasuredCurve", "read_csv", "read_fit"]


@dataclass(frozen=True)
class MeasuredCurve:
    """One measured curve: the [[response]] it measures and its data."""
    response: object  #: the problem file's Response
    file: Path
    times: np.ndarray
    values: np.ndarray
    weights: np.ndarray
    abscissa: np.ndarray  #: the CSV's abscissa (times, or a displacement: times * scale)
    x_label: str
    y_label: str
    against: object = None  #: the [[response]] the abscissa is a value of, or None (load factors)


@dataclass(frozen=True)
class FitSpec:
    """What ``[fit]`` asks for."""
    names: tuple
    start: dict
    bounds: dict
    curves: tuple
    method: str = "least_squares"
    gradient: str = "ddm"
    max_solves: int = 100
    tol: float = 1e-10
    steps: int | None = None


def read_csv(path: Path, x: str, y: str, weight: str | None, label: str, where: str):
    """(x, y, weights or None) columns of a CSV file with a header row; errors name the
    file, the column and the line."""
    if not path.exists():
        raise InputError(f"{label}: {where} file = {path.name!r}: {path} not found")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(f)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{label}: {where} file {path}: cannot read it as CSV text ({e})") from None
    numbered = [(i + 1, [c.strip() for c in r]) for i, r in enumerate(rows)
                if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)]
    if not numbered:
        raise InputError(f"{label}: {where} file {path}: the CSV file is empty")
    header_line, header = numbered[0]
    cols = {}
    for key, name in (("x", x), ("y", y), ("weight", weight)):
        if name is None:
            continue
        if name not in header:
            raise InputError(f"{label}: {where} {key} = {name!r}: no such column in {path} (line "
                             f"{header_line} names {', '.join(map(repr, header))})")
        cols[key] = header.index(name)
    data = {k: [] for k in cols}
    for line, r in numbered[1:]:
        for k, j in cols.items():
            cell = r[j] if j < len(r) else ""
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise InputError(f"{label}: {where} {path.name} line {line}, column {header[j]!r}: "
                                 f"{cell!r} is not a finite number")
            data[k].append(v)
    if not data["x"]:
        raise InputError(f"{label}: {where} file {path}: no data rows after the header")
    xs = np.array(data["x"])
    bad = np.nonzero(np.diff(xs) <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        line = numbered[k + 1][0]
        raise InputError(f"{label}: {where} {path.name} line {line}, column {x!r}: the abscissae "
                         f"must increase; {float(xs[k])!r} follows {float(xs[k - 1])!r}")
    w = np.array(data["weight"]) if "weight" in data else None
    return xs, np.array(data["y"]), w


def _parameters(rd: Reader, data):
    where = "[fit.parameters]"
    if not isinstance(data, dict) or not data:
        raise rd.error("[fit]", "parameters: expected a table name = {start = ..., bounds = "
                                "[low, high]} with at least one parameter", key="parameters")
    start, bounds = {}, {}
    for name, v in data.items():
        if name not in rd.params:
            raise rd.error(where, f"{name!r} is not a parameter (defined in [params]: "
                                  f"{', '.join(sorted(rd.params))}); a fitted parameter needs its "
                                  "nominal value there", UnknownParameterError, key=name)
        t = Table(rd, f"{where} {name}", v, {"start", "bounds"})
        start[name] = t.real("start", rd.params[name])
        b = t.get("bounds", None)
        if b is None:
            bounds[name] = (-math.inf, math.inf)
            continue
        if not (isinstance(b, list) and len(b) == 2):
            raise t.err("bounds", f"expected [low, high], got {kind(b)}")
        lo, hi = (t.real("bounds", value=x) for x in b)
        if not lo < hi or not lo <= start[name] <= hi:
            raise t.err("bounds", f"need low < high with the start {start[name]} between them, "
                                  f"got [{lo}, {hi}]")
        bounds[name] = (lo, hi)
    return tuple(start), start, bounds


def _curve(rd: Reader, k: int, data, responses) -> MeasuredCurve:
    where = f"[[fit.curve]] #{k + 1}"
    t = Table(rd, where, data, {"response", "file", "x", "y", "weight", "scale", "abscissa"},
              required=("response", "file", "y"))
    byname = {r.name: r for r in responses}

    def named(key):
        rname = t.string(key)
        if rname not in byname:
            raise t.err(key, f"{rname!r} is not the name of a [[response]] (they are "
                             f"{', '.join(byname) or 'none'})")
        try:
            byname[rname].public()
        except InputError as e:
            raise t.err(key, f"{e}") from None
        return byname[rname]
    resp = named("response")
    against = named("abscissa") if t.has("abscissa") else None
    if against is not None and t.has("scale"):
        raise t.err("scale", "an abscissa measured as a response's values takes no scale")
    f = Path(t.string("file"))
    if not f.is_absolute():
        f = rd.path.parent / f
    xname, yname = t.string("x", "t"), t.string("y")
    w = t.get("weight", None)
    wcol = w if isinstance(w, str) and w != "relative" else None
    if w is not None and not isinstance(w, str):
        t.real("weight", positive=True)
    scale = t.real("scale", 1.0, positive=True)
    xs, ys, wc = read_csv(f, xname, yname, wcol, rd.label, where)
    times = xs / scale
    if against is None and (times[0] <= 0 or times[-1] > 1 + TIME_TOL):
        raise t.err("x", f"the abscissae of {f.name} divided by scale = {scale:g} are load factors "
                         f"of the path, in (0, 1]; got {times[0]:.6g} .. {times[-1]:.6g}")
    if wc is not None:
        if np.any(wc < 0):
            raise t.err("weight", f"column {wcol!r} of {f.name} has a negative weight")
        weights = wc
    elif w == "relative":  # relative residuals: each curve counts alike
        peak = float(np.abs(ys).max())
        if not peak > 0:
            raise t.err("weight", f"\"relative\" divides by the largest |{yname}|, which is 0")
        weights = np.full(ys.size, 1.0 / peak ** 2)
    else:
        weights = np.full(ys.size, 1.0 if w is None else float(w))
    return MeasuredCurve(resp, f, times, ys, weights, xs, xname, yname, against)


def read_fit(rd: Reader, data, responses) -> FitSpec:
    t = Table(rd, "[fit]", data, {"parameters", "curve", "method", "gradient", "max_solves", "tol",
                                           "steps"},
              required=("parameters", "curve"))
    names, start, bounds = _parameters(rd, data["parameters"])
    items = data["curve"]
    if isinstance(items, dict):
        raise t.err("curve", "write each curve as a [[fit.curve]] table (double brackets)")
    if not isinstance(items, list) or not items or not all(isinstance(c, dict) for c in items):
        raise t.err("curve", f"expected [[fit.curve]] tables, got {kind(items)}")
    curves = tuple(_curve(rd, k, c, responses) for k, c in enumerate(items))
    tol = t.real("tol", 1e-10, positive=True)
    if not tol < 1:
        raise t.err("tol", f"must be below 1, got {tol}")
    method = t.string("method", "least_squares", choices=METHODS)
    gradient = t.string("gradient", "ddm", choices=GRADIENTS)
    if gradient == "adjoint" and method != "L-BFGS-B":
        raise t.err("gradient", 'the adjoint gradient is for method = "L-BFGS-B" (least squares '
                    "uses the residuals' Jacobian, from the DDM)")
    return FitSpec(names=names, start=start, bounds=bounds, curves=curves,
                   method=method, gradient=gradient,
                   max_solves=t.integer("max_solves", 100, minimum=1), tol=tol,
                   steps=t.integer("steps", None, minimum=1) if t.has("steps") else None)
