"""Named parameters: every number a user may want a derivative with respect to.

A *parameter spec* is what a model component stores in place of a number:

* a ``float`` — a constant (no sensitivity),
* a ``str`` — the name of a design parameter, looked up in the parameter dict,
* a callable ``f(params) -> scalar`` — any differentiable expression of them
  (e.g. the cylinder centre ``lambda p: p["R"]`` so that the cylinder keeps
  touching the block when its radius changes).

Parameters travel through the solver as a ``dict[str, jnp scalar]`` so JAX can
differentiate any residual with respect to any of them (DDM pseudo-load).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping
from typing import Union

import numpy as np

from ._jax import jax, jnp, to_device
from .errors import InputError, UnknownParameterError

Spec = Union[float, int, str, Callable]


def resolve(spec: Spec, params: Mapping):
    """Value of a parameter spec for the given parameter values."""
    if isinstance(spec, str):
        try:
            return params[spec]
        except KeyError:
            raise UnknownParameterError(
                f"unknown parameter {spec!r}; defined parameters: {sorted(params)}"
            ) from None
    if callable(spec):
        try:
            return spec(params)
        except KeyError as e:
            raise UnknownParameterError(
                f"unknown parameter {e.args[0]!r} in a parameter expression; defined parameters: "
                f"{sorted(params)}"
            ) from None
        except _TRACE_ERRORS as e:
            raise InputError(
                f"a parameter expression ({_name(spec)}) cannot be differentiated: it converts "
                f"its parameters to plain numbers ({type(e).__name__}); write it with jax.numpy "
                "(jnp.sin, jnp.sqrt, ...) instead of numpy or math, and without float() or if on "
                "a parameter's value"
            ) from None
    return spec


def _name(f) -> str:
    code = getattr(f, "__code__", None)
    where = f" at {code.co_filename}:{code.co_firstlineno}" if code is not None else ""
    return f"{getattr(f, '__qualname__', type(f).__name__)}{where}"


def _trace_errors() -> tuple:
    errors = jax.errors
    return tuple(getattr(errors, n) for n in ("TracerArrayConversionError", "ConcretizationTypeError",
                                            "TracerBoolConversionError", "TracerIntegerConversionError")
                 if hasattr(errors, n))


_TRACE_ERRORS = _trace_errors()


def names_in(specs: Iterable[Spec]) -> set[str]:
    """Parameter names referenced directly (by string) in ``specs``."""
    return {s for s in specs if isinstance(s, str)}


def check_names(names: Iterable[str], params: Mapping, what: str) -> None:
    """Raise :class:`UnknownParameterError` if a name is not defined."""
    for name in names:
        if name not in params:
            raise UnknownParameterError(
                f"unknown parameter {name!r} in {what}; defined parameters: "
                f"{sorted(params)}. Add it to the problem's params or fix the name."
            )


def as_jax(params: Mapping[str, float]) -> dict:
    """Parameters as a dict of float64 JAX scalars (a pytree JAX can differentiate)."""
    return {k: to_device(np.float64(float(v))) for k, v in params.items()}


def unit_tangents(params: Mapping, names: list[str]) -> dict:
    """Batched tangent pytree: entry k is 1 for ``names[k]`` and 0 elsewhere.

    Returns a dict of arrays of shape ``(len(names),)`` to be ``vmap``-ed over.
    Built once per (parameter keys, names) and reused: the DDM asks for it
    twice per increment, and building it afresh would transfer a new small
    array to the device per parameter each time.
    """
    return dict(_unit_tangents(tuple(params), tuple(names)))


@functools.lru_cache(maxsize=64)
def _unit_tangents(keys: tuple, names: tuple) -> tuple:
    return tuple((key, to_device(np.array([1.0 if key == n else 0.0 for n in names])))
                 for key in keys)


def parse_assignment(text: str) -> tuple[str, float]:
    """Parse ``NAME=VALUE`` as given to ``--set``."""
    if "=" not in text:
        raise InputError(f"--set expects NAME=VALUE, got {text!r}")
    name, value = text.split("=", 1)
    try:
        return name.strip(), float(value)
    except ValueError:
        raise InputError(f"--set {name}: {value!r} is not a number") from None
