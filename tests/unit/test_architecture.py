"""The package's layers (docs/architecture.md), read from the source itself.

Every ``import`` of ``src/signorini`` (also inside functions) is an edge of a
module graph. The graph has no circle; no module imports a higher layer; no
function imports a module of the package (a circle hidden from the reader)
except in the command's entry module, which imports the library only after
starting the output helper (marked ``lazy``), and a function imports a
third-party module only where a comment says why (an optional or heavy
dependency: ``optional`` or ``lazy``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
PKG = "signorini"

#: lowest first; a module may import its own layer or a lower one
LAYERS = [
    ("core", ["signorini._deprecation", "signorini.interfaces", "signorini._jax", "signorini._small", "signorini._memo", "signorini._version", "signorini.errors",
              "signorini.params", "signorini.progress", "signorini.timing",
              "signorini._programs"]),
    ("materials", ["signorini.materials"]),
    ("fem", ["signorini.fem"]),
    ("contact", ["signorini.contact"]),
    ("linsolve", ["signorini.linsolve"]),
    ("model", ["signorini.model"]),
    ("sensitivity", ["signorini.sensitivity"]),
    ("algorithms", ["signorini.algorithms"]),
    ("design", ["signorini.design", "signorini.responses"]),
    ("post", ["signorini.post"]),
    ("problems", ["signorini.problems"]),
    ("app", ["signorini.app"]),
    ("package", ["signorini", "signorini._compat"]),
]


def _modules() -> dict[str, Path]:
    out = {}
    for p in (SRC / PKG).rglob("*.py"):
        parts = list(p.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def layer(module: str) -> int:
    """Index in LAYERS of the longest prefix that names the module's layer."""
    best, idx = -1, None
    for k, (_, prefixes) in enumerate(LAYERS):
        for pre in prefixes:
            if (module == pre or module.startswith(pre + ".")) and len(pre) > best:
                best, idx = len(pre), k
    assert idx is not None, f"{module} is in no layer: add it to LAYERS in {__file__}"
    return idx


def _imports(module: str, path: Path):
    """(target module, line, inside a function, source line) of every import of the package."""
    tree = ast.parse(path.read_text())
    lines = path.read_text().splitlines()
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    in_function = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                   for n in ast.walk(f)}
    for node in ast.walk(tree):
        text = lines[node.lineno - 1] if hasattr(node, "lineno") else ""
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            continue
        for t in targets:
            yield t, node.lineno, id(node) in in_function, text


def graph() -> dict[str, set[str]]:
    g: dict[str, set[str]] = {m: set() for m in MODULES}
    for m, p in MODULES.items():
        for t, *_ in _imports(m, p):
            if t in MODULES and t != m:
                g[m].add(t)
    return g


def _cycle(g: dict[str, set[str]]):
    """One circle of the graph as a list of modules, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(g[m]):
            if state.get(t) == 1:
                return stack[stack.index(t):] + [t]
            if t not in state:
                found = visit(t)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(g):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def test_every_module_has_a_layer():
    for m in MODULES:
        layer(m)


def test_no_import_circle():
    assert _cycle(graph()) is None, " -> ".join(_cycle(graph()))


def upward(g: dict[str, set[str]]) -> list[str]:
    """The edges that go up the layers (a package may import its own children)."""
    return [f"{m} ({LAYERS[layer(m)][0]}) imports {t} ({LAYERS[layer(t)][0]})"
            for m, targets in g.items() for t in targets
            if layer(t) > layer(m) and not (m == PKG or t.startswith(m + "."))]


def test_no_module_imports_a_higher_layer():
    assert not upward(graph()), "\n".join(upward(graph()))


#: the modules that decide what a process loads first: they may import the
#: package's modules inside a function, where the line says "lazy"
ENTRIES = {"signorini.app.cli"}


def test_no_import_inside_a_function_without_a_reason():
    hidden = []
    for m, p in MODULES.items():
        for t, line, inside, text in _imports(m, p):
            if not inside:
                continue
            if (t == PKG or t.startswith(PKG + ".")) and not (m in ENTRIES and "lazy" in text):
                hidden.append(f"{p.relative_to(SRC)}:{line}: {text.strip()} (a module of the package)")
            elif "lazy" not in text and "optional" not in text:
                hidden.append(f"{p.relative_to(SRC)}:{line}: {text.strip()} (no 'lazy'/'optional' reason)")
    assert not hidden, "\n".join(hidden)


@pytest.mark.parametrize("edge", [("signorini.fem.mesh", "signorini.app.cli"),
                                  ("signorini.algorithms.stepping", "signorini.algorithms.coarse_to_fine")])
def test_the_checks_catch_an_upward_import_and_a_circle(edge):
    """The checks above can fail: an upward edge, and the circle that stepping <->
    coarse_to_fine once was."""
    g = graph()
    a, b = edge
    g[a] = g[a] | {b}
    assert upward(g) if layer(b) > layer(a) else _cycle(g) is not None
