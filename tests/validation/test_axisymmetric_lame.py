"""Axisymmetric analysis against Lamé's analytical thick-walled cylinder under
internal pressure (docs/theory.md §5.3): the radial displacement, its exact
sensitivity to the pressure, and second-order convergence under refinement."""

from __future__ import annotations

import numpy as np

import signorini as sg
from signorini.fem.kinematics import Axisymmetric

E, NU = 200.0, 0.3


def lame_ur(r, a, b, p):
    """Radial displacement of a thick-walled cylinder (radii a < b) under internal
    pressure p with u_z = 0 (plane strain along the axis): Lamé's solution
    u_r = (1 + nu) p a^2 / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r)."""
    return (1 + NU) * p * a**2 / (E * (b**2 - a**2)) * ((1 - 2 * NU) * r + b**2 / r)


def test_thick_cylinder_matches_lame():
    a, b, p = 1.0, 2.0, 3.0
    mesh = sg.rectangle(np.linspace(a, b, 17), np.linspace(0.0, 0.25, 3))
    pb = sg.Problem(mesh, sg.LinearElastic(), {"E": E, "nu": NU, "p": p},
                    fixed=(sg.Fixed("bottom", 1), sg.Fixed("top", 1)),
                    loads=(sg.Pressure("left", "p"),), kinematics=Axisymmetric())
    sol = sg.solve(pb, wrt=["p"])
    R = mesh.nodes[:, 0]
    ur = sol.displacement()[:, 0]
    exact = lame_ur(R, a, b, p)
    err = np.max(np.abs(ur - exact)) / np.max(np.abs(exact))
    print(f"Lamé: max relative error of u_r on a 16 x 2 mesh: {err:.2e}")
    assert err < 5e-3
    assert np.abs(sol.displacement()[:, 1]).max() < 1e-12  # u_z = 0 everywhere
    # linear problem: Du/Dp = u/p
    np.testing.assert_allclose(sol.displacement_sensitivity("p"), sol.displacement() / p, atol=1e-14)


def test_lame_error_decreases_with_refinement():
    a, b, p = 1.0, 2.0, 3.0
    errs = []
    for n in (4, 8, 16):
        mesh = sg.rectangle(np.linspace(a, b, n + 1), np.linspace(0.0, 0.25, 3))
        pb = sg.Problem(mesh, sg.LinearElastic(), {"E": E, "nu": NU},
                        fixed=(sg.Fixed("bottom", 1), sg.Fixed("top", 1)),
                        loads=(sg.Pressure("left", p),), kinematics=Axisymmetric())
        ur = sg.solve(pb).displacement()[:, 0]
        exact = lame_ur(mesh.nodes[:, 0], a, b, p)
        errs.append(np.max(np.abs(ur - exact)) / np.max(np.abs(exact)))
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print("Lamé errors:", errs, "rates:", rates)
    assert np.all(rates > 1.5)  # ~2nd order for nodal displacements
