"""A library user hears of a suspicious result once, through :mod:`warnings`:
``solution.warnings`` keeps it, a :class:`SignoriniWarning` is raised once per
solve, and the ``signorini`` logger carries it at INFO only, so an API loop with
the warnings filtered prints nothing."""

from __future__ import annotations

import logging
import warnings

import signorini as sg
from signorini.problems import hertz


def _coarse_hertz():
    # a coarse contact zone: fewer closed nodes than the check asks for
    return hertz.hertz_problem(n_fine=4)


def test_suspicious_result_warns_once_and_logs_below_warning(caplog):
    pb = _coarse_hertz()
    with caplog.at_level(logging.DEBUG, logger="signorini"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sol = sg.solve(pb)
    ours = [w for w in caught if issubclass(w.category, sg.SignoriniWarning)]
    assert sol.warnings, "the coarse problem must produce a warning for this test to mean anything"
    assert sorted(str(w.message) for w in ours) == sorted(sol.warnings)
    logged = [r for r in caplog.records if r.getMessage().startswith("warning")]
    assert logged and all(r.levelno == logging.INFO for r in logged)


def test_filtered_warnings_print_nothing_in_a_loop(caplog):
    pb = _coarse_hertz()
    with caplog.at_level(logging.WARNING, logger="signorini"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sg.SignoriniWarning)
            for E in (100.0, 110.0):
                sol = sg.solve(pb.with_params(E=E))
                assert sol.warnings
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
