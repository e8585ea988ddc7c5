"""What a model is built from, by content: the key under which a compiled
model is shared within a process (:func:`signorini.algorithms.stepping.model_for`)
and its programs are kept between processes (:mod:`signorini._programs`)."""

from __future__ import annotations

import dataclasses
import hashlib
import types
from collections.abc import Mapping

import numpy as np

from .._memo import ObjectMemo
from .problem import Problem


#: arrays of at least this many bytes keep their digest (by identity) between calls
_DIGEST_FROM = 1 << 16
_DIGESTS = ObjectMemo(64)


def _digest(a: np.ndarray) -> tuple:
    """(dtype, shape, BLAKE2 digest of the bytes) of an array; large arrays keep it
    while the same array object lives (a model key is rebuilt for every solve)."""
    a = np.asarray(a)
    memo = a.nbytes >= _DIGEST_FROM
    d = _DIGESTS.get(a) if memo else None
    if d is None:
        d = (a.dtype.str, a.shape, hashlib.blake2b(np.ascontiguousarray(a).view(np.uint8),
                                                  digest_size=16).digest())
        if memo:
            _DIGESTS.put(a, d)
    return d


def _pure_code(code) -> bool:
    """True if a function's code reads no global or attribute name (nor does any
    function defined inside it): its result is fixed by its arguments, defaults
    and closure values, so two such functions with the same code are the same."""
    return not code.co_names and all(_pure_code(c) for c in code.co_consts
                                     if isinstance(c, types.CodeType))


def _structure(obj, depth: int = 0):
    """A hashable key of what a model is built from, by content: equal for two
    problems made by the same code from the same mesh and definitions (a problem
    built again for other parameter values), so they share one compiled model.
    Arrays are keyed by their bytes, dataclasses by their fields, a function by
    its code and closure only when it reads no global name (anything else by its
    identity: never a false match)."""
    if depth > 12:
        return ("id", id(obj))
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes)):
        return (type(obj).__name__, obj)
    if isinstance(obj, np.ndarray):
        return ("array",) + _digest(obj)
    if isinstance(obj, np.generic):
        return (type(obj).__name__, obj.item())
    if isinstance(obj, (tuple, list)):
        return (type(obj).__name__,) + tuple(_structure(v, depth + 1) for v in obj)
    if isinstance(obj, Mapping):
        return ("map",) + tuple(sorted((repr(k), _structure(v, depth + 1)) for k, v in obj.items()))
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return (type(obj),) + tuple((f.name, _structure(getattr(obj, f.name), depth + 1))
                                    for f in dataclasses.fields(obj))
    if isinstance(obj, types.FunctionType) and _pure_code(obj.__code__):
        cells = tuple(_structure(c.cell_contents, depth + 1) for c in obj.__closure__ or ())
        return ("function", obj.__code__, _structure(obj.__defaults__, depth + 1),
                _structure(obj.__kwdefaults__, depth + 1), cells)
    return ("id", id(obj))


def structure_key(problem: Problem):
    """What a problem's model is built from, by content (:func:`_structure`) and
    the parameter names: equal for two problems that share a compiled model.
    TypeError if some component cannot be hashed."""
    key = (_structure((problem.mesh, problem.material, problem.fixed, problem.loads,
                       problem.contact, problem.shape, problem.shape_nominal,
                       problem.kinematics, problem.formulation)), tuple(sorted(problem.params)))
    hash(key)
    return key


def stable_digest(key) -> str | None:
    """A digest of a :func:`structure_key` that is the same in every process
    (types by their qualified names, code by its bytecode), or None if the key
    holds an object known only by its identity in this process."""
    h = hashlib.blake2b(digest_size=20)

    def feed(k) -> bool:
        if isinstance(k, tuple):
            if len(k) == 2 and k[0] == "id":
                return False
            h.update(b"(")
            ok = all(feed(v) for v in k)
            h.update(b")")
            return ok
        if isinstance(k, type):
            h.update(f"type:{k.__module__}.{k.__qualname__};".encode())
        elif isinstance(k, types.CodeType):  # what it does, not where its file is
            h.update(b"code:")
            return feed((k.co_code, k.co_consts, k.co_names, k.co_varnames, k.co_freevars,
                         k.co_cellvars, k.co_argcount, k.co_posonlyargcount,
                         k.co_kwonlyargcount, k.co_flags))
        elif isinstance(k, bytes):
            h.update(b"bytes:" + k + b";")
        elif k is None or isinstance(k, (bool, int, float, complex, str)):
            h.update(f"{type(k).__name__}:{k!r};".encode())
        else:
            return False
        return True

    return h.hexdigest() if feed(key) else None
