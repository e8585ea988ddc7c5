"""Memory estimates (signorini.linsolve.memory): PARDISO's peak memory against
the measured benchmarks (the size guard is in test_bad_inputs.py)."""

import pytest


def test_memory_estimate_of_pardiso_matches_measurements():
    """benchmarks/results: 1.77 GB at 225k DOFs (symmetric), 6.8 GB for the frictional
    Hertz at 1.06M (LU); within 20 %."""
    from signorini.linsolve import memory as resources

    est = lambda n: resources.estimated_peak_memory(n, "pardiso") / resources.GB  # noqa: E731
    assert abs(est(224_848) / 1.77 - 1) < 0.2 and abs(est(1_057_264) / 6.8 - 1) < 0.2


def test_memory_estimates_in_3d_and_with_amg_match_measurements():
    """docs/benchmarks.md, 3-D Hertz: PARDISO 1.55 GB at 68,400 DOFs and 6.21 GB at
    258,048; AMG-GMRES 1.18 GB at 68,400 and 13.6 GB at 1,085,625; within 20 %."""
    from signorini.linsolve import memory as m

    est = lambda n, s: m.estimated_peak_memory(n, s, dim=3) / m.GB  # noqa: E731
    for n, solver, measured in ((68_400, "pardiso", 1.55), (258_048, "pardiso", 6.21),
                                (68_400, "amg", 1.18), (1_085_625, "amg", 13.6)):
        assert abs(est(n, solver) / measured - 1) < 0.2, (n, solver, est(n, solver))
    # a 3-D LU fills in faster than a 2-D one of the same size
    assert m.estimated_peak_memory(1_000_000, "pardiso", 3) > 4 * m.estimated_peak_memory(
        1_000_000, "pardiso", 2)


def test_the_ironing_estimate_counts_the_pairs_kernels(monkeypatch):
    """`signorini ironing --no-fd` peaked at 1.57 GB (refine 0, 2,886 DOFs) and 3.88 GB
    (refine 1, 10,630 DOFs): the candidate pairs, not the unknowns, set its size."""
    from signorini.linsolve import memory as m
    from signorini.problems import ironing

    seen = []

    def capture(n, *, extra, **kw):
        seen.append(m.estimated_peak_memory(n, "pardiso", 2, extra(n)) / m.GB)
        return 0.0

    monkeypatch.setattr(ironing, "check_size", capture)
    for refine, measured in ((0, 1.57), (1, 3.88)):
        ironing.check_mesh_size(refine)
        assert abs(seen[-1] / measured - 1) < 0.2, (refine, seen[-1])


def test_the_largest_size_that_fits_is_the_boundary_of_the_estimate():
    from signorini.linsolve import memory as m

    for solver, dim in (("pardiso", 2), ("pardiso", 3), ("superlu", 2), ("amg", 3)):
        have = 8 * m.GB
        n = m.largest_fitting(have, solver, dim)
        assert m.estimated_peak_memory(n, solver, dim) <= have < m.estimated_peak_memory(
            n + 1, solver, dim)
    assert m.largest_fitting(0.1 * m.GB, "pardiso", 2) == 0  # not even the process fits


def test_a_3d_refusal_suggests_the_iterative_solver_of_the_run():
    """The iterative solver is suggested unless the run uses it: petsc-amg for a run on
    the petsc solver (under mpiexec), amg for the others."""
    from signorini.linsolve.memory import iterative_hint

    assert "--solver amg)" in iterative_hint("pardiso") and "--solver amg)" in iterative_hint("superlu")
    assert "--solver petsc-amg)" in iterative_hint("petsc")
    assert iterative_hint("amg") == iterative_hint("petsc-amg") == ""


def test_the_forging_estimate_counts_the_plastic_history_of_every_increment(monkeypatch):
    """`signorini forging --no-fd` (PARDISO, seven sensitivities) peaked at 1,378,712 kB
    (--mesh 40x80, 51 increments) and 2,167,224 kB (--mesh 64x128, 37 increments after
    its step cuts), against 0.44 and 0.51 GiB for the solver's model alone: within 20 %
    with the J2 kernels and the history kept per increment and sensitivity (349 bytes a
    cell, checked on a small solve). The history makes --steps count: 100x200 with the
    default 50 steps is refused with 4 GB available, 5 steps pass."""
    import numpy as np

    import signorini as sg
    from signorini._jax import jax
    from signorini.errors import ResourceError
    from signorini.linsolve import memory as m
    from signorini.problems import forging

    monkeypatch.setattr(m, "available_memory", lambda: 64.0 * m.GB)
    for mesh, steps, kb in (((40, 80), 51, 1_378_712), ((64, 128), 37, 2_167_224)):
        est = forging.check_mesh_size(mesh, steps=steps, sensitivities=7, solver="pardiso")
        assert abs(est / (kb * 1024) - 1) < 0.2, (mesh, est / m.GB)
    monkeypatch.setattr(m, "available_memory", lambda: 4.0 * m.GB)
    alone = m.estimated_peak_memory(2 * 101 * 201 + 2 * 201, "pardiso") / m.GB
    assert alone < 0.85 * 4.0  # the solver's model alone would have passed it
    with pytest.raises(ResourceError, match=r"forging mesh.*or fewer --steps"):
        forging.forging_problem(mesh=(100, 200), solver="pardiso")
    forging.check_mesh_size((100, 200), steps=5, solver="pardiso")

    def nbytes(tree):
        return sum(np.asarray(a).nbytes for a in jax.tree_util.tree_leaves(tree))

    pb = forging.forging_problem(mesh=(4, 8))
    inc = sg.solve(pb, steps=1, wrt=["mu", "sigma_y"]).increments[-1]
    assert nbytes(inc.state) <= forging.HISTORY_BYTES_PER_CELL * pb.mesh.n_cells
    assert nbytes(inc.state_sens) <= 2 * forging.HISTORY_BYTES_PER_CELL * pb.mesh.n_cells
