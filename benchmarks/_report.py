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


def solves_by_column(lin, n: int) -> dict:
    """PARDISO, on the pattern of n unknowns: of the m solves of several columns (the
    DDM's), how many went column by column ("c/m"), the handle's timings having found
    the block slower (``signorini.linsolve._Handle.solve``), and the fastest recent
    solve of one column and of a block of three (ms): they show the machine's state.
    Empty for other solvers."""
    for h in getattr(lin, "_handles", {}).values():
        if h.n == n:
            block = h.blocks.get(3)
            return {"ddm_solves_by_column": f"{h.column_solves}/{h.multi_solves}",
                    "pardiso_one_column_ms": 1e3 * min(h.single) if h.single else "",
                    "pardiso_three_columns_ms": 1e3 * min(block) if block else ""}
    return {"ddm_solves_by_column": "", "pardiso_one_column_ms": "", "pardiso_three_columns_ms": ""}
