"""The load-stepping driver solve() (signorini.algorithms.stepping): the
extrapolating predictor changes iterations, not the path; the initial guess
and options are checked; ``until`` stops a path with nominal increments; and
model_for reuses a compiled model for a problem built again from the same
content."""

import numpy as np
import pytest

import signorini as sg
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_predictor_changes_iterations_not_the_path():
    # 30 increments: without a predictor the slipping nodes start every increment on
    # the disc edge, and since they are sent to slip there (Coulomb's tie band) that
    # start costs 53 iterations here against 35 with the predictor (12 increments:
    # 29 against 27; 51 against 27 while the tie was decided by rounding)
    pb = hertz_friction_problem(refine=0)
    names = ["R", "mu", "E"]
    o = dict(steps=30, wrt=names)
    a = sg.solve(pb, options=sg.NewtonOptions(rtol=1e-10, predictor="none"), **o)
    b = sg.solve(pb, options=sg.NewtonOptions(rtol=1e-10, predictor="extrapolate"), **o)
    assert sum(b.newton_iterations) < 0.75 * sum(a.newton_iterations)
    for ia, ib in zip(a.increments, b.increments):
        assert _rel(ib.w, ia.w) < 1e-9
        for n in names:
            assert _rel(ib.sens[n], ia.sens[n]) < 1e-8


def test_initial_guess_is_checked():
    pb = hertz.hertz_problem(n_fine=8, size=8)
    with pytest.raises(sg.InputError, match="initial must be a finite array of shape"):
        sg.solve(pb, start=np.zeros(3))
    with pytest.raises(sg.InputError, match="start must be a signorini.Start"):
        sg.solve(pb, start="coarse")
    with pytest.raises(sg.InputError, match="give the start once"):
        with pytest.warns(DeprecationWarning):
            sg.solve(pb, start=np.zeros(3), initial=np.zeros(3))
    with pytest.raises(sg.InputError, match="predictor"):
        sg.NewtonOptions(predictor="quadratic")
    with pytest.raises(sg.InputError, match=r"DDM\(factorization=...\) must be"):
        sg.solve(pb, method=sg.DDM(factorization="stale"))


def test_until_stops_the_path_with_nominal_increments():
    pb = hertz_friction_problem(refine=0)
    full = sg.solve(pb, steps=6, wrt=["mu"])
    half = sg.solve(pb, steps=6, wrt=["mu"], until=0.5)
    assert [round(i.t, 12) for i in half.increments] == [round(1 / 6, 12), round(2 / 6, 12), 0.5]
    for a, b in zip(half.increments, full.increments):
        assert _rel(a.w, b.w) < 1e-9 and _rel(a.sens["mu"], b.sens["mu"]) < 1e-8
    with pytest.raises(sg.InputError, match="until"):
        sg.solve(pb, until=1.5)


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
    shared = sg.solve(b, wrt=["R"]).increments[-1]
    _MODELS.clear()
    fresh = sg.solve(hertz.hertz_problem({"R": 1.2}), wrt=["R"]).increments[-1]
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


def test_start_spellings_give_the_same_path():
    """``start=w0``, ``start=Start(initial=w0)`` and the deprecated ``initial=w0``
    start Newton at the same point: the same iterations and the same result."""
    pb = hertz.hertz_problem(n_fine=8, size=8)
    base = sg.solve(pb)
    w0 = 0.9 * base.increments[-1].w
    a = sg.solve(pb, start=w0)
    b = sg.solve(pb, start=sg.Start(initial=w0))
    with pytest.warns(DeprecationWarning, match="start=signorini.Start"):
        c = sg.solve(pb, initial=w0)
    assert a.newton_iterations == b.newton_iterations == c.newton_iterations
    assert a.newton_iterations != base.newton_iterations
    np.testing.assert_array_equal(a.increments[-1].w, b.increments[-1].w)
    np.testing.assert_array_equal(a.increments[-1].w, c.increments[-1].w)
    np.testing.assert_allclose(a.increments[-1].w, base.increments[-1].w, rtol=0, atol=1e-9)
