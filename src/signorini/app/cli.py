"""The ``signorini`` command: the paper's benchmarks and problem files.

Exit codes: 0 success, 1 the solve failed (converged increments and
``summary.json`` with ``"status": "failed"`` are written), 2 bad input.
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings

from ..errors import ConvergenceError, InputError, SignoriniError, SignoriniWarning

UNITS = "Units: mm, N/mm (force per unit thickness), N/mm² (MPa)."

HERTZ_SET = {
    "E": "Young's modulus [N/mm²], default 100",
    "nu": "Poisson's ratio, default 0.3",
    "P": "load per unit thickness [N/mm], default 1.2",
    "R": "cylinder radius [mm], default 1",
    "eps": "augmentation/penalty parameter [N/mm³], default E0/h (nominal E0, contact cell h)",
    "bump": "shape parameter: amplitude of a crown on the top face [mm], default 0",
}
FRICTION_SET = {
    "E": "Young's modulus [N/mm²], default 100",
    "nu": "Poisson's ratio, default 0.3",
    "P": "final load per unit thickness [N/mm], default 1.5",
    "R": "cylinder radius [mm], default 10",
    "mu": "Coulomb friction coefficient, default 0.3",
    "eps": "normal augmentation parameter [N/mm³], default E0/h",
    "eps_t": "tangential augmentation parameter [N/mm³], default eps",
    "bump": "shape parameter: amplitude of a crown on the top face [mm], default 0",
}


class _Formatter(argparse.HelpFormatter):
    """Shows '(default: X)' only where there is a meaningful default."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if (d not in (None, False, [], argparse.SUPPRESS) and "%(default)" not in text
                and action.option_strings):
            text += " (default: %(default)s)"
        return text


FORGING_SET = {
    **{f"phi{k}": f"Bezier control radius {k} of the preform [h0], default 0.7 (cylinder)"
       for k in range(5)},
    "mu": "Coulomb friction coefficient on the die, default 0.2",
    "sigma_y": "initial yield stress, default 100",
    "H": "linear isotropic hardening modulus, default 0",
    "E": "Young's modulus, default 1e4",
    "nu": "Poisson's ratio, default 0.3",
    "stroke": "die travel [h0], default 0.5 (50 %% height reduction)",
    "eps": "normal augmentation parameter, default E0/h0",
    "eps_t": "tangential augmentation parameter, default eps",
}


def _whole_number(least: int):
    """argparse type: a whole number >= least, with a message that says so."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if v < least:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {least}, got {text!r}")
        return v
    return parse


_positive_int = _whole_number(1)
_nonneg_int = _whole_number(0)


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return v


def parse_sets(items: list[str], allowed: dict) -> dict:
    """``--set NAME=VALUE`` items -> {name: float}; unknown, repeated, non-numeric
    or non-finite values are errors that name the item."""
    from ..params import parse_assignment

    out: dict[str, float] = {}
    for text in items:
        name, value = parse_assignment(text)
        if name not in allowed:
            raise InputError(f"--set {text}: unknown parameter {name!r}; this command accepts "
                             f"{', '.join(allowed)}")
        if name in out:
            raise InputError(f"--set {name} is given twice ({out[name]:g} and {value:g}); give "
                             "each parameter once")
        if value != value or abs(value) == float("inf"):
            raise InputError(f"--set {text}: the value must be a finite number")
        out[name] = value
    return out


def _set_help(allowed: dict) -> str:
    first = next(iter(allowed))
    return (f"set a named parameter (repeatable), e.g. --set {first}=1.5. Names: " +
            "; ".join(f"{k} = {v}" for k, v in allowed.items()) + ". The mesh never changes with "
            "these values (it is built from the defaults and the mesh options), so finite "
            "differences of two runs equal the printed DDM sensitivities.")


def _common(p: argparse.ArgumentParser, allowed: dict, steps: int, steps_help: str, a0: float,
            block: float = 20.0):
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (created if needed; must be writable)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help=_set_help(allowed))
    p.add_argument("--refine", type=_nonneg_int, default=0, metavar="N",
                   help="halve every cell N times (each level: 4x the unknowns)")
    p.add_argument("--block", type=_positive_float, default=block, metavar="B",
                   help=f"block width and depth, in units of the nominal contact half-width a0 "
                        f"(a0 = {a0:.4g} mm: Hertz's half-width at the default parameters)")
    p.add_argument("--zone-width", type=_positive_float, default=1.5, metavar="Z",
                   help="width of the uniformly fine mesh zone at the contact, in units of a0")
    p.add_argument("--steps", type=_positive_int, default=steps, metavar="N", help=steps_help)
    p.add_argument("--finite-strain", action="store_true",
                   help="neo-Hookean block with finite contact kinematics (default: linear "
                        "elasticity, linearised contact kinematics as in Hertz's theory)")
    p.add_argument("--no-fd", action="store_true",
                   help="skip the check of the DDM sensitivities by central finite differences "
                        "(saves two re-solves per parameter)")
    _solver_options(p)


def _forging_mesh_options(p):
    p.add_argument("--mesh", default="10x20", metavar="NRxNZ",
                   help="cells in the radial and axial directions")
    p.add_argument("--steps", type=_positive_int, default=50, metavar="N",
                   help="equal increments of the die stroke in every forging solve")


def _dask_options(p):
    g = p.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing Dask scheduler (default: a local cluster)")
    g.add_argument("--sequential", action="store_true", help="run the tasks here, one after another")
    p.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                   help="workers of the local cluster (default: the number of cores)")


def _adjoint_option(p, response: str):
    p.add_argument("--adjoint", action="store_true",
                   help=f"also compute the adjoint gradient of {response} (one backward pass "
                        "over the increments) with respect to the same parameters and every "
                        "nodal coordinate; written next to the DDM gradient in summary.json "
                        "('adjoint'), shape_gradient.csv and the VTU field adjoint_shape_gradient")


def _coarse_start_option(p):
    p.add_argument("--no-coarse-start", action="store_true",
                   help="start Newton from the undeformed state (later increments from the "
                        "extrapolating predictor) instead of from coarser meshes solved along the "
                        "same load path, interpolated (the result is the same)")


def _solver_options(p):
    p.add_argument("--solver", default="auto", choices=["auto", "pardiso", "superlu", "umfpack"],
                   help="sparse direct solver; auto (default) = the fastest installed: pardiso "
                        "(MKL, installed with signorini on x86-64), else superlu (SciPy)")
    p.add_argument("--force-size", action="store_true",
                   help="run even if the estimated memory exceeds what is available")
    v = p.add_mutually_exclusive_group()
    v.add_argument("-q", "--quiet", action="store_true", help="print only errors and the result line")
    v.add_argument("-v", "--verbose", action="store_true",
                   help="log every increment and Newton iteration instead of progress bars")


def _a0(name: str) -> float:
    import importlib

    from ..problems.hertz import analytical

    d = importlib.import_module(f"signorini.problems.{name}").DEFAULTS
    return float(analytical(d["P"], d["R"], d["E"], d["nu"])["a"])


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    fmt = _Formatter
    parser = argparse.ArgumentParser(
        prog="signorini", formatter_class=fmt,
        description="Contact mechanics with exact sensitivities: the Alart-Curnier augmented "
                    "Lagrangian with direct-differentiation (DDM) sensitivities. " + UNITS,
        epilog="Run 'signorini COMMAND --help' for the options of a command. Exit codes: 0 "
               "success, 1 the solve failed (converged increments and summary.json with status "
               "'failed' are written), 2 bad input.")
    parser.add_argument("--version", action="version", version=f"signorini {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    h = sub.add_parser(
        "hertz", formatter_class=fmt, help="frictionless plane-strain Hertz benchmark (paper 5.1)",
        description="Rigid cylinder (radius R) pressed with P per unit thickness onto an elastic "
                    "block; symmetric half model, held only by the contact. Writes contact.csv "
                    "(pressure and its DDM sensitivities to R, E, P), summary.json (p0 and a vs "
                    "the analytical solution, Newton log, DDM vs FD), pressure.png, "
                    "sensitivity.png and hertz.vtu. " + UNITS)
    _common(h, HERTZ_SET, 1, "number of equal load increments", _a0("hertz"))
    h.add_argument("--method", choices=["al", "penalty"], default="al",
                   help="contact method: augmented Lagrangian (exact) or penalty (comparator)")
    _coarse_start_option(h)

    f = sub.add_parser(
        "hertz-friction", formatter_class=fmt,
        help="frictional plane-strain Hertz benchmark with Coulomb friction (paper 5.2)",
        description="The Hertz half model with Coulomb friction (mu = 0.3, R = 10), the load "
                    "growing to P in --steps increments; path-dependent DDM sensitivities to R, "
                    "mu, E. Writes contact_P1..3.csv, summary.json (c/a with its bracket, Newton "
                    "log, DDM vs FD), Fig. 5/6-like figures, VTU files at P1..P3 and the series "
                    "hertz_friction.pvd. " + UNITS)
    _common(f, FRICTION_SET, 30, "number of load increments, a multiple of 3 (P1 = P/3, P2 = 2P/3 "
            "and P3 = P must be increments)", _a0("hertz_friction"), block=80.0)
    _coarse_start_option(f)
    _adjoint_option(f, "the contact work W = sum A p_N (g0 - g) at P")

    fg = sub.add_parser(
        "forging", formatter_class=fmt,
        help="axisymmetric J2 forging of a Bezier preform with friction (paper 5.3, Table 1)",
        description="A billet (height 2 h0 = 2, half model) upset by a flat rigid die with Coulomb "
                    "friction to 50 % height reduction: axisymmetric finite-strain J2 plasticity "
                    "(F-bar Q4), preform radius r0(Z) = Bezier curve of phi0..phi4. Computes the "
                    "objective F = sum (r_k - h0)^2 over the free-surface nodes and its DDM "
                    "sensitivities to phi0..phi4, mu and sigma_y, checked by central differences. "
                    "Writes summary.json, table1.csv, shape.png, force.png and forging.pvd. "
                    "Units: lengths in h0, stresses in the units of E.")
    fg.add_argument("--out", required=True, metavar="DIR",
                    help="output directory (created if needed; must be writable)")
    fg.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help=_set_help(FORGING_SET))
    _forging_mesh_options(fg)
    fg.add_argument("--no-fd", action="store_true",
                    help="skip the central-difference check (14 re-solves of the whole path)")
    _adjoint_option(fg, "F")
    _solver_options(fg)

    o = sub.add_parser(
        "optimise-forging", formatter_class=fmt,
        help="find the forging preform whose free surface ends as a cylinder (paper Figs. 8-9)",
        description="For each friction coefficient, minimise the forging objective F = sum "
                    "(r_k - h0)^2 over phi0..phi4 from the cylinder phi = 0.7 h0, with gradients "
                    "by DDM (one solve per design point) or by central differences (for "
                    "comparison). Writes per mu (mu_<value>/): history.csv of every evaluation, "
                    "summary.json, shape.png, convergence.png, forging.pvd of the optimal "
                    "process; and shapes.png and summary.json for all mu in --out. A design where "
                    "Newton fails or the shape is invalid is penalised, never fatal.")
    o.add_argument("--out", required=True, metavar="DIR", help="output directory")
    o.add_argument("--mu", default="0.1,0.2,0.3", metavar="MU[,MU...]",
                   help="friction coefficients, one optimisation each")
    _forging_mesh_options(o)
    o.add_argument("--method", default="BFGS", choices=["BFGS", "L-BFGS-B", "SLSQP"],
                   help="scipy.optimize method (L-BFGS-B, SLSQP: bounds phi >= 0.05)")
    o.add_argument("--gtol", type=_positive_float, default=1e-6, help="gradient tolerance")
    o.add_argument("--maxiter", type=_positive_int, default=50, help="iterations per mu")
    o.add_argument("--gradient", default="ddm", choices=["ddm", "adjoint", "fd"],
                   help="DDM (exact, one solve with 5 sensitivities per design), adjoint (exact, "
                        "one solve and one backward pass per design) or central differences "
                        "(11 solves)")
    o.add_argument("--resume", action="store_true",
                   help="continue from the best point of each mu's history.csv in --out")
    _dask_options(o)
    _solver_options(o)

    sw = sub.add_parser(
        "sweep", formatter_class=fmt,
        help="run a command over a grid of parameter values as independent Dask tasks",
        description="Run COMMAND once per point of the grid (the Cartesian product of the --set "
                    "and --option lists), each as an independent task on Dask (a local cluster "
                    "over the machine's cores by default, or --scheduler ADDRESS), and collect "
                    "every summary.json into DIR/sweep.csv (one row per point; nested entries "
                    "flattened with dots) and DIR/sweep.json. A failing point is recorded with "
                    "its exit code and reason; the sweep goes on. Arguments after -- are passed "
                    "to every run, e.g.: signorini sweep hertz --out s --set R=1,1.5,2 -- --no-fd")
    sw.add_argument("sweep_command", metavar="COMMAND",
                    choices=["hertz", "hertz-friction", "forging", "optimise-forging", "run"],
                    help="the command to run at every point")
    sw.add_argument("--out", required=True, metavar="DIR", help="output directory")
    sw.add_argument("--set", action="append", default=[], metavar="NAME=V1,V2,...",
                    help="values of a --set parameter (repeatable); START:STOP:NUM for a linspace")
    sw.add_argument("--option", action="append", default=[], metavar="NAME=V1,V2,...",
                    help="values of a command option, e.g. refine=0,1 (passed as --refine 0 ...)")
    _dask_options(sw)
    v = sw.add_mutually_exclusive_group()
    v.add_argument("-q", "--quiet", action="store_true", help="print only errors and the result")
    v.add_argument("-v", "--verbose", action="store_true", help="log more")

    r = sub.add_parser(
        "run", formatter_class=fmt, help="solve a problem described in a TOML file",
        description="Solve the problem of a TOML problem file (mesh, material, obstacle, loads, "
                    "contact law, increments, sensitivities, outputs; see docs/problem-files.md) "
                    "and write summary.json, contact tables, VTU and a .pvd series into --out.")
    r.add_argument("file", metavar="FILE", help="the problem file (.toml)")
    r.add_argument("--out", required=True, metavar="DIR", help="output directory")
    _solver_options(r)
    return parser


def _configure_logging(args) -> None:
    logging.basicConfig(level=logging.WARNING, format="%(message)s", stream=sys.stderr, force=True)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose else logging.INFO)
    logging.getLogger("signorini").setLevel(level)
    warnings.simplefilter("ignore", SignoriniWarning)  # already logged once


class _OnceFilter(logging.Filter):
    """The finite-difference re-solves repeat the base run's warnings: show each once."""

    def __init__(self):
        super().__init__()
        self.seen = set()

    def filter(self, record):
        if record.levelno != logging.WARNING:
            return True
        text = record.getMessage()
        key = text.split("]: ", 1)[-1] if text.startswith("warning [") else text
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


def main(argv=None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    extra: list[str] = []
    if argv[:1] == ["sweep"] and "--" in argv:  # arguments after -- go to every run of the sweep
        k = argv.index("--")
        argv, extra = argv[:k], argv[k + 1:]
    args = parser.parse_args(argv)
    args.extra = extra
    _configure_logging(args)
    from .. import progress

    show = not (args.quiet or args.verbose) and sys.stderr.isatty()
    flt = _OnceFilter()
    logger = logging.getLogger("signorini")
    logger.addFilter(flt)
    try:
        with progress.bars(show):
            return _dispatch(args)
    except ConvergenceError as e:
        print(f"signorini: the solve failed: {e}", file=sys.stderr)
        print(f"converged increments and summary.json (status 'failed') are in {args.out}/",
              file=sys.stderr)
        return 1
    except SignoriniError as e:
        print(f"signorini: error: {e}", file=sys.stderr)
        return 2
    finally:
        logger.removeFilter(flt)


def _fmt_coarse(levels) -> str:
    """' (guided by 1705 DOFs: 6 it, 3634 DOFs: 1 it)' for a coarse-to-fine start."""
    if not isinstance(levels, list) or not levels or "dofs" not in levels[0]:
        return ""
    return " (guided by " + ", ".join(
        f"{lv['dofs']} DOFs: {sum(lv['newton_iterations'])} it" for lv in levels) + ")"


def _print_adjoint(s):
    a = s.get("adjoint")
    if not isinstance(a, dict):
        return
    print(f"adjoint gradient of {a['response']}: value {a['value']:.6g}, one backward pass in "
          f"{a['time_backward_s']:.2f} s (shape gradient of all nodes in shape_gradient.csv)")
    print(f"{'parameter':>10} {'DDM':>14} {'adjoint':>14} {'rel. diff.':>10}")
    for n, d in a["ddm"].items():
        print(f"{n:>10} {d:14.6e} {a['adjoint'][n]:14.6e} {a['adjoint_vs_ddm_rel_diff'][n]:10.1e}")


def _fmt_fd(d) -> str:
    if not isinstance(d, dict):
        return "not computed (--no-fd)"
    return ", ".join(f"{k} {v:.1e}" for k, v in d.items())


def _dispatch(args) -> int:
    if args.command == "hertz":
        from ..problems import hertz

        params = parse_sets(args.set, HERTZ_SET)
        s = hertz.run(args.out, params, refine=args.refine, method=args.method,
                      finite_strain=args.finite_strain, steps=args.steps, fd_check=not args.no_fd,
                      solver=args.solver, size=args.block, zone=args.zone_width,
                      force_size=args.force_size, coarse_start=not args.no_coarse_start)
        print(f"Hertz ({args.method}, {s['mesh']['dofs']} DOFs): p0 = {s['p0']['computed']:.5g} "
              f"(analytical {s['p0']['analytical']:.5g}, error {100 * s['p0']['rel_error']:+.2f} %), "
              f"a = {s['a']['computed']:.4g} (analytical {s['a']['analytical']:.4g}); "
              f"Newton iterations {s['newton_iterations']}{_fmt_coarse(s['coarse_start'])}; "
              f"DDM vs FD (max rel. diff.): {_fmt_fd(s['ddm_vs_fd_rel_diff'])}; "
              f"solver {s['solver']}")
    elif args.command == "hertz-friction":
        from ..problems import hertz_friction

        params = parse_sets(args.set, FRICTION_SET)
        s = hertz_friction.run(args.out, params, refine=args.refine, steps=args.steps,
                               fd_check=not args.no_fd, solver=args.solver, size=args.block,
                               zone=args.zone_width, finite_strain=args.finite_strain,
                               force_size=args.force_size, coarse_start=not args.no_coarse_start,
                               adjoint=args.adjoint)
        ca = ", ".join(f"{lv['c_over_a']:.3f} [{lv['c_over_a_bracket'][0]:.3f}, "
                       f"{lv['c_over_a_bracket'][1]:.3f}]" for lv in s["loads"])
        print(f"frictional Hertz ({s['mesh']['dofs']} DOFs, {s['steps']} increments): "
              f"c/a at P1, P2, P3 = {ca}; Newton iterations {sum(s['newton_iterations'])} "
              f"in total; DDM vs FD at P3 (max rel. diff.): {_fmt_fd(s['ddm_vs_fd_rel_diff_P3'])}")
        _print_adjoint(s)
    elif args.command == "forging":
        from ..problems import forging

        params = parse_sets(args.set, FORGING_SET)
        s = forging.run(args.out, params, mesh=forging.parse_mesh(args.mesh), steps=args.steps,
                        fd_check=not args.no_fd, solver=args.solver, force_size=args.force_size,
                        adjoint=args.adjoint)
        print(f"forging ({s['mesh']['dofs']} DOFs, {s['steps']} increments, mu = "
              f"{s['params']['mu']:g}): F = {s['F']:.6g}, max |r - h0| / h0 = "
              f"{s['max_rel_deviation_from_r_opt']:.4f}, die force {s['die_force_final']:.5g}, "
              f"volume ratio {s['volume']['ratio']:.4f}")
        print(f"{'parameter':>10} {'DDM':>14} {'FD':>14} {'rel. diff.':>10}")
        for n, d in s["dF_ddm"].items():
            fd = s["dF_fd"][n] if isinstance(s["dF_fd"], dict) else float("nan")
            rel = s["ddm_vs_fd_rel_diff"][n] if isinstance(s["ddm_vs_fd_rel_diff"], dict) else float("nan")
            print(f"{n:>10} {d:14.6e} {fd:14.6e} {rel:10.1e}")
        _print_adjoint(s)
    elif args.command == "optimise-forging":
        from ..problems import forging, forging_opt

        try:
            mus = [float(m) for m in args.mu.split(",") if m.strip()]
        except ValueError:
            raise InputError(f"--mu expects comma-separated numbers, e.g. 0.1,0.2; got {args.mu!r}") from None
        if not mus or any(not 0 <= m < float("inf") for m in mus):
            raise InputError(f"--mu needs friction coefficients >= 0, got {args.mu!r}")
        kwargs = dict(mesh=forging.parse_mesh(args.mesh), steps=args.steps, method=args.method,
                      gtol=args.gtol, maxiter=args.maxiter, gradient=args.gradient,
                      resume=args.resume, solver=args.solver)
        if len(mus) > 1 and not args.sequential:  # one Dask task per mu
            from . import sweep

            s = sweep.optimise_mus_parallel(args.out, mus, scheduler=args.scheduler,
                                            n_workers=args.workers, **kwargs)
        else:
            s = forging_opt.run(args.out, mus, **kwargs)
        print(f"{'mu':>5} {'F(cylinder)':>12} {'F*':>10} {'max|r-h0|/h0':>13} {'r0 range':>9} "
              f"{'iters':>6} {'solves':>6} {'time [s]':>8}")
        for r in s.get("runs", []):
            if r.get("status") == "failed" or "F_opt" not in r:
                print(f"{r.get('mu', float('nan')):5g} failed: {r.get('message', r.get('reason', ''))}")
                continue
            print(f"{r['mu']:5g} {r['F_start']:12.4e} {r['F_opt']:10.3e} "
                  f"{r['max_rel_deviation_from_r_opt']:13.2e} {r['r0_range']['max_minus_min']:9.4f} "
                  f"{r['iterations']:6d} {r['solves']:6d} {r['time_wall_s']:8.1f}")
    elif args.command == "sweep":
        from . import sweep

        try:
            points = sweep.grid(args.set + ["--" + o for o in args.option])
        except ValueError as e:
            raise InputError(f"sweep: {e}") from None
        csv_path = sweep.run_sweep(args.sweep_command, points, args.out, extra_args=args.extra,
                                   scheduler=args.scheduler, n_workers=args.workers,
                                   sequential=args.sequential)
        table = sweep.read_csv(csv_path)
        failed = [r for r in table if str(r.get("exit_code")) not in ("0", "0.0")]
        print(f"sweep of {args.sweep_command}: {len(table)} points, {len(failed)} failed; "
              f"table in {csv_path}")
        return 1 if failed else 0
    elif args.command == "run":
        from . import problemfile

        s = problemfile.run(args.file, args.out, solver=args.solver, force_size=args.force_size)
        print(f"{args.file}: {s['status']}, {s['increments']} increment(s), "
              f"{s['mesh'].get('dofs', '?')} DOFs, Newton iterations {s['newton_iterations']}")
        for name, r in s.get("responses", {}).items():
            sens = ", ".join(f"d/d{k} {v:.6g}" for k, v in r.get("sensitivities", {}).items())
            print(f"  {name} = {r['value']:.6g}" + (f"  ({sens})" if sens else ""))
    if s.get("warnings"):
        print(f"{len(s['warnings'])} warning(s), also in summary.json:", file=sys.stderr)
        for w in s["warnings"]:
            print(f"  - {w}", file=sys.stderr)
    print(f"results in {args.out.rstrip('/')}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
