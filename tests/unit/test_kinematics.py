"""Axisymmetric kinematics and the F-bar formulation (signorini.fem.kinematics,
signorini.fem.element; docs/theory.md §5.3, §7): element tangents for both
kinematics and formulations, F-bar's one volume change per element, areas and
loads on surfaces of revolution, a mesh crossing the axis. Lamé's analytical
cylinder is in tests/validation/test_axisymmetric_lame.py."""

from __future__ import annotations

import numpy as np
import pytest

import signorini as sg
from signorini.fem import element
from signorini._jax import jax, jnp
from signorini.fem.kinematics import AXISYMMETRIC, PLANE_STRAIN, Axisymmetric
from signorini.params import as_jax

E, NU = 200.0, 0.3


@pytest.mark.parametrize("formulation", [element.STANDARD, element.FBAR], ids=["standard", "fbar"])
@pytest.mark.parametrize("kinematics", [PLANE_STRAIN, AXISYMMETRIC], ids=["plane", "axi"])
def test_element_tangent_is_jacfwd_of_residual(kinematics, formulation):
    Xe = jnp.asarray([[0.3, 0.0], [1.1, 0.1], [1.0, 0.9], [0.2, 1.2]])
    rng = np.random.default_rng(4)
    ue = jnp.asarray(0.05 * rng.standard_normal((4, 2)))
    mat = sg.NeoHooke()
    mp = mat.values(as_jax({"E": E, "nu": NU}))
    r, K, _ = element.element_residual_tangent(ue, Xe, mat, mp, None, kinematics, formulation)
    f = lambda u: element.element_residual(u.reshape(4, 2), Xe, mat, mp, None, kinematics,
                                           formulation).ravel()
    K_ref = np.asarray(jax.jacfwd(f)(ue.ravel()))
    np.testing.assert_allclose(np.asarray(r), np.asarray(f(ue.ravel())), rtol=0, atol=1e-12 * E)
    assert np.abs(np.asarray(K) - K_ref).max() <= 1e-10 * np.abs(K_ref).max()
    assert np.abs(np.asarray(K) - np.asarray(K).T).max() <= 1e-10 * np.abs(K_ref).max()  # hyperelastic


def test_fbar_hyperelastic_is_selective_reduced_integration():
    """For a hyperelastic material sum_g w_g W(Fbar_g) = sum_g w_g W_iso(F_g) + V_e U(J_0):
    F-bar integrates the volumetric energy at the centroid. Checked through the
    isochoric invariance: Fbar_g has det = J_0 at every Gauss point."""
    Xe = jnp.asarray([[0.0, 0.0], [1.0, 0.0], [1.2, 1.0], [0.1, 0.8]])
    ue = jnp.asarray([[0.0, 0.0], [0.1, -0.02], [0.05, 0.08], [-0.03, 0.04]])
    H, _ = element.gauss_gradients(ue, Xe, PLANE_STRAIN, element.FBAR)
    Hs, _ = element.gauss_gradients(ue, Xe, PLANE_STRAIN, element.STANDARD)
    dets = np.linalg.det(np.eye(3) + np.asarray(H))
    assert np.ptp(dets) < 1e-14  # one volume change per element
    assert np.ptp(np.linalg.det(np.eye(3) + np.asarray(Hs))) > 1e-3  # the standard one varies
    # the deviatoric (isochoric) part is that of F_g: Fbar_g = c_g F_g
    with np.errstate(divide="ignore", invalid="ignore"):
        c = (np.eye(3) + np.asarray(H)) / (np.eye(3) + np.asarray(Hs))
    for g in range(4):
        cg = c[g][np.isfinite(c[g]) & (np.abs(np.eye(3) + np.asarray(Hs)[g]) > 1e-12)]
        assert np.ptp(cg) < 1e-13


def test_fbar_needs_a_finite_strain_material():
    mesh = sg.rectangle([0.0, 1.0], [0.0, 1.0])
    pb = sg.Problem(mesh, sg.LinearElastic(), {"E": E, "nu": NU}, formulation=element.FBAR,
                    fixed=(sg.Fixed("bottom", 0), sg.Fixed("bottom", 1)))
    with pytest.raises(sg.InputError, match="finite-strain materials"):
        sg.solve(pb)


def test_axisymmetric_areas_and_loads_integrate_exactly():
    """A_S add up to the lateral area of the surface of revolution, stay positive on
    the axis, and a resultant pressure is exactly its resultant."""
    mesh = sg.rectangle(np.linspace(0.0, 1.5, 7), np.linspace(0.0, 1.0, 4))
    X = jnp.asarray(mesh.nodes)
    top = mesh.edge_set("top")
    A = np.asarray(sg.equivalent_areas(X, top, kinematics=AXISYMMETRIC))
    assert np.isclose(A.sum(), np.pi * 1.5**2, rtol=1e-14)  # the top disc
    assert A.min() > 0  # including the node on the axis
    right = mesh.edge_set("right")
    Ar = np.asarray(sg.equivalent_areas(X, right, kinematics=AXISYMMETRIC))
    assert np.isclose(Ar.sum(), 2 * np.pi * 1.5 * 1.0, rtol=1e-14)  # the lateral cylinder
    f = sg.Pressure("top", 7.0, resultant=True).nodal_forces(X, top, {}, 1.0, AXISYMMETRIC)
    assert np.isclose(float(f[..., 1].sum()), -7.0, rtol=1e-14)  # pushes down, total 7
    f2 = sg.Pressure("top", 2.0).nodal_forces(X, top, {}, 1.0, AXISYMMETRIC)
    assert np.isclose(float(f2[..., 1].sum()), -2.0 * np.pi * 1.5**2, rtol=1e-14)


def test_axisymmetric_mesh_must_not_cross_the_axis():
    mesh = sg.rectangle(np.linspace(-0.5, 1.0, 4), np.linspace(0.0, 1.0, 3))
    pb = sg.Problem(mesh, sg.LinearElastic(), {"E": E, "nu": NU}, kinematics=Axisymmetric(),
                    fixed=(sg.Fixed("bottom", 1),))
    with pytest.raises(sg.InputError, match="R >= 0"):
        sg.solve(pb)
