"""The one place where JAX is configured.

signorini needs float64 everywhere: Newton is driven to relative residuals of
1e-12 and DDM sensitivities are compared with central finite differences at
steps of 1e-6, neither of which survives float32. Importing this module (which
``signorini/__init__.py`` does first) switches JAX to 64-bit mode and the CPU.

What signorini compiles is kept between runs under one directory,
``$SIGNORINI_CACHE_DIR`` if set (an empty value switches every cache off), else
``$XDG_CACHE_HOME/signorini`` (default ``~/.cache/signorini``): JAX's persistent
compilation cache in ``jax/`` (set up here) and signorini's own compiled
programs in ``programs/`` (:mod:`signorini._programs`).
"""

from __future__ import annotations

import os

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


def _enable_cache() -> None:
    d = cache_dir()
    if d is None:
        return
    try:
        os.makedirs(d, exist_ok=True)
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
