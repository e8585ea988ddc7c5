"""Obstacles along load paths: a motion made of legs, each a vector times its
ramp (Ramp, Table), in 2-D and 3-D. Physics first: a held body pressed and then
slid along by an obstacle is the same problem as the body's base moved the
opposite way against a fixed obstacle (linearised kinematics: the same
tractions, status and sensitivities); an elastic body loaded and unloaded
comes back; the sensitivities to the legs' values are the FD of the solves."""

import numpy as np
import pytest

import signorini as sg
from signorini.contact import AugmentedLagrangian, Contact, Coulomb
from signorini.fem.loads import Fixed

PRESS, SLIDE = sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)
PARAMS = {"E": 100.0, "nu": 0.3, "R": 1.0, "d": 0.03, "s": 0.01, "mu": 0.3, "eps": 1600.0}
NAMES = ["d", "s", "mu"]


def problem(dim: int, moving: bool):
    """A block pressed by d then slid by s against a rigid cylinder (2-D) or sphere
    (3-D), with friction: either the obstacle moves along the legs (-d normal,
    then -s along x) and the block's base is held, or the base moves by (s, d)
    along the same ramps and the obstacle stands still."""
    law = Coulomb("mu", "eps", "eps")
    if dim == 2:
        mesh = sg.rectangle(np.linspace(0.0, 2.0, 33), np.linspace(-1.0, 0.0, 9))
        base, top, up = "bottom", "top", 1
        centre = (1.0, lambda p: p["R"])
        legs = (((0.0, lambda p: -p["d"]), PRESS), ((lambda p: -p["s"], 0.0), SLIDE))
        obstacle = sg.Circle(radius="R", centre=centre, motion=legs if moving else (0.0, 0.0))
    else:
        mesh = sg.box(np.linspace(0.0, 2.0, 17), np.linspace(0.0, 1.0, 9), np.linspace(-1.0, 0.0, 4))
        base, top, up = "z0", "z1", 2
        legs = (((0.0, 0.0, lambda p: -p["d"]), PRESS), ((lambda p: -p["s"], 0.0, 0.0), SLIDE))
        obstacle = sg.Sphere(radius="R", centre=(1.0, 0.0, lambda p: p["R"]),
                             motion=legs if moving else (0.0, 0.0, 0.0))
    if moving:
        fixed = [Fixed(base, k) for k in range(dim)]
    else:
        fixed = [Fixed(base, up, "d", ramp=PRESS), Fixed(base, 0, "s", ramp=SLIDE)]
        fixed += [Fixed(base, 1)] if dim == 3 else []
    params = dict(PARAMS, s=0.001) if dim == 3 else dict(PARAMS)  # partial slip in both
    return sg.Problem(mesh, sg.LinearElastic(), params, fixed=fixed,
                      contact=[Contact(obstacle, top, law)])


@pytest.mark.parametrize("dim", [2, 3], ids=["2-D", "3-D"])
def test_an_obstacle_path_is_the_body_moved_the_other_way(dim):
    """Press then slide by the obstacle's legs = the same path by the base's
    supports: tractions, status and sensitivities to d, s, mu equal to 1e-9,
    with stick and slip on the path; the legs' sensitivities = central FD."""
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    a, b = (sg.solve(problem(dim, m), steps=4, wrt=NAMES, options=tight) for m in (True, False))
    ca, cb = a.contact(), b.contact()
    P = a.params
    assert np.array_equal(ca["status"], cb["status"])
    assert {"stick", "slip"} <= set(ca["status"])
    scale = np.abs(ca["p_N"]).max()
    assert scale > 0
    for k in ("p_N", "p_T"):
        assert np.abs(ca[k] - cb[k]).max() <= 1e-9 * scale, k
        for n in NAMES:
            s = np.abs(ca[f"d{k}_d{n}"]).max() + scale / P[n]
            assert np.abs(ca[f"d{k}_d{n}"] - cb[f"d{k}_d{n}"]).max() <= 1e-9 * s, (k, n)
    pb = problem(dim, True)
    for n in ("d", "s"):
        h = 1e-6 * P[n]
        f = [sg.solve(pb.with_params(**{n: P[n] + e * h}), steps=4, options=tight).contact()
             for e in (1, -1)]
        for k in ("p_N", "p_T"):
            fd = (f[0][k] - f[1][k]) / (2 * h)
            assert np.abs(ca[f"d{k}_d{n}"] - fd).max() <= 1e-6 * (np.abs(fd).max() + scale / P[n]), (k, n)


def test_load_and_unload_by_a_table():
    """A frictionless elastic block indented and released by a die moving along a
    Table: at the peak the solution of the monotonic indentation, at the end
    the undeformed block; the peak's sensitivity to d is the monotonic one's."""
    mesh = sg.rectangle(np.linspace(0.0, 2.0, 9), np.linspace(-1.0, 0.0, 5))

    def pb(motion):
        return sg.Problem(mesh, sg.LinearElastic(), {**PARAMS}, fixed=[Fixed("bottom", 0), Fixed("bottom", 1)],
                          contact=[Contact(sg.Circle(radius="R", centre=(1.0, lambda p: p["R"]), motion=motion),
                                           "top", AugmentedLagrangian("eps"))])
    cycle = pb((((0.0, lambda p: -p["d"]), sg.Table((0.0, 0.5, 1.0), (0.0, 1.0, 0.0))),))
    once = pb((0.0, lambda p: -p["d"]))
    a = sg.solve(cycle, steps=4, wrt=["d"])
    b = sg.solve(once, steps=2, wrt=["d"])
    u = b.displacement()
    assert np.abs(a.displacement(1) - u).max() <= 1e-10 * np.abs(u).max()
    assert np.abs(a.displacement_sensitivity("d", 1) - b.displacement_sensitivity("d")).max() <= \
        1e-10 * np.abs(b.displacement_sensitivity("d")).max()
    assert np.abs(a.displacement()).max() <= 1e-12 * np.abs(u).max()


def test_bad_motions():
    with pytest.raises(sg.InputError, match="motion must be 3 values"):
        sg.Sphere(motion=(0.0, 1.0))
    with pytest.raises(sg.InputError, match="each leg of the motion needs a vector of 2"):
        sg.Circle(motion=(((0.0, 0.0, 1.0), PRESS),))
    with pytest.raises(sg.InputError, match="times must increase"):
        sg.Table((0.0, 0.0), (0.0, 1.0))
