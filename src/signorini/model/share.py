"""A model's cells and contact nodes shared out among MPI ranks (docs/parallel.md).

Under ``mpiexec`` with a PETSc solver every rank runs the same solve. The element
kernels (:mod:`signorini.model.cells`: forces, tangents, history updates, their
JVPs and VJPs) are then each rank's on its own contiguous block of cells, the
contact kernels (:mod:`signorini.model.nodes`: tangents, residuals, case flags,
fields, their JVPs) each rank's on its own block of every surface's contact
nodes, and one gather gives every rank every item's outputs, so that what follows
(the assembly, Newton's step, the DDM's columns) is again the same on every rank,
bit for bit. A rank whose block is empty (more ranks than a surface's nodes)
takes part in the gathers with nothing.

The communicator is an mpi4py one, handed in by the solver
(:attr:`signorini.linsolve.LinearSolver.communicator`); this module does not
import MPI. Every rank must make the same calls in the same order: the solve does
(the same program on the same data), and what one rank alone computes (rank 0's
outputs) evaluates its kernels whole (``whole=True``).
"""

from __future__ import annotations

import numpy as np

from .._jax import jax
from ..linsolve.petsc import split_rows

tree_map = jax.tree_util.tree_map


class CellShare:
    """This rank's block of a model's n cells (or of a surface's n contact nodes),
    and the collectives that give every rank the outputs of all of them."""

    def __init__(self, comm, n: int):
        self.comm = comm
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        self.n = int(n)
        self.starts = split_rows(self.n, self.size)  # as the solver splits rows
        self.lo, self.hi = int(self.starts[self.rank]), int(self.starts[self.rank + 1])

    def local(self, tree, axis: int = 0):
        """This rank's cells of every array of ``tree`` (cells on ``axis``; None kept)."""
        return self._cut(tree, axis, self.lo, self.hi)

    @property
    def empty(self) -> bool:
        """Whether this rank's block has no cell."""
        return self.hi == self.lo

    def run(self, tree, axis: int = 0):
        """The cells this rank evaluates: its own, or, when it has none, the first
        cell of all (the programs take no empty chunk; :meth:`own` drops its outputs)."""
        return self._cut(tree, axis, 0, 1) if self.empty else self.local(tree, axis)

    def own(self, tree, axis: int = 0):
        """The outputs of :meth:`run`'s cells that are this rank's (none when its block
        is empty)."""
        return self._cut(tree, axis, 0, 0) if self.empty else tree

    @staticmethod
    def _cut(tree, axis: int, lo: int, hi: int):
        cut = (slice(None),) * axis + (slice(lo, hi),)
        return tree_map(lambda a: np.asarray(a)[cut], tree)

    def gather(self, tree, axis: int = 0):
        """Every rank's cells of every array of ``tree`` (this rank's on ``axis``),
        in the cells' order, on every rank."""
        return tree_map(lambda a: self._gather(np.asarray(a), axis), tree)

    def _gather(self, a: np.ndarray, axis: int) -> np.ndarray:
        a = np.moveaxis(a, axis, 0)
        rest = a.shape[1:]
        per = int(np.prod(rest, dtype=np.int64))
        counts = np.diff(self.starts) * per
        out = np.empty((self.n,) + rest, dtype=a.dtype)
        self.comm.Allgatherv(np.ascontiguousarray(a), [out, (counts, self.starts[:-1] * per)])
        return np.moveaxis(out, 0, axis)

    def total(self, tree):
        """The sum over the ranks of every array of ``tree``, added in the ranks'
        order on every rank (the same result everywhere, bit for bit)."""
        parts = self.comm.allgather(tree_map(np.asarray, tree))
        return tree_map(lambda *a: sum(a[1:], a[0]), *parts)

    def over(self, kernels) -> SharedKernels:
        """``kernels`` (:class:`~signorini.model.chunks.Chunked`: the cells' or the
        contact nodes') run on this rank's cells."""
        return SharedKernels(kernels, self)


class SharedKernels:
    """The interface of :class:`~signorini.model.chunks.Chunked` (call, start and
    finish, jvp, value_jvp, vjp) over this rank's cells, every output gathered."""

    def __init__(self, kernels, share: CellShare):
        self.kernels, self.share = kernels, share

    def __call__(self, name: str, outs: tuple, items: tuple, shared):
        return self.finish(self.start(name, outs, items, shared))

    def start(self, name: str, outs: tuple, items: tuple, shared):
        return self.kernels.start(name, outs, self.share.run(items), shared)

    def finish(self, pending):
        s = self.share
        return s.gather(s.own(self.kernels.finish(pending)))

    def _dots(self, dots: tuple) -> tuple:
        """This rank's part of the items' tangents (k, n, ...); the shared values' whole."""
        return tuple(self.share.run(dots[:-1], axis=1)) + (dots[-1],)

    def jvp(self, name: str, outs: tuple, items: tuple, shared, dots: tuple):
        if all(d is None for d in dots):
            return None
        s = self.share
        out = self.kernels.jvp(name, outs, s.run(items), shared, self._dots(dots))
        return s.gather(s.own(out, axis=1), axis=1)

    def value_jvp(self, name: str, outs: tuple, items: tuple, shared, dots: tuple):
        s = self.share
        values, derivatives = self.kernels.value_jvp(name, outs, s.run(items), shared,
                                                     self._dots(dots))
        return s.gather(s.own(values)), s.gather(s.own(derivatives, axis=1), axis=1)

    def vjp(self, name: str, outs: tuple, items: tuple, shared, cot: tuple):
        s = self.share
        cot = s.run(cot)
        if s.empty:  # the stand-in cell adds nothing to the shared values' cotangents
            cot = tree_map(np.zeros_like, cot)
        items_bar, shared_bar = self.kernels.vjp(name, outs, s.run(items), shared, cot)
        return s.gather(s.own(items_bar)), s.total(shared_bar)
