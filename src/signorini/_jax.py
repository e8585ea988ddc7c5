"""The one place where JAX is configured.

signorini needs float64 everywhere: Newton is driven to relative residuals of
1e-12 and DDM sensitivities are compared with central finite differences at
steps of 1e-6, neither of which survives float32. Importing this module (which
``signorini/__init__.py`` does first) switches JAX to 64-bit mode and the CPU.
"""

from __future__ import annotations

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402

__all__ = ["jax", "jnp"]
