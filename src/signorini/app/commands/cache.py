"""``signorini cache``: where the compiled programs are kept, how much, and clearing them."""

from __future__ import annotations

import shutil
from pathlib import Path

from ... import _jax, _programs
from ..options import Formatter, verbosity_options

NAME = "cache"


def add_parser(sub) -> None:
    """Add this command's sub-parser to ``sub``."""
    c = sub.add_parser(
        "cache", formatter_class=Formatter, help="show or clear the caches of compiled programs",
        description="signorini keeps what it compiles between runs: its own programs (the "
                    "executables of a model's kernels, keyed by the problem's structure, the code "
                    "version, JAX and the CPU) and JAX's compilation cache. Both live under "
                    "$SIGNORINI_CACHE_DIR (default $XDG_CACHE_HOME/signorini, i.e. "
                    "~/.cache/signorini); SIGNORINI_CACHE_DIR= (empty) switches them off. A stale "
                    "or damaged entry is detected and compiled again, never used: clearing is "
                    "only needed to free disk space. A cache of executables is code: an entry is "
                    "loaded only if it is yours and nobody else can write it, and a cache "
                    "directory another user owns or can write is not used at all (a warning "
                    "says so, also in summary.json).")
    c.add_argument("--clear", action="store_true", help="delete every cached program")
    verbosity_options(c)


def _size(d: Path | None) -> tuple[int, int]:
    if d is None or not d.is_dir():
        return 0, 0
    files = [p for p in d.rglob("*") if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


def execute(args) -> int:
    """Run the command for parsed ``args``; the exit code."""
    jax_dir = None if _jax.cache_dir() is None else Path(_jax.cache_dir())
    dirs = {"signorini programs": _programs.programs_dir(), "JAX compilation cache": jax_dir}
    if all(d is None for d in dirs.values()):
        print("the caches are switched off (SIGNORINI_CACHE_DIR is set and empty)")
        return 0
    for what, d in dirs.items():
        n, size = _size(d)
        if args.clear and d is not None and d.is_dir():
            shutil.rmtree(d, ignore_errors=True)
            print(f"{what}: {d}: removed {n} file(s), {size / 2**20:.1f} MB")
        else:
            print(f"{what}: {d}: {n} file(s), {size / 2**20:.1f} MB{_untrusted(d)}")
    return 0


def _untrusted(d: Path | None) -> str:
    """'' or why the directory (or the cache directory above it) is not used."""
    for p in (() if d is None else (d.parent, d)):
        why = _programs.directory_problem(p)
        if why is not None:
            return f" (not used: {p} is {why})"
    return ""
