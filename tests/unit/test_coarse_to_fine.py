"""Coarse meshes guiding a load path (signorini.algorithms.coarse_to_fine): the
prolongation (exact for affine fields, built once per pair of meshes), a
coarse-to-fine start and guided increments give the solution from rest with
fewer Newton iterations, and a failing coarse level is abandoned at once."""

import sys
from collections import OrderedDict

import numpy as np
import pytest
import scipy.sparse as sp

import signorini as sg
from signorini.algorithms.coarse_to_fine import prolong, solve_coarse_to_fine
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms import stepping
from signorini.algorithms.stepping import model_for
from signorini.model import Model

TIGHT = sg.NewtonOptions(rtol=1e-11)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


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


def test_a_prolongation_prepared_on_its_thread_is_the_one_built_here():
    """Prolongation.prepare builds it on a thread of its own (while a coarse level
    solves); between() waits for it and keeps it; an error of the build is raised
    by between(), in the caller's thread."""
    from signorini.algorithms.coarse_to_fine import Prolongation

    cm = model_for(hertz_friction_problem(refine=0, n_fine=10))
    fm = model_for(hertz_friction_problem(refine=0, n_fine=20))
    fm.cache.pop(("prolongation", id(cm)), None)
    Prolongation.prepare(cm, fm)
    P = Prolongation.between(cm, fm)
    assert Prolongation.between(cm, fm) is P
    assert abs(P.matrix - Prolongation(cm, fm).matrix).max() == 0.0
    other = model_for(hertz.hertz_problem(n_fine=10))  # another contact surface: an error
    other.cache.pop(("prolongation", id(cm)), None)
    Prolongation.prepare(cm, other)
    with pytest.raises(sg.InputError, match="same contact"):
        Prolongation.between(cm, other)


def test_coarse_to_fine_start_same_solution_fewer_iterations():
    fine = hertz.hertz_problem(refine=1)
    plain = sg.solve(fine, options=TIGHT, wrt=["R"])
    coarse, levels = solve_coarse_to_fine([hertz.hertz_problem(n_fine=12), hertz.hertz_problem()],
                                          options=TIGHT)
    assert [lv["dofs"] for lv in levels] == [model_for(hertz.hertz_problem(n_fine=12)).n_dof,
                                             model_for(hertz.hertz_problem()).n_dof]
    started = sg.solve(fine, options=TIGHT, wrt=["R"], start=prolong(coarse, fine))
    assert started.newton_iterations[0] <= 2 < plain.newton_iterations[0]
    assert _rel(started.increments[0].w, plain.increments[0].w) < 1e-9
    assert _rel(started.w_sensitivity("R"), plain.w_sensitivity("R")) < 1e-8
    c1, c2 = plain.contact(), started.contact()
    assert np.array_equal(c1["p_N"] > 0, c2["p_N"] > 0)  # open nodes exactly zero in both


def test_coarse_meshes_guide_every_increment_of_a_frictional_path(monkeypatch):
    """The coarse meshes are solved along the whole path; every fine increment
    starts from its own last state plus the interpolated coarse increment. Only
    the start changes: the fine path is the one from rest."""
    # every mesh by programs of its own, so that both coarse levels are solved
    _fresh_models(monkeypatch, 10**9)
    fine = hertz_friction_problem(refine=1)
    o = sg.NewtonOptions(rtol=1e-10)
    guide, levels = hertz.coarse_start_for(
        fine, lambda r, n: hertz_friction_problem(refine=r, n_fine=n), 1, 24, steps=6, options=o,
        solver="auto")
    assert len(levels) == 2 and all(len(lv["newton_iterations"]) == 6 for lv in levels)
    assert [round(i.t, 12) for i in guide.increments] == [round(k / 6, 12) for k in range(1, 7)]
    plain = sg.solve(fine, steps=6, options=o, wrt=["R"])
    started = sg.solve(fine, steps=6, options=o, wrt=["R"], start=sg.Start(guide=guide))
    # measured: guided 2 1 1 2 1 1, from rest with the extrapolating predictor 7 4 3 3 3 3
    later = started.newton_iterations[1:]
    assert started.newton_iterations[0] <= 3 < plain.newton_iterations[0]
    assert max(later) <= 2 and sum(later) < sum(plain.newton_iterations[1:])
    for a, b in zip(started.increments, plain.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["R"], b.sens["R"]) < 1e-8


def _fresh_models(monkeypatch, whole_mesh_up_to: int) -> None:
    """Models built from here on with this threshold (none kept from other tests)."""
    monkeypatch.setattr(Model, "WHOLE_MESH_UP_TO", whole_mesh_up_to)
    monkeypatch.setattr(stepping, "_MODELS", OrderedDict())


def test_a_fine_mesh_run_by_kind_is_guided_only_by_levels_run_by_kind(monkeypatch):
    """A coarse level small enough for programs of its own (Model.WHOLE_MESH_UP_TO
    cells or fewer) is not solved when the fine mesh runs by its kinds' programs:
    in a new process it would load or compile them, for a few iterations saved;
    every level is solved
    when the fine mesh has programs of its own too."""
    build = lambda r, n: hertz.hertz_problem(refine=r, n_fine=n)  # noqa: E731
    sizes = {(r, n): build(r, n).mesh.n_cells for r, n in hertz.coarse_levels(1, 24)}
    assert sorted(sizes) == [(0, 12), (0, 24)] and sizes[(0, 12)] < 1000 < sizes[(0, 24)]
    _fresh_models(monkeypatch, 1000)
    fine = hertz.hertz_problem(refine=1)
    assert model_for(fine).by_kind
    guide, levels = hertz.coarse_start_for(fine, build, 1, 24, steps=1, options=TIGHT,
                                           solver="auto")
    assert [lv["dofs"] for lv in levels] == [model_for(build(0, 24)).n_dof]
    assert guide.model.n_dof == levels[0]["dofs"]
    _fresh_models(monkeypatch, 10**9)
    assert not model_for(fine).by_kind
    _, levels = hertz.coarse_start_for(fine, build, 1, 24, steps=1, options=TIGHT, solver="auto")
    assert [lv["dofs"] for lv in levels] == [model_for(build(*lv)).n_dof for lv in [(0, 12), (0, 24)]]


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
        sol = sg.solve(near if guide is plain else pb, steps=6, options=o, start=guide)
        ref = plain if guide is not plain else sg.solve(near, steps=6, options=o)
        for a, b in zip(sol.increments, ref.increments):
            assert _rel(a.w, b.w) < 1e-9
    # from the base path of the same mesh, a perturbed re-solve needs one iteration
    again = sg.solve(near, steps=6, options=o, start=plain)
    assert max(again.newton_iterations[1:]) <= 1
    P = Prolongation(plain.model, sg.solve(near, steps=1, options=o).model)
    assert (P.matrix != sp.identity(P.matrix.shape[0])).nnz == 0
    with pytest.raises(sg.InputError, match="guide must be a Solution"):
        sg.solve(pb, start=sg.Start(guide=plain.increments[0].w))


def test_a_failing_coarse_level_is_abandoned_at_once(monkeypatch):
    """A coarse level is solved without step cutting and abandoned at its first
    failure, with the coarser levels after it (not solved): the fine mesh starts
    without its guide, with a warning, and its path is the one from rest."""
    solve_module = sys.modules["signorini.algorithms.coarse_to_fine"]  # the solve it calls
    real = solve_module.solve
    pbs = [hertz_friction_problem(refine=0, n_fine=8), hertz_friction_problem(refine=0, n_fine=12),
           hertz_friction_problem(refine=0)]
    calls = []

    def failing(pb, **kw):
        calls.append((next(k for k, q in enumerate(pbs) if q is pb), kw["options"].max_cuts,
                      kw.get("start")))
        if pb is pbs[0]:  # converges to t = 0.5, then fails
            part = real(pb, **{**kw, "until": 0.5})
            raise sg.ConvergenceError("no convergence at t=0.667 (test)", partial=part)
        return real(pb, **kw)

    monkeypatch.setattr(solve_module, "solve", failing)
    o = sg.NewtonOptions(rtol=1e-10)
    sol, levels = solve_coarse_to_fine(pbs, steps=6, options=o, wrt=["mu"])
    # the coarse level without step cuts; the middle one skipped; the finest unguided,
    # with the run's own cutting budget
    assert calls == [(0, 0, None), (2, o.max_cuts, None)]
    assert len(levels) == 2 and "test" in levels[0]["failed"]
    assert len(levels[0]["newton_iterations"]) == 3
    assert "failed" not in levels[1] and len(sol.increments) == 6
    assert any("level 0" in w and "abandoned" in w for w in sol.warnings), sol.warnings
    plain = real(pbs[2], steps=6, options=o, wrt=["mu"])
    for a, b in zip(sol.increments, plain.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["mu"], b.sens["mu"]) < 1e-8


def test_a_coarse_level_that_converges_nothing_keeps_the_guide_before(monkeypatch):
    """Three levels, the middle one failing in its first increment: the finest is
    guided by the coarsest (before: by nothing)."""
    solve_module = sys.modules["signorini.algorithms.coarse_to_fine"]  # the solve it calls
    real = solve_module.solve
    pbs = [hertz_friction_problem(refine=0, n_fine=8), hertz_friction_problem(refine=0, n_fine=12),
           hertz_friction_problem(refine=0)]
    guides = []

    def failing(pb, **kw):
        guides.append(kw.get("start"))
        if pb is pbs[1]:
            raise sg.ConvergenceError("no convergence at t=0.25 (test)", partial=None)
        return real(pb, **kw)

    monkeypatch.setattr(solve_module, "solve", failing)
    sol, levels = solve_coarse_to_fine(pbs, steps=4, options=sg.NewtonOptions(rtol=1e-10))
    assert "failed" in levels[1] and levels[1]["newton_iterations"] == []
    assert guides[0] is None and guides[1] is not None and guides[2] is guides[1]
    assert len(sol.increments) == 4
    assert any("level 1" in w and "abandoned" in w for w in sol.warnings), sol.warnings


def test_prolongation_reproduces_affine_fields():
    """Piecewise linear interpolation is exact for an affine displacement field;
    nodes outside the coarse mesh take the nearest coarse node's value."""
    from signorini.algorithms.coarse_to_fine import Prolongation
    from signorini.algorithms.stepping import model_for

    cm = model_for(hertz_friction_problem(refine=0, n_fine=12))
    fm = model_for(hertz_friction_problem(refine=1))
    Xc, Xf = np.asarray(cm.reference_nodes), np.asarray(fm.reference_nodes)
    A = np.array([[0.3, -0.2], [0.1, 0.5]])
    wc = np.zeros(cm.n_dof)
    wc[: 2 * cm.n_nodes] = (Xc @ A.T + [1.0, -2.0]).ravel()
    wf = Prolongation(cm, fm)(wc)
    assert np.allclose(wf[: 2 * fm.n_nodes].reshape(-1, 2), Xf @ A.T + [1.0, -2.0], atol=1e-12)


def test_a_3d_tensor_grid_is_interpolated_trilinearly_in_its_cells():
    """Coarse nodes forming a box grid: trilinear interpolation in the grid cells,
    exact for a trilinear field (the coarse Q1 solution itself), linear
    extrapolation outside; a mesh that is not a grid goes through the
    tetrahedralisation, exact for affine fields."""
    from signorini.algorithms.prolongation import _grid_of, _linear_weights
    from signorini.problems.hertz3d import hertz3d_problem

    Xc = np.asarray(hertz3d_problem(n_fine=2, size=4.0).mesh.nodes, dtype=float)
    Xf = np.asarray(hertz3d_problem(n_fine=3, size=4.0).mesh.nodes, dtype=float)
    assert _grid_of(Xc) is not None
    f = lambda X: 1 + X[:, 0] - 2 * X[:, 1] + 3 * X[:, 2] + 5 * X[:, 0] * X[:, 1] * X[:, 2]  # noqa: E731
    P = _linear_weights(Xc, Xf)
    inside = np.all((Xf >= Xc.min(axis=0)) & (Xf <= Xc.max(axis=0)), axis=1)
    assert np.abs(P @ f(Xc) - f(Xf))[inside].max() < 1e-12 * np.abs(f(Xf)).max()
    lo, hi = Xc.min(axis=0), Xc.max(axis=0)
    out = np.array([hi + 0.1 * (hi - lo), lo - 0.05 * (hi - lo)])  # beyond two corners
    g = lambda X: X @ [1.0, 2.0, -3.0] + 0.5  # noqa: E731
    assert np.allclose(_linear_weights(Xc, out) @ g(Xc), g(out), atol=1e-12)
    # not a grid (one node moved): the tetrahedralisation, exact for affine fields
    Xp = Xc.copy()
    Xp[len(Xp) // 2] += 1e-3 * (hi - lo)
    assert _grid_of(Xp) is None
    assert np.allclose(_linear_weights(Xp, Xf[inside]) @ g(Xp), g(Xf[inside]), atol=1e-10)
