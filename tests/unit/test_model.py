"""The compiled model (signorini.model.kernels.Model): element kernels run in
chunks of cells equal one vmap, a linear body's stiffness computed once equals
the kernel's, and the kept element stiffness (and the DDM's dK_e/dphi) follows
the element parameters only."""

import numpy as np

import signorini as sg
from signorini.params import as_jax
from signorini.problems.hertz_friction import hertz_friction_problem
from signorini.algorithms.stepping import model_for


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_element_kernels_in_chunks_equal_one_vmap(monkeypatch):
    """Large meshes run the element kernels over chunks of cells (lax.map of
    vmaps, the last chunk padded): forced on a small forging (F-bar, J2
    history, axisymmetric, 200 cells in chunks of 16) the load path, its
    history and its shape sensitivities are those of one vmap."""
    from signorini.problems import forging
    from signorini.model import kernels

    names = ["phi1", "E"]
    from signorini.algorithms.stepping import _MODELS

    ref_pb, pb = forging.forging_problem(), forging.forging_problem()
    kw = dict(options=forging.options(), steps=4, wrt=names)
    ref_m = model_for(ref_pb)
    ref = sg.solve(ref_pb, **kw)
    _MODELS.clear()  # the same problem would share ref_m: a second model
    m = model_for(pb)
    assert m is not ref_m
    key = m._program_key()
    m.CELL_CHUNK, m.CHUNKED_FROM = 16, 0
    # the chunking is part of the programs' key on disk: with ref_m's key it would
    # load ref_m's executables (one vmap) and never trace the chunks
    assert m.key == ref_m.key and m._program_key() != key
    # compiled here and not kept, so that its chunks are traced on every run
    monkeypatch.setenv("SIGNORINI_PROGRAM_CACHE", "0")
    assert len(m.conn) % 16 != 0  # a padded last chunk
    traced = []
    over_cells = kernels.Model._over_cells
    monkeypatch.setattr(kernels.Model, "_over_cells",
                        lambda self, *a: traced.append(self is m) or over_cells(self, *a))
    got = sg.solve(pb, **kw)
    assert any(traced)  # the chunked model's own programs ran
    p = as_jax(pb.params)
    # the kernels at one state: the same numbers up to the order of summation
    inc, st = ref.increments[-1], ref.increments[-2].state
    (R1, b1), (R2, b2) = (mm.local_tangents(inc.w, p, inc.t, st) for mm in (ref_m, m))
    assert np.max(np.abs(R1 - R2)) <= 1e-13 * np.max(np.abs(R1))
    # (the element blocks: 1.36e-14 of the largest on one host's Xeon, whose vector
    # code orders the Gauss sums of the two compilations differently; the residual's bound)
    for x, y in zip(b1, b2):
        assert np.max(np.abs(x - y)) <= 1e-13 * np.max(np.abs(x))
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
    assert np.isclose(m._ke[1][0, 0, 0] / b1[0][0, 0, 0], 1.5)


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
    kw = {"steps": 3, "wrt": ["E", "nu", "mu", "R"], "solver": "superlu"}
    names = kw["wrt"]  # dK_e/dphi kept for nu (E's is K_e / E)
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
