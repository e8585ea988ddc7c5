"""Kernels compiled once per kind and run over chunks of items
(signorini.model.chunks, .cells, .nodes): the same values, derivatives and
cotangents as one vmap over every item, whatever the number of items (full
chunks, a padded last chunk, both chunk sizes)."""

import numpy as np
import pytest

from signorini._jax import jax
from signorini.fem import element, kinematics
from signorini.materials import J2Plasticity, LinearElastic
from signorini.model import chunks
from signorini.model.cells import CellKernels

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _cells(n, rng):
    Xe = SQUARE[None] * rng.uniform(0.5, 1.5, (n, 1, 1)) + rng.normal(0, 0.05, (n, 4, 2)) + 2.0
    ue = rng.normal(0, 1e-2, (n, 4, 2))
    return ue, Xe


def test_plan_covers_every_item_once():
    for n in (1, 511, 512, 513, 4095, 4096, 4097, 9000):
        p = chunks.plan(n, (4096, 512))
        covered = np.concatenate([np.arange(s, s + c) for s, c in p])
        assert covered[:n].tolist() == list(range(n)) and len(covered) - n < 512
        assert sum(c == 4096 for _, c in p) == n // 4096


# 4096 + 700 = a full chunk of 4096, five full chunks of 128 and a padded last one
# of 60: every kind of chunk at once (300 cells, the small chunks alone, compiled
# the references again for 35 s; meshes with small chunks only run through the
# kinds' programs in test_whole_mesh_and_kind_programs_give_the_same_solution)
@pytest.mark.parametrize("n", [4096 + 700])
def test_cell_kernels_equal_one_vmap(n):
    """Values, a batched JVP and a VJP of the element kernel of an axisymmetric
    J2 F-bar body, through the chunks, against one vmap over all cells."""
    assert chunks.plan(n, CellKernels.SIZES) == [(0, 4096)] + [(4096 + 128 * k, 128) for k in range(6)]
    rng = np.random.default_rng(n)
    mat, kin, form = J2Plasticity(), kinematics.AXISYMMETRIC, element.FBar()
    mp = {"E": 200.0, "nu": 0.3, "sigma_y": 0.4, "H": 2.0}
    ue, Xe = _cells(n, rng)
    he = np.broadcast_to(mat.initial_state(), (n, 4, mat.n_state)).copy()
    k = CellKernels.of(mat, kin, form)
    f = lambda u, X, m, h: element.element_update(u, X, mat, m, h, kin, form)
    # compiled as one program (its JVP and VJP too): run op by op, the reference
    # dispatched every primitive of the J2 return map on its own (30-40 s cold)
    whole = jax.jit(jax.vmap(f, (0, 0, None, 0)))
    r, h = k("update", (0, 1), (ue, Xe, he), mp)
    r0, h0 = whole(ue, Xe, mp, he)
    np.testing.assert_allclose(r, np.asarray(r0).reshape(n, 8), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(h, h0, rtol=1e-13, atol=1e-15)
    # JVP along two directions: displacements and E
    du = rng.normal(size=(2, n, 4, 2))
    dmp = {key: np.array([0.0, 1.0]) if key == "E" else np.zeros(2) for key in mp}
    (dr,) = k.jvp("update", (0,), (ue, Xe, he), mp, (du, None, None, dmp))
    for j in range(2):
        ref = jax.jvp(lambda u, m: whole(u, Xe, m, he)[0], (ue, mp),
                      (du[j], {key: v[j] for key, v in dmp.items()}))[1]
        np.testing.assert_allclose(dr[j], np.asarray(ref).reshape(n, 8), rtol=1e-11,
                                   atol=1e-12 * np.abs(ref).max())
    # VJP: cotangents of the cells' displacements and coordinates, E summed
    c = rng.normal(size=(n, 8))
    (bu, bX, bh), bmp = k.vjp("update", (0,), (ue, Xe, he), mp, (c,))
    ref = jax.vjp(lambda u, X, m: whole(u, X, m, he)[0].reshape(n, 8), ue, Xe, mp)[1](c)
    for got, want in ((bu, ref[0]), (bX, ref[1]), (bmp["E"], ref[2]["E"])):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_kinds_are_shared_and_keyed_by_content():
    a = CellKernels.of(LinearElastic(), kinematics.PLANE_STRAIN, element.Standard())
    b = CellKernels.of(LinearElastic(), kinematics.PLANE_STRAIN, element.Standard())
    c = CellKernels.of(LinearElastic(E="E2"), kinematics.PLANE_STRAIN, element.Standard())
    assert a is b and a is not c and a.key and a.key != c.key


# ------------------------------------------------------------------ both paths
def _solve_both(monkeypatch, run):
    """``run()`` on models evaluated by whole-mesh programs, then on models of the
    same problems evaluated by the element and contact kinds' chunked programs."""
    from collections import OrderedDict

    from signorini.algorithms import stepping
    from signorini.model.kernels import Model

    monkeypatch.setattr(stepping, "_MODELS", OrderedDict())
    whole = run()
    assert not any(m.by_kind for m in stepping._MODELS.values())
    monkeypatch.setattr(stepping, "_MODELS", OrderedDict())
    monkeypatch.setattr(Model, "WHOLE_MESH_UP_TO", -1)
    kinds = run()
    assert all(m.by_kind for m in stepping._MODELS.values())
    return whole, kinds


def _rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.mark.parametrize("case", ["hertz", "friction", pytest.param("forging", marks=pytest.mark.slow)])
def test_whole_mesh_and_kind_programs_give_the_same_solution(monkeypatch, case):
    """A mesh is evaluated by its own whole-mesh programs (small meshes) or by the
    programs of its element and contact kinds (large ones): the two give the
    same solution, sensitivities (DDM, with a linear body's kept stiffness,
    friction history and plastic history) and adjoint gradient, to round-off."""
    import signorini as sg
    from signorini.design.gradient import gradient
    from signorini.problems import forging, hertz, hertz_friction

    if case == "hertz":
        pb, names, steps = hertz.hertz_problem(n_fine=8), ["R", "E", "P"], 2
        resp = hertz.contact_work
        opts = sg.NewtonOptions(rtol=1e-11)
    elif case == "friction":
        pb, names, steps = hertz_friction.hertz_friction_problem(n_fine=12), ["R", "mu", "E"], 3
        resp = hertz.contact_work
        opts = sg.NewtonOptions(rtol=1e-11)
    else:
        pb = forging.forging_problem(mesh=(4, 8))
        names, steps = ["phi0", "phi2", "sigma_y", "mu"], 4
        resp = lambda m: forging.objective(m, forging.lateral_nodes(pb))  # noqa: E731
        opts = forging.options()

    def run():
        sol = sg.solve(pb, steps=steps, wrt=names, options=opts, solver="superlu")
        a = gradient(pb, resp, names, method=sg.Adjoint(), steps=steps, options=opts,
                     solver="superlu", solution=sol)
        stress = sol.stress()
        return sol, a, stress

    (s1, a1, st1), (s2, a2, st2) = _solve_both(monkeypatch, run)
    assert len(s1.increments) == len(s2.increments) == steps
    for i1, i2 in zip(s1.increments, s2.increments):
        assert i1.newton.iterations == i2.newton.iterations
        assert _rel(i2.w, i1.w) < 1e-9
        for n in names:
            assert _rel(i2.sens[n], i1.sens[n]) < 1e-8, n
    for n in names:
        assert abs(a2[n] - a1[n]) <= 1e-8 * abs(a1[n]) + 1e-14, (n, a1[n], a2[n])
    assert _rel(st2[0], st1[0]) < 1e-9
    for n in names:
        assert _rel(st2[1][n], st1[1][n]) < 1e-7, n
