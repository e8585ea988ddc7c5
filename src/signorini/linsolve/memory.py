"""Estimates of a run's size before it is built, and a guard against runs the
machine cannot hold.

The peak-memory model (of the solver ``auto`` picks) is fitted to the peak
resident memory of the Hertz benchmark (``benchmarks/bench_hertz.py``, from 5k
to 225k DOFs with SciPy's SuperLU); it grows a little faster than linearly,
like the fill-in of a sparse LU of a 2-D mesh. It is an estimate, printed as one.
"""

from __future__ import annotations

import logging
import os

from ..errors import ResourceError
from .petsc import MPI_SOLVERS, per_rank_memory
from .select import get_solver

log = logging.getLogger("signorini")

GB = 1024.0**3
#: the share of the available memory a run may be estimated to need: the models are
#: fitted within about 20 %, and a run estimated just below what is available can
#: still exhaust it (the ironing problem at refine 2, estimated at 22 GB, passed
#: 18 GB within minutes on a 22 GB machine)
HEADROOM = 0.85


#: fitted peak-memory models, GB = a + b n^e for n unknowns (docs/benchmarks.md):
#: per solver and dimension
_MODELS = {
    # 2-D: the Hertz benchmarks, 5k to 1.06M DOFs (symmetric and LU alike)
    ("pardiso", 2): (0.4, 6.2e-6, 1.0),
    # 3-D: the 3-D Hertz benchmarks, 68k to 258k DOFs (1.55, 3.23, 6.21 GB): the
    # factors' fill grows like n^(4/3) with nested dissection; n^1.25 fits them and
    # extrapolates to the ~40 GB of the 1.09M-DOF tangent
    ("pardiso", 3): (0.4, 1.0e-6, 1.25),
    # SciPy's SuperLU in 3-D has not been run beyond 20k DOFs: PARDISO's fill times
    # the 2.4x that SuperLU needs over PARDISO in 2-D at 225k DOFs
    ("superlu", 3): (0.5, 2.4e-6, 1.25),
    # AMG-preconditioned GMRES (the hierarchy, the Krylov spaces, the condensed
    # matrix): linear, 1.18 GB at 68k to 13.6 GB at 1.09M DOFs in 3-D
    ("amg", 2): (0.5, 1.2e-5, 1.0),
    ("amg", 3): (0.5, 1.2e-5, 1.0),
}
# the PETSc solvers, per rank (every rank holds the whole model today): petsc-amg as
# amg with PETSc's copy of the hierarchy (5.2 GB measured at 286k 3-D DOFs on 1 rank,
# 4.4 GB on 2, amg 4.35 GB); MUMPS's factors as PARDISO's (2.35 GB at 89k 3-D DOFs on
# 1 rank)
_MODELS.update({("petsc-amg", d): (0.5, 1.44e-5, 1.0) for d in (2, 3)})
_MODELS.update({("petsc", d): _MODELS[("pardiso", d)] for d in (2, 3)})


def _solver_name(solver) -> str:
    """``auto`` -> the fastest installed direct solver; a solver object -> its name."""
    if solver is None or solver == "auto":
        return get_solver("auto").name
    return str(getattr(solver, "name", solver))


def iterative_hint(solver) -> str:
    """What a 3-D refusal adds to its hint: the iterative solver (``petsc-amg`` for a
    run on the ``petsc`` solver, ``amg`` for the others), unless the run uses it."""
    name = _solver_name(solver)
    if name in ("amg", "petsc-amg"):
        return ""
    return (f", the iterative solver (--solver {'petsc-amg' if name == 'petsc' else 'amg'}), "
            "which needs less memory in 3-D")


def estimated_peak_memory(n_dof: int, solver="superlu", dim: int = 2, extra: float = 0.0) -> float:
    """Estimated peak resident memory in bytes of a solve with ``n_dof`` unknowns.

    Args:
        n_dof: unknowns (displacements and multipliers).
        solver: ``pardiso``, ``superlu``, ``umfpack``, ``amg``, ``auto`` (the fastest
            installed) or a solver object.
        dim: 2 (plane strain, axisymmetric) or 3: a sparse LU of a 3-D mesh fills
            in much faster than one of a 2-D mesh.
        extra: bytes the problem needs beyond the model (e.g. the candidate
            partners of a finite-sliding contact pair), added as they are.

    2-D ``superlu`` (and ``umfpack``): 0.5 GB + 1.1e-5 GB per DOF times
    (n_dof / 2e5)^0.25, fitted to the Hertz benchmark with SuperLU (5k to 225k
    DOFs). 2-D ``pardiso``: 0.4 GB + 6.2e-6 GB per DOF, fitted to the Hertz
    benchmarks with MKL PARDISO (5k to 0.9M DOFs symmetric, the frictional
    Hertz at 1.06M DOFs, LU). 3-D and ``amg``: see :data:`_MODELS`. Estimates,
    printed as such."""
    n = max(int(n_dof), 1)
    name = _solver_name(solver)
    d = 3 if int(dim) == 3 else 2
    if name not in ("pardiso", "amg") and d == 2:
        return (0.5 + 1.1e-5 * n * (n / 2.0e5) ** 0.25) * GB + float(extra)
    a, b, e = _MODELS.get((name, d), _MODELS[("superlu", 3)] if d == 3 else _MODELS[("pardiso", 2)])
    return (a + b * float(n) ** e) * GB + float(extra)


def history_extra(cells: int, n_dof: int, *, history_per_cell: float, steps: int,
                  sensitivities: int, program: float = 0.0, kernel_per_cell: float = 0.0,
                  kernel_cells: int = 0):
    """``extra`` for :func:`check_size` of a run whose material keeps a history: the
    bytes beyond the solver's model of a mesh of ``cells`` cells and ``n_dof``
    unknowns, as a function of the unknowns n (the cells growing with them as the
    mesh is refined). ``history_per_cell`` bytes a cell for each copy kept: the
    state of each of ``steps`` increments, and its sensitivity to each of
    ``sensitivities`` parameters; ``program``
    bytes of compiled programs, and the kernels' working memory,
    ``kernel_per_cell`` bytes a cell for at most ``kernel_cells`` cells (the cells
    evaluated at once)."""
    copies = max(int(steps), 1) * (1 + max(int(sensitivities), 0))

    def extra(n):
        c = cells * n / max(int(n_dof), 1)
        return program + kernel_per_cell * min(c, kernel_cells) + history_per_cell * c * copies
    return extra


def largest_fitting(have: float, solver="superlu", dim: int = 2, extra=None) -> int:
    """The largest number of unknowns whose estimated peak memory (with
    ``extra(n)`` bytes on top, if given) stays within ``have`` bytes (0 if none
    does)."""
    fits = lambda n: estimated_peak_memory(n, solver, dim, extra(n) if extra else 0.0) <= have  # noqa: E731
    if not fits(1):
        return 0
    lo, hi = 1, 2
    while fits(hi) and hi < 10**13:
        lo, hi = hi, 2 * hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return lo


def available_memory() -> float | None:
    """Memory available to this process in bytes (Linux ``MemAvailable``, else None)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_size(n_dof: int, *, force: bool = False, what: str = "this run", dim: int = 2,
               solver="auto", extra: float = 0.0, hint: str = "a coarser mesh (smaller --refine)",
               lower_bound: bool = False) -> float:
    """The size guard of every command and problem builder: log the estimated size
    of a run and refuse it if it cannot fit in memory, before the mesh is built.

    Args:
        n_dof: number of unknowns (displacements + multipliers); a lower bound is
            enough to refuse a run before its grid lines are built.
        force: run anyway (the caller insists; a warning is logged).
        what: name of the run in the messages.
        dim: 2 or 3 (see :func:`estimated_peak_memory`).
        solver: the linear solver of the run (name or object; ``auto``: the
            fastest installed direct solver).
        extra: bytes beyond the model's (see :func:`estimated_peak_memory`), or
            a function of the number of unknowns giving them (how they grow with
            the mesh, for the largest size that fits).
        hint: what to change, in the refusal (e.g. the command's mesh option).
        lower_bound: ``n_dof`` is a lower bound (a preliminary check, before the
            mesh's exact size is known): logged only if the run is refused.

    Returns:
        The estimated peak memory in bytes.

    Raises:
        ResourceError: the estimate exceeds :data:`HEADROOM` of the available
            memory and ``force`` is False; its message gives the estimate, what is
            available and the largest number of unknowns that fits.
    """
    name = _solver_name(solver)
    grow = extra if callable(extra) else (lambda n: float(extra) * n / max(int(n_dof), 1))
    need = estimated_peak_memory(n_dof, name, dim, grow(n_dof))
    have, ranks = available_memory(), 1
    if name in MPI_SOLVERS:  # under mpiexec: a rank's share, the same on every rank
        have, ranks = per_rank_memory(have)
    where = "available" if ranks == 1 else f"available to each rank ({ranks} ranks share a machine)"
    if not lower_bound:
        log.info("%s: %d unknowns, estimated peak memory %.2g GB%s with %s (%s %s)", what, n_dof,
                 need / GB, "" if ranks == 1 else " a rank", name,
                 "unknown" if have is None else f"{have / GB:.3g} GB", where)
    if have is not None and need > HEADROOM * have:
        most = largest_fitting(HEADROOM * have, name, dim, grow)
        least = "at least " if lower_bound else ""
        msg = (f"{what} has {least}{n_dof:,} unknowns and needs an estimated {need / GB:.3g} GB of "
               f"memory{'' if ranks == 1 else ' on each rank'} with the {name} solver, more than "
               f"{100 * HEADROOM:.0f} % of the {have / GB:.3g} GB {where} (the largest that fits "
               f"is about {most:,} unknowns)")
        if not force:
            raise ResourceError(msg + f"; use {hint}, or insist with --force-size "
                                "(API: force_size=True)")
        log.warning("warning: %s; running anyway (forced)", msg)
    return need
