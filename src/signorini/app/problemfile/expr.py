"""Arithmetic expressions of a problem file, parsed safely into JAX functions.

An implicit obstacle's surface (``expression = "sqrt(x^2 + y^2 + z^2) - R"``)
and a derived value (``"-d"``, ``"2*R"``) are parsed with :mod:`ast` and
checked against a whitelist: numbers; the names x, y, z (the point, where
coordinates are allowed) and the file's parameters; ``+ - * / ** ^`` (``^`` is
a power, as in the formulas people write), unary minus; the calls ``sqrt, exp,
log, sin, cos, tan, tanh, abs, min, max, hypot``; the constant ``pi``. Anything
else (attributes, subscripts, comparisons, strings, other calls, lambdas...) is
an :class:`~signorini.errors.InputError` naming it. The text is never given to
``eval``: the checked tree is translated node by node into jax.numpy calls.
"""

from __future__ import annotations

import ast
import math

from ..._jax import jnp
from ...errors import InputError

__all__ = ["Expression", "parse"]

_FUNCS = {"sqrt": (1, jnp.sqrt), "exp": (1, jnp.exp), "log": (1, jnp.log), "sin": (1, jnp.sin),
          "cos": (1, jnp.cos), "tan": (1, jnp.tan), "tanh": (1, jnp.tanh), "abs": (1, jnp.abs),
          "min": (2, jnp.minimum), "max": (2, jnp.maximum), "hypot": (2, jnp.hypot)}
_CONSTS = {"pi": math.pi}
_BIN = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
        ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b}
_MAX_LENGTH = 2000


class Expression:
    """A checked expression: ``names`` (the parameters it uses) and its evaluation."""

    def __init__(self, text: str, tree: ast.AST, coords: tuple[str, ...], names: tuple[str, ...]):
        self.text, self._tree, self.coords, self.names = text, tree, coords, names

    def __repr__(self) -> str:
        return f"<expression {self.text!r}>"

    def evaluate(self, env: dict):
        try:
            return _eval(self._tree, env)
        except (ArithmeticError, ValueError) as e:  # 1/0, an overflowing power of numbers
            raise InputError(f"{self.text!r} cannot be evaluated: {type(e).__name__}: {e}") from None

    def distance(self):
        """``f(y, p)``: the value at the point y (its coordinates x, y[, z]) for the
        parameter values p (what :class:`signorini.Implicit` takes)."""
        coords = self.coords

        def f(y, p):
            env = {c: y[i] for i, c in enumerate(coords)}
            env.update(p)
            return self.evaluate(env) + 0.0 * y[0]
        f.__qualname__ = f"expression {self.text!r}"
        return f

    def of_params(self):
        """``f(params)``: the value for the parameters (a parameter spec)."""
        names = self.names

        def f(p):
            return self.evaluate({n: p[n] for n in names})
        f.__qualname__ = f"expression {self.text!r}"
        return f


def _eval(node, env):
    if isinstance(node, ast.Constant):
        # an integer stays one: x ** 2 is then JAX's integer power, smooth to every
        # order at x = 0 (x ** 2.0 is not: its third derivative there is NaN)
        return node.value if isinstance(node.value, int) else float(node.value)
    if isinstance(node, ast.Name):
        return env[node.id] if node.id in env else _CONSTS[node.id]
    if isinstance(node, ast.UnaryOp):
        v = _eval(node.operand, env)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp):
        a, b = _eval(node.left, env), _eval(node.right, env)
        if isinstance(node.op, ast.Pow):
            # no power of two Python integers (9**9**9 would run for ever): a number
            # base becomes a float, and only a small integer exponent stays an integer
            if isinstance(a, int):
                a = float(a)
            if isinstance(b, int) and abs(b) > 64:
                b = float(b)
        return _BIN[type(node.op)](a, b)
    _, fn = _FUNCS[node.func.id]
    return fn(*(_eval(a, env) for a in node.args))


def _check(node, allowed: set, text: str, used: set):
    def bad(what):
        return InputError(f"{text!r}: {what} is not allowed in an expression (numbers, the names "
                          f"{', '.join(sorted(allowed)) or 'none'}, + - * / ^ **, and "
                          f"{', '.join(sorted(_FUNCS))})")
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise bad(f"the constant {node.value!r}")
        return
    if isinstance(node, ast.Name):
        if node.id in allowed:
            used.add(node.id)
            return
        if node.id in _CONSTS:
            return
        if node.id in _FUNCS:
            raise bad(f"the function {node.id!r} without its argument")
        raise InputError(f"{text!r}: unknown name {node.id!r}; an expression may use "
                         f"{', '.join(sorted(allowed)) or 'no names'} (the coordinates and the "
                         "parameters of [params]) and pi")
    if isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, (ast.USub, ast.UAdd)):
            raise bad(f"the operator {type(node.op).__name__}")
        return _check(node.operand, allowed, text, used)
    if isinstance(node, ast.BinOp):
        if type(node.op) not in _BIN:
            raise bad(f"the operator {type(node.op).__name__}")
        _check(node.left, allowed, text, used)
        return _check(node.right, allowed, text, used)
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in _FUNCS:
            name = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
            raise bad(f"the call of {name!r}")
        n, _ = _FUNCS[node.func.id]
        if node.keywords or len(node.args) != n:
            raise InputError(f"{text!r}: {node.func.id} takes {n} argument(s)")
        for a in node.args:
            _check(a, allowed, text, used)
        return
    raise bad(f"{type(node).__name__} ({ast.unparse(node)!r})")


def parse(text: str, coords: tuple[str, ...], params) -> Expression:
    """Check ``text`` (names: ``coords`` and the parameters) and return its Expression."""
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"an expression must be a non-empty string, got {text!r}")
    if len(text) > _MAX_LENGTH:
        raise InputError(f"an expression is at most {_MAX_LENGTH} characters, got {len(text)}")
    try:
        # "^" is a power here (Python's ^ binds looser than +: "x^2 + y^2" would be x^(2+y)^2)
        tree = ast.parse(text.strip().replace("^", "**"), mode="eval").body
    except SyntaxError as e:
        raise InputError(f"{text!r}: not an arithmetic expression ({e.msg})") from None
    allowed = set(coords) | set(params)
    used: set = set()
    _check(tree, allowed, text, used)
    names = tuple(sorted(n for n in used if n not in coords))
    return Expression(text, tree, tuple(coords), names)
