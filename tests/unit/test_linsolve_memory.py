"""Memory estimates (signorini.linsolve.memory): PARDISO's peak memory against
the measured benchmarks (the size guard is in test_bad_inputs.py)."""


def test_memory_estimate_of_pardiso_matches_measurements():
    """benchmarks/results: 1.77 GB at 225k DOFs (symmetric), 6.8 GB for the frictional
    Hertz at 1.06M (LU); within 20 %."""
    from signorini.linsolve import memory as resources

    est = lambda n: resources.estimated_peak_memory(n, "pardiso") / resources.GB  # noqa: E731
    assert abs(est(224_848) / 1.77 - 1) < 0.2 and abs(est(1_057_264) / 6.8 - 1) < 0.2
