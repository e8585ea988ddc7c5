"""A library user hears of a suspicious result once, through :mod:`warnings`:
``solution.warnings`` keeps it, a :class:`SignoriniWarning` is raised once per
solve, and the ``signorini`` logger carries it at INFO only, so an API loop with
the warnings filtered prints nothing."""

from __future__ import annotations

import logging
import re
import warnings

import numpy as np
import pytest

import signorini as sg
from signorini.model import checks
from signorini.problems import hertz, hertz3d


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


# --- the coarse-path warning of friction counts rings of nodes (issue 51, item 5) -----------


def _coarse_path(sol):
    return [w for w in sol.warnings if "grew by" in w]


def _quarter_model():
    # 3-D frictional Hertz on a small quarter model: its grid puts nodes (i, j) and
    # (j, i) at equal distance from the contact centre, and they close together
    return hertz3d.hertz3d_problem({"mu": 0.3}, n_fine=6, size=3.0)


def _solve(pb, steps):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sg.SignoriniWarning)
        return sg.solve(pb, steps=steps)


def test_rings_count_nodes_at_equal_distance_once():
    h = np.ones(6)
    p = np.array([3.0, 2.0, 2.0, 0.0, 0.0, 0.0])
    # a full 2-D model: a node and its mirror image are one ring
    x = np.array([[0.0, 0], [-1, 0], [1, 0], [-2, 0], [2, 0], [3, 0]])
    assert checks.closing_rings(x, np.array([0, 0, 0, 1, 1, 0], bool), p, h) == 1
    assert checks.closing_rings(x, np.array([0, 0, 0, 1, 1, 1], bool), p, h) == 2
    # a half model: one node is one ring, as the node count the threshold was calibrated on
    xh = np.array([[0.0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [5, 0]])
    assert checks.closing_rings(xh, np.array([0, 0, 0, 1, 1, 0], bool), p, h) == 2
    # no node at the centre: the two nodes of largest pressure share it
    xe = np.array([[-0.5, 0], [0.5, 0], [-1.5, 0], [1.5, 0], [2.5, 0], [-2.5, 0]])
    pe = np.array([3.0, 3.0, 2.0, 2.0, 0.0, 0.0])
    assert checks.closing_rings(xe, np.array([0, 0, 0, 0, 1, 1], bool), pe, h) == 1
    # a quarter grid in 3-D: (5, 0), (4, 3), (3, 4), (0, 5) are one ring, (5, 1) another
    xq = np.array([[0.0, 0, 0], [5, 0, 0], [4, 3, 0], [3, 4, 0], [0, 5, 0], [5, 1, 0]])
    pq = np.array([3.0, 0, 0, 0, 0, 0])
    assert checks.closing_rings(xq, np.array([0, 1, 1, 1, 1, 0], bool), pq, h) == 1
    assert checks.closing_rings(xq, np.array([0, 1, 1, 1, 1, 1], bool), pq, h) == 2


def test_a_travelling_zone_counts_rows_across_its_travel():
    """A die slid along x closes its nodes row by row: the nodes of one x (across
    the travel) are one ring, whatever their distance from the centre."""
    h = np.ones(7)
    x = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0], [2, 0, 0], [2, 1, 0], [2, 2, 0]])
    p = np.array([3.0, 0, 0, 0, 0, 0, 0])
    new = np.array([0, 1, 1, 1, 0, 0, 0], bool)
    assert checks.closing_rings(x, new, p, h) == 3  # about the centre: three radii
    along = np.array([1.0, 0.0, 0.0])
    assert len(checks.ring_distances(x, new, p, h, direction=along)[1]) == 1
    # the direction is estimated from the zone's path: a tilt of 1.4 degrees (ironing3d's)
    tilted = np.array([1.0, -0.024, 0.0]) / np.hypot(1.0, 0.024)
    assert len(checks.ring_distances(x, new, p, h, direction=tilted)[1]) == 1
    assert len(checks.ring_distances(x, ~np.eye(7, dtype=bool)[0], p, h, direction=along)[1]) == 2


def _roller(steps):
    """A rigid roller (a cylinder across a thin block) pressed, then slid along it
    by 2 with friction and finite kinematics: the contact zone travels."""
    press, slide = sg.Ramp(0.0, 0.2), sg.Ramp(0.2, 1.0)
    mesh = sg.box(np.linspace(0, 4, 33), np.linspace(0, 0.25, 3), np.linspace(-0.5, 0, 5))
    roller = sg.Cylinder(radius="R", centre=(1.0, 0.0, lambda p: p["R"]), axis=(0.0, 1.0, 0.0),
                         motion=(((0.0, 0.0, lambda p: -p["d"]), press),
                                 ((lambda p: p["s"], 0.0, 0.0), slide)))
    pb = sg.Problem(mesh, sg.LinearElastic(), {"E": 100.0, "nu": 0.3, "R": 1.0, "d": 0.03, "s": 2.0,
                                               "mu": 0.3, "eps": 800.0},
                    fixed=[sg.Fixed("z0", k) for k in range(3)],
                    contact=[sg.Contact(roller, "z1", sg.Coulomb("mu", "eps", "eps"), kinematics="finite")])
    return _solve(pb, steps)


@pytest.mark.timeout(300)
def test_a_sliding_roller_warns_by_rows_and_its_advice_clears_it():
    """The zone moves four rows per increment at 5 increments: 'grew by 3 rings'
    (rows of 3 nodes across the block), and the advised count clears it (counted
    about the centre, the rows' nodes were rings of their own and the advice,
    followed, asked for ever more)."""
    (message,) = _coarse_path(_roller(5))
    rings, nodes = map(int, re.search(r"grew by (\d+) rings of nodes \((\d+) nodes\)", message).groups())
    assert nodes == 3 * rings and rings > 1
    steps = int(re.search(r"--steps (\d+)\)", message).group(1))
    assert not _coarse_path(_roller(steps)), "following the advice must clear the warning"


@pytest.mark.timeout(300)
def test_symmetric_quarter_model_clears_with_more_increments():
    """The old node count warned on this mesh at 10, 20 and 40 increments (pairs of
    nodes at equal radius, 'grew by 2 nodes', however small the step); rings of
    nodes clear with 20."""
    assert not _coarse_path(_solve(_quarter_model(), 20))


@pytest.mark.timeout(300)
def test_coarse_quarter_path_warns_and_its_advice_clears_it():
    pb = _quarter_model()
    with pytest.warns(sg.SignoriniWarning) as rec:
        coarse = sg.solve(pb, steps=3)
    (message,) = _coarse_path(coarse)
    assert any(str(w.message) == message for w in rec)
    assert "rings of nodes" in message and "use more load increments" in message
    rings = int(re.search(r"grew by (\d+) rings", message).group(1))
    assert rings > checks.MAX_NEW_CONTACT_RINGS
    steps = int(re.search(r"--steps (\d+)\)", message).group(1))
    assert steps > 3
    assert not _coarse_path(_solve(pb, steps)), "following the advice must clear the warning"


@pytest.mark.timeout(300)
def test_half_model_in_2d_counts_nodes_and_its_advice_clears_it():
    """hertz-friction is a half model: a ring is one node, so the warning fires where
    the node count fired (3 increments, test_bad_inputs) and its advice clears it."""
    from signorini.problems import hertz_friction as hf
    pb = hf.hertz_friction_problem()
    (message,) = _coarse_path(_solve(pb, 3))
    rings, nodes = map(int, re.search(r"grew by (\d+) rings of nodes \((\d+) nodes\)", message).groups())
    assert rings == nodes > 1
    steps = int(re.search(r"--steps (\d+)\)", message).group(1))
    assert not _coarse_path(_solve(pb, steps))


@pytest.mark.timeout(300)
def test_a_failed_solve_keeps_the_warnings_of_its_converged_increments(monkeypatch):
    """The coarse-path warning is given at the end of a solve; a solve that fails
    in its last increment still carries it on the converged increments it keeps."""
    from signorini.algorithms import newton as newton_module
    from signorini.algorithms import stepping

    pb = _quarter_model()
    real = stepping.newton

    def fails_at_the_end(model, pattern, lin, w, params, t, *args, **kw):
        if t > 0.99:
            raise newton_module.StepFailure("made to fail in this test", fatal=True)
        return real(model, pattern, lin, w, params, t, *args, **kw)

    monkeypatch.setattr(stepping, "newton", fails_at_the_end)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sg.SignoriniWarning)
        with pytest.raises(sg.ConvergenceError) as e:
            sg.solve(pb, steps=3)
    partial = e.value.partial
    assert len(partial.increments) == 2
    assert len(_coarse_path(partial)) == 1
