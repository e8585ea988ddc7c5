"""The strict reading of a problem file's tables: typed getters that name the
table, the key and its line in every error (the schema: :mod:`signorini.app.problemfile`)."""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections import OrderedDict
from pathlib import Path

from ...errors import InputError, UnknownParameterError
from .expr import parse

_REQUIRED = object()
AXES = "xyz"


def kind(v) -> str:
    """What a TOML value is, for messages."""
    if isinstance(v, bool):
        return f"a boolean ({str(v).lower()})"
    if isinstance(v, int):
        return f"an integer ({v})"
    if isinstance(v, float):
        return f"a number ({v})"
    if isinstance(v, str):
        return f"a string ({v!r})"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return type(v).__name__


_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\-\"]+)\s*\]\]?")


class Reader:
    """Validation state of one file: its label (for messages), its text (for the
    lines of keys), its parameters and dimension."""

    def __init__(self, path: Path, text: str = "", force_size: bool = False, solver="auto"):
        self.path = path
        self.label = str(path)
        self.lines = text.splitlines()
        self.params: dict[str, float] = {}
        self.warnings: list[str] = []  # what reading found suspicious
        self.dim = 2
        # the size guard of a generated mesh, before it is built
        self.force_size, self.solver = force_size, solver

    def line_of(self, where: str, key: str | None) -> int | None:
        """The line (1-based) of ``key`` in the table ``where`` ("[mesh]",
        "[[contact]] #2 obstacle", "[fit.parameters]", ...), or of its header."""
        m = re.match(r"\s*(\[\[?)([A-Za-z0-9_.]+)\]\]?(?:\s*#(\d+))?", where)
        if not m:
            return None
        name, nth = m.group(2), int(m.group(3) or 1)
        double = m.group(1) == "[["
        start, seen = None, 0
        for i, line in enumerate(self.lines):
            h = _HEADER.match(line)
            if h and h.group(1) == name and line.lstrip().startswith("[[" if double else "[") \
                    and (double or not line.lstrip().startswith("[[")):
                seen += 1
                if seen == nth:
                    start = i
                    break
        if start is None:
            return None
        if key is None:
            return start + 1
        pat = re.compile(rf"(^|[\s{{,]){re.escape(str(key))}\s*=")
        for i in range(start + 1, len(self.lines)):
            line = self.lines[i]
            if _HEADER.match(line):
                break
            if pat.search(line):
                return i + 1
        return start + 1

    def error(self, where: str, msg: str, cls=InputError, key: str | None = None):
        line = self.line_of(where, key)
        return cls(f"{self.label}: {where} {msg}" + (f" (line {line})" if line else ""))


class Table:
    """One TOML table with strict keys; typed getters name the key on error."""

    def __init__(self, rd: Reader, where: str, data, allowed, required=()):
        self.rd, self.where = rd, where
        if not isinstance(data, dict):
            raise rd.error(where, f"must be a table, got {kind(data)}; see the schema in "
                                  "docs/problem-files.md")
        self.data = data
        allowed = sorted(set(allowed))
        for k in data:
            if k not in allowed:
                near = difflib.get_close_matches(k, allowed, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise rd.error(where, f"unknown key {k!r}{hint}; allowed: {', '.join(allowed)}",
                               key=k)
        for k in required:
            if k not in data:
                raise rd.error(where, f"missing required key {k!r}; add {k} = ...")

    def err(self, key, msg, cls=InputError):
        base = str(key).split("[", 1)[0]
        return self.rd.error(self.where, f"{key}: {msg}", cls, key=base)

    def get(self, key, default):
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.rd.error(self.where, f"missing required key {key!r}; add {key} = ...")
        return default

    _get = get

    def has(self, key) -> bool:
        return key in self.data

    # typed getters
    def string(self, key, default=_REQUIRED, choices=None):
        v = self.get(key, default)
        if v is default and key not in self.data:
            return v
        if not isinstance(v, str):
            raise self.err(key, f"expected a string, got {kind(v)}")
        if choices is not None and v not in choices:
            near = difflib.get_close_matches(v, choices, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise self.err(key, f"{v!r} is not one of {', '.join(map(repr, choices))}{hint}")
        return v

    def boolean(self, key, default=_REQUIRED):
        v = self.get(key, default)
        if not isinstance(v, bool):
            raise self.err(key, f"expected true or false, got {kind(v)}")
        return v

    def integer(self, key, default=_REQUIRED, minimum=None):
        v = self.get(key, default)
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(key, f"expected an integer, got {kind(v)}")
        if minimum is not None and v < minimum:
            raise self.err(key, f"must be >= {minimum}, got {v}")
        return v

    def real(self, key, default=_REQUIRED, positive=False, nonnegative=False, value=None):
        """A plain number (no parameter name)."""
        v = self.get(key, default) if value is None else value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.err(key, f"expected a number, got {kind(v)}")
        v = float(v)
        if not math.isfinite(v) or (positive and not v > 0) or (nonnegative and not v >= 0):
            need = "a positive" if positive else "a non-negative" if nonnegative else "a finite"
            raise self.err(key, f"must be {need} number, got {v}")
        return v

    def spec(self, key, default=_REQUIRED, value=None, what=None):
        """A number, the name of a parameter (returned as float or str), or an
        expression of parameters such as "-d" or "2*R" (a function of the
        parameters, parsed safely: :mod:`.expr`)."""
        v = self.get(key, default) if value is None else value
        what = what or key
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            raise self.err(what, f"expected a number or a parameter name, got {kind(v)}")
        if isinstance(v, str):
            if v in self.rd.params:
                return v
            if v.isidentifier():
                defined = ", ".join(sorted(self.rd.params)) or "none"
                raise self.err(what, f"{v!r} is not a parameter (defined in [params]: {defined}); "
                                     "add it to [params] or write a number", UnknownParameterError)
            try:
                return intern(("spec", v, tuple(sorted(self.rd.params))),
                              lambda: parse(v, (), self.rd.params).of_params())
            except InputError as e:
                raise self.err(what, f"{e}") from None
        v = float(v)
        if not math.isfinite(v):
            raise self.err(what, f"must be finite, got {v}")
        return v

    def vector(self, key, default=_REQUIRED, dim=None, value=None):
        dim = self.rd.dim if dim is None else dim
        v = self.get(key, default) if value is None else value
        if not isinstance(v, list) or len(v) != dim:
            names = ", ".join("abc"[:dim])
            raise self.err(key, f"expected a list of {dim} numbers [{names}] (the mesh is "
                                f"{self.rd.dim}-D), got {kind(v)}"
                                + (f" of length {len(v)}" if isinstance(v, list) else ""))
        return tuple(self.spec(key, value=x, what=f"{key}[{i}]") for i, x in enumerate(v))

    def component(self, key, value=None):
        v = self.get(key, _REQUIRED) if value is None else value
        dim = self.rd.dim
        if isinstance(v, str) and v in AXES[:dim]:
            return AXES.index(v)
        if isinstance(v, int) and not isinstance(v, bool) and 0 <= v < dim:
            return v
        allowed = ", ".join([str(i) for i in range(dim)] + [f'"{a}"' for a in AXES[:dim]])
        raise self.err(key, f"expected {allowed} (the mesh is {dim}-D), got {kind(v)}")

    def value(self, key):
        if callable(key):
            return float(key(self.rd.params))
        return self.rd.params[key] if isinstance(key, str) else key


def read_toml(path: Path) -> tuple[dict, str]:
    """(the document, its text)."""
    if not path.exists():
        raise InputError(f"{path}: problem file not found; check the file name and path")
    if path.is_dir():
        raise InputError(f"{path}: is a directory; give the path of a .toml problem file")
    try:
        raw = path.read_bytes()
        text = raw.decode("utf-8")
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: TOML syntax error: {e}; fix the file (TOML: key = value lines, "
                         "[table] headers, strings in quotes)") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a UTF-8 text file ({e.reason} at byte {e.start}); "
                         "a problem file must be TOML text") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read the problem file ({e.strerror or e})") from None


# Meshes, materials and expressions are reused between loads of equal descriptions,
# so that problems differing only in [params] values share the compiled model
# (signorini.solve caches models by mesh and material identity): finite
# differences and design loops by re-running a file do not recompile.
_INTERN: OrderedDict = OrderedDict()


def intern(key, make):
    try:
        v = _INTERN[key]
        _INTERN.move_to_end(key)
        return v
    except KeyError:
        pass
    v = make()
    _INTERN[key] = v
    if len(_INTERN) > 64:
        _INTERN.popitem(last=False)
    return v
