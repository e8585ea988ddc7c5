"""What the commands share: argument types and option groups, the ``--set``
parser, and the lines every command prints at the end."""

from __future__ import annotations

import argparse
import sys

from ..algorithms.newton import NewtonOptions
from ..errors import InputError
from ..params import parse_assignment
from ..problems import hertz, hertz_friction

UNITS = "Units: mm, N/mm (force per unit thickness), N/mm² (MPa)."
#: the units of the whole program: plane-strain forces per unit thickness, others whole
UNITS_ALL = ("Units: mm, N/mm² (MPa); forces in N/mm (per unit thickness) in plane strain, in N "
             "in 3-D and axisymmetry.")
#: the units of a 3-D command (its help says which forces are whole and which on the model)
UNITS_SOLID = "Units: mm, N, N/mm² (MPa)."
#: the units of a 3-D or axisymmetric command: its forces are whole forces
UNITS_3D = "Units: mm, N (P: the sphere's whole force, in 3-D and axisymmetric alike), N/mm² (MPa)."


class Formatter(argparse.HelpFormatter):
    """Shows '(default: X)' only where there is a meaningful default."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if (d not in (None, False, [], argparse.SUPPRESS) and "%(default)" not in text
                and action.option_strings):
            text += " (default: %(default)s)"
        return text


def whole_number(least: int):
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


positive_int = whole_number(1)
nonneg_int = whole_number(0)


def positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return v


def tolerance(text: str) -> float:
    """argparse type of --rtol: a number in (0, 1)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < v < 1:  # NaN fails too
        raise argparse.ArgumentTypeError(
            f"expected a relative tolerance between 0 and 1 (exclusive), e.g. 1e-10, got {text!r}")
    return v


def newton_options(p, rtol: float | None, max_iter: bool = True) -> None:
    """--rtol (and --max-iter): the Newton options a user may need to change
    (signorini.NewtonOptions; the command's other Newton settings stay). A
    default of None: the problem file's value (``signorini run``)."""
    g = p.add_argument_group("Newton")
    g.add_argument("--rtol", type=tolerance, default=rtol, metavar="R",
                   help="Newton stops when the residual norm is below R times the reference "
                        "(the external forces or the first residual of the increment); an "
                        "increment whose residual stops falling above R, at the round-off floor "
                        "of the problem, while the corrections no longer change the displacements "
                        "is accepted too, and summary.json says so (newton_stops, "
                        "newton_relative_residuals)")
    if max_iter:
        g.add_argument("--max-iter", type=positive_int,
                       default=None if rtol is None else NewtonOptions.max_iter, metavar="N",
                       help="Newton iterations per increment before the increment is halved")


def parse_sets(items: list[str], allowed: dict) -> dict:
    """``--set NAME=VALUE`` items -> {name: float}; unknown, repeated, non-numeric
    or non-finite values are errors that name the item."""
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


def with_defaults(texts: dict, defaults: dict) -> dict:
    """``--set`` help texts: each parameter's description, followed by its default
    taken from the problem builder's own ``DEFAULTS`` (one source of the values)."""
    return {k: f"{v}, default {defaults[k]:g}" if k in defaults else v for k, v in texts.items()}


def set_help(allowed: dict, example: str | None = None, fixed_mesh: bool = True) -> str:
    """The help of ``--set``: an example (default: the first name set to 1.5), every
    name with its description and, ``fixed_mesh``, that the mesh does not follow the
    values (false where a shape parameter moves the nodes, e.g. a die's radius)."""
    example = example or f"{next(iter(allowed))}=1.5"
    text = (f"set a named parameter (repeatable), e.g. --set {example}. Names: " +
            "; ".join(f"{k} = {v}" for k, v in allowed.items()))
    if fixed_mesh:
        text += (". The mesh never changes with these values (it is built from the defaults and "
                 "the mesh options), so finite differences of two runs equal the printed DDM "
                 "sensitivities.")
    return text


#: the help of --refine on a 2-D mesh
REFINE_HELP = "halve every cell N times (each level: 4x the unknowns)"


def command_options(p, set_names: dict, *, example: str | None = None, fixed_mesh: bool = True,
                    refine: str | None = REFINE_HELP) -> None:
    """The options a benchmark command begins with: --out, --set (its help lists
    ``set_names``, NAME -> description, see :func:`set_help`) and, unless ``refine``
    is None, --refine with that help. The command's own mesh and model options
    follow, then :func:`path_options`."""
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (created if needed; must be writable)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help=set_help(set_names, example, fixed_mesh))
    if refine is not None:
        p.add_argument("--refine", type=nonneg_int, default=0, metavar="N", help=refine)


def path_options(p, *, steps: int | None = None, steps_help: str | None = None,
                 fd: str = "two re-solves per parameter") -> None:
    """--steps (the load path's increments; only with ``steps_help``, default
    ``steps``) and --no-fd (``fd``: what the finite-difference check costs)."""
    if steps_help is not None:
        p.add_argument("--steps", type=positive_int, default=steps, metavar="N", help=steps_help)
    p.add_argument("--no-fd", action="store_true",
                   help="skip the check of the DDM sensitivities by central finite differences "
                        f"(saves {fd})")


def common_options(p: argparse.ArgumentParser, allowed: dict, steps: int, steps_help: str, a0: float,
            block: float = 20.0):
    """The options of the plane-strain Hertz commands (hertz, hertz-friction)."""
    command_options(p, allowed)
    p.add_argument("--block", type=positive_float, default=block, metavar="B",
                   help=f"block width and depth, in units of the nominal contact half-width a0 "
                        f"(a0 = {a0:.4g} mm: Hertz's half-width at the default parameters)")
    p.add_argument("--zone-width", type=positive_float, default=1.5, metavar="Z",
                   help="width of the uniformly fine mesh zone at the contact, in units of a0")
    p.add_argument("--finite-strain", action="store_true",
                   help="neo-Hookean block with finite contact kinematics (default: linear "
                        "elasticity, linearised contact kinematics as in Hertz's theory)")
    path_options(p, steps=steps, steps_help=steps_help)
    solver_options(p)


def forging_mesh_options(p):
    p.add_argument("--mesh", default="10x20", metavar="NRxNZ",
                   help="cells in the radial and axial directions")
    p.add_argument("--steps", type=positive_int, default=50, metavar="N",
                   help="equal increments of the die stroke in every forging solve")


def dask_options(p):
    g = p.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing Dask scheduler (default: a local cluster)")
    g.add_argument("--sequential", action="store_true", help="run the tasks here, one after another")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="workers of the local cluster (default: the number of cores)")


def adjoint_option(p, response: str):
    p.add_argument("--adjoint", action="store_true",
                   help=f"also compute the adjoint gradient of {response} (one backward pass "
                        "over the increments) with respect to the same parameters and every "
                        "nodal coordinate; written next to the DDM gradient in summary.json "
                        "('adjoint'), shape_gradient.csv and the VTU field adjoint_shape_gradient")


def coarse_start_option(p):
    p.add_argument("--no-coarse-start", action="store_true",
                   help="start Newton from the undeformed state (later increments from the "
                        "extrapolating predictor) instead of from coarser meshes solved along the "
                        "same load path, interpolated, or (a 3-D mesh without coarser ones) from "
                        "an algebraic coarse problem (the result is the same)")


def solver_options(p):
    p.add_argument("--solver", default="auto",
                   choices=["auto", "pardiso", "superlu", "umfpack", "amg", "petsc", "petsc-amg"],
                   help="linear solver; auto (default) = the fastest direct one installed: pardiso "
                        "(MKL, installed with signorini on x86-64), else superlu (SciPy); amg = "
                        "GMRES with algebraic multigrid (iterative, for large 3-D problems); petsc "
                        "= PETSc on the MPI ranks (mpiexec -n N signorini ...; MUMPS unless "
                        "--petsc-options say otherwise), petsc-amg = amg with its multigrid cycle "
                        "run by PETSc on the MPI ranks (an optional install: docs/parallel.md)")
    p.add_argument("--petsc-options", default="", metavar="OPTIONS",
                   help="PETSc options for --solver petsc or petsc-amg, as one string (e.g. \"-ksp_type gmres "
                        "-pc_type gamg\")")
    p.add_argument("--force-size", action="store_true",
                   help="run even if the estimated memory exceeds what is available")
    verbosity_options(p)


def verbosity_options(p):
    """-q / -v: what the log shows (every command has them: the entry point reads them)."""
    v = p.add_mutually_exclusive_group()
    v.add_argument("-q", "--quiet", action="store_true", help="print only errors and the result line")
    v.add_argument("-v", "--verbose", action="store_true",
                   help="log every increment and Newton iteration instead of progress bars")


def nominal_a0(name: str) -> float:
    d = {"hertz": hertz.DEFAULTS, "hertz_friction": hertz_friction.DEFAULTS}[name]
    return float(hertz.analytical(d["P"], d["R"], d["E"], d["nu"])["a"])


def fmt_coarse(levels) -> str:
    """' (guided by 1705 DOFs: 6 it, 3634 DOFs: 1 it)' for a coarse-to-fine start."""
    if not isinstance(levels, list) or not levels or "dofs" not in levels[0]:
        return ""
    return " (guided by " + ", ".join(
        f"{lv['dofs']} DOFs: {sum(lv['newton_iterations'])} it" for lv in levels) + ")"


def print_ddm_fd(s):
    """The table of a summary's DDM derivatives (``dF_ddm``) against its central
    differences (``dF_fd``, ``ddm_vs_fd_rel_diff``; NaN when not computed)."""
    print(f"{'parameter':>10} {'DDM':>14} {'FD':>14} {'rel. diff.':>10}")
    for n, d in s["dF_ddm"].items():
        fd = s["dF_fd"][n] if isinstance(s["dF_fd"], dict) else float("nan")
        rel = s["ddm_vs_fd_rel_diff"][n] if isinstance(s["ddm_vs_fd_rel_diff"], dict) else float("nan")
        print(f"{n:>10} {d:14.6e} {fd:14.6e} {rel:10.1e}")


def print_adjoint(s):
    a = s.get("adjoint")
    if not isinstance(a, dict):
        return
    print(f"adjoint gradient of {a['response']}: value {a['value']:.6g}, one backward pass in "
          f"{a['time_backward_s']:.2f} s (shape gradient of all nodes in shape_gradient.csv)")
    print(f"{'parameter':>10} {'DDM':>14} {'adjoint':>14} {'rel. diff.':>10}")
    for n, d in a["ddm"].items():
        print(f"{n:>10} {d:14.6e} {a['adjoint'][n]:14.6e} {a['adjoint_vs_ddm_rel_diff'][n]:10.1e}")


def fmt_fd(d) -> str:
    if not isinstance(d, dict):
        return "not computed (--no-fd)"
    return ", ".join(f"{k} {v:.1e}" for k, v in d.items())




def finish(args, summary: dict) -> int:
    """The warnings of a run (also in summary.json) and where its files are; exit code 0."""
    if summary.get("warnings"):
        print(f"{len(summary['warnings'])} warning(s), also in summary.json:", file=sys.stderr)
        for w in summary["warnings"]:
            print(f"  - {w}", file=sys.stderr)
    print(f"results in {args.out.rstrip('/')}/")
    return 0
