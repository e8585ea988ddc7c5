"""Where the derivative does not exist: switch points of the non-smooth laws
(docs/theory.md §11).

The contact and plasticity laws are piecewise smooth: a node is open or
closed, a closed node sticks or slips, a Gauss point loads elastically or
plastically. On each branch the solution is differentiable and the DDM and
the adjoint give its exact derivative. A point that sits *on* a switch is
where the derivative is only one-sided (the paper, §6): a perturbation of one
sign changes the branch, the other does not. After every converged increment
:func:`switches` lists

* weakly active contact nodes: gap and pressure both (nearly) zero,
  |g| <= tol h and p_N <= tol p_ref (h: mean contact cell, p_ref: the largest
  pressure of the increment, or eps_N h without contact);
* stick/slip switch nodes: closed nodes with friction whose tangential trial
  traction is on the friction disc, ||lam^_T| - rho| <= tol p_ref;
* elastic/plastic switch points: Gauss points whose trial yield function is on
  the yield surface, |f_tr| <= tol sqrt(2/3)(sigma_y + H alpha_n);
* master-end switch nodes of a contact pair with finite kinematics: closed
  slave nodes over which the end of the master surface sits, to tol of a
  segment (their overlapped length, so their weighted gap, has a kink there);

and, for contact pairs with finite kinematics, the *partner changes*: closed
slave nodes whose set of overlapping master segments changed in the increment
(reported, not a switch: the weighted gap and slip are continuously
differentiable across a master node, docs/theory.md §13);

with ``tol`` = :data:`SWITCH_TOL` by default. :func:`signorini.solve` stores
the report on every increment (``Increment.switches``) and warns when
sensitivities were requested and some increment has such points.
"""

from __future__ import annotations

import numpy as np

from ..contact import mortar, mortar3d

#: relative distance from a switch below which a point is reported as on it
SWITCH_TOL = 1e-6


class SwitchDetector:
    """Classifies the switch points of one model at converged increments."""

    def __init__(self, model, params, tol: float = SWITCH_TOL):
        self.model = model
        self.tol = float(tol)
        X = np.asarray(model.reference(params))
        self._X = X
        self._h = []
        self._eps = []
        self._pairs = {}  # surface index -> master edges (pairs with finite kinematics)
        self._partners = {}  # surface index -> the partner matrix of the last increment
        for i, s in enumerate(model.surfaces):
            self._h.append(model.contact_cell_size(s, X))
            vals = s.contact.method.values(params)
            self._eps.append(float(vals.get("eps_n", vals.get("eps", 0.0))))
            if s.patches is not None and not model.linear_contact[i]:
                mesh = model.problem.mesh
                self._pairs[i] = (mesh.face_set if model.dim == 3 else mesh.edge_set)(
                    s.contact.obstacle.master)

    def __call__(self, w, params, t, state_n) -> dict:
        """{"weakly_active": [[node, ...] per surface], "stick_slip": [[node, ...] per
        surface], "elastic_plastic": [cell, ...], "master_end": [[node, ...] per
        surface], "partner_change": [[node, ...] per surface]} at a converged
        increment (global node numbers; cells with at least one Gauss point on the
        yield surface; the last two empty but for pairs with finite kinematics)."""
        m = self.model
        surf, ratio = m.compiled.switch_fields(w, params, t, state_n)
        surf = [{k: np.asarray(v) for k, v in f.items()} for f in surf]
        p_max = max((float(np.max(f["p_N"], initial=0.0)) for f in surf), default=0.0)
        weak, stick = [], []
        for s, f, h, eps in zip(m.surfaces, surf, self._h, self._eps):
            p_ref = p_max if p_max > 0 else eps * h
            on = (np.abs(f["gap"]) <= self.tol * h) & (f["p_N"] <= self.tol * p_ref)
            weak.append([int(n) for n in s.nodes[on]])
            edge = np.isfinite(f["stick_margin"]) & (np.abs(f["stick_margin"]) <= self.tol * p_ref)
            stick.append([int(n) for n in s.nodes[edge & ~on]])
        ends, changes = self._pair_switches(w, surf)
        plastic = []
        if ratio is not None:
            plastic = [int(c) for c in np.nonzero(np.any(np.abs(np.asarray(ratio)) <= self.tol,
                                                         axis=1))[0]]
        return {"weakly_active": weak, "stick_slip": stick, "elastic_plastic": plastic,
                "master_end": ends, "partner_change": changes}

    def _pair_switches(self, w, surf):
        """Master-end switch nodes and partner changes of the pairs (finite kinematics)."""
        m = self.model
        ends = [[] for _ in m.surfaces]
        changes = [[] for _ in m.surfaces]
        if not self._pairs:
            return ends, changes
        x = self._X + np.asarray(w)[: m.dim * m.n_nodes].reshape(-1, m.dim)
        for i, master in self._pairs.items():
            s = m.surfaces[i]
            closed = surf[i]["p_N"] > 0
            if m.dim == 3:
                on = mortar3d.boundary_switches(x, s.patches, master, self.tol) & closed
                ends[i] = [int(n) for n in s.nodes[on]]
                now = mortar3d.partners(x, s.edges, s.nodes, master,
                                        memo=m.cache.setdefault(("partner-distances", i), {}))
                before = self._partners.get(i)
                if before is not None:
                    changes[i] = [int(n) for n in s.nodes[mortar3d.changed(now, before) & closed]]
                self._partners[i] = now
                continue
            on = mortar.end_switches(x, s.patches, master, self.tol) & closed
            ends[i] = [int(n) for n in s.nodes[on]]
            now = mortar.partners(x, s.patches, master, memo=m.cache.setdefault(("partner-distances", i), {}))
            before = self._partners.get(i)
            if before is not None:
                moved = np.any(now != before, axis=1) & closed
                changes[i] = [int(n) for n in s.nodes[moved]]
            self._partners[i] = now
        return ends, changes


def count(report: dict) -> int:
    """Number of switch points in one increment's report."""
    return (sum(len(v) for v in report["weakly_active"]) + sum(len(v) for v in report["stick_slip"])
            + len(report["elastic_plastic"]) + sum(len(v) for v in report.get("master_end", ())))


def summary(solution) -> list[dict]:
    """The increments with switch points, for ``summary.json``: t, increment index
    and the three lists (empty list: no increment has any)."""
    out = []
    for k, inc in enumerate(solution.increments):
        r = getattr(inc, "switches", None)
        if r and count(r):
            out.append({"increment": k + 1, "t": float(inc.t),
                        **{key: v for key, v in r.items() if key != "partner_change"}})
    return out


def partner_changes(solution) -> list[dict]:
    """The increments in which closed slave nodes of a contact pair changed master
    partners, for ``summary.json``: t, increment index and the nodes per surface."""
    out = []
    for k, inc in enumerate(solution.increments):
        r = getattr(inc, "switches", None) or {}
        nodes = r.get("partner_change")
        if nodes and any(nodes):
            out.append({"increment": k + 1, "t": float(inc.t), "nodes": nodes})
    return out


def warning(solution, names=None) -> str | None:
    """The warning of a solve whose sensitivities (``names``, default the solve's own)
    may be one-sided (None: no switch point or no sensitivity asked for)."""
    rows = summary(solution)
    if not rows or not (solution.names if names is None else names):
        return None
    kinds = []
    for key, what in (("weakly_active", "weakly active contact nodes"),
                      ("stick_slip", "nodes on the stick/slip switch"),
                      ("master_end", "slave nodes under the end of a master surface"),
                      ("elastic_plastic", "cells with Gauss points on the yield surface")):
        nodes = sorted({n for r in rows for n in (r[key] if key == "elastic_plastic"
                                                  else [x for lst in r.get(key, ()) for x in lst])})
        if nodes:
            shown = ", ".join(map(str, nodes[:8])) + (", ..." if len(nodes) > 8 else "")
            kinds.append(f"{what} [{shown}]")
    incs = ", ".join(str(r["increment"]) for r in rows[:8]) + (", ..." if len(rows) > 8 else "")
    return (f"the derivative may be one-sided: {'; '.join(kinds)} in increment(s) {incs} sit on a "
            "switch of the contact or plasticity law, where the solution is not differentiable "
            "(a perturbation of one sign changes the branch). The sensitivities are those of the "
            "branch taken; compare one-sided finite differences if they matter "
            "(summary.json 'derivative_switches', VTU field 'switch').")
