"""Kernels compiled once per kind, whatever the mesh: the chunked programs
behind the element kinds (:mod:`signorini.model.cells`) and the contact node
kinds (:mod:`signorini.model.nodes`) (docs/theory.md §10.6).

A kernel is a function of one item (a cell, a contact node): ``f(items, shared)``
with ``items`` a tuple of the item's data (arrays or pytrees of arrays, or None)
and ``shared`` a pytree of values common to every item (material values,
obstacle geometry). It is compiled for fixed chunks of items, ``vmap``-ed over
each chunk, and every mesh runs through the same compiled programs: the items
are gathered into chunks in NumPy, each chunk is one call of a program (its
executables kept in memory and on disk by :mod:`signorini._programs`), and the
results are concatenated. The last chunk is padded with copies of its first
item, whose results are dropped and whose cotangents are zero.

Besides the values, a kind gives directional derivatives (JVP, batched over
directions) and cotangents (VJP, the shared values' summed over the items) of
any kernel: the DDM pseudo-loads and the adjoint's transposed products.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .._jax import jax
from .._programs import Program
from .identity import _structure, stable_digest

tree_map = jax.tree_util.tree_map


def plan(n: int, sizes: tuple[int, int]) -> list[tuple[int, int]]:
    """(first item, chunk size) of every chunk covering n items: chunks of
    ``sizes[0]`` while that many are left, the rest in chunks of ``sizes[1]``."""
    big, small = sizes
    out, start = [], 0
    while n - start >= big:
        out.append((start, big))
        start += big
    while start < n:
        out.append((start, small))
        start += small
    return out


_POOL: list = []


def _pool() -> ThreadPoolExecutor:
    """The threads that run chunks side by side (one per core): a program runs
    on the thread that calls it, so chunks called from several threads use
    several cores."""
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max(1, os.cpu_count() or 1),
                                        thread_name_prefix="signorini-chunks"))
    return _POOL[0]


def _concat(parts, axis: int):
    """Concatenate a list of pytrees of (valid, arrays) along ``axis``."""
    return tree_map(lambda *a: np.concatenate(a, axis=axis), *parts)


class Chunked:
    """The chunked programs of one kind (subclasses define :meth:`_kernel`).

    One instance per kind and process (:meth:`of`); its programs are named by
    mode, kernel, outputs and tangent pattern, and kept on disk under the kind's
    content digest (memory only if the kind cannot be digested)."""

    #: items per chunk, largest first (subclasses choose)
    SIZES: tuple[int, int] = (4096, 512)
    _shared_kinds: dict = {}

    def __init__(self, parts, key):
        self.parts = parts
        self.key = key
        self._programs: dict = {}

    @classmethod
    def of(cls, *parts) -> Chunked:
        """The instance of this kind (``parts``: what the kernels are built from)."""
        try:
            structure = (cls.__qualname__, _structure(parts))
            hash(structure)
        except TypeError:
            structure = (cls.__qualname__, "id") + tuple(id(p) for p in parts)
        k = Chunked._shared_kinds.get(structure)
        if k is None:
            k = Chunked._shared_kinds[structure] = cls(parts, stable_digest(structure))
        return k

    def _kernel(self, name: str):  # pragma: no cover - abstract
        """f(items, shared) -> tuple of outputs, for one item."""
        raise NotImplementedError

    # ------------------------------------------------------------ programs
    def _program(self, mode: str, name: str, outs: tuple, mask: tuple = ()) -> Program:
        spec = (mode, name, outs, mask)
        p = self._programs.get(spec)
        if p is not None:
            return p
        kernel = self._kernel(name)
        one = lambda items, shared: tuple(kernel(items, shared)[i] for i in outs)
        over = jax.vmap(one, (0, None))  # every item of a chunk
        if mode == "primal":
            fn = over
        elif mode in ("jvp", "value_jvp"):
            # tangents of the arguments in ``mask`` only (the items', then the shared
            # values'; symbolic zeros elsewhere), batched over their leading axis;
            # value_jvp: with the outputs themselves, computed once (jax.linearize)
            idx = [i for i, m in enumerate(mask) if m]

            def fn(items, shared, dots):
                args = list(items) + [shared]

                def sub(*xs):
                    a = list(args)
                    for i, x in zip(idx, xs):
                        a[i] = x
                    return over(tuple(a[:-1]), a[-1])

                primals = tuple(args[i] for i in idx)
                if mode == "jvp":
                    return jax.vmap(lambda d: jax.jvp(sub, primals, d)[1])(dots)
                value, linear = jax.linearize(sub, *primals)
                return value, jax.vmap(lambda d: linear(*d))(dots)
        else:  # vjp
            def fn(items, shared, cot):
                return jax.vjp(over, items, shared)[1](cot)
        p = self._programs[spec] = Program(
            fn, f"{type(self).__name__}.{mode}.{name}.{outs}.{mask}", self.key)
        return p

    #: whether chunks run side by side from the pool's threads; a kind whose
    #: programs use XLA's own threads (the 3-D cells' larger contractions) runs
    #: them one after the other: two such programs called at once from two
    #: threads of a two-core machine wait for each other's threads for ever
    side_by_side = True

    # -------------------------------------------------------------- running
    def _run(self, n: int, prog, call, items, dots=(), zero=()):
        """``call(items chunk, dots chunk)`` of program ``prog`` over the chunks of n
        items: ``items`` cut on axis 0 (pytrees, None kept), ``dots`` on axis 1; in
        ``zero`` (indices into items) the padding is zero instead of copies. The
        chunks run side by side on the cores (:func:`_pool`). Returns
        [(valid, outputs or a future of them)]: :meth:`_done` waits for them."""
        # in C order once: a gather from a transposed array (the batched tangents come
        # as (n_dof, k) transposed) costs ten times as much, chunk by chunk
        contiguous = lambda x: np.ascontiguousarray(x) if isinstance(x, np.ndarray) else x  # noqa: E731
        items, dots = tree_map(contiguous, items), tree_map(contiguous, dots)
        chunks = []
        for start, size in plan(n, self.SIZES):
            valid = min(size, n - start)
            index = np.arange(start, start + size)
            index[valid:] = start
            chunk = []
            for j, a in enumerate(items):
                c = tree_map(lambda x: np.take(x, index, axis=0), a)
                if j in zero and valid < size:
                    c = tree_map(lambda x: _zero_tail(x, valid), c)
                chunk.append(c)
            chunks.append((valid, tuple(chunk), tree_map(lambda x: np.take(x, index, axis=1), dots)))
        if len(chunks) == 1 or not self.side_by_side:
            return [(c[0], call(c[1], c[2])) for c in chunks]
        # build every executable here (once), then run the chunks from the pool's threads
        for size in {c[1][0].shape[0] if c[1][0] is not None else None for c in chunks}:
            first = next(c for c in chunks if c[1][0] is None or c[1][0].shape[0] == size)
            call(first[1], first[2], prepare=True)
        run = lambda c: jax.block_until_ready(call(c[1], c[2]))
        return [(c[0], f) for c, f in zip(chunks, [_pool().submit(run, c) for c in chunks])]

    @staticmethod
    def _done(pending):
        """[(valid, outputs)] of :meth:`_run`'s result (futures waited for)."""
        return [(v, r.result() if hasattr(r, "result") else r) for v, r in pending]

    def __call__(self, name: str, outs: tuple, items: tuple, shared):
        """The kernel's outputs ``outs`` for every item: a tuple of (n, ...) arrays."""
        return self.finish(self.start(name, outs, items, shared))

    def start(self, name: str, outs: tuple, items: tuple, shared):
        """Dispatch :meth:`__call__`'s work and return at once (it runs in the
        background): :meth:`finish` waits for it and returns the outputs. The
        caller does other work in between (the contact kernels beside the cells')."""
        prog = self._program("primal", name, outs)
        shared = jax.device_put(shared)  # once, not per chunk
        return self._run(_count(items), prog, _caller(prog, lambda c, _: (c, shared)), items)

    def finish(self, pending):
        """The outputs of a :meth:`start`: a tuple of (n, ...) arrays."""
        return _concat([tree_map(lambda a, v=v: np.asarray(a)[:v], r)
                        for v, r in self._done(pending)], 0)

    def jvp(self, name: str, outs: tuple, items: tuple, shared, dots: tuple):
        """Derivatives of the outputs ``outs`` along ``dots`` (one per item argument,
        then one for ``shared``: arrays (k, n, ...) / pytree of (k,) arrays, or None:
        zero), a tuple of (k, n, ...) arrays; None if every tangent is None."""
        if all(d is None for d in dots):
            return None
        return _concat([tree_map(lambda a, v=v: np.asarray(a)[:, :v], r)
                        for v, r in self._run_jvp("jvp", name, outs, items, shared, dots)], 1)

    def value_jvp(self, name: str, outs: tuple, items: tuple, shared, dots: tuple):
        """The outputs ``outs`` (a tuple of (n, ...) arrays) and their derivatives
        along ``dots`` (as :meth:`jvp`; at least one not None) from one program: the
        outputs are computed once, not once by a value program and again inside
        the JVP's."""
        res = self._run_jvp("value_jvp", name, outs, items, shared, dots)
        values = _concat([tree_map(lambda a, v=v: np.asarray(a)[:v], r[0]) for v, r in res], 0)
        derivatives = _concat([tree_map(lambda a, v=v: np.asarray(a)[:, :v], r[1]) for v, r in res], 1)
        return values, derivatives

    def _run_jvp(self, mode: str, name: str, outs: tuple, items: tuple, shared, dots: tuple):
        """[(valid, outputs)] of the chunks of program ``mode`` (jvp or value_jvp)
        along ``dots`` (the items' tangents cut into chunks, the shared ones whole)."""
        mask = tuple(d is not None for d in dots)
        prog = self._program(mode, name, outs, mask)
        shared, dots = jax.device_put(shared), dots[:-1] + (jax.device_put(dots[-1]),)
        item_dots = tuple(d for d in dots[:-1] if d is not None)
        extra = [dots[-1]] if dots[-1] is not None else []
        args = lambda c, dc: (c, shared, tuple(list(dc) + extra))  # noqa: E731
        return self._done(self._run(_count(items), prog, _caller(prog, args), items, item_dots))

    def vjp(self, name: str, outs: tuple, items: tuple, shared, cot: tuple):
        """Cotangents (of ``items`` (per item), of ``shared`` (summed over the items))
        of the outputs ``outs`` with cotangents ``cot`` (a tuple of (n, ...) arrays)."""
        prog = self._program("vjp", name, outs)
        shared = jax.device_put(shared)
        k = len(items)
        args = lambda c, _: (c[:k], shared, c[k:])
        res = self._done(self._run(_count(items), prog, _caller(prog, args),
                                   tuple(items) + tuple(cot), zero=tuple(range(k, k + len(cot)))))
        items_bar = _concat([tree_map(lambda a, v=v: np.asarray(a)[:v], r[0]) for v, r in res], 0)
        shared_bar = tree_map(lambda *a: sum(np.asarray(x) for x in a), *[r[1] for _, r in res])
        return items_bar, shared_bar


def _caller(prog, args):
    """call(chunk, dots chunk, prepare=False): run ``prog`` on ``args(chunk, dots)``,
    or only build its executable."""
    def call(c, dc, prepare=False):
        a = args(c, dc)
        return prog.prepare(*a) if prepare else prog(*a)
    return call


def _count(items) -> int:
    return len(jax.tree_util.tree_leaves(items)[0])


def _zero_tail(x, valid: int):
    x = np.array(x)
    x[valid:] = 0
    return x
