"""Responses: scalar quantities of a converged increment, with their sensitivities.

Each function here returns a :class:`Response`, which is what
:func:`signorini.gradient` (adjoint, DDM or finite differences),
:class:`signorini.Objective` and :func:`signorini.finite_difference` take, in
plane strain, axisymmetry and 3-D alike::

    force = sg.responses.contact_force(component=2)          # the z force of surface 0
    g = sg.gradient(problem, force, wrt=["E", "R"])          # its adjoint gradient, last increment
    g = sg.gradient(problem, force, wrt=["E"], increments="all")   # summed over the path
    value, sens = force.of(solution)                         # its value and DDM sensitivities
    history = force.path(solution)                           # its value at every increment
    fd = sg.finite_difference(problem, "E", force, steps=4)  # central differences of the value

A response is called with a model (it gives the traceable ``fn(w, params, t,
state_n)`` that the derivatives differentiate) or with a solution (its value at
the last increment, what :func:`~signorini.finite_difference` differences).

A fit to a measured history is :func:`misfit` summed over the path::

    fit = sg.responses.misfit(sg.responses.reaction("top", 2), t_measured, f_measured)
    objective = sg.Objective(problem, ["E", "mu"], fit, steps=len(t_measured), increments="all")
    result = sg.minimize(objective, [E0, mu0])

Forces are those on the body: in plane strain per unit thickness, in
axisymmetry over the whole circumference (its radial component sums the nodes'
radial forces), in 3-D vectors in the global frame (the contact force is the sum
of the nodes' contact residual rows, not area times pressure along one normal).
Quantities that count nodes (contact area, stick zone) are piecewise constant in
the parameters but for the areas themselves (a shape parameter changes them):
their derivatives are those of the branch the solve took (docs/theory.md §11).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable

import numpy as np

from ._jax import jax, jnp
from .contact.friction import STATUS_NAMES
from .errors import InputError

#: the status code of a sticking node
_STICK = STATUS_NAMES.index("stick")

__all__ = ["Response", "contact_force", "reaction", "displacement", "contact_area",
           "max_pressure", "pressure_norm", "contact_work", "stick_area", "misfit"]


class Response:
    """A scalar response: ``build(model) -> fn(w, params, t, state_n)`` (traceable,
    state_n the state before the increment), named ``name``."""

    def __init__(self, name: str, build: Callable):
        self.name = name
        self._build = build

    def __repr__(self) -> str:
        return f"<response {self.name}>"

    def __call__(self, what):
        """With a model: the function the derivatives differentiate. With a solution:
        the value at its last increment."""
        if hasattr(what, "increments") and hasattr(what, "model"):
            return self.of(what)[0]
        return self._build(what)

    def of(self, solution, i: int = -1) -> tuple[float, dict]:
        """(value at increment i, {name: its DDM sensitivity} for the solve's ``wrt``)."""
        fn = self._build(solution.model)
        value, sens = solution.history_response(fn, i, key=("response", self.name))
        return float(value), {k: float(v) for k, v in sens.items()}

    def path(self, solution) -> np.ndarray:
        """(n_increments,) the value at every converged increment."""
        return np.array([self.of(solution, i)[0] for i in range(len(solution.increments))])


def _surface(model, surface: int):
    if not 0 <= surface < len(model.surfaces):
        raise InputError(f"response: contact surface {surface} does not exist; the problem has "
                         f"{len(model.surfaces)} (0..{len(model.surfaces) - 1})")
    return surface


def _component(model, component: int | None, what: str) -> int | None:
    if component is not None and component not in range(model.dim):
        raise InputError(f"{what}: component must be 0..{model.dim - 1} (x, y{', z' if model.dim == 3 else ''})"
                         f" or None (the magnitude), got {component!r}")
    return component


def _pick(vector, component):
    return jnp.sqrt(jnp.sum(vector ** 2)) if component is None else vector[component]


def contact_force(surface: int = 0, component: int | None = None) -> Response:
    """The contact force on the body over a contact surface (a pair: on its slave
    body): component 0, 1 (, 2) of the vector, or its magnitude (None)."""
    def build(model):
        i = _surface(model, surface)
        c = _component(model, component, "contact_force")
        return lambda w, p, t, s: _pick(jnp.sum(model.contact_forces(w, p, t, s, i), axis=0), c)
    return Response(f"contact_force[{surface},{component}]", build)


def reaction(node_set: str, component: int) -> Response:
    """The force of the supports on the body at the nodes of ``node_set`` along
    ``component`` (the sum of :meth:`~signorini.Solution.reactions` there); the
    component must be held there by a :class:`~signorini.Fixed`."""
    def build(model):
        c = _component(model, component, "reaction")
        if c is None:
            raise InputError("reaction: give the component (0, 1 or 2) of the supports' force")
        nodes = model.problem.mesh.node_set(node_set)
        dofs = model.dim * nodes + c
        held = np.isin(dofs, model.prescribed)
        if not held.all():
            raise InputError(f"reaction: component {c} of {int((~held).sum())} node(s) of "
                             f"{node_set!r} is not held by a support (Fixed), where the supports "
                             "exert no force; name a held node set and component")
        friction = model.has_contact_history

        def fn(w, p, t, s):
            cases = jax.lax.stop_gradient(model.cases(w, p, t, s)) if friction else None
            return jnp.sum(model.residual(w, p, t, s, cases)[dofs])
        return fn
    return Response(f"reaction[{node_set},{component}]", build)


def displacement(node: int | str, component: int) -> Response:
    """The displacement of a node (its index) or the mean over a node set (its name)."""
    def build(model):
        c = _component(model, component, "displacement")
        if c is None:
            raise InputError("displacement: give the component (0, 1 or 2)")
        nodes = (model.problem.mesh.node_set(node) if isinstance(node, str)
                 else np.atleast_1d(np.asarray(node, dtype=np.int64)))
        if nodes.size == 0 or nodes.min() < 0 or nodes.max() >= model.n_nodes:
            raise InputError(f"displacement: node {node!r} is not a node of the mesh "
                             f"(0..{model.n_nodes - 1})")
        dofs = model.dim * nodes + c
        return lambda w, p, t, s: jnp.mean(w[dofs])
    return Response(f"displacement[{node},{component}]", build)


def _fields(model, surface):
    i = _surface(model, surface)
    return lambda w, p, t: model.contact_fields(w, p, t, i)


def contact_area(surface: int = 0) -> Response:
    """The area in contact: the equivalent areas of the closed nodes (p_N > 0)."""
    def build(model):
        f = _fields(model, surface)

        def fn(w, p, t, s):
            c = f(w, p, t)
            return jnp.sum(jnp.where(c["p_N"] > 0, c["area"], 0.0))
        return fn
    return Response(f"contact_area[{surface}]", build)


def max_pressure(surface: int = 0) -> Response:
    """The largest contact pressure of the surface's nodes (not smooth where two
    nodes share it: :func:`pressure_norm` is its smooth proxy)."""
    def build(model):
        f = _fields(model, surface)
        return lambda w, p, t, s: jnp.max(f(w, p, t)["p_N"])
    return Response(f"max_pressure[{surface}]", build)


def pressure_norm(surface: int = 0, order: float = 8.0) -> Response:
    """(sum A p_N^k / sum A)^(1/k), k = ``order``, over the surface's nodes: a
    smooth measure of the pressure's peak (its area-weighted k-norm; it tends to
    the largest pressure as k grows, and does not depend on the mesh as a plain
    sum of powers would)."""
    if not order >= 1:
        raise InputError(f"pressure_norm: order must be at least 1, got {order!r}")

    def build(model):
        f = _fields(model, surface)

        def fn(w, p, t, s):
            c = f(w, p, t)
            pn = jnp.maximum(c["p_N"], 0.0)
            scale = jax.lax.stop_gradient(jnp.max(pn)) + 1e-300  # against overflow of p^k
            return scale * (jnp.sum(c["area"] * (pn / scale) ** order) / jnp.sum(c["area"])) ** (1.0 / order)
        return fn
    return Response(f"pressure_norm[{surface},{order}]", build)


def contact_work(surface: int = 0) -> Response:
    """W = sum_S A_S p_N,S (g_0,S - g_S): the work of the contact pressure on the
    closure of the initial gap g_0 (the gap at u = 0); at convergence p_N g = 0,
    so W = sum A p_N g_0, smooth on each branch of the contact law."""
    def build(model):
        f = _fields(model, surface)

        def fn(w, p, t, s):
            c = f(w, p, t)
            g0 = f(jnp.zeros_like(w), p, t)["gap"]
            return jnp.sum(c["area"] * c["p_N"] * (g0 - c["gap"]))
        return fn
    return Response(f"contact_work[{surface}]", build)


def stick_area(surface: int = 0) -> Response:
    """The area of the sticking nodes of a surface with friction (closed, not
    slipping): the stick zone's size."""
    def build(model):
        i = _surface(model, surface)
        if model.surfaces[i].contact.method.status is None:
            raise InputError(f"stick_area: contact surface {i} has no friction (stick and slip "
                             "are the states of a Coulomb law)")
        f = _fields(model, surface)

        def fn(w, p, t, s):
            status, _ = model.contact_status(w, p, t, s, i)
            return jnp.sum(jnp.where(jax.lax.stop_gradient(status) == _STICK, f(w, p, t)["area"], 0.0))
        return fn
    return Response(f"stick_area[{surface}]", build)



def misfit(response: Response, times, values, weights=None) -> Response:
    """w(t) (r - m(t))^2 of a response r against a measured curve m(t) (the
    load factors ``times``, increasing, and the measured ``values``, interpolated
    linearly; ``weights`` w at the same times, default 1): summed over the
    increments (``gradient(..., increments="all")``, ``Objective(...,
    increments="all")``) it is the least-squares misfit of the whole history. Put
    the increments at the measured times (equal increments: times k / n)."""
    t = np.asarray(times, dtype=float).ravel()
    v = np.asarray(values, dtype=float).ravel()
    wts = np.ones_like(t) if weights is None else np.asarray(weights, dtype=float).ravel()
    if not (t.size == v.size == wts.size) or t.size < 1:
        raise InputError(f"misfit: times, values (and weights) need one entry each per measured "
                         f"point, got {t.size}, {v.size}, {wts.size}")
    if np.any(np.diff(t) <= 0) or not np.all(np.isfinite(np.concatenate([t, v, wts]))):
        raise InputError("misfit: the times must increase and every value be a finite number")
    if np.any(wts < 0):
        raise InputError("misfit: weights must be >= 0")
    digest = hashlib.blake2b(np.concatenate([t, v, wts]).tobytes(), digest_size=8).hexdigest()

    def build(model):
        r = response(model)

        def fn(w, p, time, s):
            m = jnp.interp(time, t, v)
            return jnp.interp(time, t, wts) * (r(w, p, time, s) - m) ** 2
        return fn
    return Response(f"misfit[{response.name},{digest}]", build)
