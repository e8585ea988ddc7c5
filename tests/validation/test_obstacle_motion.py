"""Physics first: a rigid motion of the whole problem changes nothing.

For every obstacle (cylinder/sphere ``Circle``, straight die/cone ``Line``) x
contact law (augmented Lagrangian, penalty, Coulomb) x contact kinematics
(linearised with a linear elastic body, finite with a neo-Hookean one) x
planar/axisymmetric analysis:

* force control: translating the obstacle by ``s`` along a direction the body
  is free to follow leaves p_N, p_T, the stick/slip status and every
  sensitivity unchanged, and the sensitivity to ``s`` itself is zero;
* displacement control: a body held at its bottom, which moves by
  c = (cx, cy), indented by an obstacle moving by c + (0, -d): the solution
  does not depend on c (in particular, the obstacle moving down by d against
  a held body equals the body pushed up by d against a fixed obstacle), and
  the sensitivities to cx, cy are zero;
* plane strain: the whole problem rotated rigidly gives the same tractions,
  status and sensitivities.

The linearised kinematics (docs/theory.md §6.3) measure the displacement
relative to the obstacle's translation; before that, a moving cylinder changed
the Hertz pressure by 4e-4 and the frictional stick zone by 10 %.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import signorini as sg
from signorini._jax import jnp

# CI (CI=true) runs the pairwise subsets of the combinations below, the others are
# marked slow (_cases)
# the frictional paths are coarse on purpose (3 increments): the same path is compared
pytestmark = pytest.mark.filterwarnings("ignore::signorini.SignoriniWarning")

E, NU, R, MU = 100.0, 0.3, 2.0, 0.3
TIGHT = sg.NewtonOptions(rtol=1e-12)

OBSTACLES = ("circle", "line")
LAWS = ("al", "penalty", "coulomb")
KINEMATICS = ("linear", "finite")
GEOMETRIES = ("plane", "axisymmetric")


def _law(law):
    return {"al": sg.AugmentedLagrangian(eps="eps"), "penalty": sg.Penalty(eps="eps"),
            "coulomb": sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps")}[law]


def _material(kin):
    return sg.LinearElastic(E="E", nu="nu") if kin == "linear" else sg.NeoHooke(E="E", nu="nu")


def _rotate(Q, v):
    """The vector of specs v rotated by Q (each component a function of the parameters)."""
    def comp(i):
        return lambda p: Q[i, 0] * sg.params.resolve(v[0], p) + Q[i, 1] * sg.params.resolve(v[1], p)
    return (comp(0), comp(1))


def _mesh(half: bool, Q=None):
    xs = np.concatenate([np.linspace(0.0, 0.5, 21), [0.6, 0.75, 1.0]]) if half else np.linspace(-1, 1, 49)
    mesh = sg.rectangle(xs, np.linspace(-1.0, 0.0, 7))
    if Q is not None:
        mesh = sg.Mesh(mesh.nodes @ Q.T, mesh.cells, mesh.node_sets, mesh.edge_sets)
    return mesh


def _params(law, **extra):
    p = {"E": E, "nu": NU, "eps": E / 0.025, **extra}
    if law == "coulomb":
        p["mu"] = MU
    return p


def force_problem(obstacle, law, kin, geometry):
    """Half model (or axisymmetric cylinder) pressed against the obstacle by a
    bottom pressure of resultant P; the obstacle moves by (0, -s)."""
    if obstacle == "circle":
        ob = sg.Circle(radius="R", centre=(0.0, "R"), motion=(0.0, lambda p: -p["s"]))
    else:  # flat die on the flat top face
        ob = sg.Line(point=(0.0, 0.0), normal_vector=(0.0, -1.0), motion=(0.0, lambda p: -p["s"]))
    P = 2.0 if geometry == "plane" else 6.0
    return sg.Problem(
        mesh=_mesh(half=True), material=_material(kin),
        params=_params(law, R=R, P=P, s=0.0),
        fixed=(sg.Fixed("left", 0),),
        loads=(sg.Pressure("bottom", "P", resultant=True),),
        contact=(sg.Contact(ob, "top", _law(law), kinematics=kin),),
        kinematics=sg.PlaneStrain() if geometry == "plane" else sg.Axisymmetric())


def held_problem(obstacle, law, kin, geometry, Q=None):
    """A body whose bottom is moved by c t = (cx, cy) t, indented by an obstacle
    moving by (c + (0, -d)) t. Plane strain: a whole block (optionally rotated
    rigidly by Q); axisymmetric: a cylinder (c along the axis only)."""
    plane = geometry == "plane"
    if obstacle == "circle":
        point, kw = (0.0, "R"), {}
    else:  # inclined die touching a corner of the block / a cone with its apex on the axis
        point = (-1.0, 0.0) if plane else (0.0, 0.0)
        kw = {"normal_vector": (lambda p: jnp.sin(p["a"]), lambda p: -jnp.cos(p["a"]))}
    motion = (lambda p: p["cx"], lambda p: p["cy"] - p["d"])
    bottom = ("cx", "cy")
    if Q is not None:
        point, motion, bottom = _rotate(Q, point), _rotate(Q, motion), _rotate(Q, bottom)
        if "normal_vector" in kw:
            kw["normal_vector"] = _rotate(Q, kw["normal_vector"])
    ob = (sg.Circle(radius="R", centre=point, motion=motion) if obstacle == "circle"
          else sg.Line(point=point, motion=motion, **kw))
    fixed = (sg.Fixed("bottom", 0, bottom[0] if plane else 0.0), sg.Fixed("bottom", 1, bottom[1]))
    if not plane:
        fixed = (sg.Fixed("left", 0), sg.Fixed("bottom", 1, "cy"))
    return sg.Problem(
        mesh=_mesh(half=not plane, Q=Q), material=_material(kin),
        params=_params(law, R=R, a=0.02, d=0.012, cx=0.0, cy=0.0),
        fixed=fixed, contact=(sg.Contact(ob, "top", _law(law), kinematics=kin),),
        kinematics=sg.PlaneStrain() if plane else sg.Axisymmetric())


def _solve(problem, law, names, **values):
    steps = 3 if law == "coulomb" else 1
    sol = sg.solve(problem.with_params(**values), steps=steps, wrt=names, options=TIGHT)
    out = sol.contact()
    # the load factors reached: Newton starts from the body at rest, not from a body that
    # followed the obstacle, so a frictionless run may cut a step in one case and not in
    # the other; its solution at t = 1 does not depend on the path, a frictional one does
    out["t"] = np.array([inc.t for inc in sol.increments])
    return out


def _scale(ref, params, name):
    """What D p / D name is measured against: max p_N / |name| (a unit length for
    the translations, whose value is zero)."""
    return np.abs(ref["p_N"]).max() / (abs(params[name]) or 1.0)


def _compare(ref, other, names, params, label):
    """Tractions, status and sensitivities of two solutions agree to round-off."""
    scale = np.abs(ref["p_N"]).max()
    assert scale > 0 and (ref["p_N"] > 0).sum() >= 3, f"{label}: contact zone not resolved"
    if "status" in ref:  # friction is path-dependent: both runs must take the same increments
        np.testing.assert_array_equal(other["t"], ref["t"], err_msg=f"{label}: load path")
    for k in ("p_N", "p_T"):
        np.testing.assert_allclose(other[k], ref[k], rtol=0, atol=1e-9 * scale, err_msg=f"{label}: {k}")
    if "status" in ref:
        np.testing.assert_array_equal(other["status"], ref["status"], err_msg=f"{label}: status")
    for n in names:
        for k in ("p_N", "p_T"):
            key = f"d{k}_d{n}"
            s = _scale(ref, params, n)
            np.testing.assert_allclose(other[key], ref[key], rtol=0, atol=1e-8 * s,
                                       err_msg=f"{label}: {key}")


def _zero(sol, names, label):
    """D p / D name = 0 for the rigid-motion parameters (zero-valued translations)."""
    scale = np.abs(sol["p_N"]).max()
    for n in names:
        for k in ("p_N", "p_T"):
            d = sol[f"d{k}_d{n}"]
            assert np.abs(d).max() <= 1e-8 * scale, f"{label}: max |d{k}_d{n}| = {np.abs(d).max():.3g}"


def _names(obstacle, law, *extra):
    return (["R"] if obstacle == "circle" else []) + ["E"] + (["mu"] if law == "coulomb" else []) + list(extra)


def _cases(factors, pairwise):
    """Every combination of ``factors``; those not in ``pairwise`` marked slow. The
    pairwise set holds every pair of values of any two factors (each law with
    both values of every two-valued factor, and every two two-valued factors in
    all four combinations): CI runs it, which runs every code path the product does."""
    out = []
    for c in itertools.product(*factors):
        marks = () if c in pairwise else (pytest.mark.slow,)
        out.append(pytest.param(*c, id="-".join(c), marks=marks))
    return out


# the two-valued factors (obstacle, kinematics, geometry) as 0/1: each law takes a
# complementary pair of triples, and three such pairs hold every pair of values
_TRIPLES = {"000": ("circle", "linear", "plane"), "111": ("line", "finite", "axisymmetric"),
            "110": ("line", "finite", "plane"), "001": ("circle", "linear", "axisymmetric"),
            "101": ("line", "linear", "axisymmetric"), "010": ("circle", "finite", "plane"),
            "011": ("circle", "finite", "axisymmetric"), "100": ("line", "linear", "plane")}


def _pairwise(laws_to_triples):
    return {(o, law, k, g) for law, ts in laws_to_triples.items()
            for o, k, g in (_TRIPLES[t] for t in ts)}


FACTORS = (OBSTACLES, LAWS, KINEMATICS, GEOMETRIES)
# two different pairwise sets for the two tests, so that CI runs 12 of the 24 cases
PAIRWISE_FORCE = _pairwise({"al": ("000", "111"), "penalty": ("110", "001"), "coulomb": ("101", "010")})
PAIRWISE_HELD = _pairwise({"al": ("011", "100"), "penalty": ("000", "111"), "coulomb": ("110", "001")})
PAIRWISE_ROTATED = {(o, law, k) for (o, law, k, g) in PAIRWISE_FORCE}


@pytest.mark.parametrize("obstacle,law,kin,geometry", _cases(FACTORS, PAIRWISE_FORCE))
def test_translated_obstacle_with_the_body_following(obstacle, law, kin, geometry):
    pb = force_problem(obstacle, law, kin, geometry)
    names = _names(obstacle, law, "P", "s")
    ref = _solve(pb, law, names, s=0.0)
    _zero(ref, ["s"], "s = 0")
    for s in (0.01, 0.05):
        other = _solve(pb, law, names, s=s)
        _compare(ref, other, names, pb.params, f"s = {s}")
        _zero(other, ["s"], f"s = {s}")


@pytest.mark.parametrize("obstacle,law,kin,geometry", _cases(FACTORS, PAIRWISE_HELD))
def test_moving_obstacle_against_held_body_equals_body_pushed_against_fixed_obstacle(
        obstacle, law, kin, geometry):
    pb = held_problem(obstacle, law, kin, geometry)
    plane = geometry == "plane"
    rigid = ["cx", "cy"] if plane else ["cy"]
    names = _names(obstacle, law, "d", *rigid) + (["a"] if obstacle == "line" else [])
    d = pb.params["d"]
    obstacle_down = _solve(pb, law, names)                # body held, obstacle moves by (0, -d)
    body_up = _solve(pb, law, names, cy=d)                # body pushed up by d, obstacle fixed
    _compare(obstacle_down, body_up, names, pb.params, "obstacle down vs body up")
    _zero(obstacle_down, rigid, "obstacle down")
    _zero(body_up, rigid, "body up")
    if plane:  # any direction of the common translation
        _compare(obstacle_down, _solve(pb, law, names, cx=0.03, cy=-0.02), names, pb.params,
                 "c = (0.03, -0.02)")


@pytest.mark.parametrize("obstacle,law,kin", _cases((OBSTACLES, LAWS, KINEMATICS), PAIRWISE_ROTATED))
def test_rigidly_rotated_problem(obstacle, law, kin):
    th = 0.7
    Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    names = _names(obstacle, law, "d") + (["a"] if obstacle == "line" else [])
    pb = held_problem(obstacle, law, kin, "plane")
    ref = _solve(pb, law, names, cx=0.1)
    rot = _solve(held_problem(obstacle, law, kin, "plane", Q=Q), law, names, cx=0.1)
    np.testing.assert_allclose(rot["x_ref"], ref["x_ref"] @ Q.T, atol=1e-14)
    _compare(ref, rot, names, pb.params, "rotated by 0.7 rad")


def _force_response(model):
    """R(w, params, t) = sum_S A_S (p_N + 3 p_T): normal and tangential contact force."""
    def f(w, params, t):
        c = model.contact_fields(w, params, t)
        return jnp.sum(c["area"] * (c["p_N"] + 3.0 * c["p_T"]))
    return f


@pytest.mark.parametrize("kin", KINEMATICS)
def test_parameters_of_the_motion_are_design_variables(kin):
    """A cylinder moving by (v, -d) over a held block with Coulomb friction: the
    derivatives with respect to the motion (d, v) and to the obstacle (R, mu) by
    the DDM equal the adjoint's on the same path and central differences of the
    response of fresh solves; there is real slip and stick on the path."""
    ob = sg.Circle(radius="R", centre=(0.0, "R"), motion=("v", lambda p: -p["d"]))
    pb = sg.Problem(
        mesh=_mesh(half=False), material=_material(kin),
        params=_params("coulomb", R=R, d=0.012, v=0.004),
        fixed=(sg.Fixed("bottom", 0), sg.Fixed("bottom", 1)),
        contact=(sg.Contact(ob, "top", _law("coulomb"), kinematics=kin),))
    names = ["d", "v", "R", "mu"]
    kw = dict(steps=3, options=TIGHT)
    ddm = sg.gradient(pb, _force_response, names, method=sg.DDM(), **kw)
    adj = sg.gradient(pb, _force_response, names, method=sg.Adjoint(), solution=ddm.solution, **kw)
    status = ddm.solution.contact()["status"]
    assert (status == "stick").sum() >= 2 and (status == "slip").sum() >= 2, status
    fd = sg.gradient(pb, _force_response, names, method=sg.FiniteDifferences(), **kw)
    for n in names:
        assert abs(adj[n] - ddm[n]) <= 1e-10 * abs(ddm[n]), (n, adj[n], ddm[n])
        assert abs(fd[n] - ddm[n]) <= 1e-6 * abs(ddm[n]), (n, fd[n], ddm[n])


def _pairs(cases, arity):
    """Every pair of values of any two factors that ``cases`` hold."""
    return {((i, c[i]), (j, c[j])) for c in cases for i in range(arity) for j in range(i + 1, arity)}


@pytest.mark.parametrize("subset,factors", [(PAIRWISE_FORCE, FACTORS), (PAIRWISE_HELD, FACTORS),
                                            (PAIRWISE_ROTATED, FACTORS[:3])])
def test_the_subsets_run_in_ci_hold_every_pair_of_values(subset, factors):
    every = set(itertools.product(*factors))
    assert subset <= every and len(subset) == 6
    assert _pairs(subset, len(factors)) == _pairs(every, len(factors))
