"""Design optimisation (signorini.optimize): DDM gradient = central differences of
the objective on a small forging problem, one solve per fun+jac pair, convergence
to the known optimum of analytic elastic contact problems with BFGS, L-BFGS-B and
SLSQP, failed trial points (Newton failure, inverted mesh) survived, and the
forging preform optimisation's outputs and resume."""

from __future__ import annotations

import json

import numpy as np
import pytest

import signorini as sg
from signorini.app.commands import optimize_forging as fo_cmd
from signorini.design import evaluation
from signorini.design import optimize as opt
from signorini.problems import forging as fg
from signorini.problems import forging_opt as fo

pytestmark = pytest.mark.filterwarnings("ignore::signorini.SignoriniWarning")

E, NU, W, H = 1.0, 0.3, 1.0, 1.0
TIGHT = sg.NewtonOptions(rtol=1e-12)


def die_force(model):
    """Total normal force of contact surface 0 (compression positive)."""
    def f(w, p, t):
        c = model.contact_fields(w, p, t, 0)
        return (c["area"] * c["p_N"]).sum()
    return f


def pushed_block(n=2):
    """W x H linear-elastic block (plane strain) on a smooth base (left edge on the
    symmetry line), compressed by a rigid flat die moving down by ``d``. The stress is
    uniaxial: die force = W E' d / H and lateral bulge u_x(W) = W nu/(1-nu) d / H,
    E' = E / (1 - nu^2), exactly (Q4 reproduces homogeneous strain, the AL enforces g = 0)."""
    m = sg.rectangle(np.linspace(0, W, n + 1), np.linspace(0, H, n + 1))
    die = sg.Line(point=(0.0, H), normal_vector=(0.0, -1.0), motion=(0.0, lambda p: -p["d"]))
    return sg.Problem(m, sg.LinearElastic(E="E", nu="nu"), {"E": E, "nu": NU, "d": 0.01, "eps": E / H},
                      fixed=(sg.Fixed("left", 0), sg.Fixed("bottom", 1)),
                      contact=(sg.Contact(die, "top", sg.AugmentedLagrangian("eps")),))


@pytest.fixture(scope="module")
def forging_objectives():
    """F(phi0..phi4) of the forging problem on a 3 x 6 mesh, 10 increments, mu = 0.3,
    Newton rtol 1e-12: by DDM and by central differences of the value (same problem,
    same compiled model as the preform optimisation test below)."""
    kw = dict(mesh=(3, 6), steps=10, rtol=1e-12)
    return fo.objective_for(0.3, **kw), fo.objective_for(0.3, gradient="fd", **kw)


def test_forging_jac_equals_central_fd_of_fun(forging_objectives):
    """jac (DDM) = central differences of fun (step 1e-6 max(|phi|, 1)) to 1e-5 relative
    (max |DDM - FD| / max |DDM|, the measure of every command; measured 3e-8; per
    component <= 1.1e-5, the smallest component being 60 x smaller than the largest),
    at a non-cylindrical preform. All eleven solves follow the nominal load path:
    where Newton needs a step cut at x but not at x +- h (measured at
    phi0, phi2, phi4 = 0.72, 0.68, 0.75) the paths differ and so do DDM and FD (by ~1 %)."""
    ddm, fd = forging_objectives
    x = np.array([0.72, 0.7, 0.68, 0.7, 0.72])
    g = ddm.jac(x)
    g_fd = fd.jac(x)
    rel = np.abs(g - g_fd).max() / np.abs(g).max()
    print("DDM", g, "\nFD ", g_fd, "\nrel", rel, np.abs(g - g_fd) / np.abs(g))
    assert rel < 1e-5, rel
    assert np.all(np.abs(g - g_fd) / np.abs(g) < 1e-4)
    assert fd.fun(x) == ddm.fun(x)  # the same value with and without sensitivities
    assert np.abs(g).min() > 1e-3  # not a trivially small gradient
    assert all(r.cuts == 0 and r.increments == 10 for r in ddm.records + fd.records)


def test_one_solve_per_fun_jac_pair(forging_objectives, monkeypatch, tmp_path):
    ddm, fd = forging_objectives
    calls = []
    real = evaluation.solve  # the solve an Objective's evaluation calls
    monkeypatch.setattr(evaluation, "solve", lambda *a, **k: calls.append(k.get("wrt")) or real(*a, **k))
    x = np.array([0.71, 0.7, 0.69, 0.7, 0.74])
    n0 = ddm.n_solves
    F = ddm.fun(x)
    g = ddm.jac(x)
    assert len(calls) == 1 and list(calls[0]) == ddm.names  # one solve, with the 5 sensitivities
    assert ddm.fun(x.copy()) == F and np.array_equal(ddm.jac(list(x)), g)  # same bytes: cached
    assert len(calls) == 1 and ddm.n_solves == n0 + 1
    rec = ddm.records[-1]
    assert rec.ok and rec.kind == "value+gradient" and rec.F == F and np.array_equal(rec.grad, g)
    assert rec.newton_iterations > 10 and rec.increments == 10 and rec.time > 0
    # central differences: 1 + 2 x 5 solves without sensitivities, none again at the same x
    calls.clear()
    fd.fun(x), fd.jac(x), fd.fun(x), fd.jac(x)
    assert len(calls) == 11 and all(not c for c in calls)
    # the record round-trips through the CSV (x exactly: it is the restart point)
    path = ddm.write_csv(tmp_path / "h.csv")
    back = opt.read_history(path, ddm.names)
    assert len(back) == len(ddm.records)
    assert np.array_equal(back[-1].x, x) and back[-1].F == F and np.array_equal(back[-1].grad, g)


@pytest.mark.parametrize("method", ["BFGS", "L-BFGS-B", "SLSQP"])
def test_optimisation_finds_the_analytic_optimum(method):
    """Two parameters of the pushed block, die travel d and Poisson's ratio nu, fitted
    to a target die force and lateral bulge: F = (f/f* - 1)^2 + (u/u* - 1)^2 with
    f*, u* computed at (d*, nu*) = (0.02, 0.25) from the closed-form solution.
    The optimum is found to 1e-6."""
    pb = pushed_block()
    d_s, nu_s = 0.02, 0.25
    f_s = W * E / (1 - nu_s**2) * d_s / H
    u_s = W * nu_s / (1 - nu_s) * d_s / H
    right_top = int(np.argmax(pb.mesh.nodes[:, 0] + pb.mesh.nodes[:, 1]))

    def response(model):
        force = die_force(model)

        def F(w, p, t):
            u, _ = model.split(w)
            return (force(w, p, t) / f_s - 1) ** 2 + (u[right_top, 0] / u_s - 1) ** 2
        return F

    obj = opt.Objective(pb, ["d", "nu"], response, options=TIGHT)
    bounds = None if method == "BFGS" else [(1e-4, 0.1), (0.0, 0.45)]
    res = opt.minimize(obj, [0.01, 0.3], method, bounds=bounds, gtol=1e-11, maxiter=100)
    print(method, res.x, res.nit, res.n_solves, res.message)
    assert res.success
    assert np.abs(res.x - [d_s, nu_s]).max() < 1e-6
    assert res.fun < 1e-10 and res.n_failed == 0
    # one solve per evaluation, the per-iteration log starts at x0 and ends at the optimum
    assert res.n_solves == len(obj.records) == len({r.x.tobytes() for r in obj.records})
    log = res.iterations_log
    assert log[0]["x"] == [0.01, 0.3] and log[-1]["F"] == pytest.approx(res.fun, abs=1e-14)
    assert log[0]["F"] > 1e3 * log[-1]["F"]


def _survives(obj, x0, optimum, bad_status, method="BFGS"):
    res = opt.minimize(obj, x0, method, gtol=1e-11, maxiter=100)
    bad = [r for r in obj.records if not r.ok]
    good = [r for r in obj.records if r.ok]
    for r in obj.records:
        print(r.index, r.status, r.x, r.F, r.grad, r.reason[:80])
    assert bad and all(r.status == bad_status for r in bad)
    for r in bad:  # finite, larger than anything seen before it, gradient pointing away
        before = [g for g in good if g.index < r.index]
        assert np.isfinite(r.F) and np.all(np.isfinite(r.grad)) and r.F > 5 * max(g.F for g in before)
        last = before[-1]
        assert float(r.grad @ (r.x - last.x)) > 0
    assert res.success and abs(res.x[0] - optimum) < 1e-6 and res.n_failed == len(bad)
    return res


def test_newton_failure_at_a_trial_point_is_survived():
    """A block under a top pressure P rests on a rigid base at height -g: for g > 0 a
    gap opens, nothing holds the block and Newton cannot start (ConvergenceError).
    Fitting the top displacement u = -g - P H / E' to its value at g* = -0.01 from
    g0 = -0.05, BFGS's first trial step (length ~1.01 |grad|/|grad|) lands at g = 0.03:
    that point is penalised, recorded as failed, the line search backs off and
    the optimisation reaches g* to 1e-6."""
    m = sg.rectangle(np.linspace(0, W, 3), np.linspace(0, H, 3))
    base = sg.Line(point=(0.0, lambda p: -p["g"]), normal_vector=(0.0, 1.0))
    pb = sg.Problem(m, sg.LinearElastic(E="E", nu="nu"), {"E": E, "nu": NU, "g": -0.05, "P": 0.02,
                                                          "eps": E / H},
                    fixed=(sg.Fixed("left", 0),), loads=(sg.Pressure("top", "P"),),
                    contact=(sg.Contact(base, "bottom", sg.AugmentedLagrangian("eps")),))
    top = m.node_sets["top"]
    g_s = -0.01
    u_s = -g_s - 0.02 * H * (1 - NU**2) / E

    def response(model):
        def F(w, p, t):
            u, _ = model.split(w)
            return (u[top, 1].mean() - u_s) ** 2
        return F

    obj = opt.Objective(pb, ["g"], response, options=TIGHT)
    _survives(obj, [-0.05], g_s, "failed")
    # the same point again (BFGS's trial point, 0.03 to round-off): the recorded
    # penalty, no new solve
    failed = next(r for r in obj.records if not r.ok)
    assert abs(failed.x[0] - 0.03) < 1e-12
    n = obj.n_solves
    assert obj.fun(failed.x) == failed.F and obj.n_solves == n


def test_invalid_design_at_a_trial_point_is_survived():
    """Shape parameter h = block height (design velocity (0, Y / H)) under a fixed die
    travel d: die force = W E' d / h. F = 10 (f/f* - 1)^2 with f* at h* = 0.3; from h = 1
    BFGS's first trial step is h = -0.01: an inverted mesh (InvertedElementError,
    status 'invalid'), penalised and survived."""
    pb0 = pushed_block()
    X = pb0.mesh.nodes
    die = sg.Line(point=(0.0, "h"), normal_vector=(0.0, -1.0), motion=(0.0, lambda p: -p["d"]))
    pb = sg.Problem(pb0.mesh, pb0.material, {**pb0.params, "h": H}, fixed=pb0.fixed,
                    contact=(sg.Contact(die, "top", sg.AugmentedLagrangian("eps")),),
                    shape={"h": np.column_stack([np.zeros(len(X)), X[:, 1] / H])})
    h_s = 0.3
    f_s = W * E / (1 - NU**2) * 0.01 / h_s

    def response(model):
        force = die_force(model)
        return lambda w, p, t: 10 * (force(w, p, t) / f_s - 1) ** 2

    obj = opt.Objective(pb, ["h"], response, options=TIGHT)
    _survives(obj, [H], h_s, "invalid")
    with pytest.raises(sg.InputError, match="start"):  # but an optimisation cannot start there
        opt.minimize(opt.Objective(pb, ["h"], response), [-0.5])


def test_forging_preform_optimisation_outputs_and_resume(tmp_path):
    """mu = 0.3, 3 x 6 mesh, 10 increments, 4 BFGS iterations: F falls, every output is
    written, and resume continues the history from its best point."""
    out = tmp_path / "opt"
    s = fo_cmd.run(out, [0.3], mesh=(3, 6), steps=10, maxiter=4)
    r = s["runs"][0]
    d = out / "mu_0.3"
    for f in ("history.csv", "summary.json", "shape.png", "convergence.png", "forging.pvd",
              "forging_0010.vtu"):
        assert (d / f).stat().st_size > 0, f
    assert (out / "shapes.png").stat().st_size > 0
    assert json.loads((out / "summary.json").read_text())["runs"][0]["F_opt"] == r["F_opt"]
    assert r["F_opt"] < 0.2 * r["F_start"] and r["iterations"] == 4
    hist = opt.read_history(d / "history.csv", list(fg.SHAPE))
    assert len(hist) == r["solves"] and min(h.F for h in hist if h.status == "ok") == r["F_opt"]
    s2 = fo_cmd.run(out, [0.3], mesh=(3, 6), steps=10, maxiter=2, resume=True)
    r2 = s2["runs"][0]
    assert r2["resumed"] and r2["F_start"] == r["F_opt"] and r2["F_opt"] <= r["F_opt"]
    hist2 = opt.read_history(d / "history.csv", list(fg.SHAPE))
    assert [h.index for h in hist2] == list(range(1, len(hist) + r2["solves"] + 1))


def test_optimize_forging_command(tmp_path, capsys):
    """`signorini optimize-forging` on a tiny mesh: the table is printed and F falls."""
    import json

    from signorini.app.cli import main

    out = tmp_path / "opt"
    assert main(["optimize-forging", "--out", str(out), "--mu", "0.1", "--mesh", "3x6",
                 "--steps", "10", "--maxiter", "4", "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    r = s["runs"][0]
    assert r["F_opt"] < 0.2 * r["F_start"]
    assert (out / "mu_0.1" / "history.csv").exists() and (out / "shapes.png").exists()
    assert "F(cylinder)" in capsys.readouterr().out
    assert main(["optimize-forging", "--out", str(out), "--mu", "x"]) == 2
