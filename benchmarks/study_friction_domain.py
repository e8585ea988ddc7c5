"""Frictional Hertz: stick-zone ratio c/a against block size, refinement and load path.

Paper 5.2 (E = 100, nu = 0.3, P = 1.5, R = 10, mu = 0.3). Every load path is
solved without sensitivities (Newton rtol 1e-10). At P1, P2, P3 (t = 1/3,
2/3, 1) the rows give

* ``c_over_a``: the interpolated ratio of
  :func:`signorini.problems.hertz_friction.stick_zone`, with ``c_over_a_lo``,
  ``c_over_a_hi`` (c/a at the ends of the brackets [last stick node, first
  slip node] and [last closed node, first open node]);
* two diagnostic estimates of the same ratio: ``c_over_a_qlin`` extrapolates
  the friction reserve q = 1 - |p_T| / (mu p_N) linearly (instead of q**2) from
  the last two sticking nodes, clipped to the bracket; ``c_over_a_onset`` uses
  the load history: a node at x that is stuck from increment k on (and was not
  at k - 1) brackets c/a in [x / a_k, x / a_(k-1)]; the estimate is the mean of
  the geometric midpoints over the sticking nodes in the outer half of the
  stick zone (a_k interpolated, increments with fewer than 6 closed nodes
  skipped). It is limited by the increment, not by the cell size;
* ``a_over_aH``, ``p0_over_p0H``: interpolated half-width and peak pressure
  over Hertz's half-space values.

Domain study (``results/friction_domain.csv``, one row per run and load plus
the mean over P1..P3): block size B (width = depth = B a0, a0 = Hertz
half-width at P3) at refine 0 and 1 (the fine zone is the same for every B, so
a change with B is a pure domain-size effect; ``*_vs_half`` is the relative
change from the run with half the block), refinement 0, 1, 2 at the adequate
block (the smallest B beyond which every doubling changes c/a at P3 and its
mean over P1..P3 by less than 1 %) and at twice that block, and the fine zone
1.5 a0 vs 2.0 a0 (24 cells, i.e. coarser, and 32 cells, the same cell size).
Rows ``half-plane`` are an independent reference without a block: a
boundary-element model of the same cylinder on an elastic half-plane with the
normal-tangential coupling and Coulomb friction (:func:`half_plane`; its
``n_fine`` is the number of panels, its bracket that of the stick-panel edge).

Steps study (``results/friction_steps.csv``): at the adequate block, refine 0
and 1, c/a for several numbers of equal increments, its deviation from the
finest path (``dev_*``), and the growth of the contact zone per increment after
the first: the largest number of newly closed nodes (p_N > 0 at increment k,
not at k - 1), overall and for t > 1/3, and the largest ratio of newly closed
nodes to the slipping nodes of the increment before; plus whether the
library's coarse-path warning (``checks.MAX_NEW_CONTACT_NODES``) fired.

    python benchmarks/study_friction_domain.py [--quick] [--out DIR]

The full run takes ~17 min on 2 cores (refine 2 and the steps paths at refine 1 dominate);
--quick (~30 s) writes to a temporary directory unless --out is given.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from _report import report

import signorini as sg
from signorini.model import checks
from signorini.errors import ConvergenceError
from signorini.algorithms.newton import NewtonOptions
from signorini.problems import hertz
from signorini.problems.hertz_friction import (
    DEFAULTS, hertz_friction_problem, load_increments, stick_zone)

RESULTS = Path(__file__).parent / "results"
OPTIONS = NewtonOptions(rtol=1e-10)
MU = DEFAULTS["mu"]
A0 = hertz.analytical(DEFAULTS["P"], DEFAULTS["R"], DEFAULTS["E"], DEFAULTS["nu"])["a"]
TOL = 0.01  # block-doubling tolerance on c/a
DEV = 0.02  # a load path is "off" if c/a(P3) differs from the finest path by more
COARSE_TAG = "the contact zone grew by"
RATIOS = ("c_over_a", "c_over_a_lo", "c_over_a_hi", "c_over_a_qlin", "c_over_a_onset",
          "a_over_aH", "p0_over_p0H")


def solve_case(*, size=20.0, refine=0, zone=1.5, n_fine=24, steps=30):
    """Solve one load path; returns (problem, solution or None, wall seconds, error message)."""
    pb = hertz_friction_problem(size=size, refine=refine, zone=zone, n_fine=n_fine)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            sol = sg.solve(pb, steps=steps, sensitivities=[], options=OPTIONS)
        except ConvergenceError as e:
            return pb, None, time.perf_counter() - t0, str(e).splitlines()[0]
    return pb, sol, time.perf_counter() - t0, ""


class History:
    """Contact status, pressure and interpolated zones of every increment of a solution."""

    def __init__(self, sol):
        self.sol = sol
        self.c = [sol.contact(k) for k in range(len(sol.increments))]
        self.t = np.array([inc.t for inc in sol.increments])
        self.x = self.c[0]["x_ref"][:, 0]
        self.z = [stick_zone(c, MU) for c in self.c]
        self.closed = [c["p_N"] > 0 for c in self.c]
        self.n_closed = np.array([int((c["status"] != "open").sum()) for c in self.c])

    def qlin(self, k) -> float:
        """c/a with q (not q**2) extrapolated linearly from the last two sticking nodes."""
        c, z = self.c[k], self.z[k]
        o = np.argsort(self.x)
        x, pN, pT, st = self.x[o], c["p_N"][o], c["p_T"][o], c["status"][o]
        idx = np.nonzero(st == "stick")[0]
        if idx.size < 2 or idx.max() + 1 >= len(x) or z["a"] <= 0:
            return float("nan")
        j = idx.max()
        q = 1.0 - np.abs(pT[j - 1:j + 1]) / (MU * pN[j - 1:j + 1])
        e = x[j] if q[0] <= q[1] else x[j] + q[1] * (x[j] - x[j - 1]) / (q[0] - q[1])
        return float(np.clip(e, x[j], x[j + 1]) / z["a"])

    def onset(self, K) -> float:
        """c/a from the increments at which the outer sticking nodes became stuck (see module doc)."""
        stick = [c["status"] == "stick" for c in self.c]
        sK = stick[K] & (self.x > 0)
        if not sK.any():
            return float("nan")
        cK = self.x[sK].max()
        vals = []
        for i in np.nonzero(sK & (self.x >= 0.5 * cK))[0]:
            k = K
            while k > 0 and stick[k - 1][i]:
                k -= 1
            if k == 0 or self.n_closed[k - 1] < 6:
                continue
            vals.append(self.x[i] / np.sqrt(self.z[k]["a"] * self.z[k - 1]["a"]))
        return float(np.mean(vals)) if vals else float("nan")

    def levels(self) -> list[dict]:
        v = DEFAULTS
        out = []
        for i, k in enumerate(load_increments(self.sol), start=1):
            c, z = self.c[k], self.z[k]
            an = hertz.analytical(v["P"] * self.t[k], v["R"], v["E"], v["nu"])
            out.append({"load": f"P{i}", "c_over_a": z["c_over_a"],
                        "c_over_a_lo": z["c_over_a_bracket"][0], "c_over_a_hi": z["c_over_a_bracket"][1],
                        "c_over_a_qlin": self.qlin(k), "c_over_a_onset": self.onset(k),
                        "a_over_aH": z["a"] / an["a"], "p0_over_p0H": float(c["p_N"].max()) / an["p0"],
                        "n_stick": int((c["status"] == "stick").sum()), "n_closed": int(self.n_closed[k])})
        return out

    def growth(self) -> list[tuple[float, int, int]]:
        """(t, newly closed nodes, slipping nodes before) for every increment after the first."""
        out = []
        for k in range(1, len(self.c)):
            if self.closed[k - 1].any():
                out.append((float(self.t[k]), int(np.sum(self.closed[k] & ~self.closed[k - 1])),
                            int((self.c[k - 1]["status"] == "slip").sum())))
        return out


# ---------------------------------------------------------------- domain study

def domain_rows(study, pb, sol, wall, *, size, refine, zone, n_fine) -> list[dict]:
    lv = History(sol).levels()
    mean = {"load": "mean", **{k: float(np.mean([x[k] for x in lv])) for k in RATIOS},
            "n_stick": -1, "n_closed": -1}
    return [{"study": study, "block_a0": size, "refine": refine, "zone_a0": zone, "n_fine": n_fine,
             "dofs": int(sol.model.n_dof), "a0_over_h": A0 / hertz.fine_cell_size(pb), **x,
             "ca_vs_half": float("nan"), "onset_vs_half": float("nan"), "a_vs_half": float("nan"),
             "p0_vs_half": float("nan"), "newton_total": int(sum(sol.newton_iterations)),
             "wall_s": wall} for x in [*lv, mean]]


def _key(r, size):
    return (r["refine"], r["zone_a0"], r["n_fine"], size, r["load"])


def add_doubling(rows: list[dict]) -> None:
    """Fill *_vs_half: relative change from the run with half the block (same mesh otherwise)."""
    index = {_key(r, r["block_a0"]): r for r in rows}
    for r in rows:
        half = index.get(_key(r, r["block_a0"] / 2))
        if half is not None:
            for col, src in (("ca_vs_half", "c_over_a"), ("onset_vs_half", "c_over_a_onset"),
                             ("a_vs_half", "a_over_aH"), ("p0_vs_half", "p0_over_p0H")):
                r[col] = r[src] / half[src] - 1


def adequate_block(rows: list[dict], refine: int, col="ca_vs_half", zone=1.5, n_fine=24):
    """Smallest block B such that every doubling from B on changes ``col`` at P3 and in the
    mean over P1..P3 by less than TOL (None if no such B among the runs)."""
    sel = [r for r in rows if (r["refine"], r["zone_a0"], r["n_fine"]) == (refine, zone, n_fine)]
    sizes = sorted({r["block_a0"] for r in sel})
    ch = {}
    for r in sel:
        if r["load"] in ("P3", "mean") and np.isfinite(r[col]):
            ch.setdefault(r["block_a0"], []).append(abs(r[col]))
    for i, s in enumerate(sizes):
        later = [t for t in sizes[i + 1:] if t in ch]
        if later and all(max(ch[t]) < TOL for t in later):
            return s
    return None


def domain_study(quick: bool, log) -> tuple[list[dict], float]:
    rows = []
    seen = set()

    def case(study, **kw):
        kw = {"size": 20.0, "refine": 0, "zone": 1.5, "n_fine": 24, **kw}
        key = tuple(sorted(kw.items()))
        if key in seen:
            return
        seen.add(key)
        pb, sol, wall, err = solve_case(**kw)
        if sol is None:
            log(f"  {study} {kw}: FAILED ({err})")
            return
        rows.extend(domain_rows(study, pb, sol, wall, **kw))
        p3 = rows[-2]
        log(f"  {study} {kw}: {p3['dofs']} DOFs, c/a(P3) = {p3['c_over_a']:.4f} "
            f"(onset {p3['c_over_a_onset']:.4f}), {wall:.1f} s")

    sizes0 = (10.0, 20.0, 40.0) if quick else (5.0, 10.0, 20.0, 40.0, 80.0, 160.0)
    sizes1 = () if quick else (10.0, 20.0, 40.0, 80.0)
    for s in sizes0:
        case("block", size=s)
    for s in sizes1:
        case("block", size=s, refine=1)
    add_doubling(rows)
    found = {}
    for r in (0, 1):
        for col in ("ca_vs_half", "onset_vs_half", "a_vs_half"):
            found[r, col] = adequate_block(rows, r, col)
    log("  adequate block (every further doubling changes the value at P3 and its mean over "
        f"P1..P3 by < {TOL:.0%}): " + ", ".join(f"refine {r} {c.replace('_vs_half', '')}: {b}"
                                                 for (r, c), b in found.items()))
    best = max([b for (r, c), b in found.items() if c == "ca_vs_half" and b is not None] + [20.0])
    for size in ((best,) if quick else (best, 2 * best)):
        for r in range(1 if quick else 3):
            case("refine", size=size, refine=r)
    case("zone", size=best, zone=2.0, n_fine=24)
    if not quick:
        case("zone", size=best, zone=2.0, n_fine=32)
    add_doubling(rows)
    return rows, best


# ------------------------------------------------- half-plane reference (BEM)

def _G(t):
    at = np.abs(t)
    return np.where(at > 0, t * np.log(np.where(at > 0, at, 1.0)) - t, 0.0)


def half_plane(n_panels=400, steps=120, mu=MU, L=1.2):
    """Independent reference: rigid cylinder on an elastic half-plane (plane strain) with
    Coulomb friction, loaded monotonically to P in ``steps`` increments, by a boundary-element
    model of the symmetric half x > 0 (``n_panels`` panels of constant p and q over
    [0, L a_Hertz]) and an active-set iteration per increment.

    Surface displacements (z into the body, K = 2 (1 - nu^2) / (pi E), A = (1 - 2 nu)(1 + nu) / E,
    Johnson, Contact Mechanics, eq. 2.25): du_x/dx = -A p - K PV int q(s)/(x - s) ds,
    du_z/dx = -K PV int p(s)/(x - s) ds + A q, so the coupling beta = A / (pi K) =
    (1 - 2 nu) / (2 (1 - nu)) is kept (it is what makes the stick zone finite). Contact:
    u_z = delta - x^2 / (2R) where p > 0; stick: the increment of u_x vanishes; slip:
    q = mu p sign, opposing the increment of u_x. Returns a list (per load P1..P3) of dicts
    with a/a_Hertz, p0/p0_Hertz and the bracket of c/a between the last sticking panel
    centre and the next one."""
    v = DEFAULTS
    E, nu, R, P = v["E"], v["nu"], v["R"], v["P"]
    aH = hertz.analytical(P, R, E, nu)["a"]
    A = (1 - 2 * nu) * (1 + nu) / E
    K = 2 * (1 - nu**2) / (np.pi * E)
    h = L * aH / n_panels
    s = h * (np.arange(n_panels) + 0.5)
    d, dm = s[:, None] - s[None, :], s[:, None] + s[None, :]
    lz = lambda t: -K * (_G(t + h / 2) - _G(t - h / 2))
    Czp, Czq = lz(d) + lz(dm), 0.5 * A * h * (np.sign(d) - 1.0)  # u_z from even p, odd q
    Cxp, Cxq = -0.5 * A * h * (np.sign(d) + 1.0), lz(d) - lz(dm)  # u_x from even p, odd q
    n = n_panels
    ux = np.zeros(n)
    st = np.zeros(n, int)  # 0 open, 1 stick, 2 slip with q = +mu p, 3 slip with q = -mu p
    st[s < 0.5 * aH / np.sqrt(steps)] = 1
    out = []
    for k in range(1, steps + 1):
        Pk = P * k / steps
        for it in range(5000):
            I, S = np.nonzero(st > 0)[0], np.nonzero(st == 1)[0]
            sg = np.where(st == 2, 1.0, np.where(st == 3, -1.0, 0.0))
            nI, nS = len(I), len(S)
            cz = Czp[:, I] + Czq[:, I] * (mu * sg[I])
            cx = Cxp[:, I] + Cxq[:, I] * (mu * sg[I])
            M = np.zeros((nI + nS + 1, nI + nS + 1))
            b = np.zeros(nI + nS + 1)
            M[:nI, :nI], M[:nI, nI:-1], M[:nI, -1] = cz[I], Czq[np.ix_(I, S)], -1.0
            b[:nI] = -s[I] ** 2 / (2 * R)
            M[nI:-1, :nI], M[nI:-1, nI:-1], b[nI:-1] = cx[S], Cxq[np.ix_(S, S)], ux[S]
            M[-1, :nI], b[-1] = 2 * h, Pk
            x = np.linalg.solve(M, b)
            p = np.zeros(n)
            p[I] = x[:nI]
            q = mu * sg * p
            q[S] = x[nI:-1]
            uxn = Cxp @ p + Cxq @ q
            gap = Czp @ p + Czq @ q - (x[-1] - s**2 / (2 * R))
            du = uxn - ux
            tgt, viol = st.copy(), np.zeros(n)
            m = (st == 0) & (gap < -1e-15 * aH)
            tgt[m], viol[m] = np.where(du[m] > 0, 3, 2), -gap[m] / aH
            m = (st > 0) & (p < 0)
            tgt[m], viol[m] = 0, -p[m]
            m = (st == 1) & (np.abs(q) - mu * p > 1e-9 * p.max()) & (p > 0)
            tgt[m], viol[m] = np.where(q[m] > 0, 2, 3), np.abs(q[m]) - mu * p[m]
            m = (st >= 2) & (du * sg > 1e-9 * np.abs(du).max()) & (p > 0)
            tgt[m], viol[m] = 1, 1e3 * du[m] * sg[m] / aH
            if np.array_equal(tgt, st):
                break
            if it > 20:  # cycling near a zone edge: change only the worst node
                j = int(np.argmax(np.where(tgt != st, viol, -np.inf)))
                tgt, tgt[j] = st.copy(), tgt[j]
            st = tgt
        else:
            raise RuntimeError(f"half-plane BEM: active set not converged in increment {k}")
        ux = uxn
        if 3 * k % steps == 0:
            an = hertz.analytical(Pk, R, E, nu)
            i = np.nonzero(p > 0)[0].max()
            a = float(np.clip(s[i] + p[i] ** 2 * h / (p[i - 1] ** 2 - p[i] ** 2), s[i], s[i] + h))
            j = np.nonzero(st == 1)[0].max()
            out.append({"load": f"P{3 * k // steps}", "c_over_a": (s[j] + h / 2) / a,
                        "c_over_a_lo": s[j] / a, "c_over_a_hi": (s[j] + h) / a,
                        "c_over_a_qlin": float("nan"), "c_over_a_onset": float("nan"),
                        "a_over_aH": a / an["a"], "p0_over_p0H": float(p.max()) / an["p0"],
                        "n_stick": int((st == 1).sum()), "n_closed": int((st > 0).sum())})
    return out


def half_plane_rows(quick: bool, log) -> list[dict]:
    rows = []
    for n_panels, steps in ((200, 60),) if quick else ((200, 60), (400, 120), (800, 240)):
        t0 = time.perf_counter()
        lv = half_plane(n_panels, steps)
        wall = time.perf_counter() - t0
        mean = {"load": "mean", **{k: float(np.mean([x[k] for x in lv])) for k in RATIOS},
                "n_stick": -1, "n_closed": -1}
        a3 = lv[-1]["a_over_aH"] * A0
        rows += [{"study": "half-plane", "block_a0": float("inf"), "refine": -1, "zone_a0": 1.2,
                  "n_fine": n_panels, "dofs": 2 * n_panels, "a0_over_h": n_panels / 1.2, **x,
                  "ca_vs_half": float("nan"), "onset_vs_half": float("nan"), "a_vs_half": float("nan"),
                  "p0_vs_half": float("nan"), "newton_total": steps, "wall_s": wall}
                 for x in [*lv, mean]]
        log(f"  half-plane BEM, {n_panels} panels (a/h = {a3 / (1.2 * A0 / n_panels):.0f} at P3), "
            f"{steps} increments: c/a(P3) = {lv[-1]['c_over_a']:.4f} [{lv[-1]['c_over_a_lo']:.4f}, "
            f"{lv[-1]['c_over_a_hi']:.4f}], {wall:.1f} s")
    return rows


# ----------------------------------------------------------------- steps study

def steps_study(quick: bool, size: float, log) -> list[dict]:
    plan = [(0, s) for s in ((3, 15, 30, 60) if quick else (3, 6, 9, 15, 30, 60, 120, 240))]
    if not quick:
        plan += [(1, s) for s in (6, 9, 15, 30, 60, 120)]
    rows = []
    for refine, steps in plan:
        _, sol, wall, err = solve_case(size=size, refine=refine, steps=steps)
        row = {"refine": refine, "block_a0": size, "steps": steps}
        if sol is None:
            log(f"  refine {refine}, {steps} steps: FAILED ({err})")
            rows.append({**row, "failed": err})
            continue
        hist = History(sol)
        lv = hist.levels()
        g = hist.growth()
        late = [n for t, n, _ in g if t > 1 / 3 + 1e-9]
        kmax = int(np.argmax([n for _, n, _ in g])) if g else -1
        coarse = [w for w in sol.warnings if COARSE_TAG in w]
        row.update({
            "dofs": int(sol.model.n_dof), "increments": len(sol.increments),
            **{f"c_over_a_P{i}": lv[i - 1]["c_over_a"] for i in (1, 2, 3)},
            "c_over_a_P3_lo": lv[2]["c_over_a_lo"], "c_over_a_P3_hi": lv[2]["c_over_a_hi"],
            "c_over_a_mean": float(np.mean([x["c_over_a"] for x in lv])),
            "onset_P3": lv[2]["c_over_a_onset"],
            "dev_P3": float("nan"), "dev_mean": float("nan"), "dev_onset_P3": float("nan"),
            "max_new_closed": max((n for _, n, _ in g), default=0),
            "t_of_max": g[kmax][0] if g else float("nan"),
            "max_new_t>1/3": max(late, default=0),
            "max_new_over_slip": max((n / max(s, 1) for _, n, s in g), default=0.0),
            "closed_P3": lv[2]["n_closed"], "slip_P3": lv[2]["n_closed"] - lv[2]["n_stick"],
            "warning": bool(coarse), "n_warnings": len(sol.warnings),
            "newton_total": int(sum(sol.newton_iterations)), "wall_s": wall, "failed": "",
        })
        rows.append(row)
        log(f"  refine {refine}, {steps} steps: c/a(P3) = {row['c_over_a_P3']:.4f} (onset "
            f"{row['onset_P3']:.4f}), max new closed {row['max_new_closed']} (t > 1/3: "
            f"{row['max_new_t>1/3']}), coarse-path warning {row['warning']}, {wall:.1f} s")
    for refine in {r["refine"] for r in rows}:
        ok = [r for r in rows if r["refine"] == refine and not r["failed"]]
        ref = max(ok, key=lambda r: r["steps"])
        for r in ok:
            r["dev_P3"] = r["c_over_a_P3"] / ref["c_over_a_P3"] - 1
            r["dev_mean"] = r["c_over_a_mean"] / ref["c_over_a_mean"] - 1
            r["dev_onset_P3"] = r["onset_P3"] / ref["onset_P3"] - 1
    keys = list(next(r for r in rows if not r["failed"]))
    return [{k: r.get(k, float("nan")) for k in keys} for r in rows]


def threshold_analysis(rows: list[dict], log) -> None:
    """Which paths are off by more than DEV from the finest path, and which fire the warning."""
    ok = [r for r in rows if not r["failed"]]
    finest = {rf: max(r["steps"] for r in ok if r["refine"] == rf) for rf in {r["refine"] for r in ok}}
    runs = [r for r in ok if r["steps"] != finest[r["refine"]]]
    log(f"\ncoarse-path warning (fires for > {checks.MAX_NEW_CONTACT_NODES} newly closed nodes in an "
        f"increment after the first) vs c/a off the finest path by > {DEV:.0%}:")
    for dev_col in ("dev_P3", "dev_mean", "dev_onset_P3"):
        off = [(r["refine"], r["steps"]) for r in runs if abs(r[dev_col]) > DEV]
        log(f"  off by > {DEV:.0%} in {dev_col}: {off}")
        for key in ("max_new_closed", "max_new_t>1/3", "max_new_over_slip"):
            bad = [r[key] for r in runs if abs(r[dev_col]) > DEV]
            good = [r[key] for r in runs if abs(r[dev_col]) <= DEV]
            sep = not bad or not good or max(good) < min(bad)
            log(f"    {key:18s}: off {sorted(bad)}, accurate {sorted(good)} -> "
                + (f"'warn if > N' separates them for {max(good, default=0):.3g} <= N < "
                   f"{min(bad, default=float('inf')):.3g}" if sep else "not separable"))
    fired = [(r["refine"], r["steps"]) for r in ok if r["warning"]]
    log(f"  the library warning fired for (refine, steps): {fired}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a few small runs (smoke test)")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"directory of the CSV files (default {RESULTS}; with --quick a temporary one)")
    ap.add_argument("--steps-block", type=float, default=None,
                    help="block size of the steps study (default: the adequate block found)")
    args = ap.parse_args()
    out = args.out or (Path(tempfile.gettempdir()) / "signorini_study_quick" if args.quick else RESULTS)
    t0 = time.perf_counter()

    def log(msg):
        print(msg, flush=True)

    log("domain study (30 increments):")
    drows, best = domain_study(args.quick, log)
    log("half-plane reference (boundary elements, no block):")
    drows += half_plane_rows(args.quick, log)
    report(drows, out / "friction_domain.csv", width=9)
    size = args.steps_block or best
    log(f"\nsteps study (block {size:g} a0):")
    srows = steps_study(args.quick, size, log)
    report(srows, out / "friction_steps.csv", width=9)
    threshold_analysis(srows, log)
    log(f"\ntotal wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
