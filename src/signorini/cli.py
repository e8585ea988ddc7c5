"""The ``signorini`` command.

    signorini hertz --out DIR [--set NAME=VALUE ...] [--refine N] [--method al|penalty]
                    [--finite-strain] [--steps N] [--no-fd] [--solver superlu|pardiso|umfpack]
    signorini hertz-friction --out DIR [--set NAME=VALUE ...] [--refine N] [--steps 3k]
                    [--no-fd] [--solver ...]
    signorini hertz-friction --out DIR [--set NAME=VALUE ...] [--refine N] [--steps N] [--no-fd]
"""

from __future__ import annotations

import argparse
import logging
import sys

from .errors import SignoriniError
from .params import parse_assignment


def _common(p: argparse.ArgumentParser):
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override a named parameter (repeatable), e.g. --set R=2")
    p.add_argument("--refine", type=int, default=0, help="mesh refinement level (0 = default)")
    p.add_argument("--steps", type=int, default=1, help="number of load increments")
    p.add_argument("--solver", default="superlu", choices=["superlu", "pardiso", "umfpack"],
                   help="sparse direct solver (pardiso needs pypardiso, umfpack scikit-umfpack)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="signorini", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    h = sub.add_parser("hertz", help="frictionless plane-strain Hertz benchmark (paper 5.1)")
    _common(h)
    h.add_argument("--method", choices=["al", "penalty"], default="al")
    h.add_argument("--finite-strain", action="store_true", help="neo-Hookean block, finite kinematics")
    h.add_argument("--no-fd", action="store_true", help="skip the finite-difference check")
    f = sub.add_parser("hertz-friction", help="frictional plane-strain Hertz benchmark (paper 5.2)")
    _common(f)
    f.set_defaults(steps=30)  # a multiple of 3: P1, P2, P3 are increments
    f.add_argument("--no-fd", action="store_true", help="skip the finite-difference check")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="%(message)s", stream=sys.stderr)
    try:
        params = dict(parse_assignment(s) for s in args.set)
        if args.command == "hertz":
            from .problems import hertz

            s = hertz.run(args.out, params, refine=args.refine, method=args.method,
                          finite_strain=args.finite_strain, steps=args.steps, fd_check=not args.no_fd,
                          solver=args.solver)
            print(f"Hertz ({args.method}, {s['mesh']['dofs']} DOFs): p0 = {s['p0']['computed']:.5g} "
                  f"(analytical {s['p0']['analytical']:.5g}, error {100 * s['p0']['rel_error']:+.2f} %), "
                  f"a = {s['a']['computed']:.4g} (analytical {s['a']['analytical']:.4g}); "
                  f"Newton iterations {s['newton_iterations']}; DDM vs FD {s['ddm_vs_fd_rel_diff']}")
            print(f"results in {args.out}/")
        elif args.command == "hertz-friction":
            from .problems import hertz_friction

            s = hertz_friction.run(args.out, params, refine=args.refine, steps=args.steps,
                                   fd_check=not args.no_fd, solver=args.solver)
            ca = ", ".join(f"{v:.3f}" for v in s["c_over_a"])
            print(f"frictional Hertz ({s['mesh']['dofs']} DOFs, {s['steps']} increments): "
                  f"c/a at P1, P2, P3 = {ca}; Newton iterations {sum(s['newton_iterations'])} "
                  f"in total; DDM vs FD at P3 {s['ddm_vs_fd_rel_diff_P3']}")
            print(f"results in {args.out}/")
    except SignoriniError as e:
        print(f"signorini: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
