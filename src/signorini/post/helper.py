"""The output helper: a second process that draws a command's figures and
writes its VTU files while the command goes on (``python -m signorini.post.helper``).

The ``signorini`` command starts it first thing (:func:`start`), before it
imports the library and JAX: the helper imports matplotlib on the other core
meanwhile. An output function hands it a job with :func:`run` —
the name of a function of :data:`JOBS` and plain arguments (NumPy arrays,
numbers, strings) — and returns at once; :func:`finish` waits for the files
(``summary.json`` is written after it). A job the helper could not do, or all
of them when it is gone or has not answered within :data:`BUDGET_S`, is done in
the calling process, so the files are the same either way; so are jobs whose
arrays are larger than :data:`MAX_JOB_BYTES` (piping them would cost more than
it saves). Without a helper (the library called from Python, a sweep's points)
everything is done in the calling process.

Protocol: jobs arrive on the helper's standard input as pickled ``(id, kind,
args, kwargs)`` tuples; for each, a JSON line ``{"id": ..., "error": null or the
traceback}`` goes back on its standard output once the file is written. The
helper ends when its standard input closes and ignores Ctrl-C, which is the
command's to handle.
"""

from __future__ import annotations

import importlib
import json
import logging
import os
import pickle
import select
import signal
import subprocess
import sys
import threading
import time
import traceback

import numpy as np

log = logging.getLogger(__name__)

#: what the helper can do: kind -> "module:function" (the function writes its file)
JOBS = {
    "curves": "signorini.post.plots:_curves",
    "meshes": "signorini.post.plots:_meshes",
    "vtu": "signorini.post.files:_write_vtu_arrays",
}
#: seconds :func:`finish` waits for the helper before doing what is left itself
BUDGET_S = 60.0
#: a job whose arrays hold more bytes than this is done in the calling process
MAX_JOB_BYTES = 64 * 2**20


def _function(kind: str):
    module, name = JOBS[kind].split(":")
    return getattr(importlib.import_module(module), name)


def preload() -> None:
    """Import what the jobs need (the helper does it while the command starts)."""
    from matplotlib import collections, figure  # noqa: F401, PLC0415  (lazy: heavy)
    from matplotlib.backends import backend_agg  # noqa: F401, PLC0415  (lazy: heavy)

    for kind in JOBS:
        _function(kind)


class _Process:
    """The helper process and the jobs handed to it and not yet confirmed."""

    def __init__(self):
        self.proc = subprocess.Popen([sys.executable, "-m", "signorini.post.helper"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.pending: dict[int, tuple] = {}
        self.count = 0
        self.waited = 0.0
        self.jobs = 0
        self._text = b""

    def submit(self, job: tuple) -> bool:
        """Hand ``(kind, args, kwargs)`` to the helper; False if it is gone."""
        self.count += 1
        try:
            pickle.dump((self.count, *job), self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.proc.stdin.flush()
        except (OSError, ValueError):
            return False
        self.pending[self.count] = job
        self.jobs += 1
        return True

    def collect(self, budget: float) -> list[tuple]:
        """Wait up to ``budget`` seconds for the pending jobs; the jobs that failed
        or are still pending then (the helper is stopped if any is)."""
        t0 = time.monotonic()
        failed = []
        fd = self.proc.stdout.fileno()
        while self.pending:
            left = budget - (time.monotonic() - t0)
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                break
            data = os.read(fd, 65536)
            if not data:  # the helper ended
                break
            *lines, self._text = (self._text + data).split(b"\n")
            for line in lines:
                reply = json.loads(line)
                job = self.pending.pop(reply["id"], None)
                if job is not None and reply["error"]:
                    log.debug("the output helper failed on a %s job:\n%s", job[0], reply["error"])
                    failed.append(job)
        self.waited += time.monotonic() - t0
        if self.pending:
            log.debug("the output helper did not finish %d job(s); doing them here",
                      len(self.pending))
            failed += self.pending.values()
            self.pending.clear()
            self.stop()
        return failed

    def alive(self) -> bool:
        return self.proc.poll() is None and not self.proc.stdin.closed

    def stop(self) -> None:
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


_HELPER: _Process | None = None
_LOCK = threading.Lock()
#: every output job dropped (:func:`discard`)
_DISCARD = {"on": False}


def start() -> bool:
    """Start the helper that does this process's output jobs from now on (once;
    the ``signorini`` command does it first thing). False if it could not be
    started (the jobs are then done here)."""
    global _HELPER
    with _LOCK:
        if _HELPER is not None and _HELPER.alive():
            return True
        try:
            _HELPER = _Process()
        except OSError as e:
            log.debug("no output helper (%s): outputs are written by this process", e)
            _HELPER = None
        return _HELPER is not None


def stop() -> None:
    """Finish what the helper still owes (:func:`finish`) and end it."""
    global _HELPER
    finish()
    with _LOCK:
        if _HELPER is not None:
            _HELPER.stop()
            _HELPER = None


def abandon() -> None:
    """End the helper at once, the jobs it still has dropped: their files are not
    wanted (a rank's private outputs, about to be removed, :mod:`signorini.app.ranks`).
    Later jobs are done in the calling process. Takes no lock: a thread may call it
    while the main thread waits for the helper."""
    global _HELPER
    helper, _HELPER = _HELPER, None
    if helper is None:
        return
    try:
        helper.proc.kill()
        helper.proc.wait(timeout=5)
    except (OSError, subprocess.TimeoutExpired):
        pass


def discard(on: bool = True) -> None:
    """From now on (``on``) drop every figure and VTU file instead of drawing and
    writing it, and compute no VTU fields: a rank other than 0 of a run under
    ``mpiexec``, whose outputs nobody reads (:mod:`signorini.app.ranks`). Its helper,
    if any, is ended (one process fewer per rank). ``discard(False)`` restores."""
    _DISCARD["on"] = bool(on)
    if on:
        abandon()


def discarding() -> bool:
    """Whether output jobs are dropped (:func:`discard`)."""
    return _DISCARD["on"]


def finish() -> dict:
    """Wait for the jobs handed to the helper (doing here any it could not) and
    return ``{"used": whether a helper runs, "jobs": jobs handed to it,
    "wait_s": seconds waited for it}``."""
    with _LOCK:
        helper = _HELPER
        failed = helper.collect(BUDGET_S) if helper is not None else []
    for kind, args, kwargs in failed:
        _function(kind)(*args, **kwargs)
    return {"used": helper is not None and helper.alive(),
            "jobs": 0 if helper is None else helper.jobs,
            "wait_s": 0.0 if helper is None else helper.waited}


def run(kind: str, *args, **kwargs) -> None:
    """Do job ``kind`` (:data:`JOBS`) with these arguments: by the helper if one
    runs and the arrays are small enough, else here and now."""
    if _DISCARD["on"]:
        return
    job = (kind, _plain(args), _plain(kwargs))
    with _LOCK:
        handed = (_HELPER is not None and _nbytes(job) <= MAX_JOB_BYTES
                  and _HELPER.submit(job))
    if not handed:
        _function(kind)(*args, **kwargs)


def _plain(value):
    """``value`` with every array as a NumPy array (what the helper unpickles
    without JAX) and paths as strings."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "__array__") and not isinstance(value, np.ndarray):
        return np.asarray(value)
    return value


def _nbytes(value) -> int:
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return sum(_nbytes(v) for v in value)
    return value.nbytes if isinstance(value, np.ndarray) else 0


# ------------------------------------------------------------ the helper's side
def serve(jobs, replies) -> None:
    """Do the jobs read from the binary stream ``jobs`` until it ends, replying
    on the text stream ``replies``."""
    preload()
    while True:
        try:
            job_id, kind, args, kwargs = pickle.load(jobs)
        except EOFError:
            return
        try:
            _function(kind)(*args, **kwargs)
            error = None
        except Exception:  # noqa: BLE001  (reported to the command, which does the job itself)
            error = traceback.format_exc()
        replies.write(json.dumps({"id": job_id, "error": error}) + "\n")
        replies.flush()


def main() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        serve(sys.stdin.buffer, sys.stdout)
    except (BrokenPipeError, OSError, pickle.UnpicklingError):
        pass  # the command went away mid-message: nothing left to write for


if __name__ == "__main__":
    main()
