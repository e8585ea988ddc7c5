"""Plane-strain frictional Hertz problem (paper 5.2, docs/theory.md §8).

The half model of :mod:`signorini.problems.hertz` (rigid cylinder of radius R
on an elastic block, uniform pressure with resultant P/2 on the bottom,
symmetry u_x = 0 on x = 0) with Coulomb friction on the top face, R = 10,
mu = 0.3, E = 100, nu = 0.3. The force grows proportionally to P = 1.5 in
``steps`` equal increments (a multiple of 3, so that P1 = 0.5, P2 = 1.0 and
P3 = 1.5 are increments). The mesh's fine zone is sized from the contact
half-width a at P3.

Friction makes the problem path-dependent; the contact, stick and slip zones
grow self-similarly, so c/a (stick-zone over contact half-width) is constant
and p_N / p0_i against x / a_i is the same curve at every load. The
symmetry line x = 0 is a stick line (its node has no friction multiplier:
its tangential displacement is prescribed).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..contact import Contact, Coulomb
from ..errors import InputError, UnknownParameterError
from . import hertz

DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 1.5, "R": 10.0, "mu": 0.3}
LOADS = (1.0 / 3.0, 2.0 / 3.0, 1.0)  # P_i / P at the three reported loads
#: default block size in units of a0: c/a changes by < 0.15 % when it doubles, at
#: refine 0 and 1 (20 a0 and 40 a0 still jump by a stick node, up to 5 %;
#: benchmarks/study_friction_domain.py)
BLOCK = 80.0


def hertz_friction_problem(params: dict | None = None, *, refine: int = 0, n_fine: int = 24,
                           size: float = BLOCK, zone: float = 1.5, finite_strain: bool = False,
                           force_size: bool = False):
    """The frictional Hertz half model (parameters E, nu, P, R, mu, eps, eps_t, bump).

    The mesh is sized from the nominal values :data:`DEFAULTS` (a0 = Hertz
    half-width at P3), never from ``params``. ``eps`` defaults to E0 / h
    (h = contact cell size, E0 nominal) and ``eps_t`` to ``eps``. Mesh and
    material arguments as in :func:`signorini.problems.hertz.hertz_problem`
    (``finite_strain``: neo-Hookean block with finite contact kinematics).
    """
    values = dict(DEFAULTS)
    known = set(DEFAULTS) | {"eps", "eps_t", "bump"}
    for k in params or {}:
        if k not in known:
            raise UnknownParameterError(f"unknown parameter {k!r} for the frictional Hertz problem; "
                                        f"defined parameters: {sorted(known)}")
    values.update(params or {})
    if not (isinstance(values["mu"], (int, float)) and values["mu"] >= 0 and np.isfinite(values["mu"])):
        raise InputError(f"the friction coefficient must be a finite number >= 0, got mu={values['mu']}")
    base = {k: v for k, v in values.items() if k not in ("mu", "eps_t")}
    nominal = {k: DEFAULTS[k] for k in ("E", "nu", "P", "R")}
    pb = hertz.hertz_problem(base, refine=refine, n_fine=n_fine, size=size, zone=zone,
                             finite_strain=finite_strain, nominal=nominal, force_size=force_size,
                             multipliers_per_node=2)
    full = dict(pb.params, mu=values["mu"], eps_t=values.get("eps_t", pb.params["eps"]))
    c = pb.contact[0]
    return dataclasses.replace(pb, params=full, contact=(
        Contact(c.obstacle, c.edges, Coulomb(mu="mu", eps_n="eps", eps_t="eps_t")),))


def zones(contact: dict) -> tuple[float, float]:
    """(a, c): largest reference x of a closed node and of a sticking node."""
    x = contact["x_ref"][:, 0]
    closed = contact["status"] != "open"
    stick = contact["status"] == "stick"
    return (float(x[closed].max()) if closed.any() else 0.0,
            float(x[stick].max()) if stick.any() else 0.0)


def _edge(x, inside, q, power):
    """Interpolated end of the zone ``inside`` (a prefix of the sorted nodes x):
    q**power vanishes about linearly at the edge, so extrapolate it from the last
    two inside nodes to zero, clipped to the bracket [last inside, first
    outside]. Returns (edge, (lo, hi))."""
    idx = np.nonzero(inside)[0]
    if not idx.size:
        return 0.0, (0.0, float(x[0]))
    k = idx.max()
    lo = float(x[k])
    hi = float(x[k + 1]) if k + 1 < len(x) else lo
    if k < 1 or hi == lo:
        return lo, (lo, hi)
    y1, y2 = q[k - 1] ** power, q[k] ** power
    if y1 <= y2:  # not decreasing towards the edge: no extrapolation
        return lo, (lo, hi)
    edge = lo + y2 * (x[k] - x[k - 1]) / (y1 - y2)
    return float(np.clip(edge, lo, hi)), (lo, hi)


def stick_zone(contact: dict, mu: float) -> dict:
    """Contact and stick half-widths with their brackets, interpolated.

    a: the pressure vanishes like sqrt(a - x) at the contact edge, so p_N**2 is
    extrapolated to zero from the last two closed nodes. c: the friction
    reserve q = 1 - |p_T| / (mu p_N) of the stick zone vanishes at the
    stick/slip edge like (c - x)^1.2..1.3 (measured at refine 1 and 2,
    benchmarks/study_friction_domain.py), so q itself is extrapolated linearly
    to zero from the last two sticking nodes. Both are clipped to their bracket
    between the last node inside and the first node outside.

    Returns:
        dict with ``a``, ``a_bracket``, ``c``, ``c_bracket``, ``c_over_a``,
        ``c_over_a_bracket`` (c/a at the two ends of the brackets, widest
        range) and the node-based ``a_nodes``, ``c_nodes`` of :func:`zones`.
    """
    order = np.argsort(contact["x_ref"][:, 0])
    x = contact["x_ref"][order, 0]
    pN = contact["p_N"][order]
    pT = contact["p_T"][order]
    st = contact["status"][order]
    closed = st != "open"
    stick = st == "stick"
    a, ab = _edge(x, closed, np.where(closed, pN, 0.0), 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(stick & (pN > 0), 1.0 - np.abs(pT) / (mu * pN), 0.0) if mu > 0 else np.ones_like(x)
    c, cb = _edge(x, stick, q, 1)
    a_n, c_n = zones(contact)
    ratio = c / a if a > 0 else 0.0
    lo = cb[0] / ab[1] if ab[1] > 0 else 0.0
    hi = cb[1] / ab[0] if ab[0] > 0 else 0.0
    return {"a": a, "a_bracket": list(ab), "c": c, "c_bracket": list(cb), "c_over_a": ratio,
            "c_over_a_bracket": [lo, hi], "a_nodes": a_n, "c_nodes": c_n}


def load_increments(solution) -> list[int]:
    """Indices of the increments at P1, P2, P3 (t = 1/3, 2/3, 1)."""
    ts = np.array([inc.t for inc in solution.increments])
    out = []
    for target in LOADS:
        k = int(np.argmin(np.abs(ts - target)))
        if abs(ts[k] - target) > 1e-9:
            raise InputError(f"no increment ends at t = {target:.6g}; use a number of steps "
                             "that is a multiple of 3")
        out.append(k)
    return out


def run(out, params: dict | None = None, *, refine: int = 0, steps: int = 30, fd_check: bool = True,
        sensitivities=("R", "mu", "E"), options=None, fd_step: float = 1e-5, solver="auto",
        size: float = BLOCK, zone: float = 1.5, finite_strain: bool = False,
        force_size: bool = False, coarse_start: bool = True, adjoint: bool = False) -> dict:
    """Solve the frictional Hertz benchmark with path-dependent DDM sensitivities.

    Writes ``contact_P{1,2,3}.csv`` (``x_ref, x, p_N, p_T, dp_N_d<name>,
    dp_T_d<name>, status``), ``pressure.png`` / ``friction.png`` (paper Fig. 5),
    ``normalised.png`` / ``normalised_sensitivity.png`` (Fig. 6),
    ``hertz_friction_P{1,2,3}.vtu``, the series ``hertz_friction.pvd`` (one VTU
    per increment) and ``summary.json`` into ``out``. Returns the summary.
    The FD check re-runs the whole load path at phi +- h,
    h = ``fd_step`` max(|phi|, 1): smaller steps are limited by the Newton
    tolerance (error ~ rtol / h), much larger ones change stick/slip states.
    On a Newton failure the converged increments and ``summary.json`` (status
    ``failed``) are written before the error is re-raised. ``adjoint``: also the
    adjoint gradient of the contact work W at P (:func:`hertz.contact_work`) with
    respect to the sensitivity parameters and every nodal coordinate, next to its
    DDM gradient (``summary.json`` ``adjoint``, ``shape_gradient.csv``, VTU field
    ``adjoint_shape_gradient`` in ``hertz_friction_P3.vtu``).
    """
    from ..post import files as io, plots
    from ..algorithms.newton import NewtonOptions
    from ..app.runner import (
        Timer, adjoint_report, max_rel_diff, prepare_output, solve_or_report, summary_header,
        use_solver)
    from ..design.finite_differences import finite_difference

    clock = Timer()
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 3 or steps % 3:
        raise InputError(f"--steps must be a positive multiple of 3 (P1, P2, P3 = P/3, 2P/3, P "
                         f"must be increments), got {steps!r}")
    sensitivities = list(dict.fromkeys(["R", *sensitivities]))
    out = prepare_output(out)
    # rtol 1e-10 leaves margin above the residual's round-off floor at the small early loads
    options = options or NewtonOptions(rtol=1e-10)
    solver = use_solver(solver)  # one instance: its symbolic analysis serves the FD re-solves too
    pb = hertz_friction_problem(params, refine=refine, size=size, zone=zone,
                                finite_strain=finite_strain, force_size=force_size)
    v = pb.params
    h = hertz.fine_cell_size(pb)
    mesh_info = {"nodes": pb.mesh.n_nodes, "cells": pb.mesh.n_cells, "contact_cell_size": h,
                 "block_over_a0": size, "zone_over_a0": zone, "refine": refine}
    t0 = clock()
    guide, coarse = None, []
    skipped = hertz.coarse_start_skipped(pb, coarse_start)
    if skipped is None:
        guide, coarse = hertz.coarse_start_for(
            pb, lambda r, n: hertz_friction_problem(params, refine=r, n_fine=n, size=size, zone=zone,
                                                    finite_strain=finite_strain),
            refine, 24, steps=steps, options=options, solver=solver)
    sol = solve_or_report(out, "hertz_friction", pb, {"params": v, "mesh": mesh_info}, steps=steps,
                          sensitivities=sensitivities, options=options, solver=solver,
                          guide=guide)
    t_solve = clock() - t0

    adj = None
    if adjoint:
        work = hertz.contact_work(sol.model)
        _, dW = sol.history_response(lambda w, p, t, s: work(w, p, t), key=("contact-work",))
        adj = adjoint_report(out, sol, hertz.contact_work, sensitivities,
                             "contact work W = sum A p_N (g0 - g) at P (hertz.contact_work)", solver,
                             {n: float(d) for n, d in dW.items()})

    levels = []
    for i, k in enumerate(load_increments(sol), start=1):
        P = v["P"] * sol.increments[k].t
        an = hertz.analytical(P, v["R"], v["E"], v["nu"])
        c = sol.contact(k)
        z = stick_zone(c, v["mu"])
        cols = {"x_ref": c["x_ref"][:, 0], "x": c["x"][:, 0], "p_N": c["p_N"], "p_T": c["p_T"] + 0.0}
        for n in sensitivities:
            cols[f"dp_N_d{n}"] = c[f"dp_N_d{n}"]
            cols[f"dp_T_d{n}"] = c[f"dp_T_d{n}"] + 0.0
        cols["status"] = c["status"]
        io.write_csv(out / f"contact_P{i}.csv", cols)
        io.write_vtu(sol, out / f"hertz_friction_P{i}.vtu", k)
        levels.append({"P": P, "increment": k, "a": z["a"], "c": z["c"], "c_over_a": z["c_over_a"],
                       "a_bracket": z["a_bracket"], "c_bracket": z["c_bracket"],
                       "c_over_a_bracket": z["c_over_a_bracket"],
                       "a_nodes": z["a_nodes"], "c_nodes": z["c_nodes"],
                       "a_hertz": an["a"], "p0_hertz": an["p0"], "p0": float(c["p_N"].max()),
                       "n_stick": int((c["status"] == "stick").sum()),
                       "n_slip": int((c["status"] == "slip").sum()), "contact": c})
    io.write_pvd(sol, out / "hertz_friction.pvd")
    _figures(out, levels, v, plots)

    ddm_fd = {}
    if fd_check:
        k3 = levels[-1]["increment"]
        inner = levels[-1]["contact"]["x_ref"][:, 0] < 0.9 * levels[-1]["a_hertz"]
        for n in ("R", "mu"):
            if n not in sensitivities:
                continue

            def q(s, k3=k3):
                c = s.contact(k3)
                return np.concatenate([c["p_N"][inner], c["p_T"][inner]])

            fd = finite_difference(pb, n, q, steps=steps, options=options, rel_step=fd_step,
                                   solver=solver, guide=sol if coarse_start else None)
            c3 = levels[-1]["contact"]
            ddm_fd[n] = max_rel_diff(np.concatenate([c3[f"dp_N_d{n}"][inner], c3[f"dp_T_d{n}"][inner]]), fd)

    summary = summary_header("converged", sol)
    summary.update({
        "params": v,
        "steps": steps,
        "coarse_start": coarse if coarse else (skipped or "no coarser mesh"),
        "finite_strain": finite_strain,
        "solver": solver.name, "symmetric_factorisation": sol.symmetric,
        "mesh": {**mesh_info, "dofs": int(sol.model.n_dof)},
        "loads": [{k: val for k, val in lv.items() if k != "contact"} for lv in levels],
        "c_over_a": [lv["c_over_a"] for lv in levels],
        "c_over_a_bracket": [lv["c_over_a_bracket"] for lv in levels],
        "newton_iterations": sol.newton_iterations,
        "newton_residuals": [inc.newton.residuals for inc in sol.increments],
        "ddm_vs_fd_rel_diff_P3": ddm_fd if fd_check else "not computed (--no-fd)",
        "adjoint": adj if adjoint else "not computed (use --adjoint)",
        "fd_relative_step": fd_step,
        "time_solve_s": t_solve,
        "time_wall_s": clock(),
    })
    summary["warnings"] = list(sol.warnings)
    io.write_json(out / "summary.json", summary)
    return summary


def _figures(out, levels, v, plots):
    """Paper Fig. 5 (p_N, p_T at P1..P3) and Fig. 6 (normalised by p0_i, a_i, p0_i/R)."""
    def series(key, scale=None):
        res = []
        for i, lv in enumerate(levels, start=1):
            c = lv["contact"]
            m = c["x_ref"][:, 0] < 1.6 * lv["a_hertz"]
            x, y = c["x_ref"][m, 0], c[key][m]
            if scale is not None:
                x, y = x / lv["a_hertz"], y / scale(lv)
            res.append({"x": x, "y": y, "label": f"{key}, P{i} = {lv['P']:.2g}",
                        "style": "line" if scale is None else "points"})
        return res

    plots.curves(out / "pressure.png", series("p_N"), xlabel="x [mm]", ylabel="p_N [N/mm²]",
                 title="Frictional Hertz: contact pressure")
    plots.curves(out / "friction.png", series("p_T"), xlabel="x [mm]", ylabel="p_T [N/mm²]",
                 title="Frictional Hertz: friction stress")
    p0 = lambda lv: lv["p0_hertz"]
    plots.curves(out / "normalised.png", series("p_N", p0) + series("p_T", p0),
                 xlabel="x / a_i", ylabel="p / p0_i", title="Normalised tractions (self-similar)")
    p0R = lambda lv: lv["p0_hertz"] / v["R"]
    plots.curves(out / "normalised_sensitivity.png",
                 series("dp_N_dR", p0R) + series("dp_T_dR", p0R),
                 xlabel="x / a_i", ylabel="(R / p0_i) Dp/DR",
                 title="Normalised sensitivities to the cylinder radius")
