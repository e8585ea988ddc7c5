"""Figures (matplotlib's Agg canvas: no display needed).

matplotlib is imported when the first figure is drawn, not with this module, and
without ``pyplot`` (whose backend machinery a file never needs): a run that
draws no figure does not pay for it.

The ``signorini`` command draws its figures in a helper process
(:func:`start_helper`, :mod:`signorini.post.figure_worker`), started before the
command imports JAX: matplotlib's import and the drawing then run beside the
solve on another core instead of after it. :func:`curves` and :func:`meshes`
hand their figure to the helper when one runs and return at once;
:func:`finish` waits for the files (``summary.json`` is written after it). A
figure the helper could not draw, or all of them if it is gone or takes longer
than :data:`HELPER_BUDGET_S`, is drawn in the process itself, so the files are
the same either way. Without a helper (the library called from Python, a
sweep's points) everything is drawn in the calling process.
"""

from __future__ import annotations

import json
import logging
import os
import pickle
import select
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from .atomic import atomic

log = logging.getLogger(__name__)

#: seconds :func:`finish` waits for the helper before drawing what is left itself
HELPER_BUDGET_S = 60.0


def subplots(*args, **kwargs):
    """``(figure, axes)`` as ``pyplot.subplots`` makes them, on an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415  (lazy: heavy)
    from matplotlib.figure import Figure  # noqa: PLC0415  (lazy: heavy)

    fig_kw = {k: kwargs.pop(k) for k in ("figsize", "dpi") if k in kwargs}
    fig = Figure(**fig_kw)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(*args, **kwargs)


def save(fig, path) -> Path:
    """Write ``fig`` to ``path`` (the format from the extension), atomically."""
    with atomic(path) as tmp:
        fig.savefig(tmp)
    return Path(path)


def _curves(path, series: list[dict], *, xlabel: str, ylabel: str, title: str = "",
           xlim: tuple | None = None) -> Path:
    """Plot curves. Each series: ``{"x", "y", "label", "style"}`` (style optional:
    ``"line"`` or ``"points"``)."""
    fig, ax = subplots(figsize=(6, 4.2), dpi=120)
    for s in series:
        if s.get("style", "line") == "points":
            ax.plot(s["x"], s["y"], "o", ms=4, mfc="none", label=s["label"])
        else:
            ax.plot(s["x"], s["y"], "-", lw=1.5, label=s["label"])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if xlim is not None:
        ax.set_xlim(*xlim)
    ax.grid(alpha=0.3)
    ax.axhline(0, color="k", lw=0.5)
    ax.legend()
    fig.tight_layout()
    return save(fig, path)


def _meshes(path, panels: list[dict], *, title: str = "") -> Path:
    """Draw quad meshes side by side. Each panel: ``{"x": (n_nodes, 2), "cells":
    (n_cells, 4), "title": str, "color": cell values (optional)}``; equal axes."""

    from matplotlib.collections import PolyCollection  # noqa: PLC0415  (lazy: heavy)

    fig, axes = subplots(1, len(panels), figsize=(3.2 * len(panels) + 1, 4.6), dpi=120,
                             sharey=True, squeeze=False)
    lim = max(float(p["x"][:, 0].max()) for p in panels) * 1.05
    top = max(float(p["x"][:, 1].max()) for p in panels) * 1.05
    for ax, p in zip(axes[0], panels):
        polys = p["x"][p["cells"]]
        pc = PolyCollection(polys, edgecolors="k", linewidths=0.4,
                            facecolors="none" if p.get("color") is None else None)
        if p.get("color") is not None:
            pc.set_array(p["color"])
            pc.set_cmap("viridis")
            fig.colorbar(pc, ax=ax, shrink=0.8, label=p.get("color_label", ""))
        ax.add_collection(pc)
        ax.set_xlim(0, lim)
        ax.set_ylim(0, top)
        ax.set_aspect("equal")
        ax.set_xlabel("r")
        ax.set_title(p.get("title", ""))
    axes[0][0].set_ylabel("z")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path)


#: the figures a helper can draw: kind -> the function that draws it here
DRAW = {"curves": _curves, "meshes": _meshes}


def curves(path, series: list[dict], *, xlabel: str, ylabel: str, title: str = "",
           xlim: tuple | None = None) -> Path:
    """Plot curves into ``path``. Each series: ``{"x", "y", "label", "style"}``
    (style optional: ``"line"`` or ``"points"``). Drawn by the helper process if
    one runs (the file exists after :func:`finish`)."""
    return _draw("curves", path, series, xlabel=xlabel, ylabel=ylabel, title=title, xlim=xlim)


def meshes(path, panels: list[dict], *, title: str = "") -> Path:
    """Draw quad meshes side by side into ``path``. Each panel: ``{"x": (n_nodes,
    2), "cells": (n_cells, 4), "title": str, "color": cell values (optional)}``;
    equal axes. Drawn by the helper process if one runs."""
    return _draw("meshes", path, panels, title=title)


def preload() -> None:
    """Import what drawing needs (the helper does it while the command starts)."""
    from matplotlib import collections, figure  # noqa: F401, PLC0415  (lazy: heavy)
    from matplotlib.backends import backend_agg  # noqa: F401, PLC0415  (lazy: heavy)


class _Helper:
    """The helper process and the figures handed to it and not yet confirmed."""

    def __init__(self):
        self.proc = subprocess.Popen([sys.executable, "-m", "signorini.post.figure_worker"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.pending: dict[int, tuple] = {}
        self.count = 0
        self.waited = 0.0
        self._text = b""

    def submit(self, job: tuple) -> bool:
        """Hand ``(kind, path, args, kwargs)`` to the helper; False if it is gone."""
        self.count += 1
        try:
            pickle.dump((self.count, *job), self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.proc.stdin.flush()
        except (OSError, ValueError):
            return False
        self.pending[self.count] = job
        return True

    def collect(self, budget: float) -> list[tuple]:
        """Wait up to ``budget`` seconds for the pending figures; the jobs that
        failed or are still pending then (the helper is stopped if any is)."""
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
                    log.debug("the figure helper could not draw %s:\n%s", job[1], reply["error"])
                    failed.append(job)
        self.waited += time.monotonic() - t0
        if self.pending:
            log.debug("the figure helper did not finish %d figure(s); drawing them here",
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


_HELPER: _Helper | None = None
_LOCK = threading.Lock()


def start_helper() -> bool:
    """Start the helper process that draws this process's figures from now on
    (once; the ``signorini`` command does it first thing). False if it could
    not be started (figures are then drawn here)."""
    global _HELPER
    with _LOCK:
        if _HELPER is not None and _HELPER.alive():
            return True
        try:
            _HELPER = _Helper()
        except OSError as e:
            log.debug("no figure helper (%s): figures are drawn in this process", e)
            _HELPER = None
        return _HELPER is not None


def stop_helper() -> None:
    """Draw what the helper still owes (:func:`finish`) and end it."""
    global _HELPER
    finish()
    with _LOCK:
        if _HELPER is not None:
            _HELPER.stop()
            _HELPER = None


def finish() -> dict:
    """Wait for the figures handed to the helper (drawing here any it could not)
    and return ``{"helper": whether one draws the figures, "wait_s": seconds
    waited for it so far}``."""
    with _LOCK:
        helper = _HELPER
        failed = helper.collect(HELPER_BUDGET_S) if helper is not None else []
    for kind, path, args, kwargs in failed:
        DRAW[kind](path, *args, **kwargs)
    return {"helper": helper is not None and helper.alive(),
            "wait_s": 0.0 if helper is None else helper.waited}


def _draw(kind: str, path, *args, **kwargs) -> Path:
    job = (kind, str(path), _plain(args), _plain(kwargs))
    with _LOCK:
        handed = _HELPER is not None and _HELPER.submit(job)
    if not handed:
        DRAW[kind](path, *args, **kwargs)
    return Path(path)


def _plain(value):
    """``value`` with every array as a NumPy array (what the helper can unpickle
    without JAX)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    if hasattr(value, "__array__") and not isinstance(value, np.ndarray):
        return np.asarray(value)
    return value
