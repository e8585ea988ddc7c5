"""A command run by every MPI rank, rank 0 alone printing and writing.

Under ``mpiexec -n N signorini ... --solver petsc`` every rank runs the command;
the ranks other than 0 compute the same, silently, into a private directory
removed at the end (docs/parallel.md)."""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import sys
import tempfile
import warnings
from pathlib import Path

from ..linsolve import petsc


#: the private output directories of this process (a rank other than 0), removed at
#: the end of its run, or by :func:`remove_private` where the process ends abruptly
#: (the interrupt watchdog, MPI's launcher ending the job)
_PRIVATE: list[Path] = []


def remove_private() -> None:
    """Remove this rank's private output directory, if any (idempotent)."""
    while _PRIVATE:
        shutil.rmtree(_PRIVATE.pop(), ignore_errors=True)


@contextlib.contextmanager
def ranks(args):
    """A command run with a PETSc solver (``--solver petsc`` or ``petsc-amg``): PETSc's
    options from ``--petsc-options`` and, on ranks other than 0, outputs to a
    private directory and the log reduced to errors; yields the rank."""
    rank, size = petsc.world()
    options = getattr(args, "petsc_options", "") or ""
    if options:
        petsc.insert_options(options)
    if rank == 0:
        if size > 1:
            logging.getLogger("signorini").info("MPI: %d ranks", size)
        yield rank
        return
    # an interrupt is rank 0's to handle: it writes the report of what converged; the
    # launcher then ends the other ranks
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if getattr(args, "out", None) is not None:
        private = Path(tempfile.mkdtemp(prefix=f"signorini-rank{rank}-"))
        _PRIVATE.append(private)
        args.out = str(private)
    logger = logging.getLogger("signorini")
    level = logger.level
    logger.setLevel(logging.ERROR)
    # the same lines as rank 0's, the same expected errors (rank 0 prints them); an
    # unexpected exception's traceback is printed once the streams are back
    streams = sys.stdout, sys.stderr
    sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115 (closed below)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rank 0 shows them (and summary.json lists them)
            yield rank
    finally:
        sys.stdout.close()
        sys.stdout, sys.stderr = streams
        logger.setLevel(level)
        remove_private()
