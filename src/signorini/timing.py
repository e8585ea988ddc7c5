"""Where the time of a run goes: imports, tracing and compilation, solve,
sensitivities, output.

A :class:`Timings` object books the wall-clock intervals of named phases
(``with timings.phase("solve"): ...``) and, through JAX's monitoring events,
every interval JAX spends tracing a function, lowering it and compiling it (or
loading it from the persistent compilation cache). :meth:`Timings.split`
returns disjoint parts that add up to the whole: the compilation inside a phase
is counted once, as compilation, and taken out of the phase.

The ``signorini`` command writes that split into every ``summary.json`` (key
``timings``); a library user can do the same around their own calls::

    timings = signorini.timing.Timings()
    with timings.phase("solve"):
        sol = signorini.solve(problem, wrt=["R"])
    print(timings.split())

Listening to JAX's events starts with the first :class:`Timings` made (not on
import) and costs a list append per compiled program.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
import time
from contextvars import ContextVar

import numpy as np

#: JAX's events of the compilation path and the name of each in the split
_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "xla",
    "/signorini/program_load": "load",  # signorini._programs.LOAD_EVENT
}

_SPANS: list[tuple[str, float, float]] = []  # (kind, start, end) in time.time() seconds
_LOCK = threading.Lock()
_LISTENING = False


def _on_span(event: str, start: float, end: float, **_) -> None:
    kind = _EVENTS.get(event)
    if kind is not None:
        with _LOCK:
            _SPANS.append((kind, start, end))


def _listen() -> None:
    global _LISTENING
    with _LOCK:
        if _LISTENING:
            return
        _LISTENING = True
    import jax.monitoring  # noqa: PLC0415  (lazy: JAX is configured by signorini._jax first)

    jax.monitoring.register_event_time_span_listener(_on_span)


def process_start() -> float | None:
    """When this process started (``time.time()`` seconds, to 10 ms), from
    ``/proc`` on Linux; None where that is not available."""
    try:
        with open("/proc/self/stat") as f:
            ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return time.time() - (uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


class Timings:
    """Wall-clock time of a run, split into disjoint parts.

    Args:
        start: when the run started (``time.time()``); default now.
        imports_from: when the process started, to count the time before
            ``start`` as imports (e.g. :func:`process_start`); None: no imports part.
    """

    PHASES = ("solve", "sensitivities", "output")

    def __init__(self, start: float | None = None, imports_from: float | None = None):
        _listen()
        self.start = time.time() if start is None else start
        self.imports_from = imports_from
        self._phases: list[tuple[str, float, float]] = []
        self._open: tuple[str, float] | None = None  # the phase of mark(): (name, since)
        self._inner: list[str] = []  # the phase() blocks open now, innermost last

    def mark(self, name: str | None) -> None:
        """From now on the run is in phase ``name`` (None: none), until the next
        mark: the sequential alternative to :meth:`phase`."""
        now = time.time()
        if self._open is not None:
            self._phases.append((self._open[0], self._open[1], now))
        self._open = None if name is None else (name, now)

    @contextlib.contextmanager
    def phase(self, name: str):
        """Book the time of the ``with`` block under ``name`` (nested phases:
        the inner one is booked, the outer one gets the rest)."""
        a = time.time()
        self._inner.append(name)
        try:
            yield
        finally:
            self._inner.pop()
            self._phases.append((name, a, time.time()))

    def now(self) -> str | None:
        """The phase the run is in now (the innermost open one), or None."""
        if self._inner:
            return self._inner[-1]
        return None if self._open is None else self._open[0]

    def split(self, end: float | None = None) -> dict:
        """The parts in seconds: ``total_s`` (from the process start if
        ``imports_from`` was given), ``imports_s``, ``compile_s`` (tracing,
        lowering and compiling programs, or loading them from the caches, with its
        parts in ``compile``: ``trace_s``, ``lower_s``, ``xla_s`` (XLA's compilation
        or JAX's cache), ``load_s`` (signorini's kept programs) and the counts), one
        entry per phase (without the compilation in it) and ``other_s`` (the rest:
        building the problem, checks, logging).

        Every instant counts once: to compilation if JAX was compiling then,
        else to the innermost phase open then, else to ``other_s``."""
        end = time.time() if end is None else end
        phases = list(self._phases)
        if self._open is not None:  # the phase still open runs to the end
            phases.append((self._open[0], self._open[1], end))
        first = self.start if self.imports_from is None else min(self.imports_from, self.start)
        out = {"total_s": end - first}
        if self.imports_from is not None:
            out["imports_s"] = max(self.start - self.imports_from, 0.0)
        with _LOCK:
            spans = [(k, max(a, self.start), min(b, end)) for k, a, b in _SPANS
                     if b > self.start and a < end]
        cuts = np.unique(np.array([self.start, end] + [x for _, a, b in spans for x in (a, b)]
                                  + [min(max(x, self.start), end) for _, a, b in phases for x in (a, b)]))
        length = np.diff(cuts)
        names = list(self.PHASES) + sorted({n for n, _, _ in phases} - set(self.PHASES))
        owner = np.full(length.size, -1)
        for name, a, b in sorted(phases, key=lambda p: p[1] - p[2]):  # longest first, inner on top
            owner[np.searchsorted(cuts, a):np.searchsorted(cuts, b)] = names.index(name)
        parts = {}
        for kind in ("trace", "lower", "xla", "load"):
            on = np.zeros(length.size, dtype=bool)
            for k, a, b in spans:
                if k == kind:
                    on[np.searchsorted(cuts, a):np.searchsorted(cuts, b)] = True
            parts[kind] = on
        compiling = parts["trace"] | parts["lower"] | parts["xla"] | parts["load"]
        out["compile_s"] = float(length[compiling].sum())
        out["compile"] = {f"{k}_s": float(length[on].sum()) for k, on in parts.items()}
        out["compile"]["programs"] = sum(1 for k, _, _ in spans if k == "xla")
        out["compile"]["programs_loaded"] = sum(1 for k, _, _ in spans if k == "load")
        for k, name in enumerate(names):
            out[f"{name}_s"] = float(length[(owner == k) & ~compiling].sum())
        out["other_s"] = float(length[(owner < 0) & ~compiling].sum())
        return out


_CURRENT: ContextVar[Timings | None] = ContextVar("signorini_timings", default=None)


def current() -> Timings | None:
    """The :class:`Timings` of the run in progress (see :func:`recording`), or None."""
    return _CURRENT.get()


@contextlib.contextmanager
def recording(imports_from: float | None = None, fresh: bool = False):
    """Make a :class:`Timings` the current one for the ``with`` block (a run
    within a run books into the outer one, unless ``fresh``); yields it."""
    t = _CURRENT.get()
    if t is not None and not fresh:
        yield t
        return
    t = Timings(imports_from=imports_from)
    token = _CURRENT.set(t)
    try:
        yield t
    finally:
        _CURRENT.reset(token)


def mark(name: str | None) -> None:
    """:meth:`Timings.mark` of the current :class:`Timings`, if any."""
    t = _CURRENT.get()
    if t is not None:
        t.mark(name)


@contextlib.contextmanager
def phase(name: str):
    """Book the ``with`` block under ``name`` in the current :class:`Timings`, if any."""
    t = _CURRENT.get()
    if t is None:
        yield
        return
    with t.phase(name):
        yield


def recorded(fn):
    """Decorator: ``fn`` runs within :func:`recording` (a command's whole run)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with recording():
            return fn(*args, **kwargs)
    return wrapper
