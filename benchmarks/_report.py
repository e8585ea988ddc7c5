"""Shared output of the benchmark scripts: a printed table and a CSV file."""

from __future__ import annotations

import csv
from pathlib import Path


def report(rows: list[dict], out, width: int = 12) -> None:
    """Print ``rows`` as a table (one column per key) and write them to ``out`` (CSV)."""
    keys = list(dict.fromkeys(k for r in rows for k in r))  # union, in order of appearance
    print()
    print(" | ".join(f"{k:>{width}.{width}s}" for k in keys))
    for r in rows:
        vals = [r.get(k, "") for k in keys]
        print(" | ".join(f"{v:>{width}.4g}" if isinstance(v, float) else f"{v!s:>{width}.{width}s}"
                         for v in vals))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=keys)
        wr.writeheader()
        wr.writerows(rows)
    print(f"\nwritten {out}")


def solves_by_column(lin, n: int) -> str:
    """PARDISO: "c/m": of the m solves of several columns (the DDM's) on the pattern
    of n unknowns, c went column by column, the handle's timings having found the
    block slower (``signorini.linsolve._Handle.solve``); "" for other solvers."""
    for h in getattr(lin, "_handles", {}).values():
        if h.n == n:
            return f"{h.column_solves}/{h.multi_solves}"
    return ""
