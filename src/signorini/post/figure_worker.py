"""The helper process that draws a command's figures (``python -m
signorini.post.figure_worker``), started by :func:`signorini.post.plots.start_helper`.

It imports matplotlib at once (while the command imports JAX and solves, on the
other core), then draws each figure it is sent: jobs arrive on standard input as
pickled ``(id, kind, path, args, kwargs)`` tuples (``kind`` one of
:data:`signorini.post.plots.DRAW`), and for each one a JSON line ``{"id": ...,
"error": null or the traceback}`` goes back on standard output once the file is
written (atomically). It ends when its standard input closes (the command is
done or gone) and ignores Ctrl-C, which is the command's to handle.
"""

from __future__ import annotations

import json
import pickle
import signal
import sys
import traceback

from . import plots


def serve(jobs, replies) -> None:
    """Draw the jobs read from the binary stream ``jobs`` until it ends, replying
    on the text stream ``replies``."""
    plots.preload()
    while True:
        try:
            job_id, kind, path, args, kwargs = pickle.load(jobs)
        except EOFError:
            return
        try:
            plots.DRAW[kind](path, *args, **kwargs)
            error = None
        except Exception:  # noqa: BLE001  (reported to the command, which draws it itself)
            error = traceback.format_exc()
        replies.write(json.dumps({"id": job_id, "error": error}) + "\n")
        replies.flush()


def main() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        serve(sys.stdin.buffer, sys.stdout)
    except (BrokenPipeError, OSError, pickle.UnpicklingError):
        pass  # the command went away mid-message: nothing left to draw for


if __name__ == "__main__":
    main()
