"""Sphinx configuration of the signorini documentation.

Build (warnings are errors)::

    python3 -m pip install -e ".[docs]"
    python3 -m sphinx -W --keep-going -b html docs docs/_build/html

The pages are the Markdown files of this directory (MyST); the API reference
(reference.md) is generated from the docstrings by autosummary, recursively over
the ``signorini`` package, into ``docs/reference/`` (not under version control;
cleared at the start of every build so that a moved or deleted module leaves no
stale page behind).
"""

from __future__ import annotations

import ast
import importlib
import inspect
import logging
import os
import re
import shutil
import sys
import warnings
from pathlib import Path

from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx.errors import PycodeError
from sphinx.ext.autosummary import Autosummary
from sphinx.pycode import ModuleAnalyzer

# Importing signorini imports JAX: the build runs on the CPU, needs no
# accelerator, and must not write a compilation cache into the user's home.
os.environ["JAX_PLATFORMS"] = "cpu"
os.environ.setdefault("SIGNORINI_CACHE_DIR", "")

import signorini  # noqa: E402

HERE = Path(__file__).parent

# -- Project -------------------------------------------------------------------

project = "signorini"
author = "the signorini authors"
copyright = "the signorini authors, MIT licence"
release = signorini.__version__
version = ".".join(release.split(".")[:2])

# -- General -------------------------------------------------------------------

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = [
    "_build",
    "Thumbs.db",
    ".DS_Store",
    # the hand-written API reference, replaced by the generated one (reference.md);
    # kept in the repository for now, not part of the site
    "api.md",
]

# -- MyST (Markdown) -----------------------------------------------------------

myst_enable_extensions = ["dollarmath", "amsmath"]
# GitHub-style anchors for the headings, so the pages' links (theory.md#2-...) resolve
myst_heading_anchors = 6
# theory.md opens display math ($$) inside paragraphs, as GitHub allows
myst_dmath_double_inline = True

# -- autodoc / autosummary / napoleon -------------------------------------------

GENERATED = "reference"  # autosummary's output directory, relative to this file
shutil.rmtree(HERE / GENERATED, ignore_errors=True)

autosummary_generate = True
autosummary_generate_overwrite = True
autosummary_imported_members = False
# recurse into every public submodule of a package (its __all__ lists names, not modules)
autosummary_ignore_module_all = True

autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
autodoc_member_order = "bysource"
autodoc_preserve_defaults = True

napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_include_init_with_doc = False
napoleon_use_rtype = False
napoleon_attr_annotations = True

# -- HTML ----------------------------------------------------------------------

html_theme = "furo"
html_title = f"signorini {release}"
html_static_path: list[str] = []
html_show_sourcelink = False


# -- The public names of a package ------------------------------------------------

def _canonical(module, name: str) -> str:
    """Where ``module.name`` is documented: the module that defines it."""
    obj = getattr(module, name)
    if isinstance(obj, type(module)):
        return obj.__name__
    defined_in = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if isinstance(defined_in, str) and defined_in.startswith("signorini") and qualname:
        return f"{defined_in}.{qualname}"
    # a constant (no __module__): the public submodule that assigns it, preferring the
    # one with its doc comment (#:)
    found = []
    for modname, mod in sorted(sys.modules.items()):
        private = any(part.startswith("_") for part in modname.split("."))
        if (modname.startswith(module.__name__ + ".") and not private
                and getattr(mod, name, None) is obj):
            try:
                analyzer = ModuleAnalyzer.for_module(modname)
                analyzer.analyze()
            except PycodeError:
                continue
            if ("", name) in analyzer.attr_docs:
                return f"{modname}.{name}"
            if name in _assigned_names(analyzer.code):
                found.append(modname)
    return f"{found[0] if found else module.__name__}.{name}"


def _assigned_names(source: str) -> set[str]:
    """Names that a module's top level assigns (not those it imports)."""
    names = set()
    for node in ast.parse(source).body:
        targets = node.targets if isinstance(node, ast.Assign) else \
            [node.target] if isinstance(node, (ast.AnnAssign, ast.AugAssign)) else []
        for t in targets:
            names.update(n.id for n in ast.walk(t) if isinstance(n, ast.Name))
    return names


class PublicNames(Autosummary):
    """``public-names:: signorini``: an autosummary table of a module's ``__all__``,
    in its order, each name linked to the page of the module that defines it.
    Nothing if the module has no ``__all__``."""

    required_arguments = 1
    has_content = False
    option_spec = {"nosignatures": directives.flag}

    def run(self):
        module = importlib.import_module(self.arguments[0])
        names = getattr(module, "__all__", None)
        if not names:
            return []
        targets = [_canonical(module, n) for n in names]
        # inside the page of a package, name its own modules relatively (autosummary
        # refuses a full name that starts with the current module)
        current = self.env.ref_context.get("py:module")
        if current:
            targets = [t[len(current) + 1:] if t.startswith(current + ".") else t
                       for t in targets]
        self.arguments = []
        self.content = StringList([f"~{t}" for t in targets])
        return super().run()


# -- Constants without a doc comment ----------------------------------------------
#
# A module constant without a ``#:`` comment would be summarised by the docstring of
# its type (``dict() -> new empty dictionary ...``): give it none instead.


def _drop_type_docstring(app, what, name, obj, options, lines):
    if what not in ("data", "attribute") or inspect.isroutine(obj) or inspect.isclass(obj):
        return
    type_doc = getattr(type(obj), "__doc__", None)
    if isinstance(type_doc, str) and \
            "\n".join(lines).strip() == inspect.cleandoc(type_doc).strip():
        lines[:] = []


# -- Docstrings written as plain text ---------------------------------------------
#
# The docstrings write absolute values and norms as plain text (``|x|``, ``||R||``),
# which reStructuredText reads as substitution references or line blocks. Escape
# every ``|`` outside inline literals, roles, literal blocks (after ``::``) and
# directives before napoleon sees the docstring.

_INLINE = re.compile(r"(``.+?``|:[\w:.+-]+:`[^`]*`|`[^`]*`_{0,2})")


def _escape_bars(app, what, name, obj, options, lines):
    block_indent = None  # indentation of the line that opened a literal block / directive
    for i, line in enumerate(lines):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if block_indent is not None:
            if not stripped or indent > block_indent:
                continue
            block_indent = None
        if stripped.startswith(".. ") or stripped.startswith(">>>"):
            if stripped.startswith(".. "):
                block_indent = indent
            continue
        if stripped.endswith("::"):
            block_indent = indent
        if "|" in line:
            parts = _INLINE.split(line)
            lines[i] = "".join(p if k % 2 else p.replace("|", "\\|")
                               for k, p in enumerate(parts))


# -- Undocumented functions, classes and methods ------------------------------------
#
# Only members with a docstring are documented by default; a public function, class,
# method or property of signorini without one is listed too (with its signature),
# so that every row of a summary table has an entry. Undocumented data and
# attributes stay out (loggers, dataclass fields already described in an
# ``Attributes:`` section).


def _include_undocumented_code(app, what, name, obj, skip, options):
    if not skip or name.startswith("_"):
        return None
    code = obj.fget if isinstance(obj, property) else obj
    if not (inspect.isroutine(code) or inspect.isclass(code)) or inspect.getdoc(code):
        return None  # data, or skipped for another reason than a missing docstring
    module = getattr(code, "__module__", None)
    if isinstance(module, str) and (module == "signorini" or module.startswith("signorini.")):
        return False
    return None


# -- References to re-exported names --------------------------------------------------
#
# Every object is documented once, in the module that defines it. A reference by
# another path that imports it (``:func:`signorini.solve```, ``:class:`Problem``` in a
# module that imported Problem) is sent there. Deprecated 0.1 module paths are not
# followed.


def _lookup(dotted: str):
    parts = dotted.split(".")
    if parts[0] != "signorini":
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # an old path: not followed
        for i in range(len(parts), 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:i]))
            except Exception:
                continue
            try:
                for attr in parts[i:]:
                    obj = getattr(obj, attr)
            except Exception:
                return None
            return obj
    return None


def _resolve_reexported(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    module = node.get("py:module")
    candidates = [target]
    if module and not target.startswith("signorini."):
        candidates.insert(0, f"{module}.{target}")
    for name in candidates:
        obj = _lookup(name)
        if obj is None:
            continue
        if inspect.ismodule(obj):
            canonical, reftype = obj.__name__, "mod"
        else:
            defined_in = getattr(obj, "__module__", None)
            qualname = getattr(obj, "__qualname__", None)
            if not (isinstance(defined_in, str) and qualname):
                continue
            canonical, reftype = f"{defined_in}.{qualname}", "obj"
        if canonical == name:
            continue
        found = env.get_domain("py").resolve_xref(
            env, node["refdoc"], app.builder, reftype, canonical, node, contnode)
        if found is not None:
            return found
    return None


# -- Docstring warnings left to fix in src/ ---------------------------------------
#
# (object whose docstring warns, start of the docutils message). Each entry is a
# docstring that is not valid reStructuredText / Google style and can only be
# fixed in the source; the warning is dropped so that ``-W`` passes meanwhile.
# Delete an entry once its docstring is fixed (a stale entry does nothing).

DOCSTRING_WARNINGS_TO_FIX_IN_SRC: list[tuple[str, str]] = []


class _KnownDocstringWarnings(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        location = str(getattr(record, "location", "") or "")
        message = record.getMessage()
        for obj, start in DOCSTRING_WARNINGS_TO_FIX_IN_SRC:
            if re.search(rf"docstring of {re.escape(obj)}(:|$)", location) \
                    and message.startswith(start):
                return False
        return True


def setup(app):
    app.add_directive("public-names", PublicNames)
    app.connect("autodoc-process-docstring", _drop_type_docstring, priority=50)
    app.connect("autodoc-process-docstring", _escape_bars, priority=100)  # before napoleon
    app.connect("autodoc-skip-member", _include_undocumented_code)
    app.connect("missing-reference", _resolve_reexported)
    # ahead of Sphinx's own filters, which count the warnings for -W
    for handler in logging.getLogger("sphinx").handlers:
        handler.filters.insert(0, _KnownDocstringWarnings())
