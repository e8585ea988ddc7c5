"""Coulomb friction (signorini.contact.friction; Alart-Curnier AL, THEORY 3):
the law at every node, its tangent, stick/slip ties, a block sliding at mu N,
the path-dependent DDM against FD, independence of eps, mu = 0. The frictional
Hertz benchmark (paper 5.2) is in tests/validation/test_hertz_friction.py."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import signorini as sg
from signorini.app.commands import hertz_friction as hf_cmd
from signorini.problems import hertz, hertz_friction as hf

TIGHT = sg.NewtonOptions(rtol=1e-11)
MU = 0.3  # paper 5.2
STEPS = 6  # P1, P2, P3 = increments 1, 3, 5


@pytest.fixture(scope="module")
def small():
    """Small frictional Hertz (12 cells across 1.5 a, block 10 a): open, stick and
    slip nodes at every load."""
    pb = hf.hertz_friction_problem(n_fine=12, size=10)
    sol = sg.solve(pb, steps=STEPS, wrt=["R", "mu", "E", "eps", "eps_t"], options=TIGHT)
    return pb, sol


def states(c):
    return {k: int((c["status"] == k).sum()) for k in ("open", "stick", "slip")}


def test_coulomb_law_at_every_node(small):
    """|p_T| <= mu p_N; slip: p_T = +-mu p_N opposing the slip increment g_T
    (p_T is the traction on the body along t', THEORY 0); stick: g_T = 0."""
    _, sol = small
    for k in range(STEPS):
        c = sol.contact(k)
        pmax = c["p_N"].max()
        assert all(n > 0 for n in states(c).values()), states(c)
        assert np.all(np.abs(c["p_T"]) <= MU * c["p_N"] + 1e-10 * pmax)
        slip = c["status"] == "slip"
        assert np.allclose(np.abs(c["p_T"][slip]), MU * c["p_N"][slip], rtol=0, atol=1e-10 * pmax)
        assert np.all(c["p_T"][slip] * c["slip"][slip] < 0)  # friction opposes the slip
        stick = c["status"] == "stick"
        assert np.max(np.abs(c["slip"][stick])) <= 1e-12 * np.abs(c["slip"]).max()
        op = c["status"] == "open"
        assert np.max(np.abs(np.r_[c["p_N"][op], c["p_T"][op]])) <= 1e-14 * pmax


@pytest.mark.parametrize("case", ["stick", "slip", "open"])
def test_tangent_is_the_theory_jacobian(case):
    """jacfwd of Coulomb.residual = THEORY 3 explicit blocks (a)-(c) for a flat die
    (G_N = n', G_T = t', no curvature), including d rho / d(x, lam_N) in slip."""
    A, en, et, mu = 0.7, 3.0, 2.0, 0.4
    meth, die = sg.Coulomb(), sg.Line(point=(0.0, 0.0), normal_vector=(0.0, 1.0))
    geo = die.geometry({}, 0.0)
    cp = {"mu": mu, "eps_n": en, "eps_t": et}
    GN, GT = np.array([0.0, 1.0]), np.array([-1.0, 0.0])  # n', t' = (-n2, n1)
    x = np.array([-0.5, -0.1])  # g_N = -0.1, s = 0.5
    lam = {"stick": [-1.0, 0.1], "slip": [-1.0, 0.2], "open": [0.5, 0.3]}[case]
    s_n = {"stick": 0.475, "slip": 0.0, "open": 0.0}[case]  # g_T = 0.025 / 0.5
    K = np.asarray(jax.jacfwd(lambda v: meth.residual(v[:2], v[2:], A, geo, die, cp, (s_n, 1.0)))(
        jnp.asarray(np.r_[x, lam])))
    lhn, lht = lam[0] + en * (-0.1), lam[1] + et * (0.5 - s_n)
    E = np.zeros((4, 4))
    if case == "open":
        assert lhn > 0
        E[2, 2], E[3, 3] = -A / en, -A / et
    elif case == "stick":
        assert abs(lht) <= -mu * lhn
        E[:2, :2] = A * (en * np.outer(GN, GN) + et * np.outer(GT, GT))
        E[:2, 2], E[:2, 3], E[2, :2], E[3, :2] = A * GN, A * GT, A * GN, A * GT
    else:
        sig = np.sign(lht)
        assert abs(lht) > -mu * lhn and lhn < 0
        E[:2, :2] = A * (en * np.outer(GN, GN) - mu * sig * en * np.outer(GT, GN))
        E[:2, 2] = A * (GN - mu * sig * GT)
        E[2, :2] = A * GN
        E[3, :2] = -A * mu * sig * en / et * GN
        E[3, 2], E[3, 3] = -A * mu * sig / et, -A / et
    assert np.allclose(K, E, rtol=0, atol=1e-14), (K, E)


def test_disc_edge_tie_slips_whatever_the_rounding():
    """A closed node exactly on the disc edge |lam^_T| = rho (every node that slipped
    in the last increment starts the next one there) slips, also when round-off
    moves |lam^_T| a few ulps either side; inside the disc by more than the tie
    band it sticks; lam^_T = rho = 0 sticks (a body touching the die at the start
    is held). The tangent of a tie is the slip block of the theory, the same when
    compiled (flags and Jacobian in one program) or not."""
    A, en, et, mu = 0.7, 3.0, 2.0, 0.4
    meth, die = sg.Coulomb(), sg.Line(point=(0.0, 0.0), normal_vector=(0.0, 1.0))
    geo = die.geometry({}, 0.0)
    cp = {"mu": mu, "eps_n": en, "eps_t": et}
    x = np.array([-0.5, -0.1])  # g_N = -0.1, s = 0.5
    lam_n, s_n = -1.0, 0.5  # g_T = 0: lam^_T = lam_T
    rho = -mu * (lam_n + en * -0.1)

    def stick(lam_t, lam=None):
        c = meth.cases(jnp.asarray(x), jnp.asarray(lam if lam is not None else [lam_n, lam_t]),
                       geo, die, cp, (s_n, 1.0))
        return bool(c[0]), bool(c[1])

    for sign in (1.0, -1.0):
        edge = sign * rho
        near, lo, hi = [edge], edge, edge
        for _ in range(8):  # eight ulps either side of the edge
            lo, hi = np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)
            near += [lo, hi]
        assert len(set(near)) == 17
        assert all(stick(v) == (True, False) for v in near), [(v - edge) / rho for v in near]
        assert stick(edge * (1 - 1e-9)) == (True, True)  # inside by more than the band
        assert stick(edge * (1 + 1e-9)) == (True, False)
    # touching with zero pressure and no tangential traction: held (stick)
    x0 = np.array([-0.5, 0.0])
    c = meth.cases(jnp.asarray(x0), jnp.asarray([0.0, 0.0]), geo, die, cp, (0.5, 1.0))
    assert bool(c[0]) and bool(c[1])

    # the tangent of the tie: the slip block, compiled or not
    def jac(v):
        return meth.residual(v[:2], v[2:], A, geo, die, cp, (s_n, 1.0))
    v = jnp.asarray(np.r_[x, lam_n, rho])
    K, Kj = np.asarray(jax.jacfwd(jac)(v)), np.asarray(jax.jit(jax.jacfwd(jac))(v))
    GN, GT = np.array([0.0, 1.0]), np.array([-1.0, 0.0])
    E = np.zeros((4, 4))
    E[:2, :2] = A * (en * np.outer(GN, GN) - mu * en * np.outer(GT, GN))
    E[:2, 2] = A * (GN - mu * GT)
    E[2, :2] = A * GN
    E[3, :2] = -A * mu * en / et * GN
    E[3, 2], E[3, 3] = -A * mu / et, -A / et
    assert np.allclose(K, E, rtol=0, atol=1e-14) and np.allclose(Kj, E, rtol=0, atol=1e-14)


def test_one_program_tangent_equals_separate_flags_at_increment_starts():
    """Without a predictor every increment starts at the last converged state, where
    the slipping nodes sit exactly on the disc edge. The Newton tangent (flags and
    Jacobian compiled as one program) must take the same branches as flags computed
    by their own program: a branch decided by rounding differed between the two
    (stick 99.95 against 2e-15 in a tangential entry) and once gave a singular first
    tangent."""
    from signorini.params import as_jax
    from signorini.algorithms.stepping import model_for
    from signorini._jax import to_device

    pb = hf.hertz_friction_problem(refine=0)
    sol = sg.solve(pb, options=sg.NewtonOptions(rtol=1e-10, predictor="none"), steps=12)
    m, p = model_for(pb), as_jax(pb.params)
    ties = 0
    for prev, inc in zip(sol.increments[:-1], sol.increments[1:]):
        w = to_device(prev.w)
        R, blocks = m.local_tangents(w, p, inc.t, prev.state)
        cases = m.compiled.cases(w, p, inc.t, prev.state)
        # the contact part with the separately computed flags (the linear body's element
        # forces are added in NumPy, as the Newton evaluation adds them)
        assert m.linear_elements
        R2, blocks2 = m._local_contact(w, p, inc.t, prev.state, cases)
        R2 = m.linear_forces_np(m.element_stiffness(p), np.asarray(w)) + np.asarray(R2)
        Kc, Kc2 = blocks[-1], np.asarray(blocks2[-1])
        assert np.max(np.abs(Kc - Kc2)) <= 1e-12 * np.max(np.abs(Kc2))
        assert np.max(np.abs(R - R2)) <= 1e-12 * np.max(np.abs(R))
        closed, stick = np.asarray(cases[0][0]), np.asarray(cases[0][1])
        ties += int(np.sum(closed & ~stick))  # slipping at the start: on the disc edge
    assert ties > 0  # the path has tie nodes, which is what this test is about


def test_symmetry_node_has_no_friction_multiplier(small):
    """x = 0: u_x prescribed, so g_T = 0 identically; lam_T = 0 there (THEORY 3)."""
    _, sol = small
    s = sol.model.surfaces[0]
    X = sol.reference()[s.nodes]
    mask = sol.model._tangential[0]
    assert np.array_equal(mask == 0, X[:, 0] == 0)
    assert np.all(sol.multipliers()[X[:, 0] == 0, 1] == 0)
    assert sol.contact()["status"][0] == "stick"  # the symmetry line is a stick line


def _block(loads=(), fixed=()):
    """Elastic block 2 x 1 (8 x 4 cells) on a rigid flat die y = 0, pressed by a
    normal force N = 1 in the first half of the load path (t <= 1/2)."""
    mesh = sg.rectangle(np.linspace(0, 2, 9), np.linspace(0, 1, 5))
    params = dict(E=100.0, nu=0.3, N=1.0, mu=MU, eps=100.0, eps_t=100.0, T=1.2 * MU, D=0.05)
    die = sg.Line(point=(0.0, 0.0), normal_vector=(0.0, 1.0))
    normal = sg.Pressure("top", "N", resultant=True, ramp=lambda t: jnp.minimum(2 * t, 1.0))
    return sg.Problem(mesh=mesh, material=sg.LinearElastic(), params=params, loads=(normal, *loads),
                      fixed=fixed, contact=(sg.Contact(die, "bottom", sg.Coulomb()),))


def test_block_force_controlled_sliding_starts_at_mu_N():
    """Tangential force T on the top grows to 1.2 mu N: static equilibrium exists
    only while T <= mu N, so Newton stops within one increment of T = mu N; the
    friction resultant balances T before that."""
    ramp = lambda t: jnp.maximum(0.0, 2 * t - 1)
    pb = _block(loads=(sg.Traction("top", ("T", 0.0), resultant=True, ramp=ramp),))
    with pytest.raises(sg.ConvergenceError) as err:
        sg.solve(pb, steps=20, options=sg.NewtonOptions(rtol=1e-12, max_cuts=0))
    sol = err.value.partial
    dT = 1.2 * MU * 2 / 20  # tangential load increment
    T = [1.2 * MU * max(0.0, 2 * inc.t - 1) for inc in sol.increments]
    assert T[-1] < MU <= T[-1] + dT  # N = 1
    for k, Tk in enumerate(T):
        c = sol.contact(k)
        assert np.isclose(np.sum(c["area"] * c["p_N"]), min(2 * sol.increments[k].t, 1), rtol=1e-10)
        assert np.isclose(np.sum(c["area"] * c["p_T"]), Tk, rtol=1e-10, atol=1e-12)
        assert (c["status"] == "stick").any()  # not sliding as a whole yet


def test_block_dragged_sideways_slides_at_mu_N():
    """Top displaced sideways (after the normal load): the tangential reaction grows,
    reaches mu N within one increment and stays at mu N while the block slides."""
    ramp = lambda t: jnp.maximum(0.0, 2 * t - 1)
    pb = _block(fixed=(sg.Fixed("top", 0, "D", ramp=ramp),))
    sol = sg.solve(pb, steps=20, options=sg.NewtonOptions(rtol=1e-12))
    top = pb.mesh.node_set("top")
    F = np.array([-sol.reactions(k)[top, 0].sum() for k in range(20)])  # friction force on the body
    sliding = []
    for k in range(20):
        c = sol.contact(k)
        closed = c["status"] != "open"
        sliding.append(bool(np.all(c["status"][closed] == "slip")))
        assert np.isclose(np.sum(c["area"] * c["p_N"]), min(2 * sol.increments[k].t, 1), rtol=1e-10)
    first = sliding.index(True)
    assert all(sliding[first:]) and first > 10  # slides only in the tangential phase, then for good
    assert np.allclose(np.abs(F[first:]), MU, rtol=1e-10)  # mu N, N = 1
    assert np.all(np.abs(F[:first]) < MU)
    assert np.abs(F[first - 1]) + np.max(np.diff(np.abs(F[:first]))) >= MU  # within one increment
    print("tangential reaction / N:", np.round(np.abs(F), 6))


def test_path_dependent_ddm_equals_central_fd_of_the_load_path(small):
    """DDM (paper eq. 6 with history terms) vs central FD of the whole load path
    (re-run with phi +- h, same increments, rtol 1e-11), h = 1e-6 max(|phi|, 1):
    all unknowns (displacements and both multipliers) at an intermediate and at
    the last increment, to 1e-5 relative."""
    pb, sol = small
    ks = [2, STEPS - 1]
    for k in ks:
        assert all(n > 0 for n in states(sol.contact(k)).values())
    for name in ("R", "mu", "E"):
        fd = sg.finite_difference(pb, name, lambda s: np.stack([s.increments[k].w for k in ks]),
                                  steps=STEPS, options=TIGHT, rel_step=1e-6)
        for j, k in enumerate(ks):
            ddm = sol.w_sensitivity(name, k)
            err = np.max(np.abs(ddm - fd[j])) / np.max(np.abs(ddm))
            print(f"DDM vs FD, {name}, increment {k}: {err:.2e}")
            assert err <= 1e-5


def test_solution_and_sensitivities_independent_of_eps(small):
    """THEORY 3: the converged solution does not depend on eps_N, eps_T, and the
    DDM sensitivities with respect to them are numerically zero."""
    pb, sol = small
    e = pb.params["eps"]
    for eps, eps_t in ((10 * e, 0.1 * e), (0.2 * e, 5 * e)):
        other = sg.solve(pb.with_params(eps=eps, eps_t=eps_t), steps=STEPS, options=TIGHT)
        for a, b in zip(sol.increments, other.increments):
            assert np.linalg.norm(b.w - a.w) <= 1e-8 * np.linalg.norm(a.w)
    w = sol.increments[-1].w
    for name in ("eps", "eps_t"):
        for k in range(STEPS):
            assert np.linalg.norm(sol.w_sensitivity(name, k)) * e <= 1e-8 * np.linalg.norm(w)


def test_mu_zero_reproduces_frictionless_element():
    """Coulomb with mu = 0 gives the AugmentedLagrangian solution and sensitivities."""
    fric = hf.hertz_friction_problem({"mu": 0.0}, n_fine=12, size=10)
    same = {k: fric.params[k] for k in ("E", "nu", "P", "R")}
    fl = hertz.hertz_problem(same, n_fine=12, size=10, nominal=same)  # the same mesh
    a = sg.solve(fric, steps=2, wrt=["R", "E"], options=TIGHT)
    b = sg.solve(fl, steps=2, wrt=["R", "E"], options=TIGHT)
    for k in range(2):
        assert np.allclose(a.displacement(k), b.displacement(k), rtol=0,
                           atol=1e-10 * np.abs(b.displacement(k)).max())
        ca, cb = a.contact(k), b.contact(k)
        assert np.allclose(ca["p_N"], cb["p_N"], rtol=0, atol=1e-10 * cb["p_N"].max())
        assert np.max(np.abs(ca["p_T"])) <= 1e-14 * cb["p_N"].max()
        for n in ("R", "E"):
            d = cb[f"dp_N_d{n}"]
            assert np.allclose(ca[f"dp_N_d{n}"], d, rtol=0, atol=1e-9 * np.abs(d).max())


def test_newton_quadratic_with_finite_strain_friction():
    """Neo-Hooke block, finite contact kinematics, friction: the exact (unsymmetric)
    tangent gives a quadratic step r_{k+1} <= r_k^2 / r_0 near the end of every increment."""
    pb = hf.hertz_friction_problem(n_fine=12, size=10, finite_strain=True)
    sol = sg.solve(pb, steps=STEPS, options=TIGHT)
    assert all(n > 0 for n in states(sol.contact()).values())
    for inc in sol.increments:
        r = inc.newton.residuals
        print("Newton |R|:", " ".join(f"{v:.2e}" for v in r))
        pairs = list(zip(r[-4:-1], r[-3:]))
        assert any(a <= 0.1 * r[0] and b <= a * a / r[0] for a, b in pairs), r


def test_errors_are_clear(small):
    pb, sol = small
    with pytest.raises(sg.InputError, match="friction coefficient"):
        sg.solve(pb.with_params(mu=-0.1))
    with pytest.raises(sg.InputError, match="history"):
        jax.eval_shape(lambda w: sol.model.residual(w, sol.jax_params, 1.0), jnp.zeros(sol.model.n_dof))
    with pytest.raises(sg.InputError, match="multiple of 3"):
        hf_cmd.run("/nonexistent/never-written", steps=4)
