"""Obstacles along load paths: a motion made of legs, each a vector times its
ramp (Ramp, Table), in 2-D and 3-D. Physics first: a held body pressed and then
slid along by an obstacle is the same problem as the body's base moved the
opposite way against a fixed obstacle (linearised kinematics: the same
tractions, status and sensitivities); an elastic body loaded and unloaded
comes back; the sensitivities to the legs' values are the FD of the solves.
A 3-D obstacle also turns along legs: a spinning die carries what sticks to it
(exactly, with the rotation's sensitivity), a plane turned on the path is the
plane placed turned."""

import numpy as np
import pytest

import signorini as sg
import jax.numpy as jnp
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


def spun_die(phi_ramp, mu=50.0, plane=None):
    """A block (base held) pressed by a flat die by d, which then turns about
    the z axis by phi: legs ((0, 0, -d), PRESS) and rotation ((0, 0, phi), ...)."""
    mesh = sg.box(np.linspace(-1.0, 1.0, 5), np.linspace(-1.0, 1.0, 5), np.linspace(-1.0, 0.0, 3))
    die = plane or sg.Plane(point=(0.0, 0.0, 0.0), normal_vector=(0.0, 0.0, -1.0),
                            motion=(((0.0, 0.0, lambda p: -p["d"]), PRESS),),
                            rotation=(((0.0, 0.0, "phi"), phi_ramp),))
    law = Coulomb("mu", "eps", "eps") if mu else AugmentedLagrangian("eps")
    return sg.Problem(mesh, sg.LinearElastic(), {**PARAMS, "mu": mu, "phi": 0.02},
                      fixed=[Fixed("z0", k) for k in range(3)], contact=[Contact(die, "z1", law)])


def test_a_spinning_die_carries_the_stuck_surface():
    """Pressed (every top node sticks where it closed, at its reference x, y),
    then turned by phi about z: each top node's (x, y) is the die's rotation of
    its reference (x, y), and its sensitivity to phi the rotation's derivative
    (exact: the stick condition g_T = 0 holds at convergence)."""
    pb = spun_die(SLIDE)
    sol = sg.solve(pb, steps=4, wrt=["phi", "d"])
    assert set(sol.contact()["status"]) == {"stick"}
    top = pb.mesh.node_sets["z1"]
    X = pb.mesh.nodes[top]
    phi = sol.params["phi"]
    c, s = np.cos(phi), np.sin(phi)
    u = sol.displacement()[top]
    expect = np.column_stack([c * X[:, 0] - s * X[:, 1], s * X[:, 0] + c * X[:, 1]]) - X[:, :2]
    assert np.abs(u[:, :2] - expect).max() <= 1e-10 * phi
    du = sol.displacement_sensitivity("phi")[top]
    dexpect = np.column_stack([-s * X[:, 0] - c * X[:, 1], c * X[:, 0] - s * X[:, 1]])
    assert np.abs(du[:, :2] - dexpect).max() <= 1e-9
    assert np.abs(sol.displacement_sensitivity("d")[top][:, :2]).max() <= 1e-9


def test_a_spinning_die_with_slip_ddm_equals_fd():
    """The spinning die with mu = 0.3 (the rim slips, the centre sticks): the
    tractions' sensitivities to the angle phi and to the press d = central FD."""
    tight = sg.NewtonOptions(rtol=1e-13, step_tol=1e-11)
    pb = spun_die(SLIDE, mu=0.3)
    c = sg.solve(pb, steps=4, wrt=["phi", "d"], options=tight).contact()
    assert {"stick", "slip"} <= set(c["status"])
    P = pb.params
    for n in ("phi", "d"):
        h = 1e-6 * P[n]
        f = [sg.solve(pb.with_params(**{n: P[n] + e * h}), steps=4, options=tight).contact()
             for e in (1, -1)]
        for k in ("p_N", "p_T"):
            fd = (f[0][k] - f[1][k]) / (2 * h)
            assert np.abs(c[f"d{k}_d{n}"] - fd).max() <= 1e-6 * np.abs(fd).max(), (k, n)


def test_a_plane_turned_on_the_path_is_the_plane_placed_turned():
    """Frictionless and elastic (the end state depends on the end pose only): a die
    pressed by d while it turns by phi about x through its point gives, at the
    end, the solution and sensitivities to d and phi of the die standing at the
    end pose (normal (0, sin phi, -cos phi)) pressed by d."""
    turned = spun_die(sg.Ramp(0.0, 1.0), mu=0.0, plane=sg.Plane(
        point=(0.0, 0.0, 0.0), normal_vector=(0.0, 0.0, -1.0), motion=(0.0, 0.0, lambda p: -p["d"]),
        rotation=("phi", 0.0, 0.0)))
    placed = spun_die(None, mu=0.0, plane=sg.Plane(
        point=(0.0, 0.0, 0.0), motion=(0.0, 0.0, lambda p: -p["d"]),
        normal_vector=(0.0, lambda p: jnp.sin(p["phi"]), lambda p: -jnp.cos(p["phi"]))))
    a, b = (sg.solve(pb.with_params(phi=0.1), steps=3, wrt=["d", "phi"]) for pb in (turned, placed))
    ca, cb = a.contact(), b.contact()
    scale = ca["p_N"].max()
    assert scale > 0 and np.array_equal(ca["p_N"] > 0, cb["p_N"] > 0) and (ca["p_N"] == 0).any()
    assert np.abs(ca["p_N"] - cb["p_N"]).max() <= 1e-10 * scale
    for n in ("d", "phi"):
        ua, ub = a.displacement_sensitivity(n), b.displacement_sensitivity(n)
        assert np.abs(ua - ub).max() <= 1e-10 * np.abs(ub).max(), n
        assert np.abs(ca[f"dp_N_d{n}"] - cb[f"dp_N_d{n}"]).max() <= 1e-9 * np.abs(cb[f"dp_N_d{n}"]).max()


def test_bad_motions():
    with pytest.raises(sg.InputError, match="motion must be 3 values"):
        sg.Sphere(motion=(0.0, 1.0))
    with pytest.raises(sg.InputError, match="each leg of the motion needs a vector of 2"):
        sg.Circle(motion=(((0.0, 0.0, 1.0), PRESS),))
    with pytest.raises(sg.InputError, match="times must increase"):
        sg.Table((0.0, 0.0), (0.0, 1.0))
    with pytest.raises(sg.InputError, match=r"Plane \(rotation\): motion must be 3 values"):
        sg.Plane(rotation=(0.0, 1.0))
    with pytest.raises(sg.InputError, match="a rotation needs a 3-D obstacle"):
        sg.Implicit(lambda y, p: y[1], origin=(0.0, 0.0), rotation=(0.0, 0.0, 1.0))
