"""The speed-ups of issue 10 change cost, never results: solver choice, the kept
symbolic analysis (of the tangent with every contact node closed), the symmetric
factorisation, the stiffness of linear bodies computed once (and its parameter
derivative kept along a path), the extrapolating predictor, the coarse meshes
guiding a load path, the reused DDM factorisation and the persistent
compilation cache."""

import os
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini import linsolve
from signorini.linsolve import Pardiso, SuperLU, TangentSolver, get_solver
from signorini.algorithms.coarse_to_fine import prolong, solve_coarse_to_fine
from signorini.params import as_jax
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for

HAS_PARDISO = "pardiso" in linsolve.available()
needs_pardiso = pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso (MKL) is not installed")
TIGHT = sg.NewtonOptions(rtol=1e-11)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ------------------------------------------------------------------ solver choice
def test_auto_picks_the_fastest_installed():
    s = get_solver("auto")
    assert s.name == ("pardiso" if HAS_PARDISO else "superlu")
    assert get_solver() .name == s.name  # auto is the default
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8))
    assert sol.solver == s.name


def test_missing_named_solver_says_how_to_install(monkeypatch):
    def no_mkl():
        raise sg.InputError("solver 'pardiso' is not installed: `python3 -m pip install pypardiso` "
                            "(x86-64 only; it brings Intel MKL) (import failed: simulated)")

    from signorini.algorithms.stepping import _MODELS

    monkeypatch.setattr(linsolve, "_MKL", None)
    monkeypatch.setattr(linsolve, "_load_mkl", no_mkl)
    _MODELS.clear()  # a kept model keeps the solver it made before (model.cache)
    with pytest.raises(sg.InputError, match=r"pip install pypardiso"):
        get_solver("pardiso")
    with pytest.raises(sg.InputError, match=r"pip install pypardiso"):
        sg.solve(hertz.hertz_problem(n_fine=8, size=8), solver="pardiso")
    assert get_solver("auto").name == "superlu"  # auto falls back


def test_mkl_runtime_found_without_importing_pypardiso(monkeypatch):
    """PARDISO's library is found by a direct look in the environment (importing
    pypardiso and its search cost 0.7 s of every CLI start); a wrong
    PYPARDISO_MKL_RT falls back to pypardiso's search and ends in the
    install message."""
    if not HAS_PARDISO:
        pytest.skip("MKL is not installed here")
    import ctypes

    path = linsolve._mkl_rt_path()
    assert path is not None and "mkl_rt" in os.path.basename(path)
    assert hasattr(ctypes.CDLL(path), "pardiso")
    monkeypatch.setattr(linsolve, "_MKL", None)
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/nonexistent/libmkl_rt.so")
    assert linsolve._mkl_rt_path() == "/nonexistent/libmkl_rt.so"
    with pytest.raises(sg.InputError, match=r"pip install pypardiso"):
        linsolve._load_mkl()


def test_mkl_runtime_lookup_takes_the_newest_in_the_environment(tmp_path, monkeypatch):
    """Of several MKL runtimes in the environment's lib folder the newest is
    taken (libmkl_rt.so.10 over .so.9 and .so.2); none there and none in the
    user site: None (pypardiso's search then decides)."""
    import site
    import sys

    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    monkeypatch.setattr(site, "USER_BASE", str(tmp_path / "user"))
    monkeypatch.setattr(sys, "prefix", str(tmp_path / "env"))
    assert linsolve._mkl_rt_path() is None
    (tmp_path / "env" / "lib").mkdir(parents=True)
    for name in ("libmkl_rt.so.2", "libmkl_rt.so.10", "libmkl_rt.so.9", "libmkl_core.so.3"):
        (tmp_path / "env" / "lib" / name).write_bytes(b"")
    assert linsolve._mkl_rt_path() == str(tmp_path / "env" / "lib" / "libmkl_rt.so.10")


def test_umfpack_message_names_its_package():
    if "umfpack" in linsolve.available():
        pytest.skip("scikit-umfpack is installed here")
    with pytest.raises(sg.InputError, match=r"pip install scikit-umfpack"):
        get_solver("umfpack")


def test_summary_names_the_solver(tmp_path):
    s = hertz.run(tmp_path / "h", fd_check=False, size=8, coarse_start=False)
    assert s["solver"] == get_solver("auto").name and s["symmetric_factorisation"] is True


# ---------------------------------------------------------------- factorisations
def _tangent(pb, friction=False):
    sol = sg.solve(pb, steps=3 if friction else 1, options=TIGHT, solver="superlu")
    m, p = model_for(pb), as_jax(pb.params)
    st = sol.increments[-2].state if friction else None
    R, blocks = m.local_tangents(sol.increments[-1].w, p, 1.0, st)
    return m.pattern.assemble(blocks), R[m.free]


@needs_pardiso
@pytest.mark.parametrize("friction", [False, True])
def test_kept_symbolic_analysis_equals_fresh_factorisation(friction):
    """Two matrices of one pattern: the second factorisation reuses the analysis of
    the first (one phase 11) and solves like a fresh solver (to round-off)."""
    pb = hertz_friction_problem(refine=0) if friction else hertz.hertz_problem(n_fine=8, size=8)
    K, _ = _tangent(pb, friction)
    K2 = K.copy()  # same pattern (explicit zeros kept), other values, symmetric if K is
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    K2.data = K.data * (1.0 + 0.01 * np.cos(rows + K.indices))
    b = np.random.default_rng(0).normal(size=K.shape[0])
    kept = Pardiso()
    kept.factorize(K, symmetric=not friction)
    f = kept.factorize(K2, symmetric=not friction)
    x_kept = f.solve(b)
    assert kept.analyses - kept.reanalyses == 1
    x_fresh = Pardiso().factorize(K2, symmetric=not friction).solve(b)
    assert _rel(x_kept, x_fresh) < 1e-10
    assert f.backward_error <= linsolve.REFINE_TOL


_THREADS_SCRIPT = r"""
import contextlib, ctypes
import numpy as np, scipy.sparse as sp
from threadpoolctl import threadpool_limits
from signorini import linsolve
from signorini.errors import InputError, SingularTangentError
from signorini.linsolve import Pardiso, mkl_threads
n = 2000  # a 2-D Laplacian plus a shift: symmetric, with fill-in worth two threads
T = sp.diags([-1.0, 2.2, -1.0], [-1, 0, 1], shape=(45, 45))
K = (sp.kron(sp.eye(45), T) + sp.kron(T, sp.eye(45))).tocsr()
K.sort_indices()
b = np.cos(np.arange(K.shape[0]))
s = Pardiso()
with mkl_threads(2):
    old = s.factorize(K, symmetric=True)
# a factor of the old analysis is refused after a new one, also when the numeric
# factorisation that follows it fails (its solve would find no factor: a crash)
call = linsolve._Handle.call
def failing(self, phase, a=None, b=None):
    if phase == 22:
        raise SingularTangentError("planted")
    return call(self, phase, a, b)
linsolve._Handle.call = failing
with mkl_threads(1):
    try:
        s.factorize(K * 2.0, symmetric=True)
    except SingularTangentError:
        pass
linsolve._Handle.call = call
try:
    old.solve(b)
    print("stale solved", s.analyses)
except InputError:
    print("stale refused", s.analyses)
with mkl_threads(2):
    s.factorize(K, symmetric=True)
domain = s._f.lib.MKL_Domain_Set_Num_Threads  # MKL_DOMAIN_PARDISO = 4
for limit in ("pardiso-domain", "mkl", "threadpoolctl"):
    if limit == "pardiso-domain":  # MKL_Get_Max_Threads stays 2
        domain(ctypes.c_int(1), ctypes.c_int(4))
        ctx = contextlib.nullcontext()
    else:
        ctx = mkl_threads(1) if limit == "mkl" else threadpool_limits(1)
    with ctx:
        x = s.factorize(K * 1.5, symmetric=True).solve(b)
    print(limit, float(np.abs(1.5 * (K @ x) - b).max()), s.analyses)
    domain(ctypes.c_int(0), ctypes.c_int(4))  # 0: the domain follows the global count again
    with mkl_threads(2):
        s.factorize(K, symmetric=True)
"""


@needs_pardiso
def test_factorisation_with_fewer_threads_than_the_analysis_had():
    """MKL PARDISO's numeric factorisation crashes the process (segmentation fault)
    when it runs with fewer OpenMP threads than the pattern's analysis had, as under a
    user's ``threadpool_limits(1)`` around a later solve, or a limit of PARDISO's
    thread domain alone. The pattern is analysed again instead. Run in a child
    process, so that a regression fails this test only."""
    from signorini.linsolve import _mkl, mkl_max_threads, mkl_threads
    with mkl_threads(2):
        if mkl_max_threads(_mkl()) != 2:
            pytest.skip("MKL does not run two threads here")
    out = subprocess.run([sys.executable, "-c", _THREADS_SCRIPT], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, f"exit {out.returncode}: {out.stderr[-2000:]}"
    lines = [ln.split() for ln in out.stdout.splitlines()]
    assert lines.pop(0) == ["stale", "refused", "2"]
    assert [ln[0] for ln in lines] == ["pardiso-domain", "mkl", "threadpoolctl"]
    for _, err, _ in lines:
        assert float(err) < 1e-12
    # analysed with 2 threads, again with 1 (each limit), and with 2 after each
    assert [int(ln[2]) for ln in lines] == [4, 6, 8]


@needs_pardiso
@pytest.mark.parametrize("friction", [False, True])
def test_several_columns_as_a_block_or_one_by_one_as_timed(friction):
    """Three right-hand sides go to PARDISO as one block, or column by column when the
    handle's recent timings make that the faster (times planted here): the same
    checked solution either way. Two block timings are needed first; every 4th
    solve of several columns times the other way again."""
    pb = hertz_friction_problem(refine=0) if friction else hertz.hertz_problem(n_fine=8, size=8)
    K, _ = _tangent(pb, friction)
    B = np.random.default_rng(1).normal(size=(K.shape[0], 3))
    s = Pardiso()
    f = s.factorize(K, symmetric=not friction)
    h = next(iter(s._handles.values()))

    def plant(block, cols=()):
        h.blocks[3].clear()
        h.blocks[3].extend(block)
        h.by_columns[3].clear()
        h.by_columns[3].extend(cols)

    x_block = f.solve(B)
    f.solve(B[:, 0])  # one column (as Newton's solves, before the DDM's)
    plant([10.0])  # one block "took" 10 s: one timing is not enough
    f.solve(B)
    assert (h.multi_solves, h.column_solves, len(h.blocks[3])) == (2, 0, 2)
    plant([10.0, 10.0])  # three single columns beat that
    x_cols = f.solve(B)
    assert h.column_solves == 1 and len(h.by_columns[3]) == 1
    f.solve(B)  # the 4th: a block again
    assert h.column_solves == 1 and len(h.blocks[3]) == 3
    plant([10.0, 10.0], [20.0])  # columns timed slower than the block: a block
    f.solve(B)
    assert h.column_solves == 1
    plant([10.0, 10.0], [20.0])
    h.multi_solves = 7  # the 8th: columns again, as single solves would now beat the block
    f.solve(B)
    assert h.column_solves == 2
    plant([10.0, 10.0], [1.0, 20.0])  # the fastest column timing counts
    h.multi_solves = 9
    f.solve(B)
    assert h.column_solves == 3
    h.single.clear()
    h.single.append(1.0)  # one column "takes" 1 s: three take 3.15 s with the margin
    plant([2.5, 2.5])
    f.solve(B)  # a block of 2.5 s wins
    assert h.column_solves == 3
    plant([10.0, 10.0], [20.0])
    h.single.clear()
    h.single.append(10.0)
    h.multi_solves = 11  # the 12th re-times the other way, but single solves say the
    f.solve(B)  # columns cannot win: a block
    assert h.column_solves == 3
    assert _rel(x_cols, x_block) < 1e-12
    assert np.abs(K @ x_cols - B).max() <= 1e-10 * np.abs(B).max() * (1 + abs(K).max())
    for j in range(3):  # each column as one 1-D solve
        assert _rel(f.solve(B[:, j]), x_block[:, j]) < 1e-12


@needs_pardiso
def test_one_analysis_for_a_whole_load_path():
    s = Pardiso()
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8), steps=4, sensitivities=["R"], solver=s)
    n_fac = sum(lg.iterations for lg in sol.log) + len(sol.increments)  # Newton + DDM
    assert s.factorizations == n_fac and s.analyses == 1


def test_a_named_solver_keeps_its_analysis_for_every_solve_of_the_model():
    """solver="auto" (or a name) is the model's own instance: a second solve of the
    same model at other parameter values analyses nothing; a solve while that
    instance is in use gets a fresh one. The results are those of a fresh solver."""
    import contextlib

    from signorini.algorithms.stepping import kept_solver

    pb = hertz.hertz_problem(n_fine=8)
    a = sg.solve(pb, sensitivities=["E"])
    inst = a.linear_solver
    if not isinstance(inst, Pardiso):
        pytest.skip("PARDISO is not installed: no analysis to count")
    before = inst.analyses
    b = sg.solve(pb.with_params(E=1.1 * pb.params["E"]), sensitivities=["E"])
    assert b.linear_solver is inst and inst.analyses == before
    fresh = sg.solve(pb.with_params(E=1.1 * pb.params["E"]), sensitivities=["E"], solver=Pardiso())
    assert _rel(b.increments[-1].w, fresh.increments[-1].w) < 1e-12
    assert _rel(b.increments[-1].sens["E"], fresh.increments[-1].sens["E"]) < 1e-10
    with contextlib.ExitStack() as stack:  # in use: the next solve gets its own instance
        assert kept_solver(model_for(pb), "auto", stack) is inst
        assert sg.solve(pb).linear_solver is not inst
    assert sg.solve(pb).linear_solver is inst


def test_symmetric_factorisation_only_without_history():
    a = sg.solve(hertz.hertz_problem(n_fine=8, size=8))
    b = sg.solve(hertz_friction_problem(refine=0), steps=3)
    assert a.symmetric is True and b.symmetric is False
    K = sp.csr_matrix(np.array([[2.0, 1.0], [0.0, 2.0]]))
    ts = TangentSolver(SuperLU(), symmetric_candidate=True)
    ts.factorize(K)
    assert ts.symmetric is False  # a candidate whose tangent is not symmetric


def test_symmetry_decided_on_the_local_blocks():
    """Newton decides symmetry on the blocks K is assembled from: the Hertz blocks
    are symmetric, the frictional ones not; an asymmetric block falls back to the
    assembled test (which a symmetric K still passes)."""
    from signorini.linsolve import blocks_symmetric

    for pb, expected in ((hertz.hertz_problem(n_fine=8, size=8), True),
                         (hertz_friction_problem(refine=0), False)):
        m, p = model_for(pb), as_jax(pb.params)
        st = m.initial_state(np.zeros(m.n_dof), p)
        w = np.zeros(m.n_dof)
        for srf in m.surfaces:  # close every node, so that the friction rows couple
            w[srf.lam_dofs[::srf.n_mult]] = -1.0
        _, blocks = m.local_tangents(w, p, 0.5, st)
        assert blocks_symmetric(blocks) is expected
        assert sg.solve(pb, steps=2).symmetric is expected
    K = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 2.0]]))
    halves = [np.array([[[2.0, 1.0], [0.0, 2.0]]]), np.array([[[0.0, 0.0], [1.0, 0.0]]])]
    ts = TangentSolver(SuperLU(), symmetric_candidate=True)
    ts.factorize(K, halves)  # asymmetric blocks, symmetric sum: the assembled test decides
    assert not blocks_symmetric(halves) and ts.symmetric is True


@pytest.mark.parametrize("name", linsolve.available())
def test_symmetric_and_general_factorisations_agree_in_hertz(name):
    pb = hertz.hertz_problem(n_fine=8, size=8)
    K, r = _tangent(pb)
    xs = get_solver(name).factorize(K, symmetric=True).solve(r)
    xg = get_solver(name).factorize(K, symmetric=False).solve(r)
    assert _rel(xs, xg) < 1e-10


def test_refinement_repairs_a_perturbed_factor():
    """A factor of a nearby matrix, refined against the exact one, reaches the
    backward error of a fresh solve (this is how a stale pivot order is repaired)."""
    rng = np.random.default_rng(1)
    A = sp.random(80, 80, density=0.08, random_state=2) + 6.0 * sp.eye(80)
    A = A.tocsr()
    B = (A + 1e-5 * sp.diags(rng.normal(size=80))).tocsr()
    b = rng.normal(size=80)
    f = SuperLU().factorize(A).refined_for(B)
    x = f.solve(b)
    assert f.refinements >= 1 and f.backward_error <= linsolve.REFINE_TOL
    assert np.linalg.norm(B @ x - b) < 1e-12 * np.linalg.norm(b)


@needs_pardiso
def test_analysis_with_every_contact_node_closed_avoids_perturbed_pivots():
    """The symmetric analysis of a pattern uses the tangent with every contact node
    closed: from rest (one node closed at first, 30 at the end) no pivot is
    perturbed (before: 572 at 56k DOFs), and the solution is SuperLU's."""
    pb = hertz.hertz_problem(n_fine=12, size=10)
    m, p = model_for(pb), as_jax(pb.params)
    Kc = m.analysis_tangent(p)
    lam = np.searchsorted(m.free, m.surfaces[0].lam_dofs)
    assert Kc is not None and np.all(Kc.diagonal()[lam] == 0.0)  # every lam_N row closed
    s = Pardiso()
    sol = sg.solve(pb, sensitivities=["R"], solver=s)
    assert sol.symmetric and sol.newton_iterations[0] >= 4 and s.perturbed_pivots == 0
    ref = sg.solve(pb, sensitivities=["R"], solver="superlu")
    assert _rel(sol.increments[-1].w, ref.increments[-1].w) < 1e-10
    assert _rel(sol.w_sensitivity("R"), ref.w_sensitivity("R")) < 1e-8
    # analysed with the first tangent's own values instead, pivots are perturbed
    plain = Pardiso()
    orig = m.analysis_tangent
    m.analysis_tangent = lambda *a: None
    try:
        sg.solve(pb, solver=plain)
    finally:
        del m.analysis_tangent
    assert plain.perturbed_pivots > 0 and m.analysis_tangent == orig


def test_assembly_reuses_an_unchanged_element_block():
    """A read-only element array passed again is not scattered again; a new or a
    writable one is."""
    pb = hertz.hertz_problem(n_fine=8, size=8)
    m, p = model_for(pb), as_jax(pb.params)
    w = np.zeros(m.n_dof)
    _, blocks = m.local_tangents(w, p, 1.0)
    fresh = lambda bl: sp.csr_matrix(  # noqa: E731 - the assembly without any cache
        (np.bincount(m.pattern._map, weights=np.concatenate([b.reshape(-1) for b in bl])
                     [m.pattern._keep], minlength=m.pattern.nnz), m.pattern.indices,
         m.pattern.indptr), shape=(m.pattern.n,) * 2)
    K1 = m.pattern.assemble(blocks)
    contact = [b * 3.0 for b in blocks[1:]]
    K2 = m.pattern.assemble([blocks[0]] + contact)  # same element array: kept part
    assert not blocks[0].flags.writeable and m.pattern._first[0] is blocks[0]
    K3 = m.pattern.assemble([blocks[0] * 2.0] + contact)  # a new one
    for K, bl in ((K1, blocks), (K2, [blocks[0]] + contact), (K3, [blocks[0] * 2.0] + contact)):
        assert abs(K - fresh(bl)).max() <= 1e-12 * abs(K).max()


def test_assembled_tangent_states_only_true_index_properties():
    """The assembly says its CSR indices are sorted and canonical (a solver then
    skips SciPy's test of them), passes the pattern's own index arrays and where
    the diagonal entries are: all must be true of the matrix, as SciPy's own
    tests of a copy find."""
    for pb in (hertz.hertz_problem(n_fine=8, size=8), hertz_friction_problem(refine=0)):
        m, p = model_for(pb), as_jax(pb.params)
        _, blocks = m.local_tangents(np.zeros(m.n_dof), p, 1.0, m.initial_state(np.zeros(m.n_dof), p))
        K = m.pattern.assemble(blocks)
        assert K.has_sorted_indices and K.has_canonical_format
        assert K.indices is m.pattern.indices and K.indptr is m.pattern.indptr
        copy = sp.csr_matrix((K.data.copy(), K.indices.copy(), K.indptr.copy()), shape=K.shape)
        assert copy.has_sorted_indices and copy.has_canonical_format  # SciPy's own test
        assert np.array_equal(K.toarray(), copy.toarray())
        # the diagonal from the positions the assembly carries is SciPy's diagonal
        assert K.diagonal_positions is not None and not hasattr(copy, "diagonal_positions")
        assert np.array_equal(linsolve.diagonal(K), copy.diagonal())
        assert np.array_equal(linsolve.diagonal(copy), copy.diagonal())


def test_symmetry_figures_of_a_block_array_are_kept_only_while_it_lives():
    """The symmetry test keeps the figures of a read-only block array; another array
    (even one that reuses a freed array's address) and a writable one are tested
    anew."""
    from signorini.linsolve import blocks_symmetric

    def frozen(a):
        a = np.array(a, dtype=float)
        a.flags.writeable = False
        return a

    sym = frozen(np.tile(np.array([[2.0, 1.0], [1.0, 2.0]]), (50, 1, 1)))
    assert blocks_symmetric([sym]) and blocks_symmetric([sym])  # the second from the kept figures
    for _ in range(20):  # freed arrays, whose ids the next ones may reuse
        a = frozen(np.tile(np.array([[2.0, 1.0], [1.0, 2.0]]), (50, 1, 1)))
        assert blocks_symmetric([a])
        del a
        b = frozen(np.tile(np.array([[2.0, 1.0], [0.0, 2.0]]), (50, 1, 1)))
        assert not blocks_symmetric([b])
        del b
    w = np.tile(np.array([[2.0, 1.0], [1.0, 2.0]]), (50, 1, 1))
    assert blocks_symmetric([w])
    w[3, 0, 1] = 5.0  # a writable array may change between calls
    assert not blocks_symmetric([w])
    assert not blocks_symmetric([sym, frozen(np.array([[[0.0, 1.0], [0.0, 0.0]]]))])


def test_backward_error_of_zero_rows_and_a_zero_right_hand_side():
    """Rows where r_i = 0 over a zero denominator (b_i = 0 and x = 0, or an empty row)
    count as exact, for one column and several: a zero right-hand side has backward
    error 0 and no refinement; a wrong x is still found in such a system."""
    A = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 0.0]]))
    f = linsolve.Factor(lambda v: np.zeros_like(v), A)
    x = f.solve(np.zeros(3))
    assert np.all(x == 0) and f.backward_error == 0.0 and f.refinements == 0
    f.solve(np.zeros((3, 2)))
    assert f.backward_error == 0.0 and f.refinements == 0
    wrong = linsolve.Factor(lambda v: v * 0.5 if v.ndim == 1 else v, A)
    wrong.solve(np.array([1.0, 0.0, 0.0]))
    assert wrong.backward_error > 1e-3  # x = (0.5, 0, 0) leaves r_1 = -0.5 (refinement repeats it)


@pytest.mark.parametrize("columns", [None, 2])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_refinement_step_that_is_not_finite_is_rejected(bad, columns):
    """A first solve that is finite but inaccurate, then a refinement step of NaN or inf:
    the step is rejected, the finite solution kept, and its backward error reported
    as it is (not as 0, which a NaN passed over would give)."""
    A = sp.csr_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 2.0]]))
    calls = []

    def solve(v):
        calls.append(1)
        return 1.01 * np.linalg.solve(A.toarray(), v) if len(calls) == 1 else np.full_like(v, bad)

    b = np.array([1.0, 2.0, 3.0]) if columns is None else np.ones((3, columns))
    f = linsolve.Factor(solve, A)
    x = f.solve(b)
    assert np.all(np.isfinite(x)) and f.refinements == 1
    assert 1e-3 < f.backward_error < 1e-2  # the 1 % error of the first solve


@pytest.mark.parametrize("transpose", [False, True])
def test_backward_error_bound_asks_for_the_exact_value_when_it_matters(transpose):
    """The check of a solve first divides by |K_ii| (a lower bound of max_j |K_ij|;
    the exact maximum in rows without a diagonal): it may overstate the backward
    error but never hide one. A solve accurate to round-off passes on the bound; a
    solve with an error in a row whose diagonal is small against its off-diagonal
    entries, or in a row without a diagonal, is refined as before."""
    rng = np.random.default_rng(3)
    n = 60
    A = sp.random(n, n, density=0.1, random_state=4) + sp.diags(1.0 + rng.random(n))
    A = A.tolil()
    A[5, 5] = 0.0  # no diagonal (a closed contact node's multiplier row)
    A[5, 7] = 3.0
    A[8, 8] = 1e-6  # a tiny diagonal against an off-diagonal entry of 4
    A[8, 2] = 4.0
    A = A.tocsr()
    A.eliminate_zeros()
    M = (A.T if transpose else A).toarray()
    exact_scale = np.max(np.abs(M), axis=1)
    lu = sp.linalg.splu(A.tocsc())
    b = rng.normal(size=n)

    def exact_eta(x):
        r = b - M @ x
        return np.max(np.abs(r) / (exact_scale * np.max(np.abs(x)) + np.abs(b)))

    def solver(err_row):
        def solve(v, tr=False):  # an accurate solve, then an error in one component
            x = lu.solve(v, trans="T" if tr else "N")
            if err_row is not None:
                x = x.copy()
                x[err_row] += 1e-9 * np.max(np.abs(x))
            return x
        return solve

    ok = linsolve.Factor(solver(None), A, transposable=True)
    x = ok.solve(b, transpose=transpose)
    assert ok.refinements == 0 and exact_eta(x) <= ok.backward_error <= linsolve.REFINE_TOL
    for row in (5, 8, 20):
        f = linsolve.Factor(solver(row), A, transposable=True)
        f.solve(b, transpose=transpose)
        assert f.refinements >= 1  # each correction re-plants the error: never below the tolerance
        assert (transpose, True) in f._norm  # the exact row maximum was computed
        assert np.allclose(f._norm[(transpose, True)], exact_scale)
        assert np.allclose(f._norm[(transpose, False)][[5]], exact_scale[[5]])


@needs_pardiso
def test_mkl_product_of_the_check_equals_scipys():
    """A PARDISO factor checks its solves with MKL's threaded sparse product:
    b - K x and b - K^T x equal SciPy's for one and several columns, whatever
    their memory layout; where it cannot serve (64-bit indices) it says so and
    SciPy's product is used; and the check it feeds still refines an error."""
    rng = np.random.default_rng(5)
    n = 300
    A = (sp.random(n, n, density=0.05, random_state=6) + sp.diags(2.0 + rng.random(n))).tocsr()
    A.indices, A.indptr = A.indices.astype(np.int32), A.indptr.astype(np.int32)
    prod = linsolve._MklProduct(linsolve._mkl().lib, A)
    assert prod.ok
    for transpose in (False, True):
        M = (A.T if transpose else A).toarray()
        for shape in ((n,), (n, 3)):
            x, b = rng.normal(size=shape), rng.normal(size=shape)
            for xx in (x, np.asfortranarray(x)):
                r = prod(xx, b, transpose)
                assert r.shape == b.shape
                np.testing.assert_allclose(r, b - M @ x, rtol=0, atol=1e-13 * np.abs(M).max() * 10)
    # the product keeps the arrays it points into, whatever becomes of the matrix
    B = A.copy()
    kept = linsolve._MklProduct(linsolve._mkl().lib, B)
    x = rng.normal(size=n)
    expected = -(B @ x)
    B.data = np.zeros_like(B.data)
    np.testing.assert_allclose(kept(x, np.zeros(n)), expected, atol=1e-12)
    # 64-bit indices: no MKL product, the factor falls back to SciPy's
    A64 = A.copy()
    A64.indices, A64.indptr = A64.indices.astype(np.int64), A64.indptr.astype(np.int64)
    assert linsolve._MklProduct(linsolve._mkl().lib, A64)(x, x) is None
    # a PARDISO factor uses it for every solve, 1-D or 2-D, of K or K^T: SciPy's
    # product is never called
    f = get_solver("pardiso").factorize(A)
    assert isinstance(f._residual_of, linsolve._MklProduct) and f._residual_of.ok

    def no_scipy(*args):
        raise AssertionError("SciPy's product used")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linsolve, "_residual", no_scipy)
        for transpose in (False, True):
            M = (A.T if transpose else A).toarray()
            for b in (rng.normal(size=n), rng.normal(size=(n, 3)),
                      np.asfortranarray(rng.normal(size=(n, 3)))):
                x = f.solve(b, transpose=transpose)
                assert np.max(np.abs(M @ x - b)) < 1e-12 * np.max(np.abs(b))
    assert f._residual_of.ok
    # an error planted in its first solve is found and refined away
    b = rng.normal(size=n)
    good, calls = f._solve, []

    def planted(v, tr=False):
        calls.append(1)
        return good(v, tr) + (1e-8 * (np.arange(n) == 7) if len(calls) == 1 else 0.0)

    f._solve = planted
    x = f.solve(b)
    assert f.refinements == 1 and f.backward_error <= linsolve.REFINE_TOL
    assert np.max(np.abs(A @ x - b)) < 1e-13 * np.max(np.abs(b)) * np.abs(A).max()


@pytest.mark.parametrize("friction", [False, True])
def test_kept_stiffness_derivative_gives_the_jvp_pseudo_load(friction, monkeypatch):
    """Along a load path a linear body's element pseudo-load is (dK_e/dphi) u_e +
    K_e du_e/dphi with dK_e/dphi computed once: the same sensitivities as the JVP
    of the element kernels every increment, for material, shape-free contact and
    prescribed-motion parameters."""
    from signorini.sensitivity.ddm import DDM
    from test_adjoint import pressed_block

    pb = pressed_block(friction)
    names = ["d", "s", "E", "nu", "R"] + (["mu"] if friction else [])
    o = sg.NewtonOptions(rtol=1e-12)
    kept = sg.solve(pb, steps=4, sensitivities=names, options=o, solver="superlu")
    ddm = sg.solve.__globals__["ddm_for"](kept.model, names)
    # dK_e/dphi was kept for nu; for E it is K_e / E (the elastic stress is proportional to E)
    assert ddm._dke is not None and ddm._dke[1] == ("nu",) and ddm._proportional == "E"
    monkeypatch.setattr(DDM, "_linear_pseudo", lambda *a: False)  # the JVP every increment
    jvp = sg.solve(pb, steps=4, sensitivities=names, options=o, solver="superlu")
    for a, b in zip(kept.increments, jvp.increments):
        for n in names:
            assert np.max(np.abs(a.sens[n] - b.sens[n])) <= 1e-10 * np.max(np.abs(b.sens[n])), n


def test_pseudo_load_of_the_modulus_is_the_internal_force_over_it(monkeypatch):
    """Elastic stress is proportional to E at fixed nu, so a linear body's pseudo-load
    of E is its internal force over E: the same sensitivities as the JVP of the
    element kernels (one step; E alone; a frictional path, whose kept dK_e/dphi
    then holds nu only). Not used where E is not a parameter of its own."""
    import dataclasses

    from signorini.materials import LinearElastic, NeoHooke
    from signorini.sensitivity import ddm as ddm_mod
    from signorini.algorithms.stepping import _MODELS

    o = TIGHT
    for pb, steps, names in ((hertz.hertz_problem(n_fine=8, size=8), 1, ["R", "E", "P"]),
                             (hertz.hertz_problem(n_fine=8, size=8), 1, ["E"]),
                             (hertz_friction_problem(refine=0), 4, ["R", "mu", "E", "nu"])):
        _MODELS.clear()
        assert ddm_mod.proportional_parameter(model_for(pb)) == "E"
        fast = sg.solve(pb, steps=steps, sensitivities=names, options=o)
        with monkeypatch.context() as mp:
            mp.setattr(ddm_mod, "proportional_parameter", lambda m: None)
            _MODELS.clear()
            jvp = sg.solve(pb, steps=steps, sensitivities=names, options=o)
            assert sg.solve.__globals__["ddm_for"](jvp.model, names)._proportional is None
        _MODELS.clear()
        for a, b in zip(fast.increments, jvp.increments):
            for n in names:
                assert np.max(np.abs(b.sens[n])) > 0
                assert np.max(np.abs(a.sens[n] - b.sens[n])) <= 1e-10 * np.max(np.abs(b.sens[n])), n
    base = hertz.hertz_problem(n_fine=8, size=8)
    for material, params in ((LinearElastic(E="k", nu="k"), {"k": 0.3}),  # E also sets nu
                             (LinearElastic(E=lambda p: 2.0 * p["E"]), {}),  # an expression
                             (LinearElastic(E=100.0), {}),  # a number: not a parameter
                             (NeoHooke(), {})):  # not a linear body (K_e changes with u)
        pb = dataclasses.replace(base, material=material, params={**base.params, **params})
        assert ddm_mod.proportional_parameter(model_for(pb)) is None, material


def test_element_pseudo_load_on_the_parameters_alone_equals_the_full_jvp():
    """Without prescribed motion the internal-force pseudo-load is the JVP on the
    element parameters alone (material and shape): the same vector as the JVP
    with a one-hot tangent on every parameter and on the displacements."""
    import dataclasses

    from signorini.params import unit_tangents
    from signorini.sensitivity.ddm import DDM
    from signorini._jax import jnp

    base = hertz.hertz_problem(n_fine=8)
    X = base.mesh.nodes
    V = np.column_stack([X[:, 0] * X[:, 1], np.sin(X[:, 0])])  # a shape field
    pb = dataclasses.replace(base, shape={**base.shape, "h": V}, params={**base.params, "h": 0.0},
                             shape_nominal={**base.shape_nominal, "h": 0.0})
    names = ["E", "nu", "h"]
    sol = sg.solve(pb, sensitivities=names)
    m, p = model_for(pb), as_jax(pb.params)
    ddm = DDM(m, names)
    assert {"E", "nu", "h"} <= ddm._element_names
    w = jnp.asarray(sol.increments[-1].w)
    e = unit_tangents(p, names)
    full = np.asarray(ddm._pseudo["elements"](w, p, 1.0, None, None, jnp.zeros((3, m.n_dof)), e, None))
    e_el = {n: e[n] for n in ddm._element_names if n in e}
    alone = np.asarray(ddm._material_pseudo(w, p, 1.0, e_el))
    for k in range(3):
        assert np.max(np.abs(full[k])) > 0
        assert np.max(np.abs(alone[k] - full[k])) <= 1e-13 * np.max(np.abs(full[k])), names[k]


def test_only_the_designed_element_parameters_are_differentiated():
    """The element pseudo-load differentiates the designed element parameters
    only (a zero tangent on an undesigned shape parameter still differentiated
    the geometry): E's sensitivity alone equals E's among E, nu and a shape."""
    import dataclasses

    base = hertz.hertz_problem(n_fine=8)
    X = base.mesh.nodes
    V = np.column_stack([X[:, 0] * X[:, 1], np.sin(X[:, 0])])
    pb = dataclasses.replace(base, shape={**base.shape, "h": V}, params={**base.params, "h": 0.0},
                             shape_nominal={**base.shape_nominal, "h": 0.0})
    alone = sg.solve(pb, sensitivities=["E"]).increments[-1].sens["E"]
    among = sg.solve(pb, sensitivities=["h", "E", "nu"]).increments[-1].sens["E"]
    assert np.max(np.abs(alone)) > 0
    assert np.max(np.abs(alone - among)) <= 1e-12 * np.max(np.abs(among))


def test_element_kernels_in_chunks_equal_one_vmap():
    """Large meshes run the element kernels over chunks of cells (lax.map of
    vmaps, the last chunk padded): forced on a small forging (F-bar, J2
    history, axisymmetric, 200 cells in chunks of 16) the load path, its
    history and its shape sensitivities are those of one vmap."""
    from signorini.problems import forging

    names = ["phi1", "E"]
    from signorini.algorithms.stepping import _MODELS

    ref_pb, pb = forging.forging_problem(), forging.forging_problem()
    kw = dict(options=forging.options(), steps=4, sensitivities=names)
    ref_m = model_for(ref_pb)
    ref = sg.solve(ref_pb, **kw)
    _MODELS.clear()  # the same problem would share ref_m: a second model
    m = model_for(pb)
    assert m is not ref_m
    m.CELL_CHUNK, m.CHUNKED_FROM = 16, 0
    assert len(m.conn) % 16 != 0  # a padded last chunk
    got = sg.solve(pb, **kw)
    p = as_jax(pb.params)
    # the kernels at one state: the same numbers up to the order of summation
    inc, st = ref.increments[-1], ref.increments[-2].state
    (R1, b1), (R2, b2) = (mm.local_tangents(inc.w, p, inc.t, st) for mm in (ref_m, m))
    assert np.max(np.abs(R1 - R2)) <= 1e-13 * np.max(np.abs(R1))
    for x, y in zip(b1, b2):
        assert np.max(np.abs(x - y)) <= 1e-14 * np.max(np.abs(x))
    for a, b in zip(ref.increments, got.increments):
        assert np.max(np.abs(a.w - b.w)) <= 1e-13 * np.max(np.abs(a.w))
        # the tangent's condition number is ~1e13 here: two runs of the very same
        # model differ by 2.4e-11 of the largest multiplier sensitivity (measured),
        # chunked against one vmap by 4.6e-11
        for n in names:
            assert np.max(np.abs(a.sens[n] - b.sens[n])) <= 1e-9 * np.max(np.abs(a.sens[n])), n
    h_ref, h = np.asarray(ref.increments[-1].state[2]), np.asarray(got.increments[-1].state[2])
    assert np.max(np.abs(h_ref[..., 9])) > 0  # plastic flow happened
    assert np.max(np.abs(h - h_ref)) <= 1e-12 * np.max(np.abs(h_ref))  # from w's 1e-13
    w = got.increments[-1].w
    s_ref = np.asarray(ref_m.stresses(w, p, got.increments[-2].state))
    s = np.asarray(m.stresses(w, p, got.increments[-2].state))
    assert np.max(np.abs(s - s_ref)) <= 1e-12 * np.max(np.abs(s_ref))


def test_prolongation_is_built_once_per_pair_of_meshes():
    """A coarse-to-fine solve rebuilt the interpolation every time (75 of 230 ms at
    56k DOFs): it is now kept by the fine model, per coarse model."""
    from signorini.algorithms.coarse_to_fine import Prolongation

    cm = model_for(hertz_friction_problem(refine=0, n_fine=12))
    cm2 = model_for(hertz_friction_problem(refine=0, n_fine=16))
    fm = model_for(hertz_friction_problem(refine=1))
    P = Prolongation.between(cm, fm)
    assert Prolongation.between(cm, fm) is P
    P2 = Prolongation.between(cm2, fm)
    assert P2 is not P and P2.matrix.shape == (fm.n_dof, cm2.n_dof)
    assert abs(P.matrix - Prolongation(cm, fm).matrix).max() == 0.0


# --------------------------------------------------------- what Newton starts from
def test_linear_body_stiffness_once_equals_kernel():
    pb = hertz_friction_problem(refine=0)
    m, p = model_for(pb), as_jax(pb.params)
    assert m.linear_elements
    w = np.random.default_rng(0).normal(size=m.n_dof) * 1e-3
    st = m.initial_state(np.zeros(m.n_dof), p)
    R1, b1 = m.local_tangents(w, p, 0.7, st)
    m.linear_elements = False
    try:
        R2, b2 = m.local_tangents(w, p, 0.7, st)
    finally:
        m.linear_elements = True
    assert _rel(R1, R2) < 1e-13
    assert all(np.max(np.abs(x - y)) <= 1e-12 * np.max(np.abs(y)) for x, y in zip(b1, b2))
    # the cached stiffness follows E (a solve at other parameter values)
    p2 = as_jax({**pb.params, "E": 150.0})
    m.local_tangents(w, p2, 0.7, st)
    assert np.isclose(m._ke[2][0, 0, 0] / b1[0][0, 0, 0], 1.5)


def test_predictor_changes_iterations_not_the_path():
    # 30 increments: without a predictor the slipping nodes start every increment on
    # the disc edge, and since they are sent to slip there (Coulomb's tie band) that
    # start costs 53 iterations here against 35 with the predictor (12 increments:
    # 29 against 27; 51 against 27 while the tie was decided by rounding)
    pb = hertz_friction_problem(refine=0)
    names = ["R", "mu", "E"]
    o = dict(steps=30, sensitivities=names)
    a = sg.solve(pb, options=sg.NewtonOptions(rtol=1e-10, predictor="none"), **o)
    b = sg.solve(pb, options=sg.NewtonOptions(rtol=1e-10, predictor="extrapolate"), **o)
    assert sum(b.newton_iterations) < 0.75 * sum(a.newton_iterations)
    for ia, ib in zip(a.increments, b.increments):
        assert _rel(ib.w, ia.w) < 1e-9
        for n in names:
            assert _rel(ib.sens[n], ia.sens[n]) < 1e-8


def test_coarse_to_fine_start_same_solution_fewer_iterations():
    fine = hertz.hertz_problem(refine=1)
    plain = sg.solve(fine, options=TIGHT, sensitivities=["R"])
    coarse, levels = solve_coarse_to_fine([hertz.hertz_problem(n_fine=12), hertz.hertz_problem()],
                                          options=TIGHT)
    assert [lv["dofs"] for lv in levels] == [model_for(hertz.hertz_problem(n_fine=12)).n_dof,
                                             model_for(hertz.hertz_problem()).n_dof]
    started = sg.solve(fine, options=TIGHT, sensitivities=["R"], initial=prolong(coarse, fine))
    assert started.newton_iterations[0] <= 2 < plain.newton_iterations[0]
    assert _rel(started.increments[0].w, plain.increments[0].w) < 1e-9
    assert _rel(started.w_sensitivity("R"), plain.w_sensitivity("R")) < 1e-8
    c1, c2 = plain.contact(), started.contact()
    assert np.array_equal(c1["p_N"] > 0, c2["p_N"] > 0)  # open nodes exactly zero in both


def test_initial_guess_is_checked():
    pb = hertz.hertz_problem(n_fine=8, size=8)
    with pytest.raises(sg.InputError, match="initial must be a finite array of shape"):
        sg.solve(pb, initial=np.zeros(3))
    with pytest.raises(sg.InputError, match="predictor"):
        sg.NewtonOptions(predictor="quadratic")
    with pytest.raises(sg.InputError, match="ddm_factorization"):
        sg.solve(pb, ddm_factorization="stale")


def test_reused_ddm_factorisation_is_exact_to_round_off():
    pb = hertz_friction_problem(refine=0)
    names = ["R", "mu", "E"]
    o = dict(steps=12, sensitivities=names, options=sg.NewtonOptions(rtol=1e-10))
    a = sg.solve(pb, ddm_factorization="exact", **o)
    b = sg.solve(pb, ddm_factorization="reuse", **o)
    assert sum(inc.timing["reused_factorization"] for inc in b.increments) >= 6
    assert not any(inc.timing["reused_factorization"] for inc in a.increments)
    for ia, ib in zip(a.increments, b.increments):
        for n in names:
            assert _rel(ib.sens[n], ia.sens[n]) < 1e-9


# ------------------------------------------------------------ compilation cache
def test_persistent_cache_directory(tmp_path):
    code = ("import signorini, jax; from signorini._jax import cache_dir; "
            "print(cache_dir()); print(jax.config.jax_compilation_cache_dir)")
    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(tmp_path / "c")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [str(tmp_path / "c")] * 2 and (tmp_path / "c").is_dir()
    env["SIGNORINI_CACHE_DIR"] = ""
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[0] == "None"


def test_until_stops_the_path_with_nominal_increments():
    pb = hertz_friction_problem(refine=0)
    full = sg.solve(pb, steps=6, sensitivities=["mu"])
    half = sg.solve(pb, steps=6, sensitivities=["mu"], until=0.5)
    assert [round(i.t, 12) for i in half.increments] == [round(1 / 6, 12), round(2 / 6, 12), 0.5]
    for a, b in zip(half.increments, full.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["mu"], b.sens["mu"]) < 1e-8
    with pytest.raises(sg.InputError, match="until"):
        sg.solve(pb, until=1.5)


def test_coarse_meshes_guide_every_increment_of_a_frictional_path():
    """The coarse meshes are solved along the whole path; every fine increment
    starts from its own last state plus the interpolated coarse increment. Only
    the start changes: the fine path is the one from rest."""
    fine = hertz_friction_problem(refine=1)
    o = sg.NewtonOptions(rtol=1e-10)
    guide, levels = hertz.coarse_start_for(
        fine, lambda r, n: hertz_friction_problem(refine=r, n_fine=n), 1, 24, steps=6, options=o,
        solver="auto")
    assert len(levels) == 2 and all(len(lv["newton_iterations"]) == 6 for lv in levels)
    assert [round(i.t, 12) for i in guide.increments] == [round(k / 6, 12) for k in range(1, 7)]
    plain = sg.solve(fine, steps=6, options=o, sensitivities=["R"])
    started = sg.solve(fine, steps=6, options=o, sensitivities=["R"], guide=guide)
    # measured: guided 2 1 1 2 1 1, from rest with the extrapolating predictor 7 4 3 3 3 3
    later = started.newton_iterations[1:]
    assert started.newton_iterations[0] <= 3 < plain.newton_iterations[0]
    assert max(later) <= 2 and sum(later) < sum(plain.newton_iterations[1:])
    for a, b in zip(started.increments, plain.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["R"], b.sens["R"]) < 1e-8


def test_guide_covers_only_its_own_increments():
    """Between the guide's load factors (other steps, as after a step cut) the
    guide is interpolated in t; past the end of a guide that stopped early the
    predictor takes over; a guide of the same mesh at other parameters
    (finite-difference re-solves) is interpolated by the identity. Only the
    start changes."""
    from signorini.algorithms.coarse_to_fine import Prolongation

    pb = hertz_friction_problem(refine=0)
    o = sg.NewtonOptions(rtol=1e-10)
    plain = sg.solve(pb, steps=6, options=o)
    half = sg.solve(hertz_friction_problem(refine=0, n_fine=12), steps=6, options=o, until=0.5)
    other = sg.solve(hertz_friction_problem(refine=0, n_fine=12), steps=4, options=o)
    near = pb.with_params(mu=pb.params["mu"] * (1 + 1e-6))
    for guide in (half, other, plain):
        sol = sg.solve(near if guide is plain else pb, steps=6, options=o, guide=guide)
        ref = plain if guide is not plain else sg.solve(near, steps=6, options=o)
        for a, b in zip(sol.increments, ref.increments):
            assert _rel(a.w, b.w) < 1e-9
    # from the base path of the same mesh, a perturbed re-solve needs one iteration
    again = sg.solve(near, steps=6, options=o, guide=plain)
    assert max(again.newton_iterations[1:]) <= 1
    P = Prolongation(plain.model, sg.solve(near, steps=1, options=o).model)
    assert (P.matrix != sp.identity(P.matrix.shape[0])).nnz == 0
    with pytest.raises(sg.InputError, match="guide must be a Solution"):
        sg.solve(pb, guide=plain.increments[0].w)


def test_a_failing_coarse_level_guides_as_far_as_it_converged(monkeypatch):
    """A coarse level whose Newton fails is recorded as failed; the increments it
    converged still guide the next mesh, the rest use the predictor, and the
    fine path is the one from rest."""
    solve_module = sys.modules["signorini.algorithms.stepping"]
    real = solve_module.solve
    coarse, fine = hertz_friction_problem(refine=0, n_fine=12), hertz_friction_problem(refine=0)

    def failing(pb, **kw):
        if pb is coarse:  # converges to t = 0.5, then fails
            part = real(pb, **{**kw, "until": 0.5})
            raise sg.ConvergenceError("no convergence at t=0.667 (test)", partial=part)
        return real(pb, **kw)

    monkeypatch.setattr(solve_module, "solve", failing)
    o = sg.NewtonOptions(rtol=1e-10)
    sol, levels = solve_coarse_to_fine([coarse, fine], steps=6, options=o, sensitivities=["mu"])
    assert "test" in levels[0]["failed"] and len(levels[0]["newton_iterations"]) == 3
    assert "failed" not in levels[1] and len(sol.increments) == 6
    plain = real(fine, steps=6, options=o, sensitivities=["mu"])
    for a, b in zip(sol.increments, plain.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["mu"], b.sens["mu"]) < 1e-8


def test_a_coarse_level_that_converges_nothing_keeps_the_guide_before(monkeypatch):
    """Three levels, the middle one failing in its first increment: the finest is
    guided by the coarsest (before: by nothing)."""
    solve_module = sys.modules["signorini.algorithms.stepping"]
    real = solve_module.solve
    pbs = [hertz_friction_problem(refine=0, n_fine=8), hertz_friction_problem(refine=0, n_fine=12),
           hertz_friction_problem(refine=0)]
    guides = []

    def failing(pb, **kw):
        guides.append(kw.get("guide"))
        if pb is pbs[1]:
            raise sg.ConvergenceError("no convergence at t=0.25 (test)", partial=None)
        return real(pb, **kw)

    monkeypatch.setattr(solve_module, "solve", failing)
    sol, levels = solve_coarse_to_fine(pbs, steps=4, options=sg.NewtonOptions(rtol=1e-10))
    assert "failed" in levels[1] and levels[1]["newton_iterations"] == []
    assert guides[0] is None and guides[1] is not None and guides[2] is guides[1]
    assert len(sol.increments) == 4


def test_prolongation_reproduces_affine_fields():
    """Piecewise linear interpolation is exact for an affine displacement field;
    nodes outside the coarse mesh take the nearest coarse node's value."""
    from signorini.algorithms.coarse_to_fine import Prolongation
    from signorini.algorithms.stepping import model_for

    cm = model_for(hertz_friction_problem(refine=0, n_fine=12))
    fm = model_for(hertz_friction_problem(refine=1))
    Xc, Xf = np.asarray(cm._X0_np), np.asarray(fm._X0_np)
    A = np.array([[0.3, -0.2], [0.1, 0.5]])
    wc = np.zeros(cm.n_dof)
    wc[: 2 * cm.n_nodes] = (Xc @ A.T + [1.0, -2.0]).ravel()
    wf = Prolongation(cm, fm)(wc)
    assert np.allclose(wf[: 2 * fm.n_nodes].reshape(-1, 2), Xf @ A.T + [1.0, -2.0], atol=1e-12)


def test_memory_estimate_of_pardiso_matches_measurements():
    """benchmarks/results: 1.77 GB at 225k DOFs (symmetric), 6.8 GB for the frictional
    Hertz at 1.06M (LU); within 20 %."""
    from signorini.app import resources

    est = lambda n: resources.estimated_peak_memory(n, "pardiso") / resources.GB  # noqa: E731
    assert abs(est(224_848) / 1.77 - 1) < 0.2 and abs(est(1_057_264) / 6.8 - 1) < 0.2


SCALE = 0.5  # read by a load below: such a function is keyed by its identity


def test_a_problem_built_again_reuses_its_compiled_model():
    """model_for keys a model by the content of what it is built from: the same
    Hertz problem built again for other values shares the model (no retracing),
    and solves exactly as a model built afresh; anything that changes the model
    (mesh, shape nominal values, a closure value, a function reading a global
    name) gets its own."""
    import dataclasses

    from signorini.algorithms.stepping import _MODELS
    from signorini.errors import InputError
    from signorini.fem.loads import Pressure

    a, b = hertz.hertz_problem({"R": 1.0}), hertz.hertz_problem({"R": 1.2})
    m = model_for(a)
    assert model_for(b) is m and b.mesh is not a.mesh
    shared = sg.solve(b, sensitivities=["R"]).increments[-1]
    _MODELS.clear()
    fresh = sg.solve(hertz.hertz_problem({"R": 1.2}), sensitivities=["R"]).increments[-1]
    assert model_for(b) is not m
    assert np.max(np.abs(shared.w - fresh.w)) <= 1e-12 * np.max(np.abs(fresh.w))
    assert np.max(np.abs(shared.sens["R"] - fresh.sens["R"])) <= 1e-9 * np.max(np.abs(fresh.sens["R"]))

    m = model_for(a)
    assert model_for(hertz.hertz_problem(n_fine=12)) is not m  # another mesh
    assert model_for(dataclasses.replace(a, shape_nominal={"bump": 0.1})) is not m

    def scaled(c):
        return dataclasses.replace(a, loads=(Pressure("bottom", lambda p: c * p["P"], resultant=True),))
    assert model_for(scaled(0.5)) is model_for(scaled(0.5))
    assert model_for(scaled(0.5)) is not model_for(scaled(0.25))

    def global_read():
        return dataclasses.replace(a, loads=(Pressure("bottom", lambda p: SCALE * p["P"], resultant=True),))
    assert model_for(global_read()) is not model_for(global_read())

    # the values of a problem that reuses a model are checked like a new model's
    def pole():
        return dataclasses.replace(a, loads=(Pressure("bottom", lambda p: p["P"] / (p["R"] - 2.0),
                                                      resultant=True),))
    model_for(pole())
    with pytest.raises(InputError, match="cannot be evaluated .* division by zero"):
        model_for(pole().with_params(R=2.0))
    _MODELS.clear()
    with pytest.raises(InputError, match="cannot be evaluated .* division by zero"):
        model_for(pole().with_params(R=2.0))  # a new model's check says the same


def test_element_stiffness_kept_while_the_element_parameters_are():
    """A linear body's Ke and the DDM's dKe/dphi are keyed by the material and
    shape values only: a solve for another friction coefficient or radius
    reuses them and gives a fresh model's numbers; another E recomputes them."""
    from signorini.algorithms.stepping import _MODELS, ddm_for

    # SuperLU: a factorisation of its own for every tangent, so that the two solves
    # differ only in what this test is about. PARDISO keeps the analysis of the
    # model's first tangent (scaling, pivots; tested apart), which moved the reused
    # model's w from the fresh one's by round-off: 0.1-1.03e-12 relative over runs,
    # depending on the threaded factorisation's order of operations and on the
    # rounding of the check's product; with SuperLU the two are identical.
    kw = {"steps": 3, "sensitivities": ["E", "nu", "mu", "R"], "solver": "superlu"}
    names = kw["sensitivities"]  # dK_e/dphi kept for nu (E's is K_e / E)
    pb = hertz_friction_problem(n_fine=12)
    m = model_for(pb)
    sg.solve(pb, **kw)
    Ke, dKe = m._ke[1], ddm_for(m, names)._dke[2]
    other = {"mu": 0.35, "R": 1.05 * pb.params["R"]}
    got = sg.solve(pb.with_params(**other), **kw)
    assert m._ke[1] is Ke and ddm_for(m, names)._dke[2] is dKe
    sg.solve(pb.with_params(E=1.1 * pb.params["E"]), **kw)
    assert m._ke[1] is not Ke and ddm_for(m, names)._dke[2] is not dKe
    _MODELS.clear()
    ref = sg.solve(hertz_friction_problem(other, n_fine=12), **kw)
    assert model_for(pb) is not m
    for a, b in zip(ref.increments, got.increments):
        assert np.max(np.abs(a.w - b.w)) <= 1e-12 * np.max(np.abs(a.w))
        for n in names:
            assert np.max(np.abs(a.sens[n] - b.sens[n])) <= 1e-9 * np.max(np.abs(a.sens[n])), n
