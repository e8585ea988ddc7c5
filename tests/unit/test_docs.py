"""The documentation site builds from the docstrings and the Markdown pages
with Sphinx, warnings as errors (a broken cross-reference, a malformed
docstring section or a page outside the table of contents fails it); and the
examples of the documentation use the public API: no example in the README,
docs/*.md or a docstring imports a private module or a module of signorini that
the documentation does not name."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_the_documentation_site_builds_without_warnings(tmp_path):
    pytest.importorskip("sphinx", reason="the docs extra is not installed: pip install -e '.[docs]'")
    pytest.importorskip("myst_parser")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                        "-d", str(tmp_path / "doctrees"), str(DOCS), str(tmp_path / "html")],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-4000:]
    assert (tmp_path / "html" / "reference.html").is_file()
    assert (tmp_path / "html" / "reference" / "signorini.html").is_file()


# ------------------------------------------------ examples use the public API only
ROOT = DOCS.parent

#: the modules of signorini a documentation example may import: ``signorini``
#: itself (its ``__all__`` is the public API, docs/reference.md) and the
#: subpackages the README or docs/architecture.md name as places to import from
#: (an entry ending in ``.*`` allows the package's modules too). Any other module
#: of signorini is an implementation detail an example must not depend on.
NAMED = {
    "signorini": "the public API",
    "signorini.problems.*": "the paper's problems, analytical solutions and responses "
                            "(README's example; architecture.md's problems layer)",
    "signorini.design.*": "gradient, finite differences and optimize (architecture.md's design "
                          "layer; README: design.optimize)",
    "signorini.app.sweep": "parameter sweeps as Dask tasks (README; architecture.md's app layer)",
    "signorini.algorithms.uzawa": "Uzawa's nested loops, a comparator (README: "
                                  "signorini.algorithms.uzawa.solve_uzawa)",
}


def _third_party() -> set[str]:
    """Import names of the packages signorini depends on (pyproject.toml), which an
    example may use beside the standard library."""
    import tomllib

    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    names = {re.match(r"[A-Za-z0-9_.-]+", d).group().lower().replace("-", "_") for d in deps}
    return names | {"distributed"}  # dask[distributed]: its own import name


def _named(module: str) -> bool:
    return any(module == n or (n.endswith(".*") and (module == n[:-2] or module.startswith(n[:-1])))
               for n in NAMED)


def _is_module(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def import_problems(code: str, where: str) -> list[str]:
    """What is wrong with the imports of ``code`` (Python source): a private
    module or name (a component starting with ``_``), a module of signorini that
    the documentation does not name (:data:`NAMED`; ``from signorini import fem``
    counts as importing ``signorini.fem``), or a module that is neither the
    standard library nor a dependency of signorini."""
    allowed_outside = set(sys.stdlib_module_names) | _third_party()
    out = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            modules = [(a.name, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                out.append(f"{where}: relative import in an example")
                continue
            modules = [(node.module, node.module)]
            for a in node.names:
                full = f"{node.module}.{a.name}"
                if a.name.startswith("_"):
                    modules.append((full, full))
                elif node.module.split(".")[0] == "signorini" and _is_module(full):
                    modules.append((full, full))
        else:
            continue
        for module, shown in modules:
            parts = module.split(".")
            if any(p.startswith("_") for p in parts):
                out.append(f"{where}: imports the private {shown}")
            elif parts[0] == "signorini":
                if not _named(module):
                    out.append(f"{where}: imports {shown}, a module the documentation does not "
                               f"name (import from signorini, or one of {sorted(NAMED)})")
            elif parts[0] not in allowed_outside:
                out.append(f"{where}: imports {shown}, neither the standard library nor a "
                           "dependency of signorini")
    return out


_FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)
_IMPORT_LINE = re.compile(r"^(?:>>>|\.\.\.)?\s*((?:from\s+[\w.]+\s+import\s+.+)"
                          r"|(?:import\s+[\w.]+.*))$")


def markdown_examples():
    """(where, code) of every ```python block of the README and docs/*.md."""
    for path in [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]:
        text = path.read_text()
        for k, m in enumerate(_FENCE.finditer(text), start=1):
            line = text.count("\n", 0, m.start()) + 1
            yield f"{path.relative_to(ROOT)}:{line} (python block {k})", m.group(1)


def docstring_import_lines():
    """(where, line) of every import statement in a code example of a docstring
    of the package: ``>>>`` lines and the literal blocks after ``::``."""
    for path in sorted((ROOT / "src" / "signorini").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            doc = ast.get_docstring(node, clean=True)
            if not doc:
                continue
            name = getattr(node, "name", "module")
            in_block, indent = False, 0
            for line in doc.splitlines():
                stripped = line.strip()
                depth = len(line) - len(line.lstrip())
                if in_block and stripped and depth <= indent:
                    in_block = False
                if not in_block and stripped.endswith("::"):
                    in_block, indent = True, depth
                    continue
                if (in_block or stripped.startswith(">>>")) and _IMPORT_LINE.match(stripped):
                    code = _IMPORT_LINE.match(stripped).group(1)
                    yield f"{path.relative_to(ROOT)} ({name})", code


def test_docs_examples_import_only_named_public_modules():
    """The README's and docs' Python examples and the code examples in docstrings
    import signorini only through ``signorini`` and the subpackages the
    documentation names (:data:`NAMED`), never a private module or name."""
    found, problems = 0, []
    for where, code in markdown_examples():
        problems += import_problems(code, where)
        found += 1
    for where, line in docstring_import_lines():
        problems += import_problems(line, where)
        found += 1
    assert found >= 15  # the README's example, the tutorial's blocks, docstring examples
    assert not problems, "\n".join(problems)


def test_named_subpackages_are_named_by_the_docs():
    """Every entry of NAMED is a module of signorini that the README or
    docs/architecture.md mention, so that the list follows the documentation."""
    text = (ROOT / "README.md").read_text() + (DOCS / "architecture.md").read_text()
    for entry in NAMED:
        module = entry.removesuffix(".*")
        assert _is_module(module), entry
        package = ".".join(module.split(".")[:2])
        assert package in text or module == "signorini", entry
        assert module.split(".")[-1] in text, entry


def test_the_import_check_catches_what_it_should():
    """The check refuses a private module, a private name, an unnamed module of
    signorini (directly or as ``from signorini import <subpackage>``) and an
    unknown package, and accepts the public spellings."""
    bad = {
        "from signorini._jax import jnp": "private signorini._jax",
        "from signorini.problems.hertz import _x": "private signorini.problems.hertz._x",
        "from signorini.contact.obstacles3d import Implicit": "signorini.contact.obstacles3d",
        "import signorini.fem.mesh3d": "signorini.fem.mesh3d",
        "from signorini import fem": "signorini.fem",
        "import pandas": "pandas",
    }
    for code, fragment in bad.items():
        problems = import_problems(code, "x")
        assert len(problems) == 1 and fragment in problems[0], (code, problems)
    good = ["import signorini as sg", "from signorini import Implicit, box, read_mesh",
            "import jax.numpy as jnp", "import numpy as np", "from signorini.problems import hertz",
            "from signorini.design.optimize import Objective", "from pathlib import Path",
            "from signorini.app.sweep import grid, run_sweep"]
    for code in good:
        assert import_problems(code, "x") == [], code
