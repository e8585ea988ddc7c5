"""Progress of long runs: which solve is running, increment k/N, Newton iterations.

The library itself prints nothing: it logs on the ``signorini`` logger (one
INFO line per increment, one DEBUG line per Newton iteration, WARNING for
suspicious results). A front end that wants progress bars (the ``signorini``
command does) switches them on with :func:`show_bars`; each call of
:func:`signorini.solve` then shows one labelled bar over the load factor
("base", "FD R+", ...) with the increment count, the Newton iterations and the
last residual norm.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

log = logging.getLogger("signorini")

_BARS = {"on": False}
#: the functions told of each converged increment of this thread's solves (:func:`on_increment`)
_LISTENERS = threading.local()


def show_bars(on: bool = True) -> None:
    """Show (or hide) a progress bar per solve on stderr."""
    _BARS["on"] = bool(on)


def bars_enabled() -> bool:
    return _BARS["on"]


@contextlib.contextmanager
def bars(on: bool = True):
    """Context manager form of :func:`show_bars`; log records are written above
    the bars instead of through them."""
    old = _BARS["on"]
    show_bars(on)
    try:
        if on:

            # the handlers that print (the root's, as the command line sets them up)
            target = logging.root if logging.root.handlers else log
            with logging_redirect_tqdm(loggers=[target]):
                yield
        else:
            yield
    finally:
        show_bars(old)


@contextlib.contextmanager
def on_increment(fn):
    """While in the block, call ``fn(label, n, t)`` after each increment a solve of
    this thread converges: the solve's label, the increments it has converged so
    far (the new one is the solution's last) and the load factor reached. What
    ``fn`` raises goes up through the solve (an interrupt as anywhere else)."""
    fns = getattr(_LISTENERS, "fns", None)
    if fns is None:
        fns = _LISTENERS.fns = []
    fns.append(fn)
    try:
        yield
    finally:
        fns.remove(fn)


class SolveProgress:
    """Progress of one solve: a tqdm bar over the load factor t in [0, 1] when
    bars are on, INFO log lines otherwise (labelled either way)."""

    def __init__(self, label: str | None, steps: int):
        self.label = label or "solve"
        self.steps = steps
        self.n_inc = 0
        self._bar = None
        if _BARS["on"]:

            self._bar = tqdm(total=1000, desc=f"{self.label:>10s}", file=sys.stderr, leave=False,
                             bar_format="{desc}: {percentage:3.0f}%|{bar:20}| {unit}", unit="",
                             dynamic_ncols=True)

    def increment(self, t: float, steplog) -> None:
        """A converged increment ending at load factor t."""
        self.n_inc += 1
        res = steplog.residuals[-1] if steplog.residuals else float("nan")
        # with a bar the line would only repeat it: DEBUG (shown by --verbose, which has no bars)
        floor = getattr(steplog, "stop", "") == "round-off floor"
        log.log(logging.DEBUG if self._bar is not None else logging.INFO,
                "[%s] increment %d (t = %.4g of 1, nominal %d): %d Newton it%s, |R| %s%s",
                self.label, self.n_inc, t, self.steps, steplog.iterations,
                steplog.linear_summary() if hasattr(steplog, "linear_summary") else "",
                " ".join(f"{r:.1e}" for r in steplog.residuals),
                f", at the round-off floor ({steplog.relative_residual:.1e} of the reference)"
                if floor else "")
        if self._bar is not None:
            self._bar.n = int(round(1000 * t))
            self._bar.unit = (f"t = {t:.3f}, increment {self.n_inc} (nominal {self.steps}), "
                              f"{steplog.iterations} Newton it, |R| {res:.1e}")
            self._bar.refresh()
        for fn in tuple(getattr(_LISTENERS, "fns", ())):
            fn(self.label, self.n_inc, t)

    def cut(self, t: float, reason: str, dt: float) -> None:
        log.info("[%s] increment to t = %.4g failed (%s); cutting the step to %.3g", self.label, t,
                 reason, dt)

    def close(self, status: str) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        log.info("[%s] %s: %d increments", self.label, status, self.n_inc)
