"""Gradient of one scalar response, by DDM, adjoint or finite differences
(docs/theory.md §11).

:func:`gradient` is the single entry point: the same response, parameters and
load path in all three modes, one result type (:class:`Gradient`). The DDM
costs one back-substitution per parameter and increment, the adjoint one
transposed solve per increment whatever the number of parameters (including
``"nodes"``, every nodal coordinate), finite differences two solves per
parameter (for checking).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._jax import jax, jnp
from ..model import checks
from ..errors import InputError, SolverError
from ..model.kernels import NODES
from ..algorithms.newton import NewtonOptions
from ..params import as_jax, check_names
from ..sensitivity import nonsmooth
from .._deprecation import pop_old
from ..sensitivity.adjoint import Adjoint as AdjointEngine
from ..sensitivity.methods import DDM, Adjoint, FiniteDifferences, from_keywords
from ..algorithms.stepping import solve
from ..model.identity import structure_key
from .finite_differences import finite_difference

#: compiled adjoints kept per model (one per response object)
MAX_CACHED = 8


@dataclass
class Gradient:
    """A response value and its gradient.

    Attributes:
        value: G (sum over the selected increments).
        grad: name -> dG/dphi (a float; for ``"nodes"`` an (n_nodes, dim) array).
        mode: ``"ddm"``, ``"adjoint"`` or ``"fd"``.
        solution: the forward :class:`~signorini.algorithms.solution.Solution` (nominal values).
        timing: seconds: ``forward`` (the solve), ``gradient`` (the DDM's share of the
            solve — factorisation, pseudo-loads, back-substitutions, history
            sensitivities —, the backward pass, or the perturbed solves) and, for the
            adjoint, ``tangent_factorization`` (kernels, assembly and factorisation of
            the converged tangents), ``solve``, ``vjp``, ``factorizations``.
        memory: adjoint: bytes kept for the backward pass per increment
            (``per_increment``: unknowns, states and stored factors, averaged;
            ``factors_per_increment``: the stored factors alone), ``states_kept`` and
            ``factors_kept`` (how many increments keep them).
        warnings: the solve's warnings (among them one-sided derivatives).
    """

    value: float
    grad: dict
    mode: str
    solution: object = None
    timing: dict = field(default_factory=dict)
    memory: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def __getitem__(self, name):
        return self.grad[name]

    def as_array(self, names: Sequence[str] | None = None) -> np.ndarray:
        """The scalar gradients in the order of ``names`` (default: all but ``"nodes"``)."""
        names = [n for n in self.grad if n != NODES] if names is None else list(names)
        return np.array([float(self.grad[n]) for n in names])


def _positional(fn):
    """(required, total) positional parameters of fn (None if unknown)."""
    try:
        ps = [p for p in inspect.signature(fn).parameters.values()]
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_POSITIONAL for p in ps):
        return None
    pos = [p for p in ps if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    return sum(p.default is p.empty for p in pos), len(pos)


def is_factory(fn) -> bool:
    """A factory G(model) -> fn has one required positional parameter and at most
    one optional one (e.g. ``hertz.contact_work(model, surface=0)``)."""
    n = _positional(fn)
    return n is not None and n[0] == 1 and n[1] <= 2


def with_state(fn: Callable) -> Callable:
    """``fn(w, params, t[, state_n])`` as a function of four arguments (a fourth
    positional parameter, with or without default, receives the state)."""
    n = _positional(fn)
    if n is not None and n[1] == 3:
        return lambda w, p, t, s: fn(w, p, t)
    return fn


def response_function(response, model) -> Callable:
    """The traceable fn(w, params, t, state_n) of a response or response factory."""
    if not callable(response):
        raise InputError("response must be a callable fn(w, params, t[, state_n]) returning a "
                         "scalar, or a factory G(model) -> fn")
    fn = response(model) if is_factory(response) else response
    if not callable(fn):
        raise InputError("the response factory must return a callable fn(w, params, t[, state_n])")
    return with_state(fn)


def selected_increments(increments, n: int) -> list[int]:
    """Indices of the increments whose responses are summed."""
    if increments == "last":
        return [n - 1]
    if increments == "all":
        return list(range(n))
    try:
        idx = sorted({range(n)[int(i)] for i in increments})
    except (TypeError, ValueError, IndexError):
        raise InputError(f"increments must be 'last', 'all' or a list of increment indices in "
                         f"0..{n - 1}, got {increments!r}") from None
    if not idx:
        raise InputError("increments selects no increment")
    return idx


def gradient(problem, response, wrt: Sequence[str] | None = None, *, method=None, steps: int = 1,
             increments="last", options: NewtonOptions = NewtonOptions(), solver="auto",
             label: str | None = None, solution=None, **deprecated) -> Gradient:
    """Gradient of G = sum over increments of response(w_n, params, t_n, state_{n-1}).

    Args:
        problem: the :class:`~signorini.model.problem.Problem` at the design point.
        response: ``fn(w, params, t)`` or ``fn(w, params, t, state_n)`` returning a
            scalar (JAX-traceable; state_n: the state before the increment), or a
            factory ``G(model) -> fn``.
        wrt: the parameters to differentiate with respect to (names); ``"nodes"``
            (adjoint only) asks for the gradient with respect to every nodal
            coordinate of the reference mesh.
        method: :class:`~signorini.Adjoint` (default; one backward pass; its
            ``factors`` and ``checkpoint`` trade memory for time),
            :class:`~signorini.DDM` (one back-substitution per parameter and
            increment) or :class:`~signorini.FiniteDifferences` (central
            differences, two solves per parameter).
        steps: load increments (as :func:`signorini.solve`).
        increments: ``"last"`` (default), ``"all"`` (sum over every increment) or
            a list of increment indices.
        solution: adjoint: a converged solution of this problem to run the backward
            pass on (no forward solve; it must hold every increment's state or
            be replayable).

    Returns:
        A :class:`Gradient`.

    The keywords of version 0.1 still work, with a DeprecationWarning:
    ``params=`` (now ``wrt=``), ``mode=``, ``fd_step=``, ``factors=`` and
    ``checkpoint=`` (now ``method=``).
    """
    old = pop_old(deprecated, "signorini.gradient", {
        "params": "wrt=[...]", "mode": "method=signorini.DDM(), Adjoint() or FiniteDifferences()",
        "fd_step": "method=signorini.FiniteDifferences(rel_step=...)",
        "factors": "method=signorini.Adjoint(factors=...)",
        "checkpoint": "method=signorini.Adjoint(checkpoint=...)"})
    if "params" in old:
        if wrt is not None:
            raise InputError("give the parameters once, as wrt= (params= is its old name)")
        wrt = old.pop("params")
    method = from_keywords(method, old, "signorini.gradient", (DDM, Adjoint, FiniteDifferences),
                           "mode", "adjoint")
    if wrt is None:
        raise InputError("gradient needs the parameters to differentiate with respect to: wrt=[...]")
    if isinstance(wrt, str):
        raise InputError(f"wrt must be a list of parameter names, got the string {wrt!r}; "
                         f"write [{wrt!r}]")
    names = list(wrt)
    if not names:
        raise InputError("gradient needs at least one parameter name")
    if len(set(names)) != len(names):
        raise InputError(f"wrt lists a parameter twice: {names}")
    check_names([n for n in names if n != NODES], problem.params, "wrt")
    if NODES in names and not isinstance(method, Adjoint):
        raise InputError(f"the gradient with respect to {NODES!r} (every nodal coordinate) is "
                         f"computed by the adjoint (method=Adjoint()) only; for a check by finite differences or "
                         "DDM, move a node with a shape parameter (Problem(shape=...))")
    if solution is not None and not isinstance(method, Adjoint):
        raise InputError("solution= belongs to method=Adjoint() (a backward pass on a given solve)")
    if isinstance(method, Adjoint):
        return _adjoint(problem, response, names, steps, increments, options, solver, method,
                        label, solution)
    if isinstance(method, DDM):
        return _ddm(problem, response, names, steps, increments, options, solver, label)
    return _fd(problem, response, names, steps, increments, options, solver, method, label)


def _value(sol, fn, idx, key) -> float:
    return float(sum(np.asarray(sol.evaluate(fn, i, False, key, with_state=True)[0]) for i in idx))


def _ddm(problem, response, names, steps, increments, options, solver, label) -> Gradient:
    t0 = time.perf_counter()
    sol = solve(problem, steps=steps, wrt=names, options=options, solver=solver, label=label)
    t1 = time.perf_counter()
    fn = response_function(response, sol.model)
    idx = selected_increments(increments, len(sol.increments))
    check_scalar(fn, sol, idx[-1])
    key = ("gradient", response)
    G, grad = 0.0, dict.fromkeys(names, 0.0)
    for i in idx:
        v, d = sol.history_response(fn, i, key=key)
        G += float(np.asarray(v))
        for n in names:
            grad[n] += float(np.asarray(d[n]))
    ddm = sum(inc.timing.get("factorization", 0) + inc.timing.get("pseudo_load", 0) +
              inc.timing.get("back_substitution", 0) + inc.timing.get("history_sensitivity", 0)
              for inc in sol.increments)
    return Gradient(G, grad, "ddm", sol, {"forward": t1 - t0 - ddm, "gradient": ddm +
                                          time.perf_counter() - t1}, {}, list(sol.warnings))


def _fd(problem, response, names, steps, increments, options, solver, method, label) -> Gradient:
    t0 = time.perf_counter()
    sol = solve(problem, steps=steps, options=options, solver=solver, label=label)
    t1 = time.perf_counter()
    key = ("gradient", response)

    def value(s):
        fn = response_function(response, s.model)
        return _value(s, fn, selected_increments(increments, len(s.increments)), key)

    G = value(sol)
    grad = {n: float(finite_difference(problem, n, value, step=method.step_for(problem.params[n]),
                                       steps=steps, options=options, solver=solver))
            for n in names}
    return Gradient(G, grad, "fd", sol, {"forward": t1 - t0, "gradient": time.perf_counter() - t1},
                    {}, list(sol.warnings))


def _adjoint(problem, response, names, steps, increments, options, solver, method, label,
             sol) -> Gradient:
    t0 = time.perf_counter()
    if sol is None:
        sol = solve(problem, steps=steps, options=options, solver=solver, label=label, method=method)
    else:
        _check_solution(sol, problem, steps)
    t1 = time.perf_counter()
    G, grad, timing = adjoint_gradient(sol, response, names, increments=increments,
                                       solver=sol.linear_solver or solver)
    timing.update({"forward": t1 - t0, "gradient": time.perf_counter() - t1})
    out = Gradient(G, grad, "adjoint", sol, timing, memory_per_increment(sol), list(sol.warnings))
    message = nonsmooth.warning(sol, names)
    if message and message not in out.warnings:
        checks.warn(sol, message)
        out.warnings.append(message)
    return out


def _check_solution(sol, problem, steps) -> None:
    """A solution given to the adjoint must be a converged solve of this problem."""
    if getattr(sol, "status", None) != "converged" or not sol.increments:
        raise InputError("the adjoint needs a converged solution (solution.status == 'converged')")
    try:  # the same mesh and components, compared by content as the model cache does
        same = structure_key(sol.model.problem) == structure_key(problem)
    except TypeError:  # a component that cannot be hashed: the very same objects only
        same = all(getattr(sol.model.problem, f) is getattr(problem, f) for f in
                   ("mesh", "material", "fixed", "loads", "contact", "kinematics", "formulation",
                    "shape", "shape_nominal"))
    if not same or dict(sol.params) != dict(problem.params):
        raise InputError("solution= must be a solve of this problem (same mesh, components and "
                         "parameter values); solve it again or pass the problem it was solved for")
    if abs(sol.increments[-1].t - 1.0) > 1e-12:
        raise InputError(f"solution= ends at t = {sol.increments[-1].t:.6g}, not at the end of "
                         "the load path")
    if len(sol.increments) < steps:
        raise InputError(f"solution= has {len(sol.increments)} increments, fewer than steps={steps}")


def adjoint_gradient(solution, response, names: Sequence[str], *, increments="last", solver="auto"):
    """(G, {name: dG/dphi}, timings) by one backward pass over a converged solution."""
    m = solution.model
    fn = response_function(response, m)
    key = ("adjoint", response)
    if key not in m.cache:
        m.cache[key] = AdjointEngine(m, fn)
        old = [k for k in m.cache if isinstance(k, tuple) and k and k[0] == "adjoint"]
        for k in old[:-MAX_CACHED]:  # a new response object per call must not grow the cache
            del m.cache[k]
    adj = m.cache[key]
    pe = as_jax(solution.params)
    if NODES in names:
        pe[NODES] = jnp.zeros((m.n_nodes, m.dim))
    idx = selected_increments(increments, len(solution.increments))
    check_scalar(fn, solution, idx[-1])
    G, g, timing = adj.backward(solution, pe, idx, solver=solver)
    if not np.all(np.isfinite(G)) or not all(np.all(np.isfinite(v)) for v in
                                             jax.tree_util.tree_leaves(g)):
        raise SolverError("the adjoint gradient is not finite (NaN/inf): a parameter expression or "
                          "the response may not be differentiable at these values")
    grad = {n: (np.asarray(g[n]) if n == NODES else float(g[n])) for n in names}
    return G, grad, timing


def check_scalar(fn, solution, i: int) -> None:
    """The response must be one number (an InputError, not JAX's TypeError)."""
    inc = solution.increments[i]
    state = solution.state_before(i)[0]
    shape = jax.eval_shape(fn, jnp.asarray(inc.w), solution.jax_params, inc.t, state).shape
    if int(np.prod(shape)) != 1:
        raise InputError(f"the response must return a scalar, got an array of shape {shape}")


def memory_per_increment(solution) -> dict:
    """Bytes the forward pass keeps per increment for the backward pass (averaged)."""
    incs = solution.increments
    size = lambda tree: sum(np.asarray(a).nbytes for a in jax.tree_util.tree_leaves(tree))  # noqa: E731
    # the unknowns in a state are inc.w itself (shared, counted once)
    states = sum(size([a for a in jax.tree_util.tree_leaves(inc.state) if a is not inc.w])
                 for inc in incs if inc.state is not None)
    unknowns = sum(inc.w.nbytes for inc in incs)
    factors = sum(inc.factor is not None for inc in incs)
    fbytes = sum(inc.factor.nbytes or 0 for inc in incs if inc.factor is not None)
    n = max(len(incs), 1)
    return {"per_increment": (states + unknowns + fbytes) / n, "factors_per_increment": fbytes / n,
            "states_kept": sum(inc.state is not None for inc in incs), "factors_kept": factors}
