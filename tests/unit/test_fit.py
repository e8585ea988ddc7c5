"""sg.fit: parameters identified from measured curves, with standard errors (issue 52).

The client: a rigid ball pressed into a small elastic block (depth d over t in
[0, 0.5]) and then slid along it (s over [0.5, 1]) with Coulomb friction, the base
held (docs/tutorial.md §13 on a coarser block). The "measurements" are the
contact force's normal (z) and tangential (x) components at every increment of a
solve at E = 100, mu = 0.3; during the slide F_x = mu |F_z| nearly, so the two
curves separate E (the stiffness) from mu.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import signorini as sg
from signorini.design import evaluation
from signorini.design import fit as fitmod
from helpers import adjoint_misfit_is_ddms_and_central_differences, misfit_matches_central_differences
from signorini.design.fit import Misfit

TIGHT = sg.NewtonOptions(rtol=1e-12)
STEPS = 8
TRUE = {"E": 100.0, "mu": 0.3}
START = {"E": 75.0, "mu": 0.38}  # 25 % and 27 % off
BOUNDS = {"E": (10.0, 1000.0), "mu": (0.05, 0.8)}
FZ = sg.responses.contact_force(component=2)
FX = sg.responses.contact_force(component=0)


def scratch() -> sg.Problem:
    press, slide = sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)
    ball = sg.Sphere(radius="R", centre=(0.5, 0.0, lambda p: p["R"]),
                     motion=(((0.0, 0.0, lambda p: -p["d"]), press),
                             ((lambda p: p["s"], 0.0, 0.0), slide)))
    block = sg.box(np.linspace(0.2, 0.8, 13), np.linspace(-0.3, 0.3, 13), np.linspace(-0.3, 0, 3))
    return sg.Problem(
        mesh=block, material=sg.LinearElastic(),
        # H: a parameter the problem does not use (a fit cannot identify it)
        params={"E": 100.0, "nu": 0.3, "R": 0.5, "d": 0.02, "s": 0.05, "mu": 0.3, "eps": 1000.0,
                "H": 1.0},
        fixed=[sg.Fixed("z0", k) for k in range(3)],
        contact=[sg.Contact(ball, "z1", sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps"))])


@pytest.fixture(scope="module")
def measured():
    """(problem, times, F_z, F_x) at the true values, every increment."""
    pb = scratch()
    sol = sg.solve(pb, steps=STEPS, options=TIGHT)
    assert not sol.warnings  # a clean path: the fits' warnings are their own
    t = np.array([inc.t for inc in sol.increments])
    return pb, t, FZ.path(sol), FX.path(sol)


def curves(measured, fz=None, fx=None):
    """Both curves, each weighted by 1 / (its largest |value|)^2 (relative residuals)."""
    _, t, Fz, Fx = measured
    fz, fx = (Fz if fz is None else fz), (Fx if fx is None else fx)
    return [sg.Curve(FZ, t, fz, np.full(t.size, 1 / np.abs(Fz).max() ** 2)),
            (FX, t, fx, np.full(t.size, 1 / np.abs(Fx).max() ** 2))]


def _rel(values) -> np.ndarray:
    return np.array([abs(values[n] / TRUE[n] - 1) for n in TRUE])


@pytest.mark.parametrize("method", ["least_squares", "L-BFGS-B"])
def test_noise_free_histories_give_back_E_and_mu(measured, method):
    """From 25-27 % off, both optimisers recover E and mu to 1e-6 relative from the
    exact force histories; the misfit falls at every iteration (least squares);
    one solve per point, within the budget; the standard errors are as small as
    the residual round-off."""
    pb = measured[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", sg.SignoriniWarning)  # a well-posed fit warns of nothing
        res = sg.fit(pb, ["E", "mu"], curves(measured), start=START, bounds=BOUNDS, method=method,
                     options=TIGHT, max_solves=40)
    print(res)
    assert res.success and res.n_failed == 0 and not res.warnings
    assert _rel(res.values).max() < 1e-6
    assert res.values == dict(zip(["E", "mu"], res.x.tolist()))
    assert res.n_data == 2 * STEPS and res.residuals.shape == (2 * STEPS,)
    assert res.n_solves == len(res.evaluations) == len({e.x.tobytes() for e in res.evaluations}) <= 40
    F = [row["F"] for row in res.history]
    assert res.history[0]["x"] == [START["E"], START["mu"]] and F[-1] == res.misfit
    assert F[0] > 1e8 * F[-1]
    if method == "least_squares":
        assert all(b < a for a, b in itertools.pairwise(F))
    for i, n in enumerate(["E", "mu"]):
        assert res.stderr[n] < 1e-6 * res.x[i]
    assert abs(res.correlation[0, 1]) < 0.9 and res.condition < 100
    text = res.table()
    assert "E" in text and "mu" in text and "correlation" in text and str(res) == text


def test_the_gradient_the_fit_uses_is_the_central_difference_of_the_misfit(measured, monkeypatch):
    """dF/dx = 2 J^T r with J from the solve's DDM sensitivities, against central
    differences of F (step 1e-4 of each value; their error, O(h^2) and the Newton
    round-off over h, is about 1e-9 here): agreement to 1e-6 relative, at the start
    and at a point on the other side of the truth. The residuals and J at a point
    cost one solve."""
    pb = measured[0]
    calls = []
    real = fitmod.solve
    monkeypatch.setattr(fitmod, "solve", lambda *a, **k: calls.append(k["wrt"]) or real(*a, **k))
    m = Misfit(pb, ["E", "mu"], curves(measured), options=TIGHT)
    assert m.steps == STEPS  # the increments put at the measured times
    for x in (np.array([75.0, 0.38]), np.array([120.0, 0.22])):
        n0 = len(calls)
        F, g, J = m(x), m.gradient(x), m.jacobian(x)
        r = m.residuals(x)
        assert len(calls) == n0 + 1 and calls[-1] == ["E", "mu"]
        assert F == pytest.approx(r @ r, rel=1e-15) and np.allclose(g, 2 * J.T @ r, rtol=1e-15)
        misfit_matches_central_differences(m, x, g, J)


def test_the_adjoint_gradient_of_the_misfit_is_ddms_and_the_central_difference(measured):
    """gradient="adjoint": F as responses.misfit summed over the increments, with one
    backward pass (sg.Objective, sg.Adjoint()) for both parameters. At the start and
    at a point on the other side of the truth its F is r^T r (1e-13), its gradient
    2 J^T r of DDM to 1e-10 and the central differences of its own F (step 1e-4 of
    each value) to 1e-6, relative."""
    m = Misfit(measured[0], ["E", "mu"], curves(measured), options=TIGHT)
    obj = m.objective()
    assert obj.gradient_mode == "adjoint" and obj.increments == "all"
    for x in (np.array([75.0, 0.38]), np.array([120.0, 0.22])):
        adjoint_misfit_is_ddms_and_central_differences(m, obj, x)


def test_the_adjoint_misfit_counts_only_the_increments_at_measured_times(measured):
    """A curve measured at every other increment (steps=8 given): the summed
    response is zero at the increments between its times (as at a cut increment),
    so F and its adjoint gradient are still those of the data: r^T r and 2 J^T r of
    DDM. Without the zero, responses.misfit summed over all increments adds the four
    between, at interpolated values (F 3.4 times larger here)."""
    pb, t, Fz, Fx = measured
    m = Misfit(pb, ["E", "mu"], [(FZ, t[1::2], 1.02 * Fz[1::2], np.full(4, np.abs(Fz).max() ** -2)),
                                 (FX, t, Fx, np.full(8, np.abs(Fx).max() ** -2))], steps=8, options=TIGHT)
    x = np.array([90.0, 0.33])
    F, g = m.objective().value_and_grad(x)
    plain = sum(sg.Objective(pb, ["E", "mu"], sg.responses.misfit(c.response, c.times, c.values,
                                                                  c.weights),
                             steps=8, increments="all", options=TIGHT)(x) for c in m.curves)
    print(F, m(x), plain, g, m.gradient(x))
    assert F == pytest.approx(m(x), rel=1e-13) and plain > 2 * F
    assert np.abs(g / m.gradient(x) - 1).max() < 1e-10


def test_lbfgsb_with_the_adjoint_gradient_recovers_E_and_mu(measured):
    """The noise-free fit of the first test with L-BFGS-B on the adjoint gradient:
    E and mu to 1e-6 relative; the standard errors come from one more solve, with
    DDM sensitivities, at the optimum (the last evaluation, of the adjoint's best
    point)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", sg.SignoriniWarning)
        res = sg.fit(measured[0], ["E", "mu"], curves(measured), start=START, bounds=BOUNDS,
                     method="L-BFGS-B", gradient="adjoint", options=TIGHT, max_solves=40)
    print(res)
    assert res.success and res.gradient == "adjoint" and "adjoint gradient" in res.table()
    assert _rel(res.values).max() < 1e-6
    *adjoint, ddm = res.evaluations
    assert res.n_solves == len(res.evaluations) <= 41 and len(adjoint) >= 5
    assert all(e.kind == "value+gradient" for e in adjoint)
    assert np.array_equal(ddm.x, res.x) and ddm.F == pytest.approx(res.misfit, rel=1e-12)
    # the best adjoint point's misfit is the DDM solve's at the same x, to round-off: the two
    # solves run different programs, so each residual (relative to its curve's largest value,
    # 2 STEPS of them) may differ by Newton's rtol, and F = r^T r by 2 |r| sqrt(2 STEPS) rtol
    # (at this noise-free optimum F ~ 1.5e-15 is itself round-off: 5e-9 apart has been seen)
    slack = 2 * np.sqrt(res.misfit * 2 * STEPS) * TIGHT.rtol
    assert min(e.F for e in adjoint) == pytest.approx(res.misfit, rel=1e-12, abs=slack)
    for i, n in enumerate(["E", "mu"]):
        assert res.stderr[n] < 1e-6 * res.x[i]


def test_with_one_percent_noise_the_truth_lies_within_two_standard_errors(measured):
    """Gaussian noise of 1 % of each curve's largest |value| on every datum, ten
    fixed seeds, weights 1 / (that standard deviation)^2 (so the residuals' scale
    sigma should be 1): the true E and mu lie within two of the fit's standard
    errors in at least 9 of the 10 (for 14 degrees of freedom the 2-sigma
    interval covers the truth with probability ~0.94 per parameter); the mean
    sigma is within 0.8 .. 1.2 (its standard deviation over ten fits ~0.06).
    Each fit starts at the truth (the noise moves the optimum; the fit's own
    iterations find it)."""
    pb, t, Fz, Fx = measured
    inside, sigmas = [], []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        cs = []
        for resp, y in ((FZ, Fz), (FX, Fx)):
            sd = 0.01 * np.abs(y).max()
            cs.append((resp, t, y + sd * rng.standard_normal(y.size), np.full(y.size, sd ** -2)))
        res = sg.fit(pb, ["E", "mu"], cs, options=TIGHT, max_solves=20)
        assert res.success
        z = [(res.values[n] - TRUE[n]) / res.stderr[n] for n in TRUE]
        print(seed, res.values, res.stderr, z, res.sigma, res.n_solves)
        inside.append(np.abs(z) <= 2)
        sigmas.append(res.sigma)
        assert res.stderr["E"] == pytest.approx(np.sqrt(res.covariance[0, 0]), rel=1e-14)
    inside = np.array(inside)
    print("inside 2 SE:", inside.sum(axis=0), "both:", inside.all(axis=1).sum(), "mean sigma",
          np.mean(sigmas))
    assert inside.all(axis=1).sum() >= 9
    assert 0.8 < np.mean(sigmas) < 1.2


def test_parameters_the_curves_cannot_separate_are_warned_of(measured):
    """The normal force alone identifies E d^(3/2)-like combinations, not E and d
    each (Hertz: F = 4/3 E* R^(1/2) d^(3/2)): their correlation is below -0.99 and
    the fit says so; a parameter the problem does not use (H) has a zero column in
    J: J^T J is singular, no standard errors, and the fit says so."""
    pb, t, Fz, _ = measured
    with pytest.warns(sg.SignoriniWarning, match="E and d are correlated"):
        res = sg.fit(pb, ["E", "d"], [(FZ, t, Fz)], options=TIGHT, max_solves=10)
    assert res.correlation[0, 1] < -0.99
    with pytest.warns(sg.SignoriniWarning, match=r"do not depend on \['H'\]"):
        res = sg.fit(pb, ["E", "H"], [(FZ, t, Fz)], options=TIGHT, max_solves=10)
    assert np.isnan(res.stderr["H"]) and res.condition == np.inf


@pytest.mark.parametrize("method, gradient", [("least_squares", "ddm"), ("L-BFGS-B", "ddm"),
                                              ("L-BFGS-B", "adjoint")])
def test_a_failed_solve_during_the_fit_is_survived(measured, monkeypatch, method, gradient):
    """The solve at the first trial point fails (a ConvergenceError put there):
    least squares shrinks its step, L-BFGS-B backs off from the penalty (the
    adjoint's solves are sg.Objective's); the fit goes on to the truth, with the
    failure recorded."""
    pb = measured[0]
    real, n = fitmod.solve, []

    def flaky(*a, **k):
        n.append(1)
        if len(n) == 2:
            raise sg.ConvergenceError("Newton failed (put there by the test)")
        return real(*a, **k)

    monkeypatch.setattr(fitmod, "solve", flaky)
    monkeypatch.setattr(evaluation, "solve", flaky)
    res = sg.fit(pb, ["E", "mu"], curves(measured), start=START, bounds=BOUNDS, method=method,
                 gradient=gradient, options=TIGHT, max_solves=40)
    assert res.n_failed == 1 and res.evaluations[1].status == "failed"
    assert res.success and _rel(res.values).max() < 1e-6


def test_the_budget_of_solves_ends_the_fit(measured):
    pb = measured[0]
    with pytest.warns(sg.SignoriniWarning, match="did not converge"):
        res = sg.fit(pb, ["E", "mu"], curves(measured), start=START, bounds=BOUNDS, options=TIGHT,
                     max_solves=2)
    assert not res.success and res.n_solves <= 2 and res.misfit < res.history[0]["F"]


def test_times_between_increments_take_the_linear_interpolation(measured):
    """Measured times on a grid of 4 give 4 increments; with steps=4 a time between
    two increments takes the linear interpolation of their values and sensitivities."""
    pb, t, Fz, _ = measured
    assert Misfit(pb, ["E"], [(FZ, t[1::2], Fz[1::2])]).steps == 4
    sol = sg.solve(pb, steps=4, wrt=["E"], options=TIGHT)
    y4 = [FZ.of(sol, i) for i in range(4)]  # at 0.25, 0.5, 0.75, 1
    m = Misfit(pb, ["E"], [(FZ, [0.375, 0.625, 1.0], np.zeros(3))], steps=4, options=TIGHT)
    r, J = m.residuals([100.0]), m.jacobian([100.0])
    for j, (a, b) in enumerate([(0, 1), (1, 2), (3, 3)]):
        assert r[j] == pytest.approx((y4[a][0] + y4[b][0]) / 2, rel=1e-12)
        assert J[j, 0] == pytest.approx((y4[a][1]["E"] + y4[b][1]["E"]) / 2, rel=1e-12)


BAD = [
    ("unknown parameter", {"wrt": ["E", "Young"]}, "unknown parameter 'Young'"),
    ("wrt a string", {"wrt": "E"}, "list of parameter names"),
    ("start outside the bounds", {"start": {"E": 5.0}}, r"start value E = 5.0 is outside its bounds"),
    ("bounds of an unknown name", {"bounds": {"nu": (0, 0.5)}}, "not among the parameters"),
    ("empty bounds", {"bounds": {"E": (10.0, 1.0)}}, "bounds of 'E' are empty"),
    ("times not increasing", {"curves": [(FZ, [0.5, 0.25, 1.0], [1.0, 2.0, 3.0])]},
     r"curve contact_force\[0,2\]: the times must increase; time 0.25"),
    ("times repeated", {"curves": [(FZ, [0.5, 0.5], [1.0, 2.0])]}, "the times must increase"),
    ("values not numbers", {"curves": [(FZ, [0.5, 1.0], [1.0, "abc"])]}, "values must be numbers"),
    ("values missing", {"curves": [(FZ, [0.5, 1.0], [1.0, None])]}, "values must be numbers"),
    ("values not finite", {"curves": [(FZ, [0.5, 1.0], [1.0, np.nan])]}, "finite"),
    ("lengths differ", {"curves": [(FZ, [0.5, 1.0], [1.0])]}, "one entry per measured point"),
    ("negative weights", {"curves": [(FZ, [0.5, 1.0], [1.0, 2.0], [1.0, -1.0])]}, "weights must be >= 0"),
    ("times beyond the path", {"curves": [(FZ, [0.5, 1.5], [1.0, 2.0])]}, r"load factors of the path, in \(0, 1\]"),
    ("not a response", {"curves": [("force", [0.5, 1.0], [1.0, 2.0])]}, "must be a signorini.responses Response"),
    ("no curve", {"curves": []}, "at least one measured curve"),
    ("fewer data than parameters", {"curves": [(FZ, [1.0], [-0.4])]},
     r"fewer data \(1 measured points of positive weight\) than parameters \(2"),
    ("zero weights do not count", {"curves": [(FZ, [0.5, 1.0], [1.0, 2.0], [1.0, 0.0])]}, "fewer data"),
    ("times off any grid", {"curves": [(FZ, [1 / np.pi, 1.0], [1.0, 2.0])]}, "give steps="),
    ("time before the first increment", {"curves": [(FZ, [0.1, 1.0], [1.0, 2.0])], "steps": 4},
     "before the first increment"),
    ("unknown method", {"method": "newton"}, "method must be one of"),
    ("unknown gradient", {"method": "L-BFGS-B", "gradient": "fd"}, "gradient must be one of"),
    ("adjoint with least squares", {"gradient": "adjoint"}, "gradient='adjoint' is for method='L-BFGS-B'"),
    ("adjoint with a time between increments",
     {"curves": [(FZ, [0.375, 1.0], [1.0, 2.0])], "steps": 4, "method": "L-BFGS-B", "gradient": "adjoint"},
     r"the adjoint gradient needs every measured time on an increment \(k / 4\); 0.375"),
    ("no budget", {"max_solves": 0}, "max_solves must be a positive integer"),
]


@pytest.mark.parametrize("case, change, message", BAD, ids=[b[0] for b in BAD])
def test_bad_inputs_are_named_before_any_solve(measured, monkeypatch, case, change, message):
    pb, t, Fz, _ = measured
    monkeypatch.setattr(fitmod, "solve", lambda *a, **k: pytest.fail("a bad input reached a solve"))
    kw = {"wrt": ["E", "mu"], "curves": [(FZ, t, Fz)], "start": None, "bounds": BOUNDS}
    kw.update(change)
    with pytest.raises(sg.InputError, match=message):
        sg.fit(pb, kw.pop("wrt"), kw.pop("curves"), **kw)


@pytest.mark.parametrize("method, gradient", [("least_squares", "ddm"), ("L-BFGS-B", "adjoint")])
def test_a_start_the_problem_rejects_is_named(measured, method, gradient):
    pb, t, Fz, _ = measured
    with pytest.raises(sg.InputError, match=r"the fit cannot start: the start \{'E': -50.0"):
        sg.fit(pb, ["E", "mu"], [(FZ, t, Fz)], start={"E": -50.0}, method=method, gradient=gradient)


def test_a_start_whose_solve_fails_is_named(measured, monkeypatch):
    """With the adjoint gradient too, a failed solve at the start ends the fit with a
    ConvergenceError that says so."""
    pb, t, Fz, _ = measured

    def fails(*a, **k):
        raise sg.ConvergenceError("Newton failed (put there by the test)")

    monkeypatch.setattr(evaluation, "solve", fails)
    with pytest.raises(sg.ConvergenceError, match=r"the fit cannot start: the solve at the start "
                       r"\{'E': 100.0, 'mu': 0.3\} failed: Newton failed \(put there"):
        sg.fit(pb, ["E", "mu"], [(FZ, t, Fz)], method="L-BFGS-B", gradient="adjoint")


def test_the_documentation_example_runs_and_prints_what_it_shows():
    """docs/fitting.md: its python block runs, and prints its text block."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "fitting.md").read_text()
    blocks = re.findall(r"^```(\w*)\n(.*?)^```[ \t]*$", text, re.DOTALL | re.MULTILINE)
    code = [b for lang, b in blocks if lang == "python"]
    shown = [b for lang, b in blocks if lang == "text"]
    assert len(code) == len(shown) == 1
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code[0], "docs/fitting.md", "exec"), {"__name__": "fitting"})
    _same_to_the_printed_digits(out.getvalue().strip(), shown[0].strip())


NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?%?")


def _same_to_the_printed_digits(got: str, shown: str) -> None:
    """`got` prints what `shown` shows: the same words, and each number within one unit
    of its last printed digit. The optimiser's iteration and solve counts and its
    termination reason are left out: its last steps are decided by differences of the
    misfit at round-off, which differ between machines (4 iterations, `xtol`, on one;
    5, `ftol`, on another, with the same fitted values to 1e-9)."""
    run = re.compile(r"converged in \d+ iterations, \d+ solves \(.*?\)")
    got, shown = run.sub("converged (...)", got), run.sub("converged (...)", shown)
    assert NUMBER.sub("#", got) == NUMBER.sub("#", shown), (got, shown)
    for a, b in zip(NUMBER.findall(got), NUMBER.findall(shown), strict=True):
        a, b = a.rstrip("%"), b.rstrip("%")
        mantissa = b.lower().split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(b.lower().split("e")[1]) if "e" in b.lower() else 0
        unit = 10.0 ** (exponent - decimals)
        assert abs(float(a) - float(b)) <= unit * (1 + 1e-9), (a, b, got)


# ------------------------------------------------ a curve against a measured abscissa
def _force_displacement():
    """The Hertz half model under force control: the contact force P t against the
    bottom's mean vertical displacement, which depends on E (the force does not)."""
    from signorini.problems import hertz
    pb = hertz.hertz_problem(n_fine=6, size=6)
    force = sg.responses.contact_force(component=1)
    lift = sg.responses.displacement("bottom", 1)
    return pb, force, lift


def test_a_curve_against_a_displacement_recovers_E_and_its_gradient_is_exact():
    """A force-displacement curve (the abscissa a response, measured between the
    increments): its model curve is the force interpolated at the measured
    displacements, differentiated through the interpolation weights, so the
    Jacobian is all in the abscissa's sensitivity here (the force is P t whatever
    E): = central FD of the misfit and residuals (1e-6), and E recovered (1e-6)."""
    pb, force, lift = _force_displacement()
    sol = sg.solve(pb, steps=4, wrt=["E"])
    X = np.array(lift.path(sol))
    Y = np.array(force.path(sol))
    xm = 0.5 * (X[:-1] + X[1:])  # between the increments
    ym = np.interp(xm, X, Y)
    curve = sg.Curve(force, xm, ym, abscissa=lift)
    m = Misfit(pb.with_params(E=85.0), ["E"], [curve], steps=4)
    # (at E = 80 a measured abscissa falls on an increment's, to 1e-9: the linear
    # interpolant's kink, where the derivative is one-sided and FD averages the sides)
    for E in (85.0, 95.0):
        x = np.array([E])
        misfit_matches_central_differences(m, x, m.gradient(x), m.jacobian(x))
    res = sg.fit(pb.with_params(E=85.0), ["E"], [curve], steps=4)
    assert abs(res.values["E"] / 100.0 - 1) < 1e-6, res.table()
    # a measured abscissa on the first increment's own: that increment's value (a = 0)
    first = sg.Curve(force, np.r_[X[0], xm], np.r_[Y[0], ym], abscissa=lift)
    assert np.abs(Misfit(pb, ["E"], [first], steps=4).residuals(np.array([100.0]))).max() < 1e-12
    with pytest.raises(sg.InputError, match="give steps"):
        sg.fit(pb, ["E"], [curve])
    with pytest.raises(sg.InputError, match="outside the model's path"):
        sg.fit(pb, ["E"], [sg.Curve(force, [10 * X[-1]], [1.0], abscissa=lift)], steps=4)
    with pytest.raises(sg.InputError, match="abscissa response takes gradient='ddm'"):
        sg.fit(pb, ["E"], [curve], steps=4, method="L-BFGS-B", gradient="adjoint")
