"""The interface every backend implements."""

from __future__ import annotations

import logging

import scipy.sparse as sp


log = logging.getLogger("signorini")

from .factor import Factor


class LinearSolver:
    """Base class: ``factorize(K, symmetric=False) -> Factor``."""

    name = "?"
    #: the mpi4py communicator of the ranks that run each solve together (the PETSc
    #: solvers under mpiexec), over which a model shares out its cells; None: this
    #: process alone
    communicator = None

    def factorize(self, K: sp.spmatrix, symmetric: bool = False) -> Factor:
        raise NotImplementedError

    def describe(self) -> str:
        return self.name
