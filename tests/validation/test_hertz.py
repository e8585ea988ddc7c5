"""Frictionless plane-strain Hertz (paper 5.1) against the analytical solution (eq. 22),
and its DDM sensitivities against central differences."""

import numpy as np
import pytest

import signorini as sg
from signorini.problems import hertz

P, R, E, NU = 1.2, 1.0, 100.0, 0.3  # paper 5.1
AN = hertz.analytical(P, R, E, NU)
TIGHT = sg.NewtonOptions(rtol=1e-11)


@pytest.fixture(scope="module")
def default():
    pb = hertz.hertz_problem()
    return pb, sg.solve(pb, wrt=["R", "E", "P", "bump", "eps"], options=TIGHT)


def rms_error(sol):
    """RMS pressure error over |x| < 0.9 a, relative to p0 (eq. 22)."""
    c = sol.contact()
    x = c["x_ref"][:, 0]
    m = x < 0.9 * AN["a"]
    return np.sqrt(np.mean((c["p_N"][m] - hertz.pressure(x[m], P, R, E, NU)) ** 2)) / AN["p0"]


def test_peak_pressure_and_half_width(default):
    pb, sol = default
    c = sol.contact()
    assert abs(c["p_N"].max() / AN["p0"] - 1) < 0.01  # issue: within 1 % of p0 = 2P/(pi a)
    x = c["x_ref"][:, 0]
    a_fe = x[c["p_N"] > 0].max()
    assert abs(a_fe - AN["a"]) <= hertz.fine_cell_size(pb)  # within one element of a


def test_pressure_profile_and_equilibrium(default):
    pb, sol = default
    c = sol.contact()
    assert rms_error(sol) < 0.01
    # vertical equilibrium: sum A p n_y balances the applied P/2 (half model)
    closed = c["p_N"] > 0
    assert np.isclose(np.sum(c["area"][closed] * c["p_N"][closed]), P / 2, rtol=5e-3)


def test_error_decreases_under_refinement(default):
    _, sol0 = default
    sol1 = sg.solve(hertz.hertz_problem(refine=1), options=TIGHT)
    e0, e1 = rms_error(sol0), rms_error(sol1)
    assert e1 < e0, (e0, e1)


def test_signorini_conditions_exact(default):
    """AL at convergence: g >= 0, p_N >= 0, g p_N = 0 at every node (THEORY 2)."""
    _, sol = default
    c = sol.contact()
    assert c["gap"].min() >= -1e-10 * R
    assert c["p_N"].min() >= -1e-12 * AN["p0"]  # zero to solver tolerance at open nodes
    assert np.max(np.abs(c["gap"] * c["p_N"])) <= 1e-10 * R * AN["p0"]
    assert (c["p_N"] > 0).sum() >= 10  # a real contact zone, not a single node


def test_solution_independent_of_eps(default):
    pb, sol = default
    eps = pb.params["eps"]
    other = sg.solve(pb.with_params(eps=100 * eps), options=TIGHT)
    w0, w1 = sol.increments[-1].w, other.increments[-1].w
    assert np.linalg.norm(w1 - w0) <= 1e-8 * np.linalg.norm(w0)


def test_ddm_sensitivity_wrt_eps_is_zero(default):
    """Paper section 6: eps as a 'design' parameter gives a numerical zero."""
    pb, sol = default
    eps = pb.params["eps"]
    wd = sol.w_sensitivity("eps")
    w = sol.increments[-1].w
    assert np.linalg.norm(wd) * eps <= 1e-8 * np.linalg.norm(w)


@pytest.mark.parametrize("name", ["R", "E", "P", "bump"])
def test_ddm_equals_central_fd(default, name):
    """DDM vs central FD (step 1e-4 relative, keeps the active set) of the contact
    pressure on |x| < 0.9 a (p_N is not differentiable at x = a, THEORY 8), the
    multipliers and all displacements."""
    pb, sol = default
    c = sol.contact()
    inner = c["x_ref"][:, 0] < 0.9 * AN["a"]

    def q(s):
        return np.concatenate([s.contact()["p_N"][inner], s.displacement().ravel(),
                               s.multipliers().ravel()])

    fd = sg.finite_difference(pb, name, q, rel_step=1e-4, options=TIGHT)
    ddm = np.concatenate([c[f"dp_N_d{name}"][inner], sol.displacement_sensitivity(name).ravel(),
                          sol.multiplier_sensitivity(name).ravel()])
    assert np.max(np.abs(ddm - fd)) <= 1e-5 * np.max(np.abs(ddm))


def test_pressure_sensitivity_to_radius_matches_analytical(default):
    """Dp_N/DR vs the derivative of eq. 22 at constant P, away from x = a."""
    _, sol = default
    c = sol.contact()
    x = c["x_ref"][:, 0]
    m = x < 0.6 * AN["a"]
    ref = hertz.pressure_dR(x[m], P, R, E, NU)
    err = np.max(np.abs(c["dp_N_dR"][m] - ref)) / (AN["p0"] / (2 * R))
    assert err < 0.05  # 5 % of the scale p0/(2R); the node-wise error is a discretisation error


def test_response_functional_and_reactions(default):
    """DF/Dphi of a user functional (chain rule, eq. 5) and of the symmetry-line
    reactions against central FD."""
    pb, sol = default

    def G(w, p, t):  # compliance-like functional depending on w and explicitly on P
        u = w[: 2 * sol.model.n_nodes].reshape(-1, 2)
        return p["P"] * u[:, 1].mean() + p["R"] * (u ** 2).sum()

    val, d = sol.response(G)
    left = pb.mesh.node_set("left")
    for name in ("R", "P"):
        fd = sg.finite_difference(pb, name, lambda s: s.response(G, with_sensitivities=False)[0],
                                  rel_step=1e-4, options=TIGHT)
        assert np.isclose(d[name], fd, rtol=1e-6), (name, d[name], fd)
        fdr = sg.finite_difference(pb, name, lambda s: s.reactions()[left, 0], rel_step=1e-4,
                                   options=TIGHT)
        ddr = sol.reaction_sensitivity(name)[left, 0]
        assert np.max(np.abs(ddr - fdr)) <= 1e-5 * np.max(np.abs(ddr))


def test_finite_strain_hertz_quadratic_newton_and_ddm():
    """Neo-Hooke block with finite contact kinematics: Newton ends quadratically
    and DDM matches FD through the fully nonlinear problem."""
    pb = hertz.hertz_problem(finite_strain=True, n_fine=12, size=12)
    sol = sg.solve(pb, steps=2, wrt=["R", "E"], options=TIGHT)
    for inc in sol.increments:
        r = inc.newton.residuals
        print("Newton |R|:", " ".join(f"{v:.2e}" for v in r))
        # quadratic: r_k <= C r_{k-1}^2 in the last iterations (C from the scale of r_0)
        assert r[-1] <= 10 * r[-2] ** 2 / r[0] + 1e-12 * r[0]
    c = sol.contact()
    assert abs(c["p_N"].max() / AN["p0"] - 1) < 0.05  # finite strain: close to Hertz, not equal
    for name in ("R", "E"):
        fd = sg.finite_difference(pb, name, lambda s: s.displacement().ravel(), rel_step=1e-5,
                                  steps=2, options=TIGHT)
        ddm = sol.displacement_sensitivity(name).ravel()
        assert np.max(np.abs(ddm - fd)) <= 1e-5 * np.max(np.abs(ddm))


def test_obstacle_centre_and_poisson_ratio_as_design_parameters():
    """Centre: under force control, raising the cylinder by cy only translates the
    body, so exactly Du/Dcy = (0, 1) at every node and Dp_N/Dcy = 0. Exact with the
    finite contact kinematics (the linearised gap is taken about X and is not
    invariant under a common translation of body and obstacle). nu: DDM vs FD."""
    import dataclasses

    pb = hertz.hertz_problem(n_fine=8, size=8)
    circle = sg.Circle(radius="R", centre=(0.0, lambda p: p["R"] + p["cy"]))
    c = pb.contact[0]
    pb = dataclasses.replace(pb, params={**pb.params, "cy": 0.0},
                             contact=(sg.Contact(circle, c.edges, c.method, kinematics="finite"),))
    sol = sg.solve(pb, wrt=["cy", "nu"], options=TIGHT)
    du = sol.displacement_sensitivity("cy")
    assert np.allclose(du[:, 0], 0.0, atol=1e-9) and np.allclose(du[:, 1], 1.0, atol=1e-9)
    # Dp_N/Dcy is a pressure per length: its scale is p0/a (measured: 6e-10 of it)
    assert np.max(np.abs(sol.contact()["dp_N_dcy"])) <= 1e-8 * AN["p0"] / AN["a"]
    fd = sg.finite_difference(pb, "nu", lambda s: s.displacement().ravel(), rel_step=1e-4,
                              options=TIGHT)
    ddm = sol.displacement_sensitivity("nu").ravel()
    assert np.max(np.abs(ddm - fd)) <= 1e-5 * np.max(np.abs(ddm))
