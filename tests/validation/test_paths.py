"""Load paths: Taylor remainder of the path-dependent DDM (Coulomb friction),
and path independence of the frictionless solution (1 increment = 10 increments),
which friction breaks.

Small meshes (n_fine = 8, block 5 a: 510 DOFs frictional, 289 frictionless) so
that the whole file runs in ~10 s, most of it JIT compilation; one re-run of a
6-increment frictional load path costs ~0.03 s.
"""

import numpy as np
import pytest

import signorini as sg
from signorini.problems import hertz, hertz_friction as hf

# the meshes are deliberately coarse (4-6 closed nodes): silence the resolution warning
pytestmark = pytest.mark.filterwarnings("ignore:contact .* the contact zone holds only")

STEPS = 6
MU = 0.3
# rtol 1e-13 is the tightest that converges here (1e-14 is below the residual's
# round-off floor: Newton stalls and cuts the first increment to nothing). It
# puts the noise floor of |u(phi+h) - u(phi)| at ~1e-13 (mu) .. 1.5e-12 (R),
# against |w| = 4.8; with rtol 1e-12 the floor is ~3e-12 and already bends the
# mu remainder at h/phi = 1e-5.
TAYLOR = sg.NewtonOptions(rtol=1e-13)
TIGHT = sg.NewtonOptions(rtol=1e-12)
# h/phi = 1e-2 ... 1e-5: three decades. Above 1e-2 some node changes state
# within the load path (measured: R + 0.02 R turns a node of increment 3 from
# stick to slip, R - 0.03 R one of increment 5, mu - 0.02 mu one of increment 3),
# and the solution is only piecewise smooth in phi across such a switch; below
# 1e-5 the remainder (3e-10 for R, 4e-12 for mu) reaches the noise floor above.
REL_STEPS = (1e-2, 1e-3, 1e-4, 1e-5)
FLOOR_STEP = 1e-8  # remainder here = Newton noise only (h^2 term ~1e-17)


def states(c):
    return {k: int((c["status"] == k).sum()) for k in ("open", "stick", "slip")}


@pytest.fixture(scope="module")
def friction():
    pb = hf.hertz_friction_problem({"mu": MU}, n_fine=8, size=5)
    sol = sg.solve(pb, steps=STEPS, wrt=["R", "mu"], options=TAYLOR)
    return pb, sol


def status_path(sol):
    return [sol.contact(k)["status"] for k in range(len(sol.increments))]


def slope(h, r):
    return float(np.polyfit(np.log10(h), np.log10(r), 1)[0])


@pytest.mark.parametrize("name", ["R", "mu"])
def test_taylor_remainder_of_frictional_load_path(friction, name):
    """r(h) = |w(phi+h) - w(phi) - h dw/dphi| at the last of 6 increments, the whole
    path re-run at phi + h, dw/dphi the path-dependent DDM of the base run: r ~ h^2
    (slope 2 +- 0.2, each decade a factor 100 +- 0.2 decades) and r << h |dw/dphi|.
    Control: the DDM of a ONE-increment path (a different, wrong derivative for the
    6-increment path, the final load being the same) gives r ~ h, which this test
    rejects."""
    pb, sol = friction
    base_status = status_path(sol)
    for k in range(STEPS):  # open, stick and slip nodes at every increment
        c = sol.contact(k)
        assert all(n > 0 for n in states(c).values()), (k, states(c))
    c = sol.contact()
    off_axis_stick = (c["status"] == "stick") & (c["x_ref"][:, 0] > 0)
    assert off_axis_stick.any()  # a real stick node, not only the symmetry node (u_x prescribed)

    phi = pb.params[name]
    w0 = sol.increments[-1].w
    d = sol.w_sensitivity(name)
    # (both names, as the fixture: its compiled DDM programs)
    d_one_step = sg.solve(pb, steps=1, wrt=["R", "mu"], options=TAYLOR).w_sensitivity(name)

    def run(h):
        s = sg.solve(pb.with_params(**{name: phi + h}), steps=STEPS, options=TAYLOR)
        # no node changes stick/slip/open state at any increment of the path
        for k, st in enumerate(status_path(s)):
            assert np.array_equal(st, base_status[k]), (name, h, k, st, base_status[k])
        return s.increments[-1].w - w0

    hs = np.array([f * abs(phi) for f in REL_STEPS])
    dw = [run(h) for h in hs]
    r = np.array([np.linalg.norm(x - h * d) for x, h in zip(dw, hs)])
    r_bad = np.array([np.linalg.norm(x - h * d_one_step) for x, h in zip(dw, hs)])
    floor = np.linalg.norm(run(FLOOR_STEP * abs(phi)) - FLOOR_STEP * abs(phi) * d)
    lin = hs * np.linalg.norm(d)

    print(f"\nTaylor remainder, {name} = {phi}, |dw/d{name}| = {np.linalg.norm(d):.4e}, "
          f"noise floor (h/phi = {FLOOR_STEP:g}) = {floor:.2e}")
    print(f"{'h/phi':>8} {'h':>10} {'r(h)':>11} {'r(h/10)/r(h)':>13} {'r/(h|dw|)':>10}"
          f" {'r, 1-inc DDM':>13}")
    for i, (h, ri) in enumerate(zip(hs, r)):
        ratio = f"{r[i - 1] / ri:13.2f}" if i else " " * 13
        print(f"{h / abs(phi):8.0e} {h:10.3e} {ri:11.4e} {ratio} {ri / lin[i]:10.2e} {r_bad[i]:13.4e}")
    p, p_bad = slope(hs, r), slope(hs, r_bad)
    print(f"fitted slope {p:.4f}; with the one-increment DDM {p_bad:.4f}")

    assert r[-1] >= 10 * floor  # the whole range is above the Newton noise
    assert abs(p - 2) <= 0.2
    ratios = r[:-1] / r[1:]
    assert np.all((ratios >= 10 ** 1.8) & (ratios <= 10 ** 2.2)), ratios
    assert np.all(r <= 0.05 * lin)  # the remainder is a small correction ...
    assert r[-1] <= 1e-3 * lin[-1]  # ... that vanishes relative to h |dw/dphi|
    assert abs(p_bad - 1) <= 0.2  # the wrong derivative is caught: first-order remainder


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def _one_vs_ten(pb, names):
    one = sg.solve(pb, steps=1, wrt=names, options=TIGHT)
    ten = sg.solve(pb, steps=10, wrt=names, options=TIGHT)
    diff = {"u": _rel(one.displacement(), ten.displacement()),
            "lambda": _rel(one.multipliers(), ten.multipliers())}
    for n in names:
        diff[f"dw/d{n}"] = _rel(one.w_sensitivity(n), ten.w_sensitivity(n))
    return one, ten, diff


# Tolerance of the path-independence statement. Reference: the two runs stop
# Newton at rtol 1e-12 from different starting points, so they differ by the
# stopping error times the conditioning; measured 5e-15 (u), 4e-13 (lambda),
# 1e-11 .. 4e-11 (DDM sensitivities, one back-substitution with the tangent at
# slightly different w). 1e-9 leaves a margin of 20 over the worst of these, and
# is 4 orders below the DDM-vs-FD agreement of test_hertz (1e-5) and 6 orders
# below the real path dependence of friction (1.9e-3 and more, last test).
PATH_TOL = 1e-9


def test_frictionless_one_increment_equals_ten():
    """Linear elasticity + frictionless AL contact (geometrically linear gap) is the
    minimisation of a convex energy under g >= 0: the solution at t = 1 and its DDM
    sensitivities do not depend on the load path."""
    pb = hertz.hertz_problem(n_fine=8, size=5)
    names = ["R", "E", "P", "bump"]
    one, ten, diff = _one_vs_ten(pb, names)
    c = ten.contact()
    assert (c["p_N"] > 0).sum() >= 4 and (c["p_N"] == 0).any()  # open and closed nodes
    assert np.array_equal(one.contact()["p_N"] > 0, c["p_N"] > 0)
    print("\nfrictionless, 1 vs 10 increments (relative 2-norm differences):")
    for k, v in diff.items():
        print(f"  {k:>10}: {v:.2e}")
    assert all(v <= PATH_TOL for v in diff.values()), diff


def test_friction_one_increment_differs_from_ten(friction):
    """The same statement fails with Coulomb friction, mu = 0.3 (path dependence is
    real: the stick zone of the 10-increment path is larger), and holds again on the
    same model with mu = 0 -- so the frictionless test above can fail, and what
    makes it fail is friction, not the frictional code path."""
    pb, _ = friction
    one, ten, diff = _one_vs_ten(pb, ["R", "mu"])
    _, _, diff0 = _one_vs_ten(pb.with_params(mu=0.0), ["R", "mu"])
    print("\nCoulomb, 1 vs 10 increments (relative 2-norm differences):")
    for k in diff:
        print(f"  {k:>8}: mu = {MU}: {diff[k]:.2e}   mu = 0: {diff0[k]:.2e}")
    print("  status, 1 increment:  ", " ".join(one.contact()["status"][:8]))
    print("  status, 10 increments:", " ".join(ten.contact()["status"][:8]))
    assert all(v <= PATH_TOL for v in diff0.values()), diff0
    assert all(v >= 1e6 * PATH_TOL for v in diff.values()), diff
    assert states(ten.contact())["stick"] > states(one.contact())["stick"]
