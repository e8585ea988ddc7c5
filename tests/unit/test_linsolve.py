"""The linear solvers (signorini.linsolve): every available backend gives the
same Newton solution and DDM sensitivities, on symmetric (frictionless) and
unsymmetric (friction) tangents; the choice of solver and its install
messages (MKL/PARDISO, UMFPACK); the kept symbolic analysis (of the tangent
with every contact node closed) and PARDISO's threads and block solves; the
symmetric factorisation and how symmetry is decided; iterative refinement and
the backward-error check of every solve."""

import os
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini import linsolve
from signorini.linsolve import factor, mkl
from signorini.linsolve import SOLVERS, Pardiso, SuperLU, TangentSolver, get_solver
from signorini.params import as_jax
from signorini.app.commands import hertz as hertz_cmd
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for

HAS_PARDISO = "pardiso" in linsolve.available()
needs_pardiso = pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso (MKL) is not installed")
TIGHT = sg.NewtonOptions(rtol=1e-11)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _why_not(name):
    """None if the backend can be used, else the reason (its own import message)."""
    try:
        get_solver(name)
        return None
    except sg.InputError as e:  # optional backend not installed (or its library not loadable)
        return str(e)


AVAILABLE = [n for n in ("superlu", "pardiso", "umfpack") if _why_not(n) is None]
OPTIONAL = ("pardiso", "umfpack")


@pytest.mark.parametrize("name", AVAILABLE)
def test_factorisation_solves_unsymmetric_multi_rhs(name):
    rng = np.random.default_rng(0)
    A = sp.random(60, 60, density=0.1, random_state=1) + sp.eye(60) * 5.0  # unsymmetric
    B = rng.normal(size=(60, 3))
    X = get_solver(name).factorize(A.tocsr()).solve(B)
    assert np.allclose(A @ X, B, atol=1e-12)


@pytest.mark.parametrize("name", OPTIONAL)
def test_optional_solver_matches_superlu_in_hertz(name):
    """Runs for every optional backend that is installed; for one that is not, the
    skip reason says which package to install (the default install has SuperLU only)."""
    reason = _why_not(name)
    if reason is not None:
        pytest.skip(f"optional solver {name!r} is not installed on this machine: {reason}")
    pb = hertz.hertz_problem(n_fine=8, size=8)
    a = sg.solve(pb, wrt=["R"])
    b = sg.solve(pb, wrt=["R"], solver=name)
    assert np.allclose(a.increments[-1].w, b.increments[-1].w, rtol=0, atol=1e-10)
    ra, rb = a.w_sensitivity("R"), b.w_sensitivity("R")
    assert np.max(np.abs(ra - rb)) <= 1e-8 * np.max(np.abs(ra))


def test_singular_matrix_is_reported():
    A = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    with pytest.raises(sg.SingularTangentError):
        get_solver("superlu").factorize(A)


def test_solver_names():
    assert set(SOLVERS) == {"superlu", "umfpack", "pardiso", "amg", "petsc", "petsc-amg"}
    with pytest.raises(sg.InputError, match="unknown linear solver"):
        get_solver("mumps")


# -------------------------------------------------------------- solver choice
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

    monkeypatch.setattr(mkl, "_MKL", None)
    monkeypatch.setattr(mkl, "_load_mkl", no_mkl)
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

    path = mkl._mkl_rt_path()
    assert path is not None and "mkl_rt" in os.path.basename(path)
    assert hasattr(ctypes.CDLL(path), "pardiso")
    monkeypatch.setattr(mkl, "_MKL", None)
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/nonexistent/libmkl_rt.so")
    assert mkl._mkl_rt_path() == "/nonexistent/libmkl_rt.so"
    with pytest.raises(sg.InputError, match=r"pip install pypardiso"):
        mkl._load_mkl()


def test_mkl_runtime_lookup_takes_the_newest_in_the_environment(tmp_path, monkeypatch):
    """Of several MKL runtimes in the environment's lib folder the newest is
    taken (libmkl_rt.so.10 over .so.9 and .so.2); none there and none in the
    user site: None (pypardiso's search then decides)."""
    import site
    import sys

    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    monkeypatch.setattr(site, "USER_BASE", str(tmp_path / "user"))
    monkeypatch.setattr(sys, "prefix", str(tmp_path / "env"))
    assert mkl._mkl_rt_path() is None
    (tmp_path / "env" / "lib").mkdir(parents=True)
    for name in ("libmkl_rt.so.2", "libmkl_rt.so.10", "libmkl_rt.so.9", "libmkl_core.so.3"):
        (tmp_path / "env" / "lib" / name).write_bytes(b"")
    assert mkl._mkl_rt_path() == str(tmp_path / "env" / "lib" / "libmkl_rt.so.10")


def test_umfpack_message_names_its_package():
    if "umfpack" in linsolve.available():
        pytest.skip("scikit-umfpack is installed here")
    with pytest.raises(sg.InputError, match=r"pip install scikit-umfpack"):
        get_solver("umfpack")


def test_summary_names_the_solver(tmp_path):
    s = hertz_cmd.run(tmp_path / "h", fd_check=False, size=8, coarse_start=False)
    assert s["solver"] == get_solver("auto").name and s["symmetric_factorization"] is True
    assert s["symmetric_factorisation"] is True  # the key's 0.1 spelling, kept for one release
    assert "krylov_iterations" not in s  # a direct solver's summary has none


def test_summary_of_the_iterative_solver_has_its_krylov_iterations():
    from signorini.app.runner import solver_entries
    lin = get_solver("amg")
    lin.iterations.extend([12, 40])

    class Sol:
        symmetric = True
    s = solver_entries(lin, Sol())
    assert s["solver"] == "amg" and s["krylov_iterations"] == [12, 40]


# ------------------------------------------------------------- factorisations
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
from signorini.linsolve.pardiso import _Handle
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
call = _Handle.call
def failing(self, phase, a=None, b=None):
    if phase == 22:
        raise SingularTangentError("planted")
    return call(self, phase, a, b)
_Handle.call = failing
with mkl_threads(1):
    try:
        s.factorize(K * 2.0, symmetric=True)
    except SingularTangentError:
        pass
_Handle.call = call
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
    from signorini.linsolve import mkl_max_threads, mkl_threads
    from signorini.linsolve.mkl import _mkl
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
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8), steps=4, wrt=["R"], solver=s)
    n_fac = sum(lg.iterations for lg in sol.log) + len(sol.increments)  # Newton + DDM
    assert s.factorizations == n_fac and s.analyses == 1


def test_a_named_solver_keeps_its_analysis_for_every_solve_of_the_model():
    """solver="auto" (or a name) is the model's own instance: a second solve of the
    same model at other parameter values analyses nothing; a solve while that
    instance is in use gets a fresh one. The results are those of a fresh solver."""
    import contextlib

    from signorini.algorithms.stepping import kept_solver

    pb = hertz.hertz_problem(n_fine=8)
    a = sg.solve(pb, wrt=["E"])
    inst = a.linear_solver
    if not isinstance(inst, Pardiso):
        pytest.skip("PARDISO is not installed: no analysis to count")
    before = inst.analyses
    b = sg.solve(pb.with_params(E=1.1 * pb.params["E"]), wrt=["E"])
    assert b.linear_solver is inst and inst.analyses == before
    fresh = sg.solve(pb.with_params(E=1.1 * pb.params["E"]), wrt=["E"], solver=Pardiso())
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
    sol = sg.solve(pb, wrt=["R"], solver=s)
    assert sol.symmetric and sol.newton_iterations[0] >= 4 and s.perturbed_pivots == 0
    ref = sg.solve(pb, wrt=["R"], solver="superlu")
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


@needs_pardiso
def test_a_general_lu_that_stalled_is_analysed_again_without_matching():
    """Two cylinders with friction (general LU, mortar multipliers): the analysis of
    the first tangent, with its weighted matching, stalls refinement once the
    contact closes; the pattern is then analysed without matching, after which every
    solve is repaired by refinement whatever the active set: one re-analysis in the
    whole path (eight with the matching kept), and the solution is SuperLU's."""
    from signorini.problems.cylinders import cylinders_problem

    pb = cylinders_problem({"mu": 0.3, "Q": 0.015})
    s = Pardiso()
    sol = sg.solve(pb, steps=20, wrt=["R1"], solver=s)
    assert s.reanalyses == 1 and s.analyses == 2
    assert [h.matching for h in s._handles.values()] == [False]
    ref = sg.solve(pb, steps=20, wrt=["R1"], solver="superlu")
    assert sol.newton_iterations == ref.newton_iterations
    assert _rel(sol.increments[-1].w, ref.increments[-1].w) < 1e-10
    assert _rel(sol.w_sensitivity("R1"), ref.w_sensitivity("R1")) < 1e-8


def test_the_symmetry_figures_see_every_block_of_a_large_array():
    """The figures are computed by chunks of blocks: an asymmetry (at the test's
    relative 1e-12, just above and just below) or a NaN in the first, a middle or the
    last block of 5,000 (24 x 24: chunks of 113) is seen; the largest |entry| may be
    a negative one."""
    from signorini.linsolve import SYMMETRY_TOL, blocks_symmetric

    rng = np.random.default_rng(1)
    b = rng.standard_normal((5000, 24, 24))
    b = b + np.swapaxes(b, 1, 2)
    scale = np.abs(b).max()
    assert blocks_symmetric([b])
    for e in (0, 2261, 4999):
        for factor, expected in ((3.0, False), (0.3, True)):
            c = b.copy()
            c[e, 5, 17] += factor * SYMMETRY_TOL * scale
            assert blocks_symmetric([c]) is expected, (e, factor)
        c = b.copy()
        c[e, 3, 3] = np.nan
        assert not blocks_symmetric([c])
    c = -np.abs(b)  # symmetric, every entry <= 0: the scale is the largest |entry|
    c[4999, 0, 1] -= 0.3 * SYMMETRY_TOL * scale
    assert blocks_symmetric([c])
    c[4999, 0, 1] -= 3.0 * SYMMETRY_TOL * scale
    assert not blocks_symmetric([c])


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


# ------------------------------------------------------------- checked solves
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
    prod = mkl._MklProduct(mkl._mkl().lib, A)
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
    kept = mkl._MklProduct(mkl._mkl().lib, B)
    x = rng.normal(size=n)
    expected = -(B @ x)
    B.data = np.zeros_like(B.data)
    np.testing.assert_allclose(kept(x, np.zeros(n)), expected, atol=1e-12)
    # 64-bit indices: no MKL product, the factor falls back to SciPy's
    A64 = A.copy()
    A64.indices, A64.indptr = A64.indices.astype(np.int64), A64.indptr.astype(np.int64)
    assert mkl._MklProduct(mkl._mkl().lib, A64)(x, x) is None
    # a PARDISO factor uses it for every solve, 1-D or 2-D, of K or K^T: SciPy's
    # product is never called
    f = get_solver("pardiso").factorize(A)
    assert isinstance(f._residual_of, mkl._MklProduct) and f._residual_of.ok

    def no_scipy(*args):
        raise AssertionError("SciPy's product used")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(factor, "_residual", no_scipy)
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
