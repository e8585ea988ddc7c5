"""UMFPACK through ``scikit-umfpack``, if installed."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError, SingularTangentError

log = logging.getLogger("signorini")

from .base import LinearSolver
from .factor import Factor


class Umfpack(LinearSolver):
    """UMFPACK through scikit-umfpack (optional)."""

    name = "umfpack"

    def __init__(self):
        try:
            import scikits.umfpack  # noqa: F401  (optional dependency)
        except (ImportError, OSError) as e:
            raise InputError(f"solver 'umfpack' is not installed: `pip install scikit-umfpack` "
                             f"(import failed: {e})") from None

    def factorize(self, K, symmetric=False):
        import scikits.umfpack as um  # optional dependency

        try:
            lu = um.splu(K.tocsc())
        except Exception as e:  # noqa: BLE001 - umfpack raises generic errors
            raise SingularTangentError(f"UMFPACK could not factorise the tangent: {e}") from None
        def solve(b):
            return np.column_stack([lu.solve(c) for c in b.T]) if b.ndim == 2 else lu.solve(b)
        return Factor(solve, K, transpose_factor=lambda: self.factorize(K.T.tocsr()))
