"""``signorini sweep``: a command over a grid of parameter values, one Dask task
per point, collected into sweep.csv and sweep.json."""

from __future__ import annotations

import sys

from ...errors import InputError
from .. import registry, sweep
from ..options import Formatter, dask_options

NAME = "sweep"


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    sw = sub.add_parser(
        "sweep", formatter_class=Formatter,
        help="run a command over a grid of parameter values as independent Dask tasks",
        description="Run COMMAND once per point of the grid (the Cartesian product of the --set "
                    "and --option lists), each as an independent task on Dask (a local cluster "
                    "over the machine's cores by default, or --scheduler ADDRESS), and collect "
                    "every summary.json into DIR/sweep.csv (one row per point; nested entries "
                    "flattened with dots) and DIR/sweep.json. A failing point is recorded with "
                    "its exit code and reason; the sweep goes on. Arguments after -- are passed "
                    "to every run, e.g.: signorini sweep hertz --out s --set R=1,1.5,2 -- --no-fd")
    sw.add_argument("sweep_command", metavar="COMMAND",
                    choices=registry.SWEEPABLE + tuple(registry.RENAMED),
                    help="the command to run at every point")
    sw.add_argument("--out", required=True, metavar="DIR", help="output directory")
    sw.add_argument("--set", action="append", default=[], metavar="NAME=V1,V2,...",
                    help="values of a --set parameter (repeatable); START:STOP:NUM for a linspace")
    sw.add_argument("--option", action="append", default=[], metavar="NAME=V1,V2,...",
                    help="values of a command option, e.g. refine=0,1 (passed as --refine 0 ...)")
    sw.add_argument("--fresh", action="store_true",
                    help="run every point again (by default a point that an earlier run of the "
                         "same sweep completed, with the same arguments, is taken from its "
                         "directory: an interrupted sweep run again continues where it stopped)")
    dask_options(sw)
    v = sw.add_mutually_exclusive_group()
    v.add_argument("-q", "--quiet", action="store_true", help="print only errors and the result")
    v.add_argument("-v", "--verbose", action="store_true", help="log more")


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    args.sweep_command, notice = registry.current_name(args.sweep_command)
    if notice:
        print(f"signorini: {notice}", file=sys.stderr)
    try:
        points = sweep.grid(args.set + ["--" + o for o in args.option])
    except ValueError as e:
        raise InputError(f"sweep: {e}") from None
    csv_path = sweep.run_sweep(args.sweep_command, points, args.out, extra_args=args.extra,
                               scheduler=args.scheduler, n_workers=args.workers,
                               sequential=args.sequential, fresh=args.fresh)
    table = sweep.read_csv(csv_path)
    failed = [r for r in table if str(r.get("exit_code")) not in ("0", "0.0")]
    print(f"sweep of {args.sweep_command}: {len(table)} points, {len(failed)} failed; "
          f"table in {csv_path}")
    return 1 if failed else 0
