"""Adjoint gradients (docs/theory.md §11): equal to the DDM to 1e-10 on
frictionless and frictional Hertz and on forging, the shape gradient of every
nodal coordinate against DDM and central differences on 10 nodes, memory
options (checkpoints, stored factors), and the report of switch points where
the derivative is one-sided."""

import dataclasses
import json

import numpy as np
import pytest

import signorini as sg
from signorini.post import files as io
from signorini.app import runner
from signorini._jax import jnp
from signorini.contact import AugmentedLagrangian, Contact
from signorini.errors import InputError
from signorini.design.gradient import gradient
from signorini.fem.loads import Fixed
from signorini.materials import LinearElastic
from signorini.fem.mesh import rectangle
from signorini.contact.obstacles import Circle
from signorini.model.problem import Problem
from signorini.problems import forging, hertz, hertz_friction

from helpers import pressed_block

TIGHT = sg.NewtonOptions(rtol=1e-11)


def with_centre(pb):
    """The Hertz problem with the obstacle centre as a parameter yc (offset, 0)."""
    c = pb.contact[0]
    circle = Circle(radius="R", centre=(0.0, lambda p: p["R"] + p["yc"]))
    return dataclasses.replace(pb, contact=(Contact(circle, c.edges, c.method),),
                               params={**pb.params, "yc": 0.0})


def rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("friction", [False, True])
def test_adjoint_equals_ddm_hertz(friction):
    if friction:
        pb = with_centre(hertz_friction.hertz_friction_problem(n_fine=12))
        names, steps, incs = ["R", "E", "mu", "P", "yc"], 4, "all"
    else:
        pb = with_centre(hertz.hertz_problem(n_fine=12))
        names, steps, incs = ["R", "E", "P", "yc"], 2, "last"
    resp = hertz.contact_work
    d = gradient(pb, resp, names, method=sg.DDM(), steps=steps, increments=incs, options=TIGHT)
    # the backward pass on the same converged path (a new solve would converge to the
    # same point only to rtol, which the ill-conditioned frictional tangent amplifies)
    a = gradient(pb, resp, names, method=sg.Adjoint(), steps=steps, increments=incs, options=TIGHT,
                 solution=d.solution)
    assert a.value == pytest.approx(d.value, rel=1e-12)
    for n in names:
        assert abs(a[n] - d[n]) <= 1e-10 * abs(d[n]), (n, a[n], d[n])
    # one transposed solve per increment that the response reaches
    assert a.timing["factorizations"] == (steps if friction else 1)


def test_adjoint_equals_ddm_forging_and_memory_options():
    pb = forging.forging_problem(mesh=(4, 8))
    resp = lambda m: forging.objective(m, forging.lateral_nodes(pb))  # noqa: E731
    names = list(forging.TABLE1)
    kw = dict(steps=6, options=forging.options(), solver="superlu")  # bitwise repeatable solves
    d = gradient(pb, resp, names, method=sg.DDM(), **kw)
    # the parameters and every nodal coordinate in one backward pass (one set of
    # compiled VJPs for both memory options instead of a second set for "nodes")
    a = gradient(pb, resp, names + ["nodes"], method=sg.Adjoint(), **kw)
    c = gradient(pb, resp, names + ["nodes"], method=sg.Adjoint(factors="store", checkpoint=4), **kw)
    assert rel(a.as_array(names), d.as_array(names)) < 1e-10
    # the nodal shape gradient along a design velocity is that parameter's derivative
    a_nodes = a["nodes"]
    shape = [f"phi{k}" for k in range(5)]
    along = [float(np.sum(a_nodes * pb.shape[n])) for n in shape]
    assert rel(along, d.as_array(shape)) < 1e-10  # max |difference| / max |dF/dphi_k|
    # replayed states and stored factors give the same numbers
    assert rel(c.as_array(names), a.as_array(names)) < 1e-12
    assert rel(c["nodes"], a_nodes) < 1e-12
    assert a.memory["states_kept"] == 6 and c.memory["states_kept"] == 2  # increments 4 and 6
    assert c.memory["factors_kept"] == 6 and c.timing["factorizations"] == 0
    assert c.memory["factors_per_increment"] > 0
    assert c.memory["per_increment"] - c.memory["factors_per_increment"] < 0.6 * a.memory["per_increment"]


def test_shape_gradient_of_every_node_equals_ddm_and_fd():
    """dG/dX of all nodes in one backward pass; 10 sampled nodes checked against the
    DDM of one-hot shape fields (exact) and central differences of two solves."""
    base = hertz_friction.hertz_friction_problem(n_fine=12)
    kw = dict(steps=3, increments="all", options=TIGHT)
    a = gradient(base, hertz.contact_work, ["R", "nodes"], method=sg.Adjoint(), **kw)
    g = a["nodes"]
    assert g.shape == (base.mesh.nodes.shape[0], 2)
    top = base.mesh.node_set("top")
    rng = np.random.default_rng(3)
    x = base.mesh.nodes
    near = np.nonzero((np.abs(x[:, 0]) < 1.0) & (x[:, 1] > -0.3))[0]  # where G is sensitive
    # contact nodes near the centre, but not the one at x = 0: the body is held by
    # touching the cylinder there at the start (moving it would leave it unsupported)
    sample = list(top[np.argsort(np.abs(x[top, 0]))[1:6]]) + list(
        rng.choice(np.setdiff1d(near, top), 5, replace=False))
    comps = [k % 2 for k in range(10)]
    shape = {**base.shape}
    params = dict(base.params)
    for k, (n, c) in enumerate(zip(sample, comps)):
        V = np.zeros_like(x)
        V[n, c] = 1.0
        shape[f"x{k}"], params[f"x{k}"] = V, 0.0
    pb = dataclasses.replace(base, shape=shape, params=params,
                             shape_nominal={**base.shape_nominal, **{f"x{k}": 0.0 for k in range(10)}})
    names = [f"x{k}" for k in range(10)]
    d = gradient(pb, hertz.contact_work, names, method=sg.DDM(), **kw)
    adj = np.array([g[n, c] for n, c in zip(sample, comps)])
    assert rel(adj, d.as_array(names)) < 1e-10
    f = gradient(pb, hertz.contact_work, names, method=sg.FiniteDifferences(rel_step=1e-5), **kw)
    # central differences of two solves at rtol 1e-11: their round-off falls as 1/step.
    # At step 1e-6 it reached 1.75-2.1e-9 absolute on an interior node, 0.54-1.05 of
    # this bound, varying between identical runs (the threaded factorisation's order
    # of operations); at step 1e-5 the largest error is 0.016-0.049 of it
    err = np.abs(f.as_array(names) - adj)
    assert np.all(err <= 1e-5 * np.abs(adj) + 2e-9), (adj, f.as_array(names))
    assert np.sum(np.abs(adj) > 1e-6) >= 5


def test_nodes_gradient_of_rigid_translation_is_consistent():
    """A rigid vertical translation of mesh and obstacle together changes nothing: the
    y-components of the nodal gradient sum with the obstacle-centre derivative to 0."""
    pb = with_centre(hertz.hertz_problem(n_fine=12))
    a = gradient(pb, hertz.contact_work, ["nodes", "yc"], method=sg.Adjoint(), options=TIGHT)
    total = a["nodes"][:, 1].sum() + a["yc"]
    assert abs(total) < 1e-9 * np.abs(a["nodes"][:, 1]).sum()


def test_gradient_input_errors():
    pb = hertz.hertz_problem(n_fine=12)
    with pytest.raises(InputError, match="method must be"):
        gradient(pb, hertz.contact_work, ["R"], method="backward")
    with pytest.raises(InputError, match="adjoint"):
        gradient(pb, hertz.contact_work, ["nodes"], method=sg.DDM())
    with pytest.raises(sg.errors.UnknownParameterError, match="Rr"):
        gradient(pb, hertz.contact_work, ["Rr"])
    with pytest.raises(InputError, match="factors"):
        gradient(pb, hertz.contact_work, ["R"], method=sg.Adjoint(factors="keep"))
    with pytest.raises(InputError, match="increments"):
        gradient(pb, hertz.contact_work, ["R"], increments=[5])
    with pytest.raises(InputError, match="reserved"):
        dataclasses.replace(pb, params={**pb.params, "nodes": 1.0})
    with pytest.raises(InputError, match="checkpoint"):
        sg.solve(pb, method=sg.Adjoint(checkpoint=0))


def touching_block(yc: float = 0.0):
    """A block fixed at its base, unloaded, a cylinder touching exactly the top
    node at x = 1: that node is on the edge of the contact zone (g = 0, p = 0)."""
    mesh = rectangle(np.linspace(0.0, 2.0, 9), np.linspace(-1.0, 0.0, 5))
    return Problem(mesh=mesh, material=LinearElastic(), params={"E": 100.0, "nu": 0.3, "R": 1.0,
                                                                 "yc": yc, "eps": 400.0},
                   fixed=(Fixed("bottom", 0), Fixed("bottom", 1)),
                   contact=(Contact(Circle(radius="R", centre=(1.0, lambda p: p["R"] + p["yc"])), "top",
                                    AugmentedLagrangian("eps")),))


def test_weakly_active_node_is_reported_and_derivative_is_one_sided(tmp_path):
    pb = touching_block()
    node = int(np.argmin(np.abs(pb.mesh.nodes[:, 0] - 1.0) + np.abs(pb.mesh.nodes[:, 1])))
    with pytest.warns(sg.errors.SignoriniWarning, match="one-sided"):
        sol = sg.solve(pb, steps=2, wrt=["yc"])
    for inc in sol.increments:
        assert inc.switches["weakly_active"] == [[node]]
    summary = runner.summary_header("converged", sol)
    assert [r["weakly_active"] for r in summary["derivative_switches"]] == [[[node]], [[node]]]
    assert any("weakly active contact nodes [%d]" % node in w for w in summary["warnings"])
    json.dumps(summary)
    mesh = __import__("meshio").read(io.write_vtu(sol, tmp_path / "s.vtu"))
    sw = mesh.point_data["switch"]
    assert sw[node] == 1 and np.count_nonzero(sw) == 1
    # the derivative is one-sided there: moving the cylinder into the block makes
    # contact, moving it away does not
    pressure = lambda s: s.contact()["p_N"].sum()  # noqa: E731
    h = 1e-4
    up = (pressure(sg.solve(touching_block(h))) - pressure(sol)) / h
    down = (pressure(sol) - pressure(sg.solve(touching_block(-h)))) / h
    assert up == 0.0 and down < -1.0
    ddm = sol.contact()["dp_N_dyc"].sum()
    assert ddm == pytest.approx(down, rel=1e-6)  # the closed branch (closed at zero)
    # the adjoint warns the same way
    with pytest.warns(sg.errors.SignoriniWarning, match="one-sided"):
        a = gradient(pb, lambda m: lambda w, p, t: m.contact_fields(w, p, t, 0)["p_N"].sum(), ["yc"])
    assert a["yc"] == pytest.approx(ddm, rel=1e-10)


def test_no_switch_points_in_a_clear_hertz_contact():
    sol = sg.solve(hertz.hertz_problem(n_fine=12), wrt=["R"])
    assert all(sum(map(len, inc.switches["weakly_active"])) == 0 for inc in sol.increments)
    assert not any("one-sided" in w for w in sol.warnings)


def test_transposed_solves_match_superlu():
    """K^T x = b by every backend, checked against SciPy's SuperLU, on a frictional
    tangent (unsymmetric) with PARDISO's kept analysis from another tangent."""
    from signorini.linsolve import available, get_solver
    import scipy.sparse.linalg as spla

    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    sol = sg.solve(pb, steps=3, options=TIGHT, solver="superlu")
    m = sol.model
    Ks = []
    for i in (0, 2):
        inc = sol.increments[i]
        _, blocks = m.local_tangents(jnp.asarray(inc.w), sol.jax_params, inc.t, sol.state_before(i)[0])
        Ks.append(m.pattern.assemble(blocks))
    b = np.random.default_rng(0).standard_normal(Ks[0].shape[0])
    ref = spla.splu(Ks[1].tocsc()).solve(b, trans="T")
    for name in available():
        s = get_solver(name)
        s.factorize(Ks[0])
        f = s.factorize(Ks[1])  # a kept analysis: values of another active set
        x = f.solve(b, transpose=True)
        assert rel(x, ref) < 1e-10, name


def test_optimisation_objective_with_adjoint_gradient():
    """The optimisation interface takes either mode: same value and gradient (the
    Table 1 parameters on the 2 x 4 mesh: the DDM programs of test_cli_adjoint_next_to_ddm)."""
    from signorini.design.optimize import Objective

    pb = forging.forging_problem(mesh=(2, 4))
    names = list(forging.TABLE1)  # phi0..phi4, mu, sigma_y
    resp = lambda m: forging.objective(m, forging.lateral_nodes(pb))  # noqa: E731
    x = np.array([0.72, 0.7, 0.69, 0.7, 0.71, 0.25, 100.0])
    evs = [Objective(pb, names, resp, steps=4, options=forging.options(), method=method).evaluate(x)
           for method in (sg.DDM(), sg.Adjoint())]
    assert evs[1].F == pytest.approx(evs[0].F, rel=1e-13)  # two solves (MKL threads)
    assert rel(evs[1].grad, evs[0].grad) < 1e-10


def test_cli_adjoint_next_to_ddm(tmp_path):
    from signorini.app.cli import main

    main(["forging", "--out", str(tmp_path), "--mesh", "2x4", "--steps", "4", "--no-fd", "--adjoint"])
    s = json.loads((tmp_path / "summary.json").read_text())
    a = s["adjoint"]
    assert set(a["adjoint"]) == set(forging.TABLE1)
    assert max(a["adjoint_vs_ddm_rel_diff"].values()) < 1e-10
    assert a["ddm"] == s["dF_ddm"]
    rows = np.genfromtxt(tmp_path / "shape_gradient.csv", delimiter=",", names=True)
    pb = forging.forging_problem(mesh=(2, 4))
    g = np.column_stack([rows["dG_dX"], rows["dG_dY"]])
    assert abs(np.sum(g * pb.shape["phi4"]) - a["adjoint"]["phi4"]) <= 1e-9 * abs(a["adjoint"]["phi4"])
    mesh = __import__("meshio").read(sorted(tmp_path.glob("forging_*.vtu"))[-1])
    assert np.allclose(mesh.point_data["adjoint_shape_gradient"][:, :2], g)


def test_solution_argument_must_match_and_memory_counts_factors():
    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    sol = sg.solve(pb, steps=3, options=TIGHT, solver="superlu")  # bitwise repeatable
    with pytest.raises(InputError, match="same mesh, components and parameter values"):
        gradient(pb.with_params(P=3.0), hertz.contact_work, ["R"], solution=sol)
    a = gradient(pb, hertz.contact_work, ["R"], steps=3, options=TIGHT,
                 method=sg.Adjoint(factors="store"), solver="superlu")
    b = gradient(pb, hertz.contact_work, ["R"], steps=3, options=TIGHT, solution=sol)
    assert a["R"] == pytest.approx(b["R"], rel=1e-10)
    # the same problem built again (equal content, other objects) is the same problem
    c = gradient(hertz_friction.hertz_friction_problem(n_fine=12), hertz.contact_work, ["R"],
                 steps=3, options=TIGHT, solution=sol)
    assert c["R"] == b["R"]
    assert a.memory["factors_per_increment"] > 0
    assert a.memory["per_increment"] > a.memory["factors_per_increment"]
    # the state shares the unknowns of its increment (no second copy)
    assert all(inc.state[0] is inc.w for inc in sol.increments)


def test_cli_optimize_forging_with_adjoint_gradient(tmp_path):
    """optimize-forging --gradient adjoint takes the same path as the DDM."""
    from signorini.app.cli import main

    F = {}
    for g in ("adjoint", "ddm"):
        main(["optimize-forging", "--out", str(tmp_path / g), "--mu", "0.2", "--mesh", "2x4",
              "--steps", "4", "--maxiter", "2", "--gradient", g, "--sequential", "-q"])
        rows = list(__import__("csv").DictReader(open(next((tmp_path / g).rglob("history.csv")))))
        F[g] = np.array([float(r["F"]) for r in rows])
    assert len(F["adjoint"]) == len(F["ddm"]) >= 3
    assert np.allclose(F["adjoint"], F["ddm"], rtol=1e-9, atol=0)


@pytest.mark.parametrize("friction", [False, True])
def test_adjoint_with_prescribed_values_and_a_state_response(friction):
    pb = pressed_block(friction)
    names = ["d", "s", "E", "R"] + (["mu"] if friction else [])
    m = sg.solve.__globals__["model_for"](pb)

    def resp(w, p, t, state_n):  # depends on the history before the increment, too
        f = m.contact_fields(w, p, t, 0)
        extra = jnp.sum(state_n[1][0] ** 2) if state_n is not None else 0.0
        return jnp.sum(f["p_N"] * f["area"]) ** 2 + extra

    d = gradient(pb, resp, names, method=sg.DDM(), steps=3, increments="all", options=TIGHT)
    a = gradient(pb, resp, names, method=sg.Adjoint(), steps=3, increments="all", options=TIGHT,
                 solution=d.solution)
    assert abs(d["d"]) > 0 and abs(d["s"]) > 0
    assert rel(a.as_array(names), d.as_array(names)) < 1e-10


class _Foreign:
    """A user solver: factorize(K) -> object with solve(b) only (no transposed solve)."""

    def factorize(self, K):
        import scipy.sparse.linalg as spla

        lu = spla.splu(K.tocsc())
        return type("F", (), {"solve": staticmethod(lu.solve)})()


def test_user_solvers_forward_and_adjoint():
    from signorini.linsolve import Factor

    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    d = gradient(pb, hertz.contact_work, ["R", "mu"], method=sg.DDM(), steps=2, options=TIGHT)
    a = gradient(pb, hertz.contact_work, ["R", "mu"], steps=2, options=TIGHT, solver=_Foreign())
    assert rel(a.as_array(), d.as_array()) < 1e-9
    # a factor written to the solve(b) contract still serves Newton; its transposed
    # solve, which it does not have, is a clear error
    import scipy.sparse as sp

    K = sp.csr_matrix(np.array([[4.0, 1.0], [2.0, 3.0]]))
    f = Factor(lambda b: np.linalg.solve(K.toarray(), b), K)
    assert np.allclose(K @ f.solve(np.ones(2)), 1.0)
    with pytest.raises(InputError, match="transposed solve"):
        f.solve(np.ones(2), transpose=True)
    r = Factor(lambda b: np.linalg.solve(K.toarray(), b), K,
               transpose_factor=lambda: Factor(lambda b: np.linalg.solve(K.T.toarray(), b), K.T.tocsr()))
    K2 = sp.csr_matrix(np.array([[4.0001, 1.0], [2.0, 3.0002]]))
    x = r.refined_for(K2).solve(np.ones(2), transpose=True)  # refined against K2^T, not K^T
    assert np.allclose(K2.T @ x, 1.0, atol=1e-12)
    assert not np.allclose(K.T @ x, 1.0, atol=1e-6)


def test_checkpointed_states_replay_exactly():
    pb = hertz_friction.hertz_friction_problem(n_fine=12)
    # SuperLU: two solves bit for bit the same (MKL's threads are not), so the
    # replayed states can be compared with stored ones exactly
    full = sg.solve(pb, steps=6, options=TIGHT, solver="superlu")
    cp = sg.solve(pb, steps=6, options=TIGHT, method=sg.Adjoint(checkpoint=4), solver="superlu")
    assert [inc.state is not None for inc in cp.increments] == [False, False, False, True, False, True]
    for n in (0, 2, 4, -2):
        a, b = cp.state_after(n), full.state_after(n)
        for x, y in zip(jax_leaves(a), jax_leaves(b)):
            assert np.array_equal(np.asarray(x), np.asarray(y))


def jax_leaves(tree):
    from signorini._jax import jax

    return jax.tree_util.tree_leaves(tree)


def test_stick_slip_and_yield_switches_are_detected_with_a_wide_tolerance(tmp_path):
    """The detectors report points once the tolerance covers them (their positive
    case; at 1e-6 these paths have none)."""
    fr = sg.solve(hertz_friction.hertz_friction_problem(n_fine=12), steps=3, switch_tol=0.5)
    assert any(inc.switches["stick_slip"][0] for inc in fr.increments)
    pb = forging.forging_problem(mesh=(2, 4))
    fg = sg.solve(pb, steps=4, options=forging.options(), switch_tol=0.5)
    assert any(inc.switches["elastic_plastic"] for inc in fg.increments)
    mesh = __import__("meshio").read(io.write_vtu(fg, tmp_path / "f.vtu"))
    assert mesh.cell_data["plastic_switch"][0].sum() == len(fg.increments[-1].switches["elastic_plastic"])
