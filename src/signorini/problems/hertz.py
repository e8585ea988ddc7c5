"""Plane-strain Hertz contact of a rigid cylinder on an elastic block (paper 5.1).

Symmetric half model: block 0 <= x <= W, -H <= y <= 0, symmetry u_x = 0 on
x = 0, uniform pressure on the bottom with resultant P/2, so the block is held
only by the contact with the cylinder (centre (0, R), touching at the origin).
The mesh is graded: uniform cells of size ~a/16 near the contact, growing
geometrically away from it; the block is 20 a wide and deep so that it acts
as a half-space.

Design parameters: E, nu, P, R, eps and the shape parameter ``bump`` (the
amplitude of a smooth ring-shaped crown on the top face that leaves the
initial contact point in place; design velocity V = (0, b(X) (1 + Y/H)),
b = s (1 - s)^2 with s = (X/2a)^2 for X < 2a).
"""

from __future__ import annotations

import numpy as np

from ..contact import AugmentedLagrangian, Contact, Penalty
from ..errors import InputError, UnknownParameterError
from ..loads import Fixed, Pressure
from ..materials import LinearElastic, NeoHooke
from ..mesh import graded_coordinates, rectangle
from ..obstacles import Circle
from ..problem import Problem

DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 1.2, "R": 1.0}


def analytical(P, R, E, nu) -> dict:
    """Half-width a, peak pressure p0 and their R-derivatives (THEORY 8, paper eq. 22)."""
    a = np.sqrt(4.0 * P * R * (1.0 - nu**2) / (np.pi * E))
    p0 = 2.0 * P / (np.pi * a)
    return {"a": a, "p0": p0, "da_dR": a / (2 * R), "dp0_dR": -p0 / (2 * R)}


def pressure(x, P, R, E, nu):
    """p_N(x) = p0 sqrt(1 - (x/a)^2) for |x| < a, 0 outside (eq. 22)."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(x) / h["a"]
    return np.where(np.abs(xi) < 1, h["p0"] * np.sqrt(np.clip(1 - xi**2, 0, None)), 0.0)


def pressure_dR(x, P, R, E, nu):
    """Dp_N/DR at constant P: p0/(2R) (2 xi^2 - 1)/sqrt(1 - xi^2) for |xi| < 1."""
    h = analytical(P, R, E, nu)
    xi = np.asarray(x) / h["a"]
    inside = np.abs(xi) < 1
    s = np.sqrt(np.where(inside, 1 - xi**2, 1.0))
    return np.where(inside, h["p0"] / (2 * R) * (2 * xi**2 - 1) / s, 0.0)


def hertz_problem(params: dict | None = None, *, refine: int = 0, method: str = "al",
                  finite_strain: bool = False, n_fine: int = 24, size: float = 20.0) -> Problem:
    """Build the Hertz half model.

    Args:
        params: overrides of the defaults E=100, nu=0.3, P=1.2, R=1 (and eps, bump).
        refine: each level halves the cell size everywhere (x2 cells per direction).
        method: ``"al"`` (augmented Lagrangian) or ``"penalty"``.
        finite_strain: neo-Hookean total-Lagrangian block instead of linear elasticity.
        n_fine: cells across the fine zone (1.5 a wide, 1.0 a deep) at refine 0.
        size: block width and depth in units of a.
    """
    values = dict(DEFAULTS)
    known = set(DEFAULTS) | {"eps", "bump"}
    for k in params or {}:
        if k not in known:
            raise UnknownParameterError(
                f"unknown parameter {k!r} for the Hertz problem; defined parameters: {sorted(known)}")
    values.update(params or {})
    if refine < 0:
        raise InputError(f"refine must be >= 0, got {refine}")
    for k in ("E", "P", "R"):
        if not values[k] > 0:
            raise InputError(f"Hertz problem: {k} must be positive, got {values[k]}")
    a = analytical(values["P"], values["R"], values["E"], values["nu"])["a"]
    k = 2**refine
    nf = n_fine * k
    growth = 1.2 ** (1.0 / k)
    W = H = size * a
    xs = graded_coordinates(W, 1.5 * a, nf, growth)
    ys = -graded_coordinates(H, 1.0 * a, int(round(nf * 2 / 3)), growth)[::-1]
    mesh = rectangle(xs, ys)
    h = 1.5 * a / nf
    values.setdefault("eps", values["E"] / h)
    values.setdefault("bump", 0.0)
    X = mesh.nodes
    r2 = (X[:, 0] / (2 * a)) ** 2
    b = np.where(r2 < 1, r2 * (1 - r2) ** 2, 0.0)
    V = np.column_stack([np.zeros(len(X)), b * (1 + X[:, 1] / H)])
    if method == "al":
        meth = AugmentedLagrangian("eps")
    elif method == "penalty":
        meth = Penalty("eps")
    else:
        raise InputError(f"unknown contact method {method!r}; use 'al' or 'penalty'")
    material = NeoHooke() if finite_strain else LinearElastic()
    return Problem(
        mesh=mesh,
        material=material,
        params=values,
        fixed=(Fixed("left", 0),),
        loads=(Pressure("bottom", lambda p: 0.5 * p["P"], resultant=True),),
        contact=(Contact(Circle(radius="R", centre=(0.0, "R")), "top", meth),),
        shape={"bump": V},
        shape_nominal={"bump": 0.0},
    )


def fine_cell_size(problem: Problem) -> float:
    """Smallest top-edge length (the contact resolution)."""
    return problem.mesh.min_edge_length("top")


def run(out, params: dict | None = None, *, refine: int = 0, method: str = "al",
        finite_strain: bool = False, steps: int = 1, fd_check: bool = True,
        sensitivities=("R", "E", "P"), options=None, fd_step: float = 1e-4, solver="superlu") -> dict:
    """Solve the Hertz benchmark with DDM sensitivities and write the results.

    Writes ``contact.csv``, ``summary.json``, ``pressure.png``,
    ``sensitivity.png`` and ``hertz.vtu`` into ``out``. Returns the summary.
    """
    import time
    from pathlib import Path

    from .. import io, plots
    from ..newton import NewtonOptions
    from ..sensitivity import finite_difference
    from ..solve import solve

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    options = options or NewtonOptions(rtol=1e-11)
    pb = hertz_problem(params, refine=refine, method=method, finite_strain=finite_strain)
    v = pb.params
    an = analytical(v["P"], v["R"], v["E"], v["nu"])
    t0 = time.perf_counter()
    sol = solve(pb, steps=steps, sensitivities=list(sensitivities), options=options, solver=solver)
    t_solve = time.perf_counter() - t0
    c = sol.contact()
    x = c["x_ref"][:, 0]
    closed = c["p_N"] > 0
    a_fe = float(x[closed].max()) if closed.any() else 0.0
    p0_fe = float(c["p_N"].max())

    cols = {"x_ref": x, "x": c["x"][:, 0], "p_N": c["p_N"]}
    for n in sensitivities:
        cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
    io.write_csv(out / "contact.csv", cols)
    io.write_vtu(sol, out / "hertz.vtu")

    ddm_fd = {}
    if fd_check:
        inner = x < 0.9 * an["a"]  # p_N is not differentiable at x = a (THEORY 8)
        for n in sensitivities:
            fd = finite_difference(pb, n, lambda s: s.contact()["p_N"][inner], steps=steps,
                                   options=options, rel_step=fd_step, solver=solver)
            ddm = c[f"dp_N_d{n}"][inner]
            ddm_fd[n] = float(np.max(np.abs(ddm - fd)) / np.max(np.abs(ddm)))

    xa = np.linspace(0, 1.5 * an["a"], 400)
    plots.curves(out / "pressure.png", [
        {"x": xa, "y": pressure(xa, v["P"], v["R"], v["E"], v["nu"]), "label": "Hertz (eq. 22)"},
        {"x": x, "y": c["p_N"], "label": f"FE, {method}", "style": "points"}],
        xlabel="x [mm]", ylabel="p_N [N/mm²]", title="Frictionless Hertz: contact pressure",
        xlim=(0, 1.5 * an["a"]))
    if "R" in sensitivities:
        xs = np.linspace(0, 0.995 * an["a"], 400)
        plots.curves(out / "sensitivity.png", [
            {"x": np.concatenate([xs, [an["a"], 1.5 * an["a"]]]),
             "y": np.concatenate([pressure_dR(xs, v["P"], v["R"], v["E"], v["nu"]), [0, 0]]),
             "label": "analytical"},
            {"x": x, "y": c["dp_N_dR"], "label": "FE, DDM", "style": "points"}],
            xlabel="x [mm]", ylabel="Dp_N/DR [N/mm³]",
            title="Sensitivity of the pressure to the cylinder radius", xlim=(0, 1.5 * an["a"]))

    summary = {
        "params": v,
        "method": method,
        "finite_strain": finite_strain,
        "mesh": {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells,
                 "dofs": int(sol.model.n_dof), "contact_cell_size": fine_cell_size(pb)},
        "p0": {"computed": p0_fe, "analytical": an["p0"], "rel_error": p0_fe / an["p0"] - 1},
        "a": {"computed": a_fe, "analytical": an["a"], "rel_error": a_fe / an["a"] - 1,
              "error_in_cells": (a_fe - an["a"]) / fine_cell_size(pb)},
        "newton_iterations": sol.newton_iterations,
        "newton_residuals": [inc.newton.residuals for inc in sol.increments],
        "ddm_vs_fd_rel_diff": ddm_fd,
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
    }
    io.write_json(out / "summary.json", summary)
    return summary
