"""Which backend: by name, ``auto`` (the fastest installed), or a user's own
object; and the tangent solver that picks the symmetric or the general
factorisation from the matrix."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from .._memo import ObjectMemo
from ..errors import InputError
from .base import LinearSolver
from .factor import Factor
from .iterative import AMGKrylov
from .kept import KeptFactor
from .pardiso import Pardiso
from .petsc import PetscAMG, PetscSolver
from .superlu import SuperLU
from .umfpack import Umfpack

log = logging.getLogger("signorini")


SOLVERS = {"superlu": SuperLU, "umfpack": Umfpack, "pardiso": Pardiso, "amg": AMGKrylov,
           "petsc": PetscSolver, "petsc-amg": PetscAMG}

#: the order in which ``auto`` tries the backends (fastest first)
AUTO_ORDER = ("pardiso", "superlu")


class _Foreign(LinearSolver):
    """A user object with ``factorize(K)``: the symmetry flag is not passed on."""

    def __init__(self, obj):
        self._obj = obj
        self.name = getattr(obj, "name", type(obj).__name__)

    def factorize(self, K, symmetric=False):
        f = self._obj.factorize(K)
        if isinstance(f, Factor):
            return f
        return Factor(f.solve, K, transpose_factor=lambda: self.factorize(K.T.tocsr()))


def available() -> list[str]:
    """Names of the direct backends that can be used on this machine (they factorise
    any matrix; the iterative ``amg`` solves a model's tangents, :func:`for_model`)."""
    out = []
    for name, cls in SOLVERS.items():
        if hasattr(cls, "bind") or cls is PetscSolver:  # (PETSc: one started by mpiexec)
            continue
        try:
            cls()
            out.append(name)
        except InputError:
            pass
    return out


def get_solver(name_or_solver="auto") -> LinearSolver:
    """A solver instance from its name (``auto``, ``pardiso``, ``superlu``,
    ``umfpack``) or a user object with a ``factorize(K)`` method.

    ``auto`` picks the fastest backend installed (PARDISO, else SuperLU); a named
    backend that is not installed raises :class:`InputError` saying how to install it.
    """
    if isinstance(name_or_solver, LinearSolver):
        return name_or_solver
    if not isinstance(name_or_solver, str):
        if not callable(getattr(name_or_solver, "factorize", None)):
            raise InputError(f"solver must be 'auto', one of {sorted(SOLVERS)} or an object with a "
                             f"factorize(K) method, got {name_or_solver!r}")
        return _Foreign(name_or_solver)
    if name_or_solver == "auto":
        for name in AUTO_ORDER:
            try:
                return SOLVERS[name]()
            except InputError as e:
                log.debug("auto solver: %s unavailable (%s)", name, e)
        raise AssertionError("SuperLU is always available")
    try:
        cls = SOLVERS[name_or_solver]
    except KeyError:
        raise InputError(f"unknown linear solver {name_or_solver!r}; choose from "
                         f"{['auto'] + sorted(SOLVERS)}") from None
    return cls()


def for_model(solver: LinearSolver, model) -> LinearSolver:
    """``solver``, told the structure of ``model``'s tangent if it needs it (the
    iterative solver: which rows are displacements and multipliers of which node)."""
    bind = getattr(solver, "bind", None)
    if callable(bind):
        bind(model)
    return solver


#: ||K - K^T||_max / ||K||_max below which a tangent is taken as symmetric
SYMMETRY_TOL = 1e-12


def is_symmetric(K: sp.spmatrix, tol: float = SYMMETRY_TOL) -> bool:
    """True if K equals its transpose to ``tol`` relative (max norm)."""
    scale = abs(K).max()
    return scale == 0 or abs(K - K.T).max() <= tol * scale


#: (max |b|, max |b - b^T|) of the read-only block arrays tested last, kept while
#: each lives (a kept figure must not keep a model's stiffness alive)
_BLOCK_STATS = ObjectMemo(4)


def _block_stats(b: np.ndarray) -> tuple[float, float]:
    """(max |b|, max |b - b^T|) of a block array (n, k, k). A read-only array (a
    linear body's element stiffness, one per parameter values) cannot change, so
    its figures are kept while it is passed again: a pass over every element
    block is paid once per array, not once per solve."""
    frozen = not b.flags.writeable
    stats = _BLOCK_STATS.get(b) if frozen else None
    if stats is None:
        # by chunks of blocks that stay in cache (no temporary the size of b); b - b^T is
        # antisymmetric, so its largest entry is its largest |entry|; a NaN propagates
        size, top, asym = max(1, 2 ** 16 // max(1, b[0].size)), [0.0], [0.0]
        for lo in range(0, len(b), size):
            c = b[lo:lo + size]
            top += [c.max(), -c.min()]
            asym.append((c - np.swapaxes(c, -1, -2)).max())
        stats = (float(np.max(top)), float(np.max(asym)))
        if frozen:
            _BLOCK_STATS.put(b, stats)
    return stats


def blocks_symmetric(blocks, tol: float = SYMMETRY_TOL) -> bool:
    """True if every local block (n, k, k) equals its transpose to ``tol`` relative
    to the largest entry of all: then so does their assembly, and every square
    submatrix of it on the same rows and columns. A sufficient test (blocks
    whose asymmetries cancel in the sum would say False), far cheaper than
    comparing the assembled K with its transpose, which builds the transpose
    and a sparse difference (docs/theory.md §10.1)."""
    stats = [_block_stats(np.asarray(b)) for b in blocks if np.size(b)]
    scale = max((m for m, _ in stats), default=0.0)
    return scale == 0 or all(a <= tol * scale for _, a in stats)


class TangentSolver:
    """The solver of one load path: picks the symmetric factorisation once.

    A model without history (no friction, no plasticity) has a symmetric exact
    tangent (the Hessian of its augmented Lagrangian); this is verified on the
    first tangent factorised, and that choice is kept for the whole path.
    """

    def __init__(self, solver: LinearSolver, symmetric_candidate: bool, analysis=None,
                 reuse: str = "auto"):
        self.solver = solver
        self._candidate = symmetric_candidate
        self.symmetric: bool | None = None
        self._analysis = analysis  # () -> tangent to analyse the pattern with (PARDISO)
        # an iterative backend's "factorisation" is its preconditioner, which it reuses
        # in its own way: every tangent goes to it
        iterative = callable(getattr(solver, "bind", None))
        #: the factorisations of the path, each kept to solve the tangents near it
        self.kept = KeptFactor(self._factorize, "never" if iterative else reuse)

    def factor(self, K: sp.spmatrix, blocks=None) -> Factor:
        """A :class:`Factor` of K: GMRES on the factorisation kept from an earlier
        tangent while that pays, else K factorised (and kept): :mod:`.kept`."""
        return self.kept.factor(K, blocks)

    def factorize(self, K: sp.spmatrix, blocks=None) -> Factor:
        """Factorise K (and keep the factor for :meth:`factor`); ``blocks`` (the
        local blocks K was assembled from), if given, let the first call decide
        symmetry on them (:func:`blocks_symmetric`)."""
        return self.kept.fresh(K, blocks, "direct")

    def _factorize(self, K: sp.spmatrix, blocks=None) -> Factor:
        if self.symmetric is None:
            self.symmetric = bool(self._candidate and (
                (blocks is not None and blocks_symmetric(blocks)) or is_symmetric(K)))
            log.debug("tangent factorised as %s by %s",
                      "symmetric" if self.symmetric else "unsymmetric", self.solver.describe())
        if self._analysis is not None and isinstance(self.solver, Pardiso):
            return self.solver.factorize(K, symmetric=self.symmetric, analysis=self._analysis)
        return self.solver.factorize(K, symmetric=self.symmetric)
