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
from .values import checked_values
from ..errors import InputError
from . import hertz

DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 1.5, "R": 10.0, "mu": 0.3}
LOADS = (1.0 / 3.0, 2.0 / 3.0, 1.0)  # P_i / P at the three reported loads
#: default block size in units of a0: c/a changes by < 0.15 % when it doubles, at
#: refine 0 and 1 (20 a0 and 40 a0 still jump by a stick node, up to 5 %;
#: benchmarks/study_friction_domain.py)
BLOCK = 80.0


def hertz_friction_problem(params: dict | None = None, *, refine: int = 0, n_fine: int = 24,
                           size: float = BLOCK, zone: float = 1.5, finite_strain: bool = False,
                           force_size: bool = False, solver="auto"):
    """The frictional Hertz half model (parameters E, nu, P, R, mu, eps, eps_t, bump).

    The mesh is sized from the nominal values :data:`DEFAULTS` (a0 = Hertz
    half-width at P3), never from ``params``. ``eps`` defaults to E0 / h
    (h = contact cell size, E0 nominal) and ``eps_t`` to ``eps``. Mesh and
    material arguments as in :func:`signorini.problems.hertz.hertz_problem`
    (``finite_strain``: neo-Hookean block with finite contact kinematics;
    ``solver``: the run's linear solver, for the size guard).
    """
    values = checked_values("frictional Hertz problem", DEFAULTS, params, extra=("eps", "eps_t", "bump"))
    if not (isinstance(values["mu"], (int, float)) and values["mu"] >= 0 and np.isfinite(values["mu"])):
        raise InputError(f"the friction coefficient must be a finite number >= 0, got mu={values['mu']}")
    base = {k: v for k, v in values.items() if k not in ("mu", "eps_t")}
    nominal = {k: DEFAULTS[k] for k in ("E", "nu", "P", "R")}
    pb = hertz.hertz_problem(base, refine=refine, n_fine=n_fine, size=size, zone=zone,
                             finite_strain=finite_strain, nominal=nominal, force_size=force_size,
                             multipliers_per_node=2, solver=solver)
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
