"""The direct differentiation method (signorini.sensitivity.ddm): the element
pseudo-load of a linear body from dK_e/dphi kept along a path, the modulus'
pseudo-load as the internal force over E, the pseudo-load on the designed
element parameters only, and the reused DDM factorisation: each gives the
sensitivities of the plain JVP / exact factorisation."""

import numpy as np
import pytest

import signorini as sg
from signorini.params import as_jax
from signorini.problems import hertz
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for

TIGHT = sg.NewtonOptions(rtol=1e-11)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("friction", [False, True])
def test_kept_stiffness_derivative_gives_the_jvp_pseudo_load(friction, monkeypatch):
    """Along a load path a linear body's element pseudo-load is (dK_e/dphi) u_e +
    K_e du_e/dphi with dK_e/dphi computed once: the same sensitivities as the JVP
    of the element kernels every increment, for material, shape-free contact and
    prescribed-motion parameters."""
    from signorini.sensitivity.ddm import DDM
    from helpers import pressed_block

    pb = pressed_block(friction)
    names = ["d", "s", "E", "nu", "R"] + (["mu"] if friction else [])
    o = sg.NewtonOptions(rtol=1e-12)
    kept = sg.solve(pb, steps=4, wrt=names, options=o, solver="superlu")
    ddm = sg.solve.__globals__["ddm_for"](kept.model, names)
    # dK_e/dphi was kept for nu; for E it is K_e / E (the elastic stress is proportional to E)
    assert ddm._dke is not None and ddm._dke[1] == ("nu",) and ddm._proportional == "E"
    monkeypatch.setattr(DDM, "_linear_pseudo", lambda *a: False)  # the JVP every increment
    jvp = sg.solve(pb, steps=4, wrt=names, options=o, solver="superlu")
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
        fast = sg.solve(pb, steps=steps, wrt=names, options=o)
        with monkeypatch.context() as mp:
            mp.setattr(ddm_mod, "proportional_parameter", lambda m: None)
            _MODELS.clear()
            jvp = sg.solve(pb, steps=steps, wrt=names, options=o)
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


def test_element_pseudo_load_of_the_element_programs_equals_the_whole_mesh_jvp():
    """The internal-force pseudo-load from the element kind's chunked programs, on
    the element parameters alone (material and shape; the displacements held),
    is the JVP of the model's pure residual over the whole mesh with a one-hot
    tangent on every parameter and a zero one on the displacements."""
    import dataclasses

    from signorini._jax import jax, jnp
    from signorini.params import unit_tangents

    base = hertz.hertz_problem(n_fine=8)
    X = base.mesh.nodes
    V = np.column_stack([X[:, 0] * X[:, 1], np.sin(X[:, 0])])  # a shape field
    pb = dataclasses.replace(base, shape={**base.shape, "h": V}, params={**base.params, "h": 0.0},
                             shape_nominal={**base.shape_nominal, "h": 0.0})
    names = ["E", "nu", "h"]
    sol = sg.solve(pb, wrt=names)
    m, p = model_for(pb), as_jax(pb.params)
    w = jnp.asarray(sol.increments[-1].w)
    e = unit_tangents(p, names)
    f = lambda p_: m.residual(w, p_, 1.0, None, None, "elements")
    full = np.asarray(jax.vmap(lambda d: jax.jvp(f, (p,), (d,))[1])(e))
    cells = m.scatter(m.element_jvp("update", (0,), w, p, None, np.zeros((3, m.n_dof)), e, None)[0])
    for k in range(3):
        assert np.max(np.abs(full[k])) > 0
        assert np.max(np.abs(cells[k] - full[k])) <= 1e-12 * np.max(np.abs(full[k])), names[k]


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
    alone = sg.solve(pb, wrt=["E"]).increments[-1].sens["E"]
    among = sg.solve(pb, wrt=["h", "E", "nu"]).increments[-1].sens["E"]
    assert np.max(np.abs(alone)) > 0
    assert np.max(np.abs(alone - among)) <= 1e-12 * np.max(np.abs(among))


def test_reused_ddm_factorisation_is_exact_to_round_off():
    pb = hertz_friction_problem(refine=0)
    names = ["R", "mu", "E"]
    o = dict(steps=12, wrt=names, options=sg.NewtonOptions(rtol=1e-10))
    a = sg.solve(pb, method=sg.DDM(factorization="exact"), **o)
    b = sg.solve(pb, method=sg.DDM(factorization="reuse"), **o)
    assert sum(inc.timing["reused_factorization"] for inc in b.increments) >= 6
    assert not any(inc.timing["reused_factorization"] for inc in a.increments)
    for ia, ib in zip(a.increments, b.increments):
        for n in names:
            assert _rel(ib.sens[n], ia.sens[n]) < 1e-9
