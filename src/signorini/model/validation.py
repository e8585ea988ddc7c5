"""Checks of the parameter values and names against the model (before a solve).

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError, SignoriniError
from ..fem.mesh import check_orientation
from ..fem.mesh3d import check_cells
from ..params import as_jax, check_names, names_in, resolve


class ModelChecks:
    """Checks of the parameter values and names against the model (before a solve)."""

    # ------------------------------------------------------------------ setup
    def _check_names(self):
        p = self.problem
        specs = list(p.material.specs())
        for f in p.fixed:
            specs += f.specs()
        for l in p.loads:
            specs += l.specs()
        for c in p.contact:
            specs += c.specs()
        check_names(names_in(specs), p.params, "the problem definition")
        self._specs = specs
        self.check_values(p.params)

    def check_values(self, params) -> None:
        """Every expression of the definition evaluates to finite numbers at these
        values (before any JAX tracing; again for each problem that reuses the model)."""
        for s in self._specs:
            if isinstance(s, str):
                continue
            try:
                v = np.asarray(resolve(s, params), dtype=float)
            except SignoriniError:
                raise
            except (TypeError, ValueError):
                raise InputError(f"a load, support, material or contact value is {s!r}, which is "
                                 "not a number, a parameter name or a function of the "
                                 "parameters") from None
            except ArithmeticError as e:  # e.g. a division by a parameter that is zero
                raise InputError(f"a load, support, material or contact value {s!r} cannot be "
                                 f"evaluated at these parameter values ({e}); every value must "
                                 "be a finite number") from None
            if not np.all(np.isfinite(v)):
                raise InputError(f"a load, support, material or contact value evaluates to {v} "
                                 "(NaN or inf); every value must be a finite number")

    def check(self, params: dict) -> None:
        """Validate parameter values (material, obstacles, eps; no inverted element)."""
        p = self.problem
        p.material.check(params)
        for s in self.surfaces:
            s.contact.obstacle.check(params)
            s.contact.method.check(params)
            self._check_regularisation(s, params)
        if self.shape_names:
            X = np.asarray(self.reference(as_jax(params)))
            what = "reference mesh at the given shape parameters"
            if self.dim == 3:
                check_cells(X, self.conn, what)
            else:
                check_orientation(X, self.conn, what)
            self.kinematics.check_mesh(X)

    @staticmethod
    def contact_cell_size(s, X) -> float:
        """Mean edge length h of contact surface ``s`` on the coordinates X."""
        X = np.asarray(X)
        return float(np.linalg.norm(X[s.edges[:, 1]] - X[s.edges[:, 0]], axis=1).mean())

    def _check_regularisation(self, s, params) -> None:
        """eps (penalty / augmentation) must be finite and not absurd next to E/h."""
        vals = {k: float(v) for k, v in s.contact.method.values(params).items() if k.startswith("eps")}
        try:
            E = float(resolve(self.problem.material.E, params))
        except AttributeError:
            return
        h = self.contact_cell_size(s, self.reference_nodes)
        scale = E / h
        lo, hi = self.EPS_RANGE
        for k, v in vals.items():
            if not np.isfinite(v) or not lo * scale <= v <= hi * scale:
                raise InputError(
                    f"contact {s.contact.edges!r}: {k} = {v:.4g} is outside [{lo:g}, {hi:g}] x E/h "
                    f"= [{lo * scale:.3g}, {hi * scale:.3g}] (E = {E:.4g}, mean contact cell h = "
                    f"{h:.3g}); such a value only ruins the conditioning of the tangent. "
                    f"Use eps of the order of E/h = {scale:.3g}")
