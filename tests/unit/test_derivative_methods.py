"""One way to ask for a derivative: ``DDM()``, ``Adjoint()``, ``FiniteDifferences()``
accepted by ``solve``, ``gradient`` and ``Objective``, one name (``wrt``) for the
parameters; the 0.1 spellings keep working for one release with a
DeprecationWarning that names the new one, and give the same numbers."""

from __future__ import annotations

import importlib
import sys
import warnings

import numpy as np
import pytest

import signorini as sg
from signorini.design.optimize import Objective
from signorini.problems import hertz, hertz_friction

TIGHT = sg.NewtonOptions(rtol=1e-11)


@pytest.fixture(scope="module")
def problem():
    return hertz.hertz_problem(n_fine=12)


def _no_deprecation(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        return fn(*a, **k)


def test_method_objects_check_their_arguments():
    with pytest.raises(sg.InputError, match="factorization"):
        sg.DDM(factorization="cached")
    with pytest.raises(sg.InputError, match="factors"):
        sg.Adjoint(factors="keep")
    with pytest.raises(sg.InputError, match="checkpoint"):
        sg.Adjoint(checkpoint=0)
    with pytest.raises(sg.InputError, match="rel_step"):
        sg.FiniteDifferences(rel_step=-1.0)
    assert sg.FiniteDifferences(step=1e-3).step_for(5.0) == 1e-3
    assert sg.FiniteDifferences(rel_step=1e-4).step_for(5.0) == pytest.approx(5e-4)
    assert sg.FiniteDifferences(rel_step=1e-4).step_for(0.1) == pytest.approx(1e-4)


def test_solve_wrt_and_method(problem):
    new = _no_deprecation(sg.solve, problem, wrt=["R", "E"], method=sg.DDM(factorization="reuse"),
                          options=TIGHT)
    with pytest.warns(DeprecationWarning, match=r"solve\(sensitivities=...\).*wrt="):
        old = sg.solve(problem, sensitivities=["R", "E"], options=TIGHT)
    for n in ("R", "E"):
        d_new, d_old = new.contact()[f"dp_N_d{n}"], old.contact()[f"dp_N_d{n}"]
        assert np.abs(d_new - d_old).max() <= 1e-9 * np.abs(d_old).max()
    with pytest.raises(sg.InputError, match="wrt= has no use"):
        sg.solve(problem, wrt=["R"], method=sg.Adjoint())
    with pytest.raises(sg.InputError, match=r"method=signorini.FiniteDifferences\(\)"):
        sg.solve(problem, method="fd")
    with pytest.raises(sg.InputError, match="DDM"):
        sg.solve(problem, method=sg.FiniteDifferences())
    with pytest.raises(TypeError, match="unexpected keyword argument 'sensitivity'"):
        sg.solve(problem, sensitivity=["R"])


def test_adjoint_keeps_what_the_backward_pass_needs():
    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    sol = _no_deprecation(sg.solve, pb, steps=4, method=sg.Adjoint(factors="store", checkpoint=2),
                          options=sg.NewtonOptions(rtol=1e-10))
    assert all(inc.factor is not None for inc in sol.increments)
    kept = [inc.state is not None for inc in sol.increments]
    assert kept == [False, True, False, True]


def test_gradient_by_each_method_and_by_the_old_keywords(problem):
    names = ["R", "E", "P"]
    kw = dict(steps=1, options=TIGHT)
    ddm = _no_deprecation(sg.gradient, problem, hertz.contact_work, names, method=sg.DDM(), **kw)
    adj = _no_deprecation(sg.gradient, problem, hertz.contact_work, wrt=names, method=sg.Adjoint(), **kw)
    fd = _no_deprecation(sg.gradient, problem, hertz.contact_work, names,
                         method=sg.FiniteDifferences(rel_step=1e-5), **kw)
    for n in names:
        assert abs(adj[n] - ddm[n]) <= 1e-9 * abs(ddm[n])
        assert abs(fd[n] - ddm[n]) <= 1e-5 * abs(ddm[n])
    assert (ddm.mode, adj.mode, fd.mode) == ("ddm", "adjoint", "fd")
    with pytest.warns(DeprecationWarning, match=r"gradient\(mode=...\)"):
        old = sg.gradient(problem, hertz.contact_work, names, mode="ddm", **kw)
    assert old.as_array(names) == pytest.approx(ddm.as_array(names), rel=1e-12)
    with pytest.warns(DeprecationWarning, match=r"gradient\(params=...\)"):
        old = sg.gradient(problem, hertz.contact_work, params=names, **kw)
    assert old.as_array(names) == pytest.approx(adj.as_array(names), rel=1e-12)
    with pytest.raises(sg.InputError, match="give the method once"):
        with pytest.warns(DeprecationWarning):
            sg.gradient(problem, hertz.contact_work, names, method=sg.DDM(), mode="ddm")


def test_objective_wrt_and_method(problem):
    names = ["R", "E"]
    x = np.array([problem.params[n] for n in names])
    a = _no_deprecation(Objective, problem, names, hertz.contact_work, method=sg.Adjoint(), options=TIGHT)
    d = _no_deprecation(Objective, problem, wrt=names, response=hertz.contact_work, options=TIGHT)
    assert a.gradient_mode == "adjoint" and d.gradient_mode == "ddm"
    assert a.jac(x) == pytest.approx(d.jac(x), rel=1e-9)
    with pytest.warns(DeprecationWarning, match=r"Objective\(gradient_mode=...\)"):
        f = Objective(problem, names, hertz.contact_work, gradient_mode="fd", fd_step=1e-5, options=TIGHT)
    assert f.method == sg.FiniteDifferences(rel_step=1e-5)
    assert f.jac(x) == pytest.approx(d.jac(x), rel=1e-5)


@pytest.mark.parametrize("old,new", [("signorini.obstacles", "signorini.contact.obstacles"),
                                     ("signorini.multilevel", "signorini.algorithms.coarse_to_fine")])
def test_old_module_paths_import_the_new_modules_with_a_warning(old, new):
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=f"{old} moved to {new}"):
        mod = importlib.import_module(old)
    assert mod is importlib.import_module(new)
    assert mod.__spec__.name == new  # the real module keeps its own identity (pickling)


@pytest.mark.parametrize("old,new,function", [("signorini.solve", "signorini.algorithms.stepping", "solve"),
                                              ("signorini.gradient", "signorini.design.gradient", "gradient")])
def test_an_old_module_path_named_like_a_function_stays_that_function(old, new, function, problem):
    """``import signorini.solve`` binds the module at ``signorini.solve``, where the
    function is: the deprecated module calls the function and has the module's names."""
    real = getattr(sg, function)
    sys.modules.pop(old, None)
    try:
        with pytest.warns(DeprecationWarning, match=f"{old} moved to {new}"):
            mod = importlib.import_module(old)
        assert getattr(sg, function) is mod and callable(mod)
        assert getattr(mod, function) is real
        assert mod(problem, **({} if function == "solve" else {"response": hertz.contact_work,
                                                                 "wrt": ["E"]})) is not None
    finally:
        sys.modules.pop(old, None)
        setattr(sg, function, real)


def test_the_old_io_module_holds_the_reader_and_the_writers():
    sys.modules.pop("signorini.io", None)
    with pytest.warns(DeprecationWarning, match="signorini.io moved"):
        io = importlib.import_module("signorini.io")
    assert io.read_mesh is sg.read_mesh and io.write_vtu is sg.write_vtu
