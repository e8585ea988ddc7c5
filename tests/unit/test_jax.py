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
