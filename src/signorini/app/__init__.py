"""Applications on top of the library: the ``signorini`` command line, problem
files (TOML), parameter sweeps on Dask, and the helpers that turn a run into
files (summary.json, partial results, memory checks)."""
