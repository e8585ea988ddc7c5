"""Configuration shared by both test folders:

* ``tests/unit/``: one file per module of ``src/signorini`` (test_<module>.py),
  plus the cross-cutting catalogues test_errors.py and test_bad_inputs.py;
* ``tests/validation/``: the paper's benchmarks and analytical checks (Hertz,
  frictional Hertz, punch, forging Table 1, load paths, obstacle motion,
  Lamé, the tutorial, the CLI's printed sensitivities against FD).

Test modules are imported by their file name (pytest's default ``prepend``
import mode, no ``__init__.py``), so a file name must be unique across both
folders. Helpers used by more than one test module live in ``tests/helpers.py``
(``from helpers import ...``; this folder is put on ``sys.path`` below).
"""

import os
import sys

import pytest

import signorini  # noqa: F401  (float64 on)

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)  # tests/helpers.py, whatever the import mode


def pytest_collection_modifyitems(config, items):
    """Long runs are marked ``slow``; CI (CI=true) skips them. Each has a faster
    test covering the same code."""
    if os.environ.get("CI", "").lower() != "true":
        return
    skip = pytest.mark.skip(reason="slow test skipped in CI (CI=true); a faster test covers the same code")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
