"""The one place where JAX is configured.

signorini needs float64 everywhere: Newton is driven to relative residuals of
1e-12 and DDM sensitivities are compared with central finite differences at
steps of 1e-6, neither of which survives float32. Importing this module (which
``signorini/__init__.py`` does first) switches JAX to 64-bit mode and the CPU.

What signorini compiles is kept between runs under one directory,
``$SIGNORINI_CACHE_DIR`` if set (an empty value switches every cache off), else
``$XDG_CACHE_HOME/signorini`` (default ``~/.cache/signorini``): JAX's persistent
compilation cache in ``jax/`` (set up here) and signorini's own compiled
programs in ``programs/`` (:mod:`signorini._programs`). A cache of executables
is code that runs: the directories are created private (mode 0700), and JAX's
cache is not set up in a directory that another user owns or can write
(:func:`cache_path_problem`; :mod:`signorini._programs` says so when it first
uses the caches, and guards JAX's entries one by one).
"""

from __future__ import annotations

import os
import stat

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)


def cache_root() -> str | None:
    """Directory of everything signorini keeps between runs (None: switched off)."""
    d = os.environ.get("SIGNORINI_CACHE_DIR")
    if d is not None:
        return d or None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "signorini")


def cache_dir() -> str | None:
    """Directory of JAX's persistent compilation cache (None: switched off)."""
    root = cache_root()
    return None if root is None else os.path.join(root, "jax")


def cache_path_problem(st: os.stat_result) -> str | None:
    """Why a cache directory or entry with this ``os.stat`` must not be trusted
    (None: it may be): owned by another user, or writable by the group or others
    (who could then put their code in it)."""
    getuid = getattr(os, "getuid", None)
    if getuid is None:  # no owners to compare (Windows)
        return None
    uid = getuid()
    if st.st_uid != uid:
        return f"owned by another user (uid {st.st_uid}; this process runs as uid {uid})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by other users (mode {stat.S_IMODE(st.st_mode):04o})"
    return None


def make_private_dir(path) -> None:
    """Create ``path`` (and missing parents) if needed, itself with mode 0700."""
    os.makedirs(path, mode=0o700, exist_ok=True)


def _enable_cache() -> None:
    d = cache_dir()
    if d is None:
        return
    try:
        make_private_dir(cache_root())
        make_private_dir(d)
        if any(cache_path_problem(os.stat(p)) for p in (cache_root(), d)):
            return  # not trusted: run without JAX's cache (signorini._programs says why)
    except OSError:  # read-only home: run without the cache
        return
    jax.config.update("jax_compilation_cache_dir", d)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


_enable_cache()

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


def to_device(x):
    """A NumPy array (or scalar) as a JAX array, by a plain transfer: ``jnp.asarray``
    compiles a conversion program for every new shape, a compilation per shape on
    a first run (docs/theory.md §10.5). JAX arrays and tracers pass unchanged."""
    if isinstance(x, jax.Array):
        return x
    return jax.device_put(np.asarray(x))


__all__ = ["jax", "jnp", "to_device"]
