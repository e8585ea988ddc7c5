"""``signorini fit``: the parameters of a problem file's ``[fit]`` identified from
its measured curves (:func:`signorini.fit`)."""

from __future__ import annotations

import sys

from .. import problemfile
from ..options import Formatter, solver_options

NAME = "fit"


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    r = sub.add_parser(
        "fit", formatter_class=Formatter, help="identify parameters of a TOML problem file from "
                                               "measured curves",
        description="Fit the [fit] parameters of a TOML problem file to its measured curves (CSV "
                    "files: a response against the load factor or a displacement), minimising "
                    "the misfit over the whole load path with exact DDM gradients "
                    "(signorini.fit; docs/problem-files.md, Fits). Writes fit.json (fitted values, "
                    "standard errors, correlation matrix, warnings when ill-conditioned), "
                    "fit_history.csv, fitted.toml, the measured and fitted curves (curve_*.csv) "
                    "and the figure fit.png into --out. Ctrl-C keeps the history; --resume "
                    "continues it.")
    r.add_argument("file", metavar="FILE", help="the problem file (.toml) with a [fit] section")
    r.add_argument("--out", required=True, metavar="DIR", help="output directory")
    r.add_argument("--resume", action="store_true",
                   help="continue the fit whose history (fit_history.json) is in --out from its "
                        "last point")
    solver_options(r)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    quiet = getattr(args, "quiet", False)

    def progress(row):
        if not quiet:
            x = ", ".join(f"{v:.8g}" for v in row["x"])
            print(f"  iteration {row['iteration']:3d}: misfit {row['F']:.6e}, |grad| "
                  f"{row['grad_norm']:.3e}, x = [{x}], {row['solves']} solves", flush=True)

    s = problemfile.fit(args.file, args.out, solver=args.solver, progress=progress,
                        resume=args.resume, force_size=args.force_size)
    print(f"{args.file}: {'converged' if s['success'] else 'NOT converged'} ({s['message']}), "
          f"{s['iterations']} iterations, {s['n_solves']} solves, misfit {s['misfit']:.6g}")
    for n in s["names"]:
        se = s["stderr"][n]
        print(f"  {n} = {s['values'][n]:.9g}  (start {s['start'][n]:.6g}, std error "
              f"{'nan' if se is None else f'{se:.3g}'})")
    if s["warnings"]:
        print(f"{len(s['warnings'])} warning(s), also in fit.json:", file=sys.stderr)
        for w in s["warnings"]:
            print(f"  - {w}", file=sys.stderr)
    print(f"results in {args.out.rstrip('/')}/")
    return 0
