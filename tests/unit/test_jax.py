"""JAX set-up (signorini._jax): the persistent compilation cache directory,
set by SIGNORINI_CACHE_DIR (an empty value turns it off)."""

import os
import subprocess
import sys


def test_persistent_cache_directory(tmp_path):
    code = ("import signorini, jax; from signorini._jax import cache_dir; "
            "print(cache_dir()); print(jax.config.jax_compilation_cache_dir)")
    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(tmp_path / "c")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [str(tmp_path / "c" / "jax")] * 2 and (tmp_path / "c" / "jax").is_dir()
    env["SIGNORINI_CACHE_DIR"] = ""
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[0] == "None"


def test_import_signorini_is_quick_and_still_float64():
    """``import signorini`` imports no JAX (its names load when first used); JAX is
    in 64-bit mode whether it is imported after signorini or before it."""
    after = ("import sys, signorini; assert 'jax' not in sys.modules; import jax, jax.numpy as jnp; "
             "print(jnp.ones(1).dtype, jax.devices()[0].platform)")
    before = ("import jax, jax.numpy as jnp, signorini as sg; sg.Problem; "
              "print(jnp.ones(1).dtype, jax.devices()[0].platform)")
    for code in (after, before):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout.split()
        assert out == ["float64", "cpu"], code


def test_public_names_resolve():
    import signorini as sg

    for name in sg.__all__:
        assert getattr(sg, name) is not None
    assert set(sg.__all__) - {"__version__"} == set(sg._WHERE) | set(sg._SUBPACKAGES)
    assert sg.responses.contact_force.__module__ == "signorini.responses"
