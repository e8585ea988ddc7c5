"""Figures (matplotlib's Agg canvas: no display needed).

matplotlib is imported when the first figure is drawn, not with this module, and
without ``pyplot`` (whose backend machinery a file never needs): a run that
draws no figure does not pay for it.

The ``signorini`` command draws its figures in its output helper
(:mod:`signorini.post.helper`): :func:`curves` and :func:`meshes` hand the
figure over and return at once when the helper runs, and draw it here otherwise.
"""

from __future__ import annotations

from pathlib import Path

from . import helper
from .atomic import atomic


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


def curves(path, series: list[dict], *, xlabel: str, ylabel: str, title: str = "",
           xlim: tuple | None = None) -> Path:
    """Plot curves into ``path``. Each series: ``{"x", "y", "label", "style"}``
    (style optional: ``"line"`` or ``"points"``). Drawn by the output helper if
    one runs (the file exists after :func:`signorini.post.helper.finish`)."""
    helper.run("curves", path, series, xlabel=xlabel, ylabel=ylabel, title=title, xlim=xlim)
    return Path(path)


def meshes(path, panels: list[dict], *, title: str = "") -> Path:
    """Draw quad meshes side by side into ``path``. Each panel: ``{"x": (n_nodes,
    2), "cells": (n_cells, 4), "title": str, "color": cell values (optional)}``;
    equal axes. Drawn by the output helper if one runs."""
    helper.run("meshes", path, panels, title=title)
    return Path(path)
