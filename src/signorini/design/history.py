"""The evaluations of an optimisation: one :class:`Evaluation` per solve, and
the history CSV an :class:`~signorini.design.optimize.Objective` appends to as
it goes (so that an interrupted optimisation can be resumed from it)."""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError


@dataclass
class Evaluation:
    """One solve of the objective at a design point.

    Attributes:
        index: 1-based number of the evaluation (continues an appended history).
        kind: ``"value+gradient"`` (DDM: one solve gives both), ``"value"``
            (``gradient_mode="fd"``: the value at a design point) or ``"fd"``
            (a perturbed point of a finite-difference gradient).
        x: the design point (parameter values, in the order of ``names``).
        F: the value returned to the optimiser (``F_fail`` when failed).
        grad: the gradient returned (None for ``"value"``/``"fd"`` kinds).
        status: ``"ok"``, ``"failed"`` (Newton did not converge) or ``"invalid"``
            (the design was rejected: inverted elements, ``validate``).
        reason: the error message of a failure.
        newton_iterations: Newton iterations of the solve, over all attempted
            increments (cut ones included).
        increments: converged load increments.
        cuts: increments that failed and were cut (the load path then differs
            from the nominal one; the gradient is that of the path taken).
        time: wall time of the evaluation [s].
        warnings: warnings of the solve (``Solution.warnings``).
    """

    index: int
    kind: str
    x: np.ndarray
    F: float
    grad: np.ndarray | None
    status: str
    reason: str = ""
    newton_iterations: int = 0
    increments: int = 0
    cuts: int = 0
    time: float = 0.0
    warnings: list = field(default_factory=list)
    error: BaseException | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def grad_norm(self) -> float:
        return float(np.linalg.norm(self.grad)) if self.grad is not None else math.nan



def columns(names: Sequence[str]) -> list[str]:
    """The columns of a history CSV for design parameters ``names``."""
    return (["eval", "kind", "status", "F", "grad_norm"] + [f"x_{n}" for n in names]
            + [f"dF_d{n}" for n in names]
            + ["newton_iterations", "increments", "cuts", "time_s", "reason"])


def write_header(path: Path, names: Sequence[str]) -> None:
    """Start a history CSV (overwrites)."""
    with open(path, "w", newline="") as f:
        csv.writer(f).writerow(columns(names))


def row(r: Evaluation, names: Sequence[str]) -> list:
    """One evaluation as a CSV row (x and F written to round-trip exactly, for resuming)."""
    g = r.grad if r.grad is not None else [math.nan] * len(names)
    num = lambda v: repr(float(v) + 0.0)  # noqa: E731
    return ([r.index, r.kind, r.status, num(r.F), num(r.grad_norm)] + [num(v) for v in r.x]
            + [num(v) for v in g] + [r.newton_iterations, r.increments, r.cuts, f"{r.time:.4f}",
                                     r.reason.splitlines()[0] if r.reason else ""])


def append_rows(path: Path, names: Sequence[str], records) -> None:
    """Append evaluations to a history CSV, each row in one write, flushed to
    the disk (an interrupted run loses at most the row being written, which
    :func:`read_history` then leaves out)."""
    buf = io.StringIO()
    wr = csv.writer(buf)
    with open(path, "a", newline="") as f:
        for r in records:
            buf.seek(0)
            buf.truncate()
            wr.writerow(row(r, names))
            f.write(buf.getvalue())
            f.flush()
            os.fsync(f.fileno())


def _complete(r: dict) -> bool:
    """A row with every column (csv.DictReader fills the missing ones with None)."""
    return None not in r.values() and None not in r


def read_history(path, names: Sequence[str] | None = None) -> list[Evaluation]:
    """The evaluations of a history CSV written by an :class:`Objective`
    (``names``: the parameter order; default the file's ``x_*`` columns)."""
    path = Path(path)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return []
    if names is None:
        names = [c[2:] for c in rows[0] if c.startswith("x_")]
    missing = [n for n in names if f"x_{n}" not in rows[0]]
    if missing:
        raise InputError(f"the history {str(path)!r} has no column for {missing}")
    out = []
    if rows and not _complete(rows[-1]):  # a row cut short by an interrupted run
        rows = rows[:-1]
    for r in rows:
        grad = np.array([float(r[f"dF_d{n}"]) for n in names])
        out.append(Evaluation(int(r["eval"]), r["kind"], np.array([float(r[f"x_{n}"]) for n in names]),
                              float(r["F"]), None if np.all(np.isnan(grad)) else grad, r["status"],
                              r.get("reason", ""), int(r["newton_iterations"]), int(r["increments"]),
                              int(r.get("cuts") or 0), float(r["time_s"])))
    return out
