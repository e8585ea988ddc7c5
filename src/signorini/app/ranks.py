"""A command run by every MPI rank, rank 0 alone printing and writing.

Under ``mpiexec -n N signorini ... --solver petsc`` every rank runs the command;
the ranks other than 0 compute the same, silently, into a private directory
removed at the end, drawing no figure and writing no VTU file (docs/parallel.md).

An interrupt is rank 0's to report. Open MPI's launcher, on Ctrl-C, sends every
rank SIGTERM and kills it one second later; PETSc's calls hold the interpreter's
lock while they wait for the other ranks. So a rank other than 0 does not leave
on SIGTERM: it goes on with the run, so that rank 0, if it was waiting for it
inside a PETSc call, gets out of it and writes its report (a rank that left would
keep it there until it is killed). Rank 0 then removes the other ranks' private
directories (their names gathered at the start), which those ranks, waiting in
their next PETSc call for a rank 0 that has left, no longer can."""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

from ..linsolve import petsc
from ..post import helper
from . import runner

#: the private output directories of this process (a rank other than 0), removed at
#: the end of its run, or by :func:`remove_private` where the process ends abruptly
#: (the interrupt watchdog, MPI's launcher ending the job)
_PRIVATE: list[Path] = []
#: rank 0: the other ranks' private directories on this machine, removed by
#: :func:`remove_others` when rank 0 reports an interrupt
_OTHERS: list[Path] = []
#: one removal at a time (the main thread's, the interrupt watchdog's)
_LOCK = threading.Lock()
#: seconds rank 0 tries to remove another rank's directory (its output helper may
#: be writing a file into it meanwhile)
REMOVE_S = 0.5


def remove_private() -> None:
    """Remove this rank's private output directory, if any (idempotent; from any
    thread: a second caller returns once the first has removed it). Its output
    helper is ended first, the files it still had to write dropped: it would
    write into the directory while it is removed."""
    with _LOCK:
        if _PRIVATE:
            helper.abandon()
        while _PRIVATE:
            shutil.rmtree(_PRIVATE[-1], ignore_errors=True)
            _PRIVATE.pop()


def remove_others() -> None:
    """Rank 0, reporting an interrupt: remove the other ranks' private directories
    on this machine (idempotent). Each may still be written by its rank's output
    helper: tried again until it is gone, for up to :data:`REMOVE_S` seconds."""
    with _LOCK:
        while _OTHERS:
            path, t0 = _OTHERS[-1], time.monotonic()
            shutil.rmtree(path, ignore_errors=True)
            while path.exists() and time.monotonic() - t0 < REMOVE_S:
                time.sleep(0.01)
                shutil.rmtree(path, ignore_errors=True)
            _OTHERS.pop()


@contextlib.contextmanager
def ranks(args):
    """A command run with a PETSc solver (``--solver petsc`` or ``petsc-amg``): PETSc's
    options from ``--petsc-options`` and, on ranks other than 0, outputs to a
    private directory and the log reduced to errors; yields the rank."""
    rank, size = petsc.world()
    options = getattr(args, "petsc_options", "") or ""
    if options:
        petsc.insert_options(options)
    private = None
    if rank > 0 and getattr(args, "out", None) is not None:
        private = Path(tempfile.mkdtemp(prefix=f"signorini-rank{rank}-"))
        _PRIVATE.append(private)
        args.out = str(private)
        # its figures and VTU files (and their fields) are not computed at all
        helper.discard(True)
    if size > 1:
        from mpi4py import MPI  # noqa: PLC0415  (lazy: an optional install, loaded by petsc.world)

        names = MPI.COMM_WORLD.gather(None if private is None else str(private), root=0)
        if rank == 0:
            _OTHERS[:] = [Path(p) for p in names if p is not None]
    # the launcher kills an interrupted rank a second after its SIGTERM (Open MPI), too
    # soon to compute the fields of a series then: every rank writes it as it converges
    runner.stream_series(size > 1)
    try:
        if rank == 0:
            if size > 1:
                logging.getLogger("signorini").info("MPI: %d ranks", size)
            yield rank
        else:
            with _silent():
                yield rank
    finally:
        runner.stream_series(False)
        _OTHERS.clear()
        remove_private()
        if rank > 0:
            helper.discard(False)


@contextlib.contextmanager
def _silent():
    """A rank other than 0: SIGINT ignored (rank 0 reports an interrupt), the log
    reduced to errors, the streams silent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
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
            yield
    finally:
        sys.stdout.close()
        sys.stdout, sys.stderr = streams
        logger.setLevel(level)
