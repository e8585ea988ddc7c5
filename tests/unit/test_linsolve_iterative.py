"""The iterative solver (AMG-preconditioned flexible GMRES): the same solutions and
sensitivities as a direct solver, frictionless and with friction (unsymmetric),
adjoint (transposed solves), 2-D and 3-D, and its errors."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini.errors import InputError, SolverError
from signorini.linsolve import AMGKrylov, get_solver
from test_model3d import block, hertz3d, hertz3d_friction


def same(a, b, fields, tol=1e-8):
    for f in fields:
        scale = np.abs(a[f]).max()
        assert np.max(np.abs(a[f] - b[f])) <= tol * scale, f


@pytest.mark.parametrize("friction, condense", [(False, "symmetric"), (True, "symmetric"),
                                               (True, True)])
def test_amg_gives_the_direct_solution_and_sensitivities(friction, condense):
    """Frictionless (condensed), frictional (block-triangular by default, and
    condensed on demand)."""
    pb = hertz3d_friction(block(n=5)) if friction else hertz3d(block(n=5))
    steps = 2 if friction else 1
    d = sg.solve(pb, steps=steps, wrt=["R", "E"], solver="superlu").contact()
    lin = AMGKrylov(condense=condense)
    it = sg.solve(pb, steps=steps, wrt=["R", "E"], solver=lin).contact()
    same(d, it, ["p_N", "dp_N_dR", "dp_N_dE"] + (["p_T", "dp_T_dR"] if friction else []))
    assert lin.iterations and max(lin.iterations) < 200  # preconditioned: tens, not thousands


def test_amg_adjoint_and_2d():
    """The adjoint's transposed solves, and a plane-strain problem (rigid modes in 2-D)."""
    from signorini._jax import jnp
    pb = hertz3d_friction(block(n=4))
    n_u = 3 * pb.mesh.n_nodes
    response = lambda w, p, t: jnp.sum(w[:n_u] ** 2)  # noqa: E731
    a = sg.gradient(pb, response, ["R", "mu"], method=sg.Adjoint(), steps=2, solver="amg")
    b = sg.gradient(pb, response, ["R", "mu"], method=sg.Adjoint(), steps=2, solver="superlu")
    for k in ("R", "mu"):
        assert a.grad[k] == pytest.approx(b.grad[k], rel=1e-8)
    from signorini.problems.hertz import hertz_problem
    p2 = hertz_problem(n_fine=12)
    same(sg.solve(p2, wrt=["R"], solver="superlu").contact(),
         sg.solve(p2, wrt=["R"], solver="amg").contact(), ["p_N", "dp_N_dR"])


def test_amg_errors_are_named():
    lin = get_solver("amg")
    with pytest.raises(InputError, match="needs the tangent's structure"):
        lin.factorize(sp.identity(4, format="csr"))
    with pytest.raises(SolverError, match="did not reach the relative residual .* use a direct solver"):
        sg.solve(hertz3d(block(n=3)), solver=AMGKrylov(restart=2, max_iterations=2))


@pytest.mark.parametrize("kwargs, name", [
    ({"condense": "always"}, "condense"), ({"condense": 1}, "condense"),
    ({"theta": -0.1}, "theta"), ({"theta": 2.0}, "theta"), ({"theta": float("nan")}, "theta"),
    ({"rtol": 0.0}, "rtol"), ({"rtol": 1.5}, "rtol"), ({"restart": 0}, "restart"),
    ({"max_iterations": 2.5}, "max_iterations")])
def test_amg_options_are_checked(kwargs, name):
    with pytest.raises(InputError, match=f"AMGKrylov: {name} (must|\\(the)"):
        AMGKrylov(**kwargs)
    AMGKrylov(theta=0.0, condense=False)  # the limits themselves are valid


def test_newton_corrections_are_solved_inexactly_to_the_same_solution(monkeypatch):
    """With an iterative solver Newton's corrections stop at Eisenstat and Walker's
    forcing tolerance (about 1e-3 at first, not 1e-11): fewer Krylov iterations,
    the same converged solution and sensitivities (docs/theory.md §12.7)."""
    from signorini.algorithms import newton
    pb = hertz3d(block(n=5))
    loose = AMGKrylov()
    a = sg.solve(pb, wrt=["R"], solver=loose)
    monkeypatch.setattr(newton, "FORCING_MAX", 0.0)  # every correction to the solver's 1e-11
    tight = AMGKrylov()
    b = sg.solve(pb, wrt=["R"], solver=tight)
    same(a.contact(), b.contact(), ["p_N", "dp_N_dR"], tol=1e-9)
    n_newton = a.newton_iterations[0]
    # the first correction at 1e-3 takes a fraction of the tight solve's iterations
    assert loose.iterations[0] < 0.5 * tight.iterations[0]
    # all of them, the last (expected to end the increment) solved to the floor of
    # the tolerance: 40 against 65 when measured
    assert sum(loose.iterations[:n_newton]) < 0.65 * sum(tight.iterations[:b.newton_iterations[0]])
    # the increment ends at the floor (1e-13 relative, 3.5e-16 here: the round-off of
    # the residual's evaluation, so within a factor 2), not at Newton's rtol (1e-10)
    log = a.increments[0].newton
    assert log.relative_residual <= 2 * newton.FORCING_FLOOR * newton.NewtonOptions().rtol


def test_forcing_terms():
    """Eisenstat-Walker: the loosest tolerance first, then (||R_k|| / ||R_k-1||)^2,
    safeguarded, and never tighter than the final residual needs."""
    from signorini.algorithms.newton import FORCING_FLOOR, FORCING_MAX, NewtonOptions, _forcing
    opt = NewtonOptions()
    assert _forcing(1.0, [1.0], 1.0, None, opt) == FORCING_MAX
    # quadratic convergence: 0.9 (1e-6 / 1e-3)^2 = 9e-7
    assert _forcing(1e-6, [1e-3, 1e-6], 1.0, 1e-3, opt) == pytest.approx(9e-7)
    # a slow decrease never loosens beyond FORCING_MAX
    assert _forcing(0.9, [1.0, 0.9], 1.0, 1e-3, opt) == FORCING_MAX
    # close to convergence: no tighter than FORCING_FLOOR rtol ref / ||R||
    assert _forcing(1e-9, [1e-4, 1e-9], 1.0, 1e-3, opt) == pytest.approx(FORCING_FLOOR * 1e-10 / 1e-9)


def test_solve_to_of_direct_and_iterative_factors():
    """A direct factor's solve_to solves to round-off; an iterative one stops at rtol."""
    rng = np.random.default_rng(3)
    K = sp.random(60, 60, density=0.1, random_state=4) + 10 * sp.identity(60)
    K = sp.csr_matrix(K)
    b = rng.standard_normal(60)
    f = get_solver("superlu").factorize(K)
    assert not f.inexact
    x = f.solve_to(b, 1e-2)
    assert np.linalg.norm(K @ x - b) <= 1e-13 * np.linalg.norm(b)
    calls = []
    exact = np.linalg.solve(K.toarray(), b)
    g = sg.linsolve.Factor(lambda v: exact, K, solve_to=lambda v, r: calls.append(r) or 0.5 * exact)
    assert g.inexact
    g.solve_to(b, 1e-2)
    assert calls == [1e-2] and g.relative_residual == pytest.approx(0.5)


def _setups(lin, monkeypatch) -> list:
    """The cycles ``lin`` builds (one per hierarchy set up), recorded."""
    built = []
    real = lin._cycle
    monkeypatch.setattr(lin, "_cycle", lambda *a: built.append(real(*a)) or built[-1])
    return built


@pytest.mark.parametrize("friction", [False, True])
def test_a_kept_hierarchy_serves_tangents_that_differ_in_contact_rows(friction, monkeypatch):
    """Newton's tangents and the increments' differ in the contact nodes' rows: one
    hierarchy serves them all, its finest level made anew for the full solves
    (frictionless: Newton's corrections, the condensed sensitivity solve building
    its own; with friction: the whole path, sensitivities included), with the
    solution and the sensitivities of a hierarchy built for every tangent (the
    inexact Newton iterates differ, so its iteration count may)."""
    pb = hertz3d_friction(block(n=5)) if friction else hertz3d(block(n=5))
    steps = 3 if friction else 1
    out = {}
    for refresh in (True, False):
        lin = AMGKrylov()
        if not refresh:  # a new hierarchy for every tangent
            lin.REFRESH_ROWS, lin.REUSE = -1.0, 0
        built = _setups(lin, monkeypatch)
        sol = sg.solve(pb, steps=steps, wrt=["R"], solver=lin)
        out[refresh] = (len(built), sum(sol.newton_iterations), sol.contact())
    n1, _, c1 = out[True]
    n0, its0, c0 = out[False]
    if friction:
        assert n1 == 1 and n0 == its0 + steps  # a tangent per correction and per increment's end
    else:
        assert n1 == 2 and n0 == its0 + 1
    same(c0, c1, ["p_N", "dp_N_dR"] + (["p_T", "dp_T_dR"] if friction else []), tol=1e-9)


def test_a_tangent_that_changes_everywhere_gets_a_new_hierarchy_after_reuse(monkeypatch):
    """A displacement block that differs from the kept hierarchy's in more than
    REFRESH_ROWS of its rows (a material tangent: every row) is served REUSE
    times, then gets a hierarchy of its own; one that differs in a few rows keeps
    it. A refreshed cycle of the block it was built on is that cycle."""
    from signorini.linsolve.multigrid import ChebyshevCycle
    pb = hertz3d_friction(block(n=5))
    captured = []
    lin = AMGKrylov()
    real = lin.factorize
    monkeypatch.setattr(lin, "factorize", lambda K, symmetric=False: captured.append(K) or real(K, symmetric))
    sg.solve(pb, steps=1, solver=lin)
    K, structure = sp.csr_matrix(captured[-1]), lin.structure
    lin = AMGKrylov()
    lin.structure = structure
    built = _setups(lin, monkeypatch)
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    x = lin.factorize(K).solve(b)
    assert len(built) == 1 and isinstance(built[0], ChebyshevCycle)
    n_u = lin.structure.n_u
    # a few rows changed: the kept hierarchy, its finest level made anew by a full solve
    K2 = K.tolil()
    K2[0, 0] *= 1.5
    first = lin._kept.cycle
    lin.factorize(sp.csr_matrix(K2)).solve(b)
    assert len(built) == 1 and lin._kept.uses == 0
    assert lin._kept.cycle is not first and lin._kept.cycle.levels[0].P is first.levels[0].P
    # every row changed: REUSE tangents, then a new hierarchy
    for i in range(AMGKrylov.REUSE + 1):
        Ki = K.copy()
        Ki[:n_u, :n_u] *= 1.0 + 0.01 * (i + 1)
        y = lin.factorize(sp.csr_matrix(Ki)).solve(b)
        assert np.linalg.norm(Ki @ y - b) <= 1e-10 * np.linalg.norm(b)
        assert len(built) == (1 if i < AMGKrylov.REUSE else 2)
    # refreshed with the very block it was built on (the symmetric part): the same cycle
    cycle = built[0]
    A = K[:n_u, :n_u]
    full = lin._full(sp.csr_matrix(0.5 * (A + A.T)))
    again = cycle.with_finest(full, lin.structure.dim)
    r = np.random.default_rng(1).standard_normal(full.shape[0])
    assert np.linalg.norm(again(r) - cycle(r)) <= 1e-12 * np.linalg.norm(cycle(r))
    assert np.linalg.norm(K @ x - b) <= 1e-10 * np.linalg.norm(b)


def test_nodal_inverse_of_a_csr_matrix_is_the_block_one():
    """The smoother's inverse nodal blocks from a CSR matrix equal pyamg's from BSR."""
    from signorini.linsolve.multigrid import nodal_inverse
    A = sp.random(60, 60, density=0.2, random_state=1) + sp.eye(60) * 5.0
    A = sp.csr_matrix(A + A.T)
    a = nodal_inverse(A, 3).toarray()
    b = nodal_inverse(A.tobsr(blocksize=(3, 3)), 3).toarray()
    assert np.allclose(a, b, rtol=1e-12, atol=1e-14)
    blk = A.toarray()[3:6, 3:6]
    assert np.allclose(a[3:6, 3:6] @ blk, np.eye(3), atol=1e-12)


def test_aggregates_follow_the_stretching_of_the_cells():
    """On a grid of flat cells (10 times wider than high) every first-level aggregate
    is a piece of one vertical column of nodes; on a grid of cubes the aggregates
    span all three directions (docs/theory.md §12.7)."""
    from signorini.fem.mesh3d import box
    from signorini.linsolve.iterative import geometric_aggregates
    flat = np.linspace(0.0, 1.0, 9)
    for zs, columns in ((0.1 * flat, True), (flat, False)):
        X = box(flat, flat, zs).nodes
        n = len(X)
        # the node graph of a trilinear mesh: neighbours within one cell
        d = np.abs(X[:, None, :] - X[None, :, :]) <= np.array([0.126, 0.126, zs[1] + 1e-9])
        G = sp.csr_matrix(np.all(d, axis=2).astype(float))
        M = sp.kron(G, np.ones((3, 3))).tobsr(blocksize=(3, 3))
        agg = geometric_aggregates(M, X, 0.05, n // 10)[0].tocsc()
        spans = [np.ptp(X[agg.indices[agg.indptr[j]:agg.indptr[j + 1]]], axis=0)
                 for j in range(agg.shape[1])]
        lateral = max(max(s[0], s[1]) for s in spans)
        assert (lateral == 0.0) if columns else (lateral > 0.0)
        assert max(s[2] for s in spans) > 0.0


def test_aggregation_by_geometry_needs_fewer_iterations_on_stretched_cells():
    """The graded block (cells up to 8 times longer than wide): the geometric
    strength takes far fewer GMRES iterations than aggregating every neighbour
    (theta = 0), to the same solution and sensitivities."""
    pb = hertz3d(block(n=8))
    runs = {}
    for theta in (0.0, 0.05):
        lin = AMGKrylov(theta=theta)
        runs[theta] = (sg.solve(pb, wrt=["R"], solver=lin).contact(), lin.iterations)
    same(runs[0.0][0], runs[0.05][0], ["p_N", "dp_N_dR"], tol=1e-9)
    # the sensitivity solve (the last, to 1e-11): 52 against 31 when measured
    assert runs[0.05][1][-1] < 0.7 * runs[0.0][1][-1]


def _tangents(pb, steps, monkeypatch):
    """Every tangent the iterative solver is given while solving ``pb`` (with R's
    sensitivity), with its structure."""
    seen = []
    real = AMGKrylov.factorize

    def keep(self, K, symmetric=False):
        seen.append((sp.csr_matrix(K).copy(), self.structure, symmetric))
        return real(self, K, symmetric)
    monkeypatch.setattr(AMGKrylov, "factorize", keep)
    sg.solve(pb, steps=steps, wrt=["R"], solver=AMGKrylov())
    monkeypatch.setattr(AMGKrylov, "factorize", real)
    return seen


def test_condensation_with_an_exact_inner_solve_is_the_inverse(monkeypatch):
    """The node-by-node condensation of the multipliers around an exact solve of the
    reduced operator solves K exactly: frictionless and with friction (open, sticking
    and slipping nodes, unsymmetric), and for the transposed tangent (the adjoint)."""
    import scipy.sparse.linalg as spla
    from signorini.linsolve.condensation import condense
    rng = np.random.default_rng(5)
    kinds = set()
    for pb, steps in ((hertz3d(block(n=4)), 1), (hertz3d_friction(block(n=4)), 2)):
        K, st, _ = _tangents(pb, steps, monkeypatch)[-1]
        for M in (K, K.T.tocsr()):
            c = condense(M, st.n_u, st.lam_group, st.u_global, st.dim)
            assert c is not None
            kinds |= {(b.lam.shape[1], bool(np.any(b.Dp)), b.Pp is not None)
                      for b in c.buckets if len(b.lam)}
            exact = spla.splu(c.reduced(True, 1.0).tocsc()).solve
            r = rng.standard_normal(M.shape[0])
            x = c.preconditioner(exact)(r)
            assert np.linalg.norm(M @ x - r) <= 1e-9 * np.linalg.norm(r)
    # closed normals (1 multiplier, constrained), open nodes (D of full rank), and
    # friction nodes with both constraints and rows in D's range
    assert {(1, False, True), (1, True, False), (3, True, False), (3, True, True)} <= kinds


def test_condensation_is_declined_where_a_multiplier_reaches_two_nodes():
    """A multiplier row coupled to the displacements of two nodes (a mortar pair's
    weighted gap) is not condensed: the solver keeps the block-triangular
    preconditioner."""
    from signorini.linsolve.condensation import condense
    A = sp.identity(6) * 4.0
    C = sp.csr_matrix(np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.5]]))  # nodes 0 and 1 (dim 3)
    K = sp.bmat([[A, C.T], [C, None]]).tocsr()
    assert condense(K, 6, np.array([0]), np.arange(6), 3) is None
    C1 = sp.csr_matrix(np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]]))
    K1 = sp.bmat([[A, C1.T], [C1, None]]).tocsr()
    c = condense(K1, 6, np.array([0]), np.arange(6), 3)
    assert c is not None
    x = c.preconditioner(lambda v: v / 4.0)(np.arange(7.0))
    assert np.allclose(K1 @ x, np.arange(7.0))


def test_frictionless_sensitivity_solves_are_condensed(monkeypatch):
    """The full solves of a frictionless (symmetric) tangent condense its
    multipliers, and take fewer iterations than the block-triangular
    preconditioner, to the same sensitivities."""
    from signorini.linsolve import iterative
    made = []
    real = iterative.condense
    monkeypatch.setattr(iterative, "condense", lambda *a: made.append(real(*a)) or made[-1])
    pb = hertz3d(block(n=8))
    runs = {}
    for condense in (False, "symmetric"):
        lin = AMGKrylov(condense=condense)
        runs[condense] = (sg.solve(pb, wrt=["R"], solver=lin).contact(), lin.iterations[-1])
    assert len(made) == 1 and made[0] is not None  # the converged tangent, once
    same(runs[False][0], runs["symmetric"][0], ["p_N", "dp_N_dR"], tol=1e-9)
    assert runs["symmetric"][1] < 0.85 * runs[False][1]  # 22 against 31 when measured


def test_several_right_hand_sides_share_their_search_space(monkeypatch):
    """The sensitivities of several parameters solved with one tangent: each column
    after the first starts from the space the columns before it searched (GCRO's
    deflation), so it needs fewer iterations than alone, for the same solutions."""
    captured = []
    real = AMGKrylov._shared_gmres

    def keep(self, K, apply, b, rtol, x0=None):
        if b.shape[1] > 1:  # the sensitivities' solve
            captured.append((K, apply, b, self.structure))
        return real(self, K, apply, b, rtol, x0)
    monkeypatch.setattr(AMGKrylov, "_shared_gmres", keep)
    sg.solve(hertz3d_friction(block(n=5)), steps=2, wrt=["R", "E", "eps", "mu"], solver=AMGKrylov())
    K, apply, b, st = captured[-1]
    assert b.shape[1] == 4
    shared, alone = AMGKrylov(), AMGKrylov()
    shared.RECYCLE_BYTES, alone.RECYCLE_BYTES = 500_000_000, 0  # shared; each by its own GMRES
    x = real(shared, K, apply, b, 1e-11)
    y = alone._krylov(K, apply, b)
    for j in range(4):
        assert np.linalg.norm(b[:, j] - K @ x[:, j]) <= 1e-11 * np.linalg.norm(b[:, j])
    assert np.abs(x - y).max() <= 1e-9 * np.abs(y).max()
    # the first column has nothing to recycle: the same GMRES but for its
    # orthogonalisation, pyamg's Householder against one or two Gram-Schmidt passes, so
    # that the last iteration's residual estimate may fall on either side of the
    # tolerance (25 and 25 measured). Both counts are the same in every process, the
    # hierarchy being independent of NumPy's random state
    # (test_a_solve_does_not_depend_on_what_the_process_drew_before); they may differ
    # with OpenBLAS's thread count, which sets the order of its sums.
    assert abs(shared.iterations[0] - alone.iterations[0]) <= 1
    # measured: 18, 20, 19 against 22, 26, 22 iterations for the later columns
    assert sum(shared.iterations[1:]) < sum(alone.iterations[1:]) - 3


@pytest.mark.parametrize("friction", [True, False])
def test_right_hand_sides_iterated_side_by_side_are_solved_as_one_by_one(monkeypatch, friction):
    """The sensitivities of several parameters (a frictional tangent, the
    block-triangular preconditioner; a frictionless one, the condensed
    preconditioner): GMRES on the columns side by side, the V-cycle and K acting on
    the block of the columns still iterating, gives each column the iterations and
    the solution of its own GMRES, also in groups (a memory budget for two columns
    at once), from guesses, and with a zero column."""
    captured = []
    real = AMGKrylov._shared_gmres

    def keep(self, K, apply, b, rtol, x0=None):
        if b.shape[1] > 1:
            captured.append((K, apply, b))
        return real(self, K, apply, b, rtol, x0)
    monkeypatch.setattr(AMGKrylov, "_shared_gmres", keep)
    lin = AMGKrylov()
    if friction:
        sg.solve(hertz3d_friction(block(n=5)), steps=2, wrt=["R", "E", "eps", "mu"], solver=lin)
    else:
        sg.solve(hertz3d(block(n=5)), wrt=["R", "E"], solver=lin)
    monkeypatch.setattr(AMGKrylov, "_shared_gmres", real)
    K, apply, b = captured[-1]
    assert b.shape[1] == (4 if friction else 2) and apply.blocks
    n = K.shape[0]
    b = np.column_stack([b, np.zeros(n)])  # a zero column: x = 0, no iteration
    k = b.shape[1]
    guess = 0.9 * np.linalg.solve(K.toarray(), b) if n < 4000 else None
    runs = {}
    for name, budget in [("one by one", 0), ("side by side", 1e12),
                         ("two at a time", 2.5 * 16 * n * (lin.restart + 1))]:
        s = AMGKrylov()
        s.LOCKSTEP_BYTES = budget
        calls = []
        if budget:  # every column goes through the side-by-side iteration
            monkeypatch.setattr(s, "_lockstep", lambda *a, s=s, calls=calls: (
                calls.append(a[2].shape[1]), AMGKrylov._lockstep(s, *a))[1])
        x = s._krylov(K, apply, b)
        xg = s._krylov(K, apply, b, x0=guess) if guess is not None else x
        runs[name] = (x, xg, s.iterations, calls)
        for j in range(k):
            assert np.linalg.norm(b[:, j] - K @ x[:, j]) <= 1e-11 * max(np.linalg.norm(b[:, j]), 1e-300)
    assert runs["side by side"][3] == [k] + ([k] if guess is not None else [])
    assert runs["two at a time"][3][:(k + 1) // 2] == [min(2, k - j) for j in range(0, k, 2)]
    ref = runs["one by one"]
    assert ref[2][k - 1] == 0 and not np.any(ref[0][:, k - 1])
    for name in ("side by side", "two at a time"):
        x, xg, its, _ = runs[name]
        assert its == ref[2], name  # each column the same GMRES
        assert np.abs(x - ref[0]).max() <= 1e-12 * np.abs(ref[0]).max(), name
        assert np.abs(xg - ref[1]).max() <= 1e-12 * np.abs(ref[1]).max(), name


def test_a_solve_does_not_depend_on_what_the_process_drew_before():
    """The same solve twice, with NumPy's global random generator drawn from in
    between (as pyamg's own setups, an earlier AMG solve or a user's ``np.random`` do):
    the same iteration counts and the same bits. pyamg weights the smoothing of the
    prolongator by a spectral radius it estimates from a random start; the solver
    seeds that start, so that a hierarchy is a function of its matrix alone, and
    leaves the caller's generator where it found it."""
    import pyamg
    pb = hertz3d_friction(block(n=4))
    runs = []
    for disturb in (False, True):
        if disturb:  # what tests/unit/test_linsolve_multigrid.py does before
            A = pyamg.gallery.poisson((20, 20), format="csr")
            pyamg.smoothed_aggregation_solver(A, max_coarse=10)
            np.random.rand(1000)
        before = np.random.get_state()
        lin = AMGKrylov()
        sol = sg.solve(pb, steps=2, wrt=["R", "E"], solver=lin)
        after = np.random.get_state()
        assert np.array_equal(after[1], before[1]) and after[2:] == before[2:]
        runs.append((lin.iterations, sol.contact()))
    assert runs[0][0] == runs[1][0]
    for f in ("p_N", "p_T", "dp_N_dR", "dp_N_dE", "dp_T_dR"):
        assert np.array_equal(runs[0][1][f], runs[1][1][f]), f


def test_a_solve_starts_from_its_guess_where_the_guess_is_better_than_none():
    """Factor.solve(b, guess=...): an iterative factor starts from the guess (none
    needed where it is the solution), declines one that leaves more residual than
    zero does, and reaches the same accuracy either way; a direct factor ignores it."""
    pb = hertz3d_friction(block(n=4))
    captured = []
    real = AMGKrylov._shared_gmres

    def keep(self, K, apply, b, rtol, x0=None):
        if b.shape[1] > 1:  # the sensitivities' solve
            captured.append((self, K))
        return real(self, K, apply, b, rtol, x0)
    import unittest.mock as um
    with um.patch.object(AMGKrylov, "_shared_gmres", keep):
        sg.solve(pb, steps=2, wrt=["R", "E"], solver=AMGKrylov())
    lin, K = captured[-1]
    rng = np.random.default_rng(0)
    x_true = rng.standard_normal((K.shape[0], 2))
    b = np.column_stack([K @ x_true[:, j] for j in range(2)])
    f = lin.factorize(K)
    assert f.takes_guess and not get_solver("superlu").factorize(K).takes_guess
    counts = {}
    for name, guess in [("none", None), ("exact", x_true), ("bad", -3.0 * x_true),
                        ("near", x_true + 1e-3 * rng.standard_normal(x_true.shape))]:
        n0 = len(lin.iterations)
        x = f.solve(b, guess=guess)
        counts[name] = lin.iterations[n0:]
        for j in range(2):
            assert np.linalg.norm(b[:, j] - K @ x[:, j]) <= 1e-11 * np.linalg.norm(b[:, j])
    assert counts["exact"] == [0, 0]
    assert counts["bad"] == counts["none"]  # declined: ||b - K x0|| = 4 ||b||
    assert sum(counts["near"]) < sum(counts["none"])
    direct = get_solver("superlu").factorize(K)
    assert np.abs(direct.solve(b, guess=-3.0 * x_true) - x_true).max() <= 1e-9 * np.abs(x_true).max()


def test_sensitivity_solves_start_from_the_increments_before(monkeypatch):
    """With an iterative solver an increment's sensitivity solves start from the
    sensitivities of the two increments before, extrapolated linearly in t: the same
    sensitivities in fewer iterations (the 43k-DOF frictional hertz3d: 10 % less
    time in its sensitivities)."""
    from signorini.algorithms import stepping
    pb = hertz3d_friction(block(n=5))
    runs = {}
    for guess in (True, False):
        if not guess:
            monkeypatch.setattr(stepping._LoadPath, "_sensitivity_guess", lambda self, t: None)
        lin = AMGKrylov()
        spent = []
        real = lin._shared_gmres

        def count(K, apply, b, rtol, x0=None, real=real, lin=lin, spent=spent):
            n0 = len(lin.iterations)
            x = real(K, apply, b, rtol, x0)
            if b.shape[1] > 1:  # the sensitivities' solves, not Newton's corrections
                spent.append(sum(lin.iterations[n0:]))
            return x
        monkeypatch.setattr(lin, "_shared_gmres", count)
        sol = sg.solve(pb, steps=5, wrt=["R", "E", "mu"], solver=lin)
        runs[guess] = (sol.contact(), spent)
    same(runs[True][0], runs[False][0], ["p_N", "dp_N_dR", "dp_N_dE", "dp_N_dmu", "dp_T_dR"],
         tol=1e-9)
    with_guess, without = runs[True][1], runs[False][1]
    assert len(with_guess) == len(without) == 5
    # nothing to start from at the first increment: the same solve, the same count (58)
    assert with_guess[0] == without[0]
    # measured: 58, 57, 63, 52 against 59, 61, 63, 63 for increments 2 to 5
    assert sum(with_guess[1:]) < sum(without[1:]) - 8


def test_newton_with_an_iterative_solver_ends_without_a_wasted_correction():
    """A correction already solved to the floor's tolerance is not polished once
    more: every increment's last correction lowered the residual (before, a
    converged state at round-off was corrected again: 1.1e-17 -> 1.3e-17 here, with
    the tolerance rtol ref at the round-off floor, as in the hertz3d command)."""
    from signorini.algorithms.newton import NewtonOptions
    sol = sg.solve(hertz3d_friction(block(n=5)), steps=3, solver=AMGKrylov(),
                   options=NewtonOptions(rtol=1e-12))
    for inc in sol.increments:
        res = inc.newton.residuals
        assert inc.newton.converged and len(res) >= 2
        assert res[-1] < 0.5 * res[-2], res



def test_symmetric_part_keeps_no_stored_zeros():
    """(A + A^T) / 2 on A's symmetric pattern, without the zeros A stores (a pair's
    couplings of nodes not in contact: kept, they would join aggregates across the
    two bodies); the same matrix where the pattern is not symmetric."""
    from signorini.linsolve.iterative import symmetric_part
    A = sp.random(40, 40, density=0.2, random_state=2, format="csr")
    A = sp.csr_matrix(A + abs(A.T) + sp.eye(40))  # a symmetric pattern, unsymmetric values
    A.data[::7] = 0.0  # stored zeros
    A.data[1] = 0.0
    S = symmetric_part(A)
    dense = 0.5 * (A.toarray() + A.toarray().T)
    assert np.array_equal(S.toarray(), dense)
    assert S.nnz == np.count_nonzero(dense) < A.nnz
    B = sp.csr_matrix(sp.triu(sp.random(40, 40, density=0.2, random_state=3)) + sp.eye(40))
    assert np.allclose(symmetric_part(B).toarray(), 0.5 * (B.toarray() + B.toarray().T), rtol=0,
                       atol=1e-15)


def test_a_preconditioner_returning_nan_is_a_solver_error():
    """A cycle that returns NaN ends the solve with a SolverError naming the
    preconditioner, not NumPy's least-squares error from inside GMRES."""
    K = sp.csr_matrix(sp.eye(30) * 2.0)
    lin = AMGKrylov()
    with pytest.raises(SolverError, match="preconditioner returned non-finite"):
        lin._krylov(K, lambda r: r * np.nan, np.ones(30))
    assert np.allclose(lin._krylov(K, lambda r: 0.5 * r, np.ones(30)), 0.5)
