"""Figures (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def curves(path, series: list[dict], *, xlabel: str, ylabel: str, title: str = "",
           xlim: tuple | None = None) -> Path:
    """Plot curves. Each series: ``{"x", "y", "label", "style"}`` (style optional:
    ``"line"`` or ``"points"``)."""
    fig, ax = plt.subplots(figsize=(6, 4.2), dpi=120)
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
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
