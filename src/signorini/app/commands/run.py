"""``signorini run``: the problem of a TOML problem file."""

from __future__ import annotations

from .. import problemfile
from ..options import Formatter, finish, newton_options, solver_options

NAME = "run"


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    r = sub.add_parser(
        "run", formatter_class=Formatter, help="solve a problem described in a TOML file",
        description="Solve the problem of a TOML problem file (mesh, material, obstacle, loads, "
                    "contact law, increments, sensitivities, outputs; see docs/problem-files.md) "
                    "and write summary.json, contact tables, VTU and a .pvd series into --out.")
    r.add_argument("file", metavar="FILE", help="the problem file (.toml)")
    r.add_argument("--out", required=True, metavar="DIR", help="output directory")
    newton_options(r, None)  # default: the file's [solve] rtol and max_iter
    solver_options(r)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    s = problemfile.run(args.file, args.out, solver=args.solver, force_size=args.force_size,
                        rtol=args.rtol, max_iter=args.max_iter)
    print(f"{args.file}: {s['status']}, {s['increments']} increment(s), "
          f"{s['mesh'].get('dofs', '?')} DOFs, Newton iterations {s['newton_iterations']}")
    for name, r in s.get("responses", {}).items():
        sens = ", ".join(f"d/d{k} {v:.6g}" for k, v in r.get("sensitivities", {}).items())
        print(f"  {name} = {r['value']:.6g}" + (f"  ({sens})" if sens else ""))
    return finish(args, s)
