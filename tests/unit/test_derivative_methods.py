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
    with pytest.warns(DeprecationWarning, match=r"Objective\(gradient_mode=...\)"), \
            pytest.warns(DeprecationWarning, match=r"Objective\(fd_step=...\)"):
        f = Objective(problem, names, hertz.contact_work, gradient_mode="fd", fd_step=1e-5, options=TIGHT)
    assert f.method == sg.FiniteDifferences(rel_step=1e-5)
    assert f.jac(x) == pytest.approx(d.jac(x), rel=1e-5)


# The 0.1 keywords below have no other test (the rest of the suite asks in the 0.2
# spelling, and pyproject.toml makes our DeprecationWarnings errors elsewhere).
# SuperLU: two solves of the same problem are the same bit for bit.


def test_old_solve_keywords_are_the_method_objects():
    """solve(ddm_factorization=) is method=DDM(factorization=...); solve(checkpoint=,
    keep_factors=True) is method=Adjoint(checkpoint=..., factors="store")."""
    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    o = dict(steps=4, options=sg.NewtonOptions(rtol=1e-10), solver="superlu")
    new = _no_deprecation(sg.solve, pb, wrt=["R", "mu"], method=sg.DDM(factorization="reuse"), **o)
    with pytest.warns(DeprecationWarning, match=r"solve\(ddm_factorization=...\).*DDM\(factorization="):
        old = sg.solve(pb, wrt=["R", "mu"], ddm_factorization="reuse", **o)
    reused = [inc.timing["reused_factorization"] for inc in new.increments]
    assert any(reused) and [inc.timing["reused_factorization"] for inc in old.increments] == reused
    for a, b in zip(old.increments, new.increments):
        for n in ("R", "mu"):
            np.testing.assert_array_equal(a.sens[n], b.sens[n])
    new = _no_deprecation(sg.solve, pb, method=sg.Adjoint(factors="store", checkpoint=2), **o)
    with pytest.warns(DeprecationWarning) as caught:
        old = sg.solve(pb, keep_factors=True, checkpoint=2, **o)
    assert {str(w.message).split("=")[0] for w in caught if w.category is DeprecationWarning} >= {
        "signorini.solve(keep_factors", "signorini.solve(checkpoint"}
    for sol in (old, new):
        assert all(inc.factor is not None for inc in sol.increments)
        assert [inc.state is not None for inc in sol.increments] == [False, True, False, True]
    for a, b in zip(old.increments, new.increments):
        np.testing.assert_array_equal(a.w, b.w)


def test_old_guide_keyword_is_start(problem):
    """solve(guide=coarse) is start=Start(guide=coarse): the same start, the same path."""
    o = dict(steps=2, options=TIGHT, solver="superlu")
    base = _no_deprecation(sg.solve, problem, **o)
    near = problem.with_params(R=problem.params["R"] * (1 + 1e-6))
    new = _no_deprecation(sg.solve, near, start=sg.Start(guide=base), **o)
    with pytest.warns(DeprecationWarning, match=r"solve\(guide=...\).*start=signorini.Start"):
        old = sg.solve(near, guide=base, **o)
    assert old.newton_iterations == new.newton_iterations
    assert new.newton_iterations != _no_deprecation(sg.solve, near, **o).newton_iterations
    for a, b in zip(old.increments, new.increments):
        np.testing.assert_array_equal(a.w, b.w)


def test_old_gradient_keywords_fd_step_factors_checkpoint(problem):
    """gradient(mode="fd", fd_step=h) is FiniteDifferences(rel_step=h); gradient(factors=,
    checkpoint=) is Adjoint(factors=..., checkpoint=...)."""
    kw = dict(steps=2, options=TIGHT, solver="superlu")
    new = _no_deprecation(sg.gradient, problem, hertz.contact_work, ["E"],
                          method=sg.FiniteDifferences(rel_step=1e-3), **kw)
    with pytest.warns(DeprecationWarning, match=r"gradient\(mode=...\)"), \
            pytest.warns(DeprecationWarning, match=r"gradient\(fd_step=...\).*rel_step"):
        old = sg.gradient(problem, hertz.contact_work, ["E"], mode="fd", fd_step=1e-3, **kw)
    assert old.mode == "fd" and old["E"] == new["E"]
    # the old step was relative (E = 100: h = 0.1), not the absolute step= (h = 1e-3)
    assert problem.params["E"] == 100.0
    absolute = _no_deprecation(sg.gradient, problem, hertz.contact_work, ["E"],
                               method=sg.FiniteDifferences(step=1e-3), **kw)
    assert absolute["E"] != old["E"]
    pb = hertz_friction.hertz_friction_problem(n_fine=12)  # a history state to checkpoint
    new = _no_deprecation(sg.gradient, pb, hertz.contact_work, ["R", "mu"],
                          method=sg.Adjoint(factors="store", checkpoint=2), **kw)
    with pytest.warns(DeprecationWarning, match=r"gradient\(factors=...\)"), \
            pytest.warns(DeprecationWarning, match=r"gradient\(checkpoint=...\)"):
        old = sg.gradient(pb, hertz.contact_work, ["R", "mu"], factors="store", checkpoint=2, **kw)
    assert old.mode == "adjoint"
    np.testing.assert_array_equal(old.as_array(), new.as_array())
    assert old.memory == new.memory
    assert new.memory["factors_kept"] == 2 and new.memory["states_kept"] == 1


def test_old_objective_names_keyword_is_wrt(problem):
    names = ["R", "E"]
    x = np.array([problem.params[n] for n in names])
    new = _no_deprecation(Objective, problem, wrt=names, response=hertz.contact_work, options=TIGHT,
                          solver="superlu")
    with pytest.warns(DeprecationWarning, match=r"Objective\(names=...\).*wrt="):
        old = Objective(problem, names=names, response=hertz.contact_work, options=TIGHT,
                        solver="superlu")
    assert old.names == new.names == names and old.method == new.method == sg.DDM()
    np.testing.assert_array_equal(old.jac(x), new.jac(x))


def test_old_solve_uzawa_sensitivities_keyword_is_wrt():
    import dataclasses

    from signorini.algorithms.uzawa import solve_uzawa
    from signorini.contact.uzawa import UzawaPenalty

    pb = hertz.hertz_problem(n_fine=8, size=8)
    c = pb.contact[0]
    pu = dataclasses.replace(pb, contact=(sg.Contact(c.obstacle, c.edges, UzawaPenalty("eps")),))
    o = dict(options=TIGHT, tol=1e-10, solver="superlu")
    new = _no_deprecation(solve_uzawa, pu, wrt=["R"], **o)
    with pytest.warns(DeprecationWarning, match=r"solve_uzawa\(sensitivities=...\).*wrt="):
        old = solve_uzawa(pu, sensitivities=["R"], **o)
    assert len(old.sens_history["R"]) == len(new.sens_history["R"]) > 1
    np.testing.assert_array_equal(old.lam_sens["R"], new.lam_sens["R"])
    np.testing.assert_array_equal(old.sens["R"], new.sens["R"])


@pytest.mark.parametrize("old,new", [("signorini.obstacles", "signorini.contact.obstacles"),
                                     ("signorini.multilevel", "signorini.algorithms.coarse_to_fine"),
                                     ("signorini.mesh", "signorini.fem.mesh"),
                                     ("signorini.cli", "signorini.app.cli")])
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


def test_an_old_module_name_as_an_attribute_of_the_package():
    """``sg.mesh`` (an attribute, no import statement) is the new module, with the warning."""
    sys.modules.pop("signorini.mesh", None)
    vars(sg).pop("mesh", None)  # bound by an earlier import of the old path
    with pytest.warns(DeprecationWarning, match="signorini.mesh moved to signorini.fem.mesh"):
        mod = sg.mesh
    assert mod is importlib.import_module("signorini.fem.mesh")
