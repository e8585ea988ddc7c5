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
from .select import get_solver

log = logging.getLogger("signorini")

GB = 1024.0**3


def estimated_peak_memory(n_dof: int, solver: str = "superlu") -> float:
    """Estimated peak resident memory in bytes of a solve with ``n_dof`` unknowns.

    ``superlu``: 0.5 GB + 1.1e-5 GB per DOF times (n_dof / 2e5)^0.25, fitted as
    described above. ``pardiso``: 0.4 GB + 6.2e-6 GB per DOF, linear, fitted to
    the Hertz benchmarks with MKL PARDISO (5k to 0.9M DOFs symmetric, and the
    frictional Hertz at 1.06M DOFs, LU)."""
    n = max(int(n_dof), 1)
    if solver == "pardiso":
        return (0.4 + 6.2e-6 * n) * GB
    return (0.5 + 1.1e-5 * n * (n / 2.0e5) ** 0.25) * GB


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


def check_size(n_dof: int, *, force: bool = False, what: str = "this run") -> float:
    """Log the estimated size of a run and refuse it if it cannot fit in memory.

    Args:
        n_dof: number of unknowns (displacements + multipliers).
        force: run anyway (the caller insists; a warning is logged).
        what: name of the run in the messages.

    Returns:
        The estimated peak memory in bytes.

    Raises:
        ResourceError: the estimate exceeds the available memory and ``force`` is False.
    """
    need = estimated_peak_memory(n_dof, get_solver("auto").name)
    have = available_memory()
    log.info("%s: %d unknowns, estimated peak memory %.2g GB (%s available)", what, n_dof,
             need / GB, "unknown" if have is None else f"{have / GB:.3g} GB")
    if have is not None and need > have:
        msg = (f"{what} has {n_dof:,} unknowns and needs an estimated {need / GB:.3g} GB of memory, "
               f"more than the {have / GB:.3g} GB available")
        if not force:
            raise ResourceError(msg + "; use a coarser mesh (smaller --refine) or insist with "
                                "--force-size (API: force_size=True)")
        log.warning("warning: %s; running anyway (forced)", msg)
    return need
