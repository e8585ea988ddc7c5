"""Q4 element, material and tangent invariants.

Reference values are exact by construction (shoelace area, analytical
plane-strain / neo-Hookean stresses, rigid-body motions), or come from an
independent differentiation (``jax.jacfwd``, central finite differences).
"""

from __future__ import annotations


import numpy as np
import pytest

import signorini as sg
from signorini.fem import element
from signorini._jax import jax, jnp
from signorini.model.kernels import Model
from signorini.params import as_jax
from signorini.problems.hertz import hertz_problem
from signorini.algorithms.stepping import model_for

PARAMS = {"E": 100.0, "nu": 0.3}


def lame(E, nu):
    """Textbook Lame constants (mu, lambda), written out independently of src."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def shoelace(P):
    """Exact area of a simple polygon with counter-clockwise vertices P (n, 2)."""
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# a convex quad that is not a parallelogram (so det J varies over the element)
QUAD = np.array([[0.0, 0.0], [2.0, 0.3], [2.4, 1.9], [-0.3, 1.2]])


def distorted_mesh():
    """3x3 cells on a non-uniform grid, interior nodes moved (cells stay convex)."""
    base = sg.rectangle([0.0, 1.0, 2.5, 3.0], [0.0, 0.8, 1.5, 2.4])
    nodes = base.nodes.copy()
    boundary = np.unique(np.concatenate([base.node_sets[k] for k in ("left", "right", "top", "bottom")]))
    interior = np.setdiff1d(np.arange(base.n_nodes), boundary)
    assert interior.size == 4
    shifts = np.array([[0.17, -0.12], [-0.21, 0.15], [0.13, 0.19], [-0.16, -0.14]])
    nodes[interior] += shifts
    # Mesh() checks the corner Jacobians: it would raise if a cell were inverted
    mesh = sg.Mesh(nodes, base.cells, base.node_sets, base.edge_sets)
    return mesh, interior, boundary


def is_parallelogram(Xe):
    return np.allclose(Xe[0] + Xe[2], Xe[1] + Xe[3])


# ------------------------------------------------------------------ element
def test_reference_area_equals_shoelace():
    assert not is_parallelogram(QUAD)
    _, w = element.reference_gradients(jnp.asarray(QUAD))
    w = np.asarray(w)
    exact = shoelace(QUAD)  # exact polygon area
    assert np.all(w > 0)
    # the 4 weights differ: det J is not constant on a non-parallelogram
    assert np.ptp(w) > 1e-3
    assert abs(w.sum() - exact) <= 1e-13 * exact


def test_partition_of_unity():
    rng = np.random.default_rng(0)
    for xi in rng.uniform(-1.0, 1.0, size=(6, 2)):
        N = np.asarray(element.shape_functions(xi))
        dN = np.asarray(element.shape_gradients(xi))
        assert N.shape == (4,) and dN.shape == (4, 2)
        assert abs(N.sum() - 1.0) < 1e-14
        np.testing.assert_allclose(dN.sum(axis=0), 0.0, atol=1e-14)
    # Kronecker property at the corners (counter-clockwise from (-1, -1))
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    for a, xi in enumerate(corners):
        np.testing.assert_allclose(np.asarray(element.shape_functions(np.array(xi, float))),
                                   np.eye(4)[a], atol=1e-15)


def test_gradients_reproduce_linear_field():
    """dN/dX of a distorted quad differentiates X itself exactly: sum_a X_a (x) dN_a/dX = I."""
    dNdX, _ = element.reference_gradients(jnp.asarray(QUAD))
    G = np.einsum("ai,gaj->gij", QUAD, np.asarray(dNdX))
    np.testing.assert_allclose(G, np.broadcast_to(np.eye(2), G.shape), atol=1e-14)


# ------------------------------------------------------------- patch tests
def _patch(material, A, b):
    mesh, interior, boundary = distorted_mesh()
    assert not all(is_parallelogram(mesh.nodes[c]) for c in mesh.cells)
    problem = sg.Problem(mesh=mesh, material=material, params=PARAMS)
    model = Model(problem)
    u = mesh.nodes @ A.T + b  # u = A X + b at every node
    w = jnp.asarray(u.ravel())
    params = as_jax(problem.params)
    R = np.asarray(jax.jit(model.residual)(w, params, 0.0)).reshape(-1, 2)
    return model, w, params, R, interior, boundary


A_LIN = np.array([[0.3, -0.7], [0.45, -0.2]])  # arbitrary, non-symmetric
A_NH = np.array([[0.04, -0.07], [0.05, -0.03]])  # small: F = I + A, det F > 0
B = np.array([0.3, -1.1])


@pytest.mark.parametrize("material, A", [(sg.LinearElastic(), A_LIN), (sg.NeoHooke(), A_NH)],
                         ids=["linear", "neohooke"])
def test_patch_test_interior_residual_vanishes(material, A):
    _, _, _, R, interior, boundary = _patch(material, A, B)
    scale = np.abs(R[boundary]).max()
    # the boundary carries the tractions of the homogeneous stress: |sigma| ~ E |A| ~ 5..50
    # times edge lengths ~0.5..1.5, so O(1..50) nodal forces
    assert scale > 1.0
    assert np.abs(R[interior]).max() <= 1e-12 * scale


def test_patch_test_linear_elastic_stress():
    model, w, params, _, _, _ = _patch(sg.LinearElastic(), A_LIN, B)
    mu, lam = lame(**PARAMS)
    eps = 0.5 * (A_LIN + A_LIN.T)
    sig2 = lam * np.trace(eps) * np.eye(2) + 2.0 * mu * eps
    exact = np.zeros((3, 3))
    exact[:2, :2] = sig2
    exact[2, 2] = lam * np.trace(eps)  # plane strain: sigma_zz = lambda tr(eps)
    S = np.asarray(jax.jit(model.stresses)(w, params))
    assert S.shape == (9, 3, 3)
    assert np.abs(S - exact).max() <= 1e-10 * np.abs(exact).max()


def test_patch_test_neohooke_stress():
    model, w, params, _, _, _ = _patch(sg.NeoHooke(), A_NH, B)
    mu, lam = lame(**PARAMS)
    F = np.eye(3)
    F[:2, :2] += A_NH
    J = np.linalg.det(F)
    # compressible neo-Hooke: sigma = (mu (F F^T - I) + lambda ln J I) / J
    exact = (mu * (F @ F.T - np.eye(3)) + lam * np.log(J) * np.eye(3)) / J
    S = np.asarray(jax.jit(model.stresses)(w, params))
    assert np.abs(S - exact).max() <= 1e-10 * np.abs(exact).max()


# ------------------------------------------------------- rigid-body motion
_jit_element_residual = jax.jit(element.element_residual, static_argnums=2)


def _element_residual(material, ue, Xe=QUAD):
    mp = material.values(as_jax(PARAMS))
    return np.asarray(_jit_element_residual(jnp.asarray(ue), jnp.asarray(Xe), material, mp))


def test_neohooke_rigid_rotation_gives_zero_residual():
    th = np.deg2rad(30.0)
    Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    c = np.array([0.7, -1.3])
    ue = QUAD @ (Q - np.eye(2)).T + c  # x = Q X + c
    r = _element_residual(sg.NeoHooke(), ue)
    # force scale of the element: E * size (unit strain); a 1 % stretch gives ~ (lambda + 2 mu)
    # * 0.01 * size ~ 5e-3 of it, far above the 1e-12 round-off bound
    scale = PARAMS["E"] * np.ptp(QUAD, axis=0).max()
    r_stretch = _element_residual(sg.NeoHooke(), 0.01 * QUAD * np.array([1.0, 0.0]))
    assert np.abs(r_stretch).max() > 1e-3 * scale
    assert np.abs(r).max() <= 1e-12 * scale
    # linear elasticity is not rotation invariant: eps = (cos 30 - 1) I = -0.13 I loads it
    assert np.abs(_element_residual(sg.LinearElastic(), ue)).max() > 1e-2 * scale


def test_linear_elastic_translation_gives_zero_residual():
    ue = np.tile([0.7, -1.3], (4, 1))
    r = _element_residual(sg.LinearElastic(), ue)
    assert np.abs(r).max() <= 1e-14 * PARAMS["E"]
    np.testing.assert_allclose(r.sum(axis=0), 0.0, atol=1e-14)


# ----------------------------------------------------------------- tangents
def test_element_tangents_match_jacfwd_and_finite_differences():
    mesh, _, _ = distorted_mesh()
    material = sg.NeoHooke()
    problem = sg.Problem(mesh=mesh, material=material, params=PARAMS)
    model = Model(problem)
    params = as_jax(problem.params)
    rng = np.random.default_rng(1)
    w = 0.05 * rng.standard_normal(model.n_dof)
    R, blocks = model.local_tangents(jnp.asarray(w), params, 0.0)
    (Ke,) = blocks
    assert Ke.shape == (mesh.n_cells, 8, 8)
    # residual of local_tangents = the pure residual function
    R_ref = np.asarray(jax.jit(model.residual)(jnp.asarray(w), params, 0.0))
    assert np.abs(R - R_ref).max() <= 1e-12 * np.abs(R_ref).max()
    mp = material.values(params)

    def r(v, Xe):
        return element.element_residual(v.reshape(4, 2), Xe, material, mp).ravel()

    r_jit = jax.jit(r)
    jac = jax.jit(jax.jacfwd(r))
    u = w.reshape(-1, 2)
    for e, cell in enumerate(mesh.cells):
        Xe = jnp.asarray(mesh.nodes[cell])
        ue = jnp.asarray(u[cell].ravel())
        K_ref = np.asarray(jac(ue, Xe))
        scale = np.abs(K_ref).max()
        assert np.abs(Ke[e] - K_ref).max() <= 1e-10 * scale
        # hyperelastic: symmetric tangent
        assert np.abs(Ke[e] - Ke[e].T).max() <= 1e-10 * scale
        # central finite differences (independent of JAX's differentiation), step 1e-6:
        # truncation ~1e-12 and round-off ~1e-10 relative
        h = 1e-6
        K_fd = np.column_stack([(np.asarray(r_jit(ue + h * d, Xe)) - np.asarray(r_jit(ue - h * d, Xe)))
                                / (2 * h) for d in np.eye(8)])
        assert np.abs(Ke[e] - K_fd).max() <= 1e-7 * scale


# ------------------------------------------- assembled tangent with contact
_CACHE: dict = {}


def hertz_case(finite_strain: bool):
    """Small Hertz problem, its model, converged state and a jitted reference
    function w -> (dR/dw dense, R, gap, area) (built once per module)."""
    if finite_strain not in _CACHE:
        problem = hertz_problem(n_fine=4, size=6, finite_strain=finite_strain)
        sol = sg.solve(problem)
        model = model_for(problem)

        def reference(w, params):
            def res(v):
                R = model.residual(v, params, 1.0)
                return R, R
            K, R = jax.jacfwd(res, has_aux=True)(w)
            f = model.contact_fields(w, params, 1.0)
            return K, R, f["gap"], f["area"]

        _CACHE[finite_strain] = (problem, model, sol.increments[-1].w.copy(), jax.jit(reference))
    return _CACHE[finite_strain]


def random_state(model, problem, ref, params, seed):
    """Small random displacements and multipliers with lam_hat = lam + eps g of
    chosen, alternating sign (gap evaluated at the random displacements)."""
    rng = np.random.default_rng(seed)
    w = np.zeros(model.n_dof)
    w[: 2 * model.n_nodes] = 1e-3 * rng.standard_normal(2 * model.n_nodes)
    s = model.surfaces[0]
    gap = np.asarray(ref(jnp.asarray(w), params)[2])
    target = rng.uniform(1.0, 5.0, s.nodes.size) * np.where(np.arange(s.nodes.size) % 2, 1.0, -1.0)
    w[s.lam_dofs.ravel()] = target - problem.params["eps"] * gap
    return w


@pytest.mark.parametrize("state", ["converged", "random"])
@pytest.mark.parametrize("finite_strain", [False, True], ids=["linear", "neohooke"])
def test_assembled_tangent_equals_jacfwd_of_residual(finite_strain, state):
    problem, model, w_conv, ref = hertz_case(finite_strain)
    params = as_jax(problem.params)
    w = w_conv if state == "converged" else random_state(model, problem, ref, params, seed=3)
    K_full, R_ref, gap, A = (np.asarray(a) for a in ref(jnp.asarray(w), params))
    s = model.surfaces[0]
    eps = problem.params["eps"]
    lh = w[s.lam_dofs.ravel()] + eps * gap  # closed where lam + eps g <= 0
    closed, opened = lh < 0, lh > 0
    # the state exercises both branches of the contact law, away from the kink lam_hat = 0
    # (random state: |lam_hat| in [1, 5] by construction; converged: >= 0.14, measured)
    assert closed.sum() >= 2 and opened.sum() >= 2
    assert np.abs(lh).min() > 1e-3

    R, blocks = model.local_tangents(jnp.asarray(w), params, 1.0)
    K = model.pattern.assemble(blocks).toarray()
    free = model.free
    K_ref = K_full[np.ix_(free, free)]
    assert K.shape == K_ref.shape == (free.size, free.size)
    assert np.abs(K - K_ref).max() <= 1e-10 * np.abs(K_ref).max()
    assert np.abs(R - R_ref).max() <= 1e-12 * max(np.abs(R_ref).max(), 1.0)

    # analytic contact blocks (pseudo-potential A (<lam_hat>_-^2 - lam^2) / (2 eps)):
    # open: d2/dlam2 = -A/eps, no coupling to x; closed: d2/dlam2 = 0, dR_lam/dx = A grad g != 0
    Kc = blocks[1]
    assert Kc.shape == (s.nodes.size, 3, 3)
    np.testing.assert_allclose(Kc[opened, 2, 2], -A[opened] / eps, rtol=1e-12)
    assert np.abs(Kc[opened][:, :2, :]).max() == 0.0
    assert np.abs(Kc[opened][:, 2, :2]).max() == 0.0
    assert np.abs(Kc[closed, 2, 2]).max() <= 1e-12 * A[closed].max() / eps
    # |grad g| = 1 (finite kinematics) or |N . n'(X)| >= cos 45 deg (linear kinematics: the
    # top face ends at x = 6a ~ 0.7 R), so > 0.5 A
    assert np.all(np.linalg.norm(Kc[closed, 2, :2], axis=1) > 0.5 * A[closed])


class _OtherFBar:
    """The F-bar map under another name: exercises the Gauss-point tangent that
    differentiates a formulation's map by autodiff (FBar's is differentiated by hand)."""

    name = "other"
    linear = False

    def modify(self, H, H0):
        return element.FBAR.modify(H, H0)


# compiled (material, kinematics and formulation static): run op by op, every call
# traced and compiled the J2 return map's loop again (10-20 s per case)
_residual_tangent = jax.jit(element.element_residual_tangent, static_argnums=(2, 5, 6))
_update = jax.jit(element.element_update, static_argnums=(2, 5, 6))


def _update_and_jacobian(ue, Xe, mp, hn, mat, kin):
    """(dr/du_e by forward mode, r, h) of the F-bar element's update kernel."""
    res = lambda u: element.element_update(u.reshape(4, 2), Xe, mat, mp, hn, kin, element.FBAR)
    r, h = res(ue.reshape(8))
    return jax.jacfwd(lambda u: res(u)[0].reshape(8))(ue.reshape(8)), r, h


_update_and_jacobian = jax.jit(_update_and_jacobian, static_argnums=(4, 5))


@pytest.mark.parametrize("formulation", ["fbar", "autodiff"])
@pytest.mark.parametrize("kinematics", ["plane", "axisymmetric"])
@pytest.mark.parametrize("material", ["j2", "neohooke"])
def test_fbar_tangent_equals_forward_jacobian_of_the_element(kinematics, material, formulation):
    """The F-bar tangent is assembled from Gauss-point derivatives (dHbar/dv, by hand
    for FBar or by autodiff for another formulation, dP/dHbar and the curvature of
    the map): it equals the forward-mode Jacobian of the element residual, on
    elastic and plastic J2 states and for a neo-Hookean solid, and the internal
    forces and history equal those of the residual kernel."""
    from signorini.fem.kinematics import AXISYMMETRIC, PLANE_STRAIN
    from signorini.materials import J2Plasticity

    form = element.FBAR if formulation == "fbar" else _OtherFBar()

    kin = PLANE_STRAIN if kinematics == "plane" else AXISYMMETRIC
    rng = np.random.default_rng(3)
    Xe = jnp.asarray(np.array([[1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0]]) + 0.1 * rng.random((4, 2)))
    if material == "j2":
        mat = J2Plasticity()
        mp = {"E": 200.0, "nu": 0.3, "sigma_y": 0.5, "H": 2.0}
    else:
        mat = sg.NeoHooke()
        mp = {"E": 100.0, "nu": 0.3}
    mp = {k: jnp.float64(v) for k, v in mp.items()}
    hn = None
    if mat.n_state:  # a plastic history from a first step
        hn = jnp.broadcast_to(mat.initial_state(), (4, mat.n_state))
        _, hn = _update(jnp.asarray(0.05 * rng.standard_normal((4, 2))), Xe, mat, mp, hn, kin,
                        element.FBAR)
        assert float(jnp.max(hn[:, 9])) > 0.0
    plastic = 0
    for scale in (1e-3, 0.05, 0.15, 0.3):
        ue = jnp.asarray(scale * rng.standard_normal((4, 2)))
        r, K, h = _residual_tangent(ue, Xe, mat, mp, hn, kin, form)
        K_ref, r_ref, h_ref = _update_and_jacobian(ue, Xe, mp, hn, mat, kin)
        K_ref = np.asarray(K_ref)
        assert np.abs(np.asarray(K) - K_ref).max() <= 1e-13 * np.abs(K_ref).max()
        assert np.abs(np.asarray(r) - np.asarray(r_ref).ravel()).max() <= 1e-13 * np.abs(r_ref).max()
        if hn is not None:
            assert np.abs(np.asarray(h) - np.asarray(h_ref)).max() <= 1e-14
            plastic += int(np.any(np.asarray(h)[:, 9] > np.asarray(hn)[:, 9]))
    if hn is not None:
        assert plastic >= 1  # the larger steps yield


@pytest.mark.parametrize("kinematics", ["plane", "axisymmetric"])
@pytest.mark.parametrize("material", ["linear", "neohooke", "j2"])
def test_standard_internal_forces_equal_the_vjp_of_the_gradients(kinematics, material):
    """The standard element's internal forces, summed as w B^T P by hand (hoop row
    included), equal their definition r = (dH/du_e)^T (w P) taken by JAX's VJP of
    the Gauss-point gradients, and the r of the residual-and-tangent kernel."""
    from signorini.fem.kinematics import AXISYMMETRIC, PLANE_STRAIN
    from signorini.materials import J2Plasticity

    kin = PLANE_STRAIN if kinematics == "plane" else AXISYMMETRIC
    mat = {"linear": sg.LinearElastic(), "neohooke": sg.NeoHooke(), "j2": J2Plasticity()}[material]
    mp = {"E": 200.0, "nu": 0.3, "sigma_y": 0.5, "H": 2.0} if material == "j2" else {"E": 100.0, "nu": 0.3}
    mp = {k: jnp.float64(v) for k, v in mp.items()}
    rng = np.random.default_rng(5)
    Xe = jnp.asarray(QUAD + np.array([1.0, 0.0]))  # R > 0 for the axisymmetric case
    hn = jnp.broadcast_to(mat.initial_state(), (4, mat.n_state)) if mat.n_state else None
    for scale in (1e-3, 0.1):
        ue = jnp.asarray(scale * rng.standard_normal((4, 2)))
        r, h = element.element_update(ue, Xe, mat, mp, hn, kin, element.STANDARD)
        w = element.gauss_gradients(ue, Xe, kin, element.STANDARD)[1]
        H, vjp = jax.vjp(lambda u: element.gauss_gradients(u, Xe, kin, element.STANDARD)[0], ue)
        P, h_ref = jax.vmap(mat.update, (0, 0 if hn is not None else None, None))(
            H, hn if hn is not None else jnp.zeros(0), mp)
        (r_ref,) = vjp(w[:, None, None] * P)
        scale_r = float(jnp.abs(r_ref).max())
        assert scale_r > 0.0
        assert float(jnp.abs(r - r_ref).max()) <= 1e-13 * scale_r
        r2 = element.element_residual_tangent(ue, Xe, mat, mp, hn, kin, element.STANDARD)[0]
        assert float(jnp.abs(r2 - r_ref.ravel()).max()) <= 1e-13 * scale_r
        if hn is not None:
            assert float(jnp.abs(h - h_ref).max()) <= 1e-14
