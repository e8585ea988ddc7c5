"""A moving obstacle against a fixed one: the same problem must give the same answer.

Three studies, each row one solve (Newton rtol 1e-10, PARDISO or SuperLU as
installed), written to ``results/moving_obstacle.csv`` and printed:

* ``force``: the frictional Hertz half model of
  :func:`signorini.problems.hertz_friction.hertz_friction_problem` (force
  control, the block held only by the contact, 30 increments, mu = 0.3), with
  the cylinder moving by (0, -shift) while the body follows it; the frictionless
  one-step Hertz problem likewise. Every shift must give the same c/a, max |p_T|
  and p0, with linearised (LinearElastic) and finite (NeoHooke) kinematics.
* ``held``: a block whose bottom is held, indented by the cylinder moving down
  by d, against the same block pushed up by d at its bottom against the fixed
  cylinder (frictional, 30 increments): the same problem.

c/a is reported node-based (largest reference x of a sticking node over that
of a closed node) and interpolated (:func:`~signorini.problems.hertz_friction.stick_zone`).

Run: ``python benchmarks/study_moving_obstacle.py`` (about a minute).
"""

from __future__ import annotations

import csv
import dataclasses
import sys
from pathlib import Path

import numpy as np

import signorini as sg
from signorini.contact import Contact
from signorini.fem.loads import Fixed
from signorini.contact.obstacles import Circle
from signorini.problems import hertz, hertz_friction

OUT = Path(__file__).resolve().parent / "results" / "moving_obstacle.csv"
TIGHT = sg.NewtonOptions(rtol=1e-10)
SHIFTS = (0.0, 0.01, 0.03)


def moving(pb, shift: float):
    """The problem with the cylinder moving by (0, -shift) over the load path."""
    c = pb.contact[0]
    circle = Circle(radius="R", centre=(0.0, "R"), motion=(0.0, -shift))
    return dataclasses.replace(pb, contact=(Contact(circle, c.edges, c.method, c.kinematics),))


def held(pb, d: float, obstacle_moves: bool):
    """Bottom held (u_y = 0, or u_y = d when the body is pushed), no bottom load;
    the cylinder moves by (0, -d) or stays."""
    c = pb.contact[0]
    motion = (0.0, -d) if obstacle_moves else (0.0, 0.0)
    circle = Circle(radius="R", centre=(0.0, "R"), motion=motion)
    fixed = tuple(pb.fixed) + (Fixed("bottom", 1, 0.0 if obstacle_moves else d),)
    return dataclasses.replace(pb, loads=(), fixed=fixed,
                               contact=(Contact(circle, c.edges, c.method, c.kinematics),))


def row(study, kinematics, case, value, sol, mu):
    c = sol.contact()
    out = {"study": study, "kinematics": kinematics, "case": case, "value": value,
           "increments": len(sol.increments), "p0": float(c["p_N"].max()),
           "force": float(np.sum(c["area"] * c["p_N"]))}
    if "status" in c:
        a, cn = hertz_friction.zones(c)
        z = hertz_friction.stick_zone(c, mu)
        out.update(c_over_a_nodes=cn / a if a else 0.0, c_over_a=z["c_over_a"],
                   max_abs_p_T=float(np.abs(c["p_T"]).max()))
    return out


def main() -> int:
    rows = []
    mu = hertz_friction.DEFAULTS["mu"]
    for kin, finite in (("linear", False), ("finite", True)):
        fr = hertz_friction.hertz_friction_problem(finite_strain=finite)
        for s in SHIFTS:
            rows.append(row("force", kin, "frictional, cylinder moves by (0, -shift)", s,
                            sg.solve(moving(fr, s), steps=30, options=TIGHT), mu))
        fl = hertz.hertz_problem(finite_strain=finite)
        for s in SHIFTS:
            rows.append(row("force", kin, "frictionless, cylinder moves by (0, -shift)", s,
                            sg.solve(moving(fl, s), steps=1, options=TIGHT), mu))
        # the indentation that carries the same final force as the force-controlled run (about)
        d = 0.02
        for moves, case in ((True, "held body, cylinder moves down by d"),
                            (False, "body pushed up by d, cylinder fixed")):
            rows.append(row("held", kin, case, d, sg.solve(held(fr, d, moves), steps=30, options=TIGHT), mu))
    keys = list(dict.fromkeys(k for r in rows for k in r))
    OUT.parent.mkdir(exist_ok=True)
    with open(OUT, "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    print(f"{'study':6} {'kin':7} {'case':45} {'value':>6} {'c/a nodes':>9} {'c/a':>7} "
          f"{'max|p_T|':>9} {'p0':>9} {'force':>9}")
    for r in rows:
        print(f"{r['study']:6} {r['kinematics']:7} {r['case']:45} {r['value']:6.3g} "
              f"{r.get('c_over_a_nodes', float('nan')):9.4f} {r.get('c_over_a', float('nan')):7.4f} "
              f"{r.get('max_abs_p_T', float('nan')):9.5f} {r['p0']:9.6f} {r['force']:9.6f}")
    print(f"written: {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
