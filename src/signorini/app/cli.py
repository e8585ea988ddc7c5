"""The ``signorini`` command: the paper's benchmarks, problem files and sweeps.

Each command lives in its own module of :mod:`signorini.app.commands`, listed
in :mod:`signorini.app.registry`. Exit codes: 0 success, 1 the solve failed
(converged increments and ``summary.json`` with ``"status": "failed"`` are
written), 2 bad input, 130 / 143 interrupted by SIGINT (Ctrl-C) / SIGTERM (the
converged increments and ``summary.json`` with ``"status": "interrupted"`` are
written).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import threading
import warnings

from .. import timing
from .._version import __version__
from ..errors import ConvergenceError, Interrupted, SignoriniError, SignoriniWarning
from ..post import helper
from . import registry


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command in :data:`signorini.app.registry.COMMANDS`, or of
    command ``only`` alone (what a run needs: the other commands' modules are not
    imported then)."""
    from .options import UNITS_ALL, Formatter  # noqa: PLC0415  (lazy: the library, after the output helper started)

    parser = argparse.ArgumentParser(
        prog="signorini", formatter_class=Formatter,
        description="Contact mechanics with exact sensitivities: the Alart-Curnier augmented "
                    "Lagrangian with direct-differentiation (DDM) sensitivities. " + UNITS_ALL,
        epilog="Run 'signorini COMMAND --help' for the options of a command. Exit codes: 0 "
               "success, 1 the solve failed (converged increments and summary.json with status "
               "'failed' are written), 2 bad input, 130 / 143 interrupted by Ctrl-C (SIGINT) / "
               "SIGTERM (the converged increments and summary.json with status 'interrupted' "
               "are written).")
    parser.add_argument("--version", action="version", version=f"signorini {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in registry.COMMANDS if only is None else (only,):
        registry.command(name).add_parser(sub)
    return parser


def _configure_logging(args) -> None:
    logging.basicConfig(level=logging.WARNING, format="%(message)s", stream=sys.stderr, force=True)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose else logging.INFO)
    logging.getLogger("signorini").setLevel(level)
    warnings.simplefilter("ignore", SignoriniWarning)  # logged (at INFO) and listed at the end


class _OnceFilter(logging.Filter):
    """The finite-difference re-solves repeat the base run's warnings: show each once."""

    def __init__(self):
        super().__init__()
        self.seen = set()

    def filter(self, record):
        text = record.getMessage()
        if not text.startswith("warning"):
            return True
        key = text.split(": ", 1)[-1]  # "warning: X" and "warning [FD R+]: X" alike
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


def main(argv=None) -> int:
    # the console command's run counts from the process start, the import of the
    # command's module (and so of the library) as imports; a run from Python (a
    # sweep's point) from here
    if argv is None:
        _import_command(sys.argv[1:2])
    with timing.recording(imports_from=timing.process_start() if argv is None else None,
                          fresh=True):
        return _main(sys.argv[1:] if argv is None else argv)


def _import_command(first: list[str]) -> None:
    """Import the module of the command named first on the command line, if any."""
    name = registry.current_name(first[0])[0] if first else None
    if name in registry.COMMANDS:
        registry.command(name)


def entry() -> None:
    """The ``signorini`` console command: :func:`main`, then a prompt exit. Every
    output is written and closed by then (a sweep's cluster too); the interpreter's
    teardown, which frees JAX's programs and arrays one by one, would only add a
    few tenths of a second to the user's wait.

    A command that writes figures and VTU files gets its output helper first
    (:mod:`signorini.post.helper`), before the library (and JAX) is imported,
    so that matplotlib and meshio load beside it."""
    argv = sys.argv[1:]
    if argv[:1] and argv[0] in registry.OUTPUT_HELPER and not {"-h", "--help"} & set(argv):
        helper.start()
    code = main()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more to say
            pass
    logging.shutdown()
    _finalize_mpi()
    os._exit(code if isinstance(code, int) else 1)


#: the solvers run under mpiexec (:mod:`signorini.app.ranks`): the names of
#: :data:`signorini.linsolve.petsc.MPI_SOLVERS`, written out so that the command line
#: loads no solver before it knows the command
MPI_SOLVERS = ("petsc", "petsc-amg")


def _finalize_mpi() -> None:
    """End PETSc and MPI where a run (``--solver petsc``) started them: ``os._exit``
    skips their exit handlers, and MPI's launcher counts a rank that ends without
    finalising as failed. A rank's private output directory is removed first."""
    _remove_private()
    petsc, mpi = sys.modules.get("petsc4py.PETSc"), sys.modules.get("mpi4py.MPI")
    if petsc is not None:
        petsc._finalize()
    if mpi is not None and mpi.Is_initialized() and not mpi.Is_finalized():
        mpi.Finalize()


def _remove_private() -> None:
    """Remove this rank's private output directory, where a run under mpiexec made one
    (:mod:`signorini.app.ranks`, loaded only by such a run)."""
    ranks = sys.modules.get("signorini.app.ranks")
    if ranks is not None:
        ranks.remove_private()


def _remove_others() -> None:
    """Rank 0 under mpiexec, its interrupt reported: remove the other ranks' private
    output directories (:func:`signorini.app.ranks.remove_others`)."""
    ranks = sys.modules.get("signorini.app.ranks")
    if ranks is not None:
        ranks.remove_others()


#: seconds a signal may wait for the main thread (inside a library call: a
#: factorisation, a compilation, a large allocation) before the watchdog reports
#: the interrupt itself and ends the process; and the seconds that report may take
GRACE_S, REPORT_S = 3.0, 20.0
#: seconds the interrupt, once its handler has run, may take to leave the command: an
#: exception raised where Python ignores it (a finaliser, a callback from a library)
#: is lost, and the run would go on; the watchdog then reports and ends the process
UNWIND_S = 10.0


@contextlib.contextmanager
def _signals(final: int | None = None, report: bool = True):
    """SIGTERM raises :class:`~signorini.errors.Interrupted` and SIGINT
    ``Interrupted(2)``, a ``KeyboardInterrupt`` (so a batch scheduler's stop keeps
    the run's work too); with ``final``, while the report of an interrupt is
    written, either signal ends the process at once with that exit status. Only in
    the main thread (signal handlers cannot be set elsewhere: a sweep's points in
    Dask threads run without). Yields the event set when a signal's handler has
    run (None without handlers).

    Without ``report`` (a rank other than 0 under mpiexec, whose interrupt rank 0
    reports) SIGINT is left as it is (ignored) and SIGTERM is noted while the run
    goes on: rank 0 may be waiting for this rank inside a PETSc call, which holds
    the interpreter's lock (:mod:`signorini.app.ranks`); if the run has not ended
    :data:`GRACE_S` seconds later, the watchdog removes the rank's private directory
    and ends the process.

    Python runs a signal's handler in the main thread between two bytecodes, so a
    signal that comes during a long library call (PARDISO's factorisation, XLA's
    compilation) would wait for its end. A watchdog thread is woken at once
    (``signal.set_wakeup_fd``); if the handler has not run within
    :data:`GRACE_S` seconds, the watchdog writes the interrupt report (what has
    converged is kept) and ends the process with 128 + the signal's number; so it
    does if the interrupt has not left the command :data:`UNWIND_S` seconds after
    its handler ran (measured: one SIGTERM in about ten, during the compilation of
    a sensitivity program, raised where Python ignores an exception, and the run
    went on). A library call that holds the interpreter's lock throughout stops the
    watchdog too; none of those the solver spends its time in does."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if final is not None:
        def now(signum, frame):
            os._exit(final)

        before = {s: signal.signal(s, now) for s in (signal.SIGTERM, signal.SIGINT)}
        try:
            yield
        finally:
            for s, h in before.items():
                signal.signal(s, h)
        return

    handled = threading.Event()

    def stop(signum, frame):
        handled.set()
        if report:
            raise Interrupted(signum)

    caught = (signal.SIGTERM, signal.SIGINT) if report else (signal.SIGTERM,)
    before = {s: signal.signal(s, stop) for s in caught}
    watch = _Watchdog(handled, report)
    try:
        yield handled
    finally:
        watch.close()
        for s, h in before.items():
            signal.signal(s, h)


class _Watchdog:
    """The thread that ends a process whose main thread does not answer a signal
    (:func:`_signals`)."""

    def __init__(self, handled: threading.Event, report: bool = True):
        import socket  # noqa: PLC0415  (lazy: only a command's run needs it)

        self.handled, self.report = handled, report
        self.closed = threading.Event()
        self.rsock, self.wsock = socket.socketpair()
        self.wsock.setblocking(False)
        try:
            self.old_fd = signal.set_wakeup_fd(self.wsock.fileno(), warn_on_full_buffer=False)
        except ValueError:  # not the main thread of the main interpreter
            self.old_fd = None
            return
        self.thread = threading.Thread(target=self._run, name="signorini-signal-watchdog",
                                       daemon=True)
        self.thread.start()

    def _run(self):
        while not self.closed.is_set():
            try:
                data = self.rsock.recv(1)
            except OSError:
                return
            if not data or self.closed.is_set():
                return
            signum = data[0]
            if signum not in (signal.SIGINT, signal.SIGTERM):
                continue
            if not self.report:  # a rank other than 0 goes on (_signals), for a while
                if not self.closed.wait(GRACE_S):
                    self._end(signum)
                return
            if self.handled.wait(GRACE_S) or self.closed.is_set():
                # the main thread took it: it writes the report once the interrupt has
                # left the command (the signals' block closed), unless it was lost
                if self.closed.wait(UNWIND_S):
                    return
            self._end(signum)

    def _end(self, signum: int) -> None:
        if not self.report:  # nothing to say or keep: rank 0 reports what converged
            _remove_private()
            os._exit(128 + signum)
        from . import runner  # noqa: PLC0415  (lazy: the library is imported by now)

        line = []

        def report():
            try:
                line.append(runner.report_interrupt(signum))
            except Exception as e:  # noqa: BLE001 - the process ends anyway; say why
                line.append(f"interrupted; the report could not be written ({e})")

        t = threading.Thread(target=report, daemon=True)
        t.start()
        t.join(REPORT_S)
        text = line[0] if line else "interrupted; the report took too long and was abandoned"
        try:
            print(f"\nsignorini: {text} (the signal came inside a library call, which was "
                  "abandoned)", file=sys.stderr, flush=True)
        finally:
            _remove_private()
            _remove_others()
            os._exit(128 + signum)

    def close(self):
        self.closed.set()
        if self.old_fd is not None:
            signal.set_wakeup_fd(self.old_fd)
            try:
                self.wsock.send(b"\0")  # wakes the thread, which sees it is closed
            except OSError:
                pass
            self.thread.join(1.0)
        for s in (self.wsock, self.rsock):
            try:
                s.close()
            except OSError:
                pass


def _main(argv) -> int:
    argv = list(argv)
    if argv:
        argv[0], notice = registry.current_name(argv[0])
        if notice:
            print(f"signorini: {notice}", file=sys.stderr)
    parser = build_parser(argv[0] if argv and argv[0] in registry.COMMANDS else None)
    extra: list[str] = []
    if argv[:1] == ["sweep"] and "--" in argv:  # arguments after -- go to every run of the sweep
        k = argv.index("--")
        argv, extra = argv[:k], argv[k + 1:]
    args = parser.parse_args(argv)
    args.extra = extra
    _configure_logging(args)
    show = not (args.quiet or args.verbose) and sys.stderr.isatty()
    flt = _OnceFilter()
    logger = logging.getLogger("signorini")
    logger.addFilter(flt)
    try:
        if getattr(args, "solver", None) in MPI_SOLVERS:
            # under mpiexec, every rank but 0 silent, its outputs in a private directory
            # kept until its interrupt or error report is written
            from . import ranks  # noqa: PLC0415  (lazy: the library, after the output helper started)

            with ranks.ranks(args) as rank:
                return _run(args, show and rank == 0, report=rank == 0)
        return _run(args, show)
    finally:
        logger.removeFilter(flt)


def _run(args, show: bool, report: bool = True) -> int:
    """The command, its errors and interrupts reported (:func:`_main`); without
    ``report`` (a rank other than 0 under mpiexec) SIGINT is left ignored and
    SIGTERM does not stop the run (:func:`_signals`): rank 0 reports what converged
    and then removes this rank's private directory, after which an error of this
    rank (a file it can no longer write) ends it without a word."""
    noted = None
    try:
        from .. import progress  # noqa: PLC0415  (lazy: after the output helper started)

        with progress.bars(show), _signals(report=report) as noted:
            return registry.command(args.command).execute(args)
    except KeyboardInterrupt as e:  # SIGINT, or SIGTERM (_signals): keep what converged
        signum = getattr(e, "signum", signal.SIGINT)
        with _signals(final=128 + signum):
            print(file=sys.stderr)  # past a progress bar's line
            from . import runner  # noqa: PLC0415  (lazy: the library, after the output helper started)

            print(f"signorini: {runner.report_interrupt(signum)}", file=sys.stderr)
            _remove_others()  # under mpiexec: the launcher kills the other ranks any moment
        return 128 + signum
    except ConvergenceError as e:
        print(f"signorini: the solve failed: {e}", file=sys.stderr)
        print(f"converged increments and summary.json (status 'failed') are in {args.out}/",
              file=sys.stderr)
        return 1
    except SignoriniError as e:
        print(f"signorini: error: {e}", file=sys.stderr)
        return 2
    except Exception:
        if noted is not None and noted.is_set() and not report:
            return 128 + signal.SIGTERM  # its directory removed by rank 0, which reports
        raise


if __name__ == "__main__":
    entry()
