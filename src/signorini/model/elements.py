"""The element part of the residual, the tangent, the history update and their
derivatives, evaluated through the element kind's programs
(:mod:`signorini.model.cells`): the model gathers its cells' data, the kind's
programs run over chunks of them, the model scatters the results back.

These are what solvers and sensitivities call eagerly; the pure functions of
:class:`~signorini.model.kernels.Model` (``residual``, ``update``), which a user's
response may differentiate, compute the same forces by a ``vmap`` over the cells
inside the caller's program.

A part of :class:`signorini.model.kernels.Model` (a mixin: its methods use the
model's layout, kernels and compiled programs)."""

from __future__ import annotations

import contextlib
import threading

import numpy as np

from .._jax import jax
from .share import CellShare


class ModelElements:
    """The element part of residual, tangent and update, and their derivatives."""

    #: (the thread that entered :meth:`sharing`, (this rank's share of the cells,
    #: (its share of each contact surface's nodes)))
    _share: tuple | None = None

    @contextlib.contextmanager
    def sharing(self, comm):
        """While inside, each rank of ``comm`` (an mpi4py communicator, or None: no
        effect) evaluates the element kernels of its own block of cells and the
        contact kernels of its own block of each surface's contact nodes, and every
        rank gets every cell's and node's outputs (:mod:`signorini.model.share`).
        Only where the kinds' programs evaluate them (``by_kind``), and only on the
        calling thread: every rank must make the same calls in the same order,
        which the solve's thread does and another (an interrupt's report on rank 0)
        does not; :meth:`alone` lifts it for what one rank computes alone."""
        if comm is None or comm.Get_size() < 2 or not self.by_kind:
            yield
            return
        shares = (CellShare(comm, len(self.conn)),
                  tuple(CellShare(comm, s.nodes.size) for s in self.surfaces))
        old, self._share = self._share, (threading.get_ident(), shares)
        try:
            yield
        finally:
            self._share = old

    @contextlib.contextmanager
    def alone(self):
        """While inside, every cell and contact node on this rank alone, also within
        :meth:`sharing` (rank 0's outputs as the increments converge)."""
        old, self._share = self._share, None
        try:
            yield
        finally:
            self._share = old

    def _shares(self) -> tuple | None:
        """(the cells' share, (each surface's nodes' share)) on this thread, or None."""
        s = self._share
        return None if s is None or s[0] != threading.get_ident() else s[1]

    @property
    def share(self) -> CellShare | None:
        """This rank's share of the cells on this thread, or None (every cell)."""
        s = self._shares()
        return None if s is None else s[0]

    def _kernels(self):
        """The element kind's programs, on this rank's cells while :meth:`sharing`."""
        share = self.share
        return self.cells if share is None else share.over(self.cells)

    def _cell_arrays(self, w, params, state_n):
        """(u_e (n, k, dim), X_e (n, k, dim), mp, h_e or None) of every cell (NumPy)."""
        X = np.asarray(self.reference(params))
        ue = np.asarray(w)[self.edofs].reshape(len(self.conn), -1, self.dim)
        h = None
        if self.n_state:
            h = np.asarray(self._material_history(state_n))
        return ue, X[self.conn], self.material.values(params), h

    def scatter(self, re) -> np.ndarray:
        """(n_dof,) sum of per-cell (n, 8) values at their DOFs (k-batched: (k, n, 8))."""
        flat = self._edofs_flat
        if re.ndim == 2:
            return np.bincount(flat, weights=re.ravel(), minlength=self.n_dof)
        return np.stack([np.bincount(flat, weights=r.ravel(), minlength=self.n_dof) for r in re])

    def _scatter_nodes(self, Xbar) -> np.ndarray:
        """(n_nodes, dim) sum of per-cell (n, k, dim) node values."""
        d = self.dim
        return self.scatter(Xbar.reshape(len(self.conn), -1))[:d * self.n_nodes].reshape(-1, d)

    @property
    def _edofs_flat(self):
        if getattr(self, "_edofs_ravel", None) is None:
            self._edofs_ravel = np.ascontiguousarray(self.edofs.ravel())
        return self._edofs_ravel

    # --------------------------------------------------------------- values
    def element_forces(self, w, params, state_n=None):
        """(internal forces (n_dof,), updated Gauss-point history or None)."""
        ue, Xe, mp, he = self._cell_arrays(w, params, state_n)
        re, h = self._kernels()("update", (0, 1), (ue, Xe, he), mp)
        return self.scatter(re), (h if self.n_state else None)

    def element_history(self, w, params, state_n):
        """The updated Gauss-point history (n, 4, n_state) after convergence at w."""
        ue, Xe, mp, he = self._cell_arrays(w, params, state_n)
        return self._kernels()("update", (0, 1), (ue, Xe, he), mp)[1]  # one program for both

    def element_tangents(self, w, params, state_n=None):
        """(internal forces (n_dof,), element tangents (n, 8, 8))."""
        return self.element_tangents_finish(self.element_tangents_start(w, params, state_n))

    def element_tangents_start(self, w, params, state_n=None):
        """Dispatch :meth:`element_tangents` (JAX computes while the caller goes on)."""
        ue, Xe, mp, he = self._cell_arrays(w, params, state_n)
        return self._kernels().start("tangent", (0, 1), (ue, Xe, he), mp)

    def element_tangents_finish(self, pending):
        re, Ke = self._kernels().finish(pending)
        return self.scatter(re), Ke

    def _element_stiffness_cells(self, params) -> np.ndarray:
        """K_e (n, 8, 8) of a linear body: the tangent at u = 0 (every cell on every
        rank: once per parameter values, and kept, also by a rank's own outputs)."""
        ue, Xe, mp, _ = self._cell_arrays(np.zeros(self.n_dof), params, None)
        return self.cells("tangent", (1,), (ue, Xe, None), mp)[0]

    def linear_forces_np(self, Ke, w) -> np.ndarray:
        """(n_dof,) internal forces sum_e K_e u_e of a linear body (NumPy)."""
        ue = np.asarray(w)[self.edofs]
        return self.scatter(np.matmul(Ke, ue[:, :, None])[:, :, 0])

    # ---------------------------------------------------------- derivatives
    def element_jvp(self, name: str, outs: tuple, w, params, state_n, w_dot, e, state_dot_n):
        """JVP of the element outputs ``outs`` of kernel ``name`` along the batched
        tangents (w_dot (k, n_dof) or None: the displacements held, e, state_dot_n),
        per cell ((k, n, ...) each).

        Which tangents are passed is fixed by the model, not by their values (a
        program per pattern: the heavy kernels are compiled once): the
        displacements' whenever w_dot is given, the coordinates' when the model has
        shape parameters, the material values' always, the history's when the
        material has one (zero when the state's sensitivity is not given)."""
        return self._kernels().jvp(name, outs, *self._jvp_arrays(w, params, state_n, w_dot, e, state_dot_n))

    def element_value_jvp(self, name: str, outs: tuple, w, params, state_n, w_dot, e, state_dot_n):
        """(the element outputs ``outs``, their JVP as :meth:`element_jvp`) from one
        program of the element kind (the outputs computed once)."""
        return self._kernels().value_jvp(name, outs, *self._jvp_arrays(w, params, state_n, w_dot, e,
                                                                   state_dot_n))

    def _jvp_arrays(self, w, params, state_n, w_dot, e, state_dot_n):
        """(items, shared, tangents) of the cells for the kind's JVP programs."""
        ue, Xe, mp, he = self._cell_arrays(w, params, state_n)
        dX, dmp = self._parameter_jvp(params, e)
        k = len(next(iter(e.values())))
        du = None if w_dot is None else np.asarray(w_dot)[:, self.edofs].reshape(
            k, len(self.conn), -1, self.dim)
        dXe = np.asarray(dX)[:, self.conn] if self.shape_names else None
        dh = None
        if self.n_state:
            sd = None if state_dot_n is None else state_dot_n[2]
            dh = np.zeros((k,) + he.shape) if sd is None else np.asarray(sd)
        dmp = {key: np.asarray(v) for key, v in dmp.items()}
        return (ue, Xe, he), mp, (du, dXe, dh, dmp)

    def element_vjp(self, name: str, outs: tuple, w, params, state_n, cot):
        """Cotangents of (w (n_dof,), params (pytree like ``params``), Gauss-point
        history (n, 4, n_state) or None) of the element outputs ``outs`` of kernel
        ``name`` with per-cell cotangents ``cot`` (one per output)."""
        ue, Xe, mp, he = self._cell_arrays(w, params, state_n)
        (du, dXe, dh), dmp = self._kernels().vjp(name, outs, (ue, Xe, he), mp, cot)
        w_bar = self.scatter(du.reshape(len(self.conn), -1))
        p_bar = self._parameter_vjp(params, self._scatter_nodes(dXe), dmp)
        return w_bar, p_bar, dh

    def _parameter_jvp_impl(self, params, e):
        f = lambda p: (self.reference(p) if self.shape_names else self._X0,
                       self.material.values(p))
        return jax.vmap(lambda d: jax.jvp(f, (params,), (d,))[1])(e)

    def _parameter_vjp_impl(self, params, X_bar, mp_bar):
        f = lambda p: (self._reference_impl(p), self.material.values(p))
        return jax.vjp(f, params)[1]((X_bar, mp_bar))[0]
