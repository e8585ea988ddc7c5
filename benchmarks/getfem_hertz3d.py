"""GetFEM peer of ``signorini hertz3d --n-fine N --no-fd``: the same 3-D Hertz problem on
the same mesh, solved by GetFEM, to compare the two whole processes like with like.

Run it with the *system* Python, which has GetFEM (``apt-get install -y python3-getfem``,
GetFEM 5.4.2 with MUMPS on Debian 12); it does not import signorini::

    /usr/bin/python3 benchmarks/getfem_hertz3d.py --n-fine N [--overlap small|disc]
        [--contact obstacle|basic] [--csv FILE] [--compare DIR]

It compares with (pyenv's python3)::

    signorini hertz3d --n-fine N --no-fd --out DIR

whose ``DIR/summary.json`` holds p0 and a; ``--compare DIR`` reads it and ``DIR/contact.csv``
and prints the differences (p0, a, the contact pressures node by node).

The problem (src/signorini/problems/hertz3d.py at --refine 0): quarter model of an elastic
block 0 <= x, y <= W, -H <= z <= 0, W = H = 12 a0 (a0 Hertz's radius at the nominal E = 100,
nu = 0.3, P = 0.1, R = 1), trilinear hexahedra (GetFEM's FEM_QK(3,1), 2x2x2 Gauss points) on
the same graded tensor grid (``--n-fine`` cells across the fine zone, 1.5 a0 wide and 1 a0
deep, cells growing by 1.3 beyond it: bit for bit the node coordinates of ``hertz3d.grid``,
hence the same DOFs, 3 n_nodes + n_contact: 89,298 at --n-fine 19); u_x = 0 on x = 0 and
u_y = 0 on y = 0; a uniform pressure on the bottom face with resultant P/4 (force control,
one increment); the block held only by the frictionless contact with the rigid sphere of
radius R centred at (0, 0, R): one Alart-Curnier multiplier per node of the top face, gap and
normal taken at the reference position (linearised kinematics, as signorini's with a linear
elastic material). Two GetFEM contact bricks (``--contact``):

* ``obstacle`` (default; the brick of the GetFEM runs of issue 53):
  ``add_nodal_contact_with_rigid_obstacle_brick`` with the sphere's signed distance. Its
  multipliers are nodal forces along the sphere's normal (p_N = -lambda_N / A_S,
  A_S = int_top N_S dA), and its gap is linearised along that normal,
  g = g0 + n(X) . u with n = (X - c) / |X - c|, where signorini's is linearised along the
  block's normal e_z, g = g0 + (n(X) . e_z) u_z (``contact.obstacles.Linearized``): the two
  discrete problems differ by the tangential displacement's term, p0 by 0.08-0.22 % at
  --n-fine 4-8.
* ``basic``: ``add_basic_contact_brick``, the same Alart-Curnier machinery given signorini's
  linearised gap (B_N, gap and alpha assembled here): signorini's discrete problem, whose
  pressures it reproduces to ~1e-11.

Both cost the same per Newton iteration (one MUMPS factorisation each). Newton cannot start
from rest: with no node in contact the block floats in z and the tangent is singular. It
starts from a rigid translation u_z = delta of the block (the multipliers zero):

* ``--overlap small``: delta = h^2 / (4 R) (h the fine cell size), half the gap of the first
  ring of nodes: only the node at the origin overlaps;
* ``--overlap disc``: delta = sqrt(a^2 + R^2) - R with Hertz's a: the nodes over the predicted
  Hertz disc r < a overlap.

The symmetry conditions are penalised nodal constraints (``add_constraint_with_penalization``,
coefficient ``--penalty`` E0 h: no extra unknowns, |u.n| ~ 1e-13 on the planes); signorini
eliminates those DOFs (and counts them all the same), so GetFEM factorises 89,298 rows at
--n-fine 19 where signorini factorises 87,516. Newton: GetFEM's ``Model.solve`` (its
Newton with step control), MUMPS (``--lsolver mumps``, the non-symmetric one; ``auto`` lets
GetFEM take the symmetric MUMPS when the model is symmetric, with ``--aug-version 2``),
converged when the residual's 1-norm is below ``--max-res`` (1e-10, signorini's rtol) times
the external load's.

Prints: DOFs, Newton iterations, the time to import GetFEM, the setup, the solve
(``Model.solve``), the whole process's wall time (since the process started, from /proc,
and since the script's first line), p0 (largest contact pressure) and the contact radius a
(largest r of a node in contact) against Hertz's theory; ``--csv FILE`` appends them as a row.
"""

import time

_T0 = time.perf_counter()

import argparse
import csv
import json
import math
import os
import sys

_T1 = time.perf_counter()
import numpy as np

_T2 = time.perf_counter()
import getfem as gf

#: the times to import NumPy and then GetFEM (its Python module and libgetfem, MUMPS, ...)
T_IMPORT_NUMPY, T_IMPORT = _T2 - _T1, time.perf_counter() - _T2

#: the nominal parameters: they size the mesh (as signorini's hertz3d.DEFAULTS)
DEFAULTS = {"E": 100.0, "nu": 0.3, "P": 0.1, "R": 1.0}
#: the CSV's columns of --compare
COMPARE_KEYS = ("signorini_dofs", "signorini_p0", "signorini_a", "signorini_newton_iterations",
                "p0_rel_diff", "a_diff", "nodes_matched", "p_N_max_abs_diff_over_p0")
#: GetFEM's regions
TOP, BOTTOM, X0, Y0 = 1, 2, 3, 4


def process_age() -> float | None:
    """Seconds since this process started (Linux /proc, 10 ms resolution); None elsewhere."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def hertz(P, R, E, nu) -> dict:
    """Hertz's sphere on a half-space: a = (3 P R / (4 E*))^(1/3), p0 = 3 P / (2 pi a^2)."""
    Es = E / (1.0 - nu**2)
    a = (3.0 * P * R / (4.0 * Es)) ** (1.0 / 3.0)
    return {"a": a, "p0": 3.0 * P / (2.0 * math.pi * a**2)}


def graded_coordinates(length, fine_length, n_fine, growth):
    """1-D grid on [0, length]: n_fine uniform cells on [0, fine_length], then cells growing
    by ``growth``, scaled to end at ``length`` (signorini.fem.mesh.graded_coordinates)."""
    fine = np.linspace(0.0, fine_length, n_fine + 1)
    rest = length - fine_length
    if rest <= 1e-14 * length:
        return fine
    h = fine_length / n_fine
    sizes, total = [], 0.0
    while total < rest:
        h = h * growth
        sizes.append(h)
        total += h
    if len(sizes) > 1 and sum(sizes) - rest > 0.5 * sizes[-1]:
        sizes.pop()
    sizes = np.asarray(sizes) * rest / sum(sizes)
    return np.concatenate([fine, fine_length + np.cumsum(sizes)])


def grid(n_fine, size=12.0, zone=1.5):
    """(lateral lines 0..W, vertical lines -H..0, a0) of the graded quarter model
    (signorini.problems.hertz3d.grid at --refine 0)."""
    n = DEFAULTS
    a0 = hertz(n["P"], n["R"], n["E"], n["nu"])["a"]
    xs = graded_coordinates(size * a0, zone * a0, n_fine, 1.3)
    zs = -graded_coordinates(size * a0, zone * a0 * 2.0 / 3.0, max(round(n_fine * 2 / 3), 1),
                             1.3)[::-1]
    return xs, zs, a0


def hat_integrals(g):
    """int N_i over [g0, gn] of the 1-D hat functions on the grid g."""
    d = np.diff(g)
    w = np.zeros(len(g))
    w[:-1] += d / 2
    w[1:] += d / 2
    return w


def nodal_areas(xs, x, y):
    """A_S = int N_S dA over the top face 0 <= x, y <= W of the tensor grid xs x xs, at the
    nodes (x, y) (signorini's equivalent areas: the faces are rectangles)."""
    w = hat_integrals(xs)
    tol = 1e-9 * float(xs[-1])

    def index(v):
        i = np.argmin(np.abs(xs[None, :] - v[:, None]), axis=1)
        assert np.all(np.abs(xs[i] - v) <= tol), "a contact node off the grid"
        return i

    return w[index(x)] * w[index(y)]


def parse_sets(items):
    """``--set E=200 nu=0.25``: the problem's parameters (the mesh stays the nominal one)."""
    values = dict(DEFAULTS)
    for item in items or []:
        name, _, value = item.partition("=")
        if name not in DEFAULTS or not value:
            raise SystemExit(f"--set: expected NAME=VALUE with NAME among {', '.join(DEFAULTS)}, "
                             f"got {item!r}")
        values[name] = float(value)
    return values


def solve(args) -> dict:
    """Build and solve the GetFEM model; the results."""
    v = parse_sets(args.set)
    E, nu, P, R = v["E"], v["nu"], v["P"], v["R"]
    an = hertz(P, R, E, nu)
    t_setup0 = time.perf_counter()
    xs, zs, _ = grid(args.n_fine, args.block, args.zone_width)
    W, H = float(xs[-1]), float(-zs[0])
    h = float(xs[1] - xs[0])

    mesh = gf.Mesh("cartesian", xs, xs, zs)
    for region, normal in ((TOP, [0, 0, 1]), (BOTTOM, [0, 0, -1]), (X0, [-1, 0, 0]),
                           (Y0, [0, -1, 0])):
        mesh.set_region(region, mesh.outer_faces_with_direction(normal, 0.01))
    mfu = gf.MeshFem(mesh, 3)
    mfu.set_classical_fem(1)  # Q1 (FEM_QK(3,1))
    mim = gf.MeshIm(mesh, gf.Integ("IM_GAUSS_PARALLELEPIPED(3,3)"))  # 2x2x2 Gauss points

    md = gf.Model("real")
    md.add_fem_variable("u", mfu)
    lam_el, mu_el = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    md.add_initialized_data("lambda", [lam_el])
    md.add_initialized_data("mu", [mu_el])
    md.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda", "mu")
    # symmetry: u_x = 0 at the nodes on x = 0, u_y = 0 at those on y = 0 (penalised)
    fixed = np.concatenate([[d for d in mfu.basic_dof_on_region(X0) if d % 3 == 0],
                            [d for d in mfu.basic_dof_on_region(Y0) if d % 3 == 1]])
    B = gf.Spmat("copy", gf.Spmat("identity", mfu.nbdof()), fixed.astype(int),
                 list(range(mfu.nbdof())))
    pen = args.penalty * DEFAULTS["E"] * h
    md.add_constraint_with_penalization("u", pen, B, np.zeros(len(fixed)))
    # force control: a uniform pressure on the bottom, resultant P/4 (pushing up, +z)
    md.add_initialized_data("traction", [0.0, 0.0, 0.25 * P / (W * W)])
    md.add_source_term_brick(mim, "u", "traction", BOTTOM)
    # contact with the rigid sphere: nodal augmented Lagrangian (Alart-Curnier), one
    # multiplier per node of the top face
    cdofs = np.asarray(mfu.basic_dof_on_region(TOP))
    nodes_dof = cdofs[::3]
    assert np.all(nodes_dof % 3 == 0) and len(cdofs) == 3 * len(nodes_dof)
    n_contact = len(nodes_dof)
    X = mfu.basic_dof_nodes(nodes_dof)  # (3, n_contact), z = 0
    A = nodal_areas(xs, X[0], X[1])  # A_S = int_top N_S dA
    dist = np.sqrt(X[0] ** 2 + X[1] ** 2 + R**2)  # |X - c|
    md.add_variable("lambda_n", n_contact)
    if args.contact == "obstacle":
        # GetFEM's rigid-obstacle brick: gap = signed distance at X, B_N row = its unit
        # normal (a finite-difference gradient); lambda_N = nodal force. It augments with
        # r alpha_S, alpha_S = M_SS / l (M the top face's mass matrix, l the bounding box's
        # largest side; M_SS = 4 h^2 / 9 in the fine zone), signorini with eps A_S =
        # (E0 / h) h^2: the same augmentation there for r = eps 9 l / 4
        l_box = max(W, H)
        r = args.r if args.r is not None else (DEFAULTS["E"] / h) * 9.0 * l_box / 4.0
        md.add_initialized_data("r", [r])
        obstacle = f"sqrt(x*x+y*y+(z-({R!r}))*(z-({R!r})))-({R!r})"
        md.add_nodal_contact_with_rigid_obstacle_brick(mim, "u", "lambda_n", "r", TOP, obstacle,
                                                       args.aug_version)
    else:
        # GetFEM's basic contact brick with signorini's linearisation of the gap
        # (signorini.contact.obstacles.Linearized: the displacement enters through its
        # component along the body's normal N = e_z): g_S = g0_S - (R / d_S) u_zS >= 0,
        # scaled by A_S so that lambda_N is the pressure: A_S (R / d_S) u_zS <= A_S g0_S;
        # augmentation r alpha_S (A_S g_S) = eps g_S for r = eps = E0 / h, alpha_S = 1 / A_S
        r = args.r if args.r is not None else DEFAULTS["E"] / h
        md.add_initialized_data("r", [r])
        md.add_initialized_data("gap", A * (dist - R))
        md.add_initialized_data("alpha", 1.0 / A)
        select = gf.Spmat("copy", gf.Spmat("identity", mfu.nbdof()), (nodes_dof + 2).astype(int),
                          list(range(mfu.nbdof())))
        BN = gf.Spmat("mult", gf.Spmat("diag", A * R / dist), select)
        md.add_basic_contact_brick("u", "lambda_n", "r", BN, "gap", "alpha", args.aug_version)

    # the start: a rigid translation u_z = delta of the block
    if args.overlap == "small":
        delta = h * h / (4.0 * R)
    else:
        delta = math.sqrt(an["a"] ** 2 + R**2) - R
    U0 = np.zeros(mfu.nbdof())
    U0[2::3] = delta
    md.set_variable("u", U0)
    md.set_variable("lambda_n", np.zeros(n_contact))
    n_dof = int(md.nbdof())
    t_setup = time.perf_counter() - t_setup0

    opts = ["max_iter", args.max_iter, "max_res", args.max_res, "lsolver", args.lsolver]
    if args.noisy:
        opts = ["noisy"] + opts
    sys.stdout.flush()
    t_solve0 = time.perf_counter()
    out = md.solve(*opts)
    t_solve = time.perf_counter() - t_solve0
    if isinstance(out, (tuple, list)):
        n_iter, converged = int(out[0]), bool(out[1])
    else:
        n_iter, converged = int(out), None

    t_post0 = time.perf_counter()
    lam = np.asarray(md.variable("lambda_n"))
    # the contact pressure (lambda_N < 0 in compression), and the z component of the
    # contact force on the block
    if args.contact == "obstacle":
        p = -lam / A  # lambda_N: a nodal force along the sphere's normal (-x, -y, R) / d
        force_z = float(np.sum(-lam * R / dist))
    else:
        p = -lam  # a pressure, along e_z: the force A_S (R / d_S) p_S
        force_z = float(np.sum(A * R / dist * p))
    p0 = float(p.max())
    rad = np.hypot(X[0], X[1])
    closed = p > args.closed_tol * p0
    a_fe = float(rad[closed].max()) if closed.any() else 0.0
    U = np.asarray(md.variable("u"))
    sym = float(np.abs(U[fixed]).max())  # u.n on the symmetry planes
    t_post = time.perf_counter() - t_post0
    return {
        "n_fine": args.n_fine, "overlap": args.overlap, "delta": delta,
        "dofs": n_dof, "nodes": int(mesh.nbpts()), "cells": int(mesh.nbcvs()),
        "contact_nodes": n_contact, "contact_cell_size": h,
        "newton_iterations": n_iter, "converged": converged,
        "p0": p0, "p0_hertz": an["p0"], "p0_rel_error": p0 / an["p0"] - 1,
        "a": a_fe, "a_hertz": an["a"], "a_rel_error": a_fe / an["a"] - 1,
        "closed_nodes": int(closed.sum()), "resultant": force_z,
        "resultant_expected": 0.25 * P, "max_sym_displacement": sym,
        "max_uz": float(U[2::3].max()),
        "contact_brick": args.contact, "aug_version": args.aug_version, "r": r, "penalty": pen,
        "lsolver": args.lsolver,
        "max_res": args.max_res,
        "time_import_numpy_s": T_IMPORT_NUMPY, "time_import_getfem_s": T_IMPORT,
        "time_setup_s": t_setup, "time_solve_s": t_solve, "time_post_s": t_post,
        "contact": {"x": X[0], "y": X[1], "r": rad, "p_N": p},
    }


def compare(res: dict, folder: str) -> dict:
    """Differences from signorini's run in ``folder`` (summary.json, contact.csv)."""
    with open(os.path.join(folder, "summary.json")) as f:
        s = json.load(f)
    out = {"signorini_dofs": s["mesh"]["dofs"], "signorini_p0": s["p0"]["computed"],
           "signorini_a": s["a"]["computed"],
           "signorini_newton_iterations": sum(s["newton_iterations"])}
    out["p0_rel_diff"] = res["p0"] / out["signorini_p0"] - 1
    out["a_diff"] = res["a"] - out["signorini_a"]
    path = os.path.join(folder, "contact.csv")
    if os.path.exists(path):
        with open(path) as f:
            rows = list(csv.DictReader(f))
        unit = res["contact_cell_size"] / 64

        def key(x, y):  # the node at (x, y, 0), to a 64th of the contact cells
            return round(x / unit), round(y / unit)

        theirs = {key(float(r["x"]), float(r["y"])): float(r["p_N"]) for r in rows}
        c = res["contact"]
        diffs = [abs(pn - theirs[key(x, y)]) for x, y, pn in zip(c["x"], c["y"], c["p_N"])
                 if key(x, y) in theirs]
        out["nodes_matched"] = len(diffs)
        out["p_N_max_abs_diff_over_p0"] = (max(diffs) / out["signorini_p0"]) if diffs else None
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--n-fine", type=int, default=8, metavar="N",
                    help="cells across the fine zone (as signorini hertz3d --n-fine)")
    ap.add_argument("--overlap", choices=("small", "disc"), default="small",
                    help="Newton's start: the block translated up so that only the node at the "
                         "origin overlaps the sphere (small) or the predicted Hertz disc does")
    ap.add_argument("--block", type=float, default=12.0, metavar="B",
                    help="block width and depth in units of a0 (as signorini's --block)")
    ap.add_argument("--zone-width", type=float, default=1.5, metavar="Z",
                    help="width of the fine zone in units of a0 (as signorini's --zone-width)")
    ap.add_argument("--set", nargs="+", metavar="NAME=VALUE",
                    help="E, nu, P, R (default 100, 0.3, 0.1, 1); the mesh is sized by the "
                         "defaults, as signorini's")
    ap.add_argument("--contact", choices=("obstacle", "basic"), default="obstacle",
                    help="obstacle: GetFEM's nodal contact brick with a rigid obstacle given by "
                         "its signed distance (its linearisation: the gap along the sphere's "
                         "normal); basic: GetFEM's basic nodal contact brick given signorini's "
                         "linearisation (the gap along the block's normal e_z): signorini's "
                         "discrete problem exactly")
    ap.add_argument("--aug-version", type=int, default=1, choices=(1, 2),
                    help="GetFEM's augmentation: 1 non-symmetric Alart-Curnier, 2 symmetric "
                         "(signorini's tangent is the symmetric one; GetFEM's version 3 diverges "
                         "on this problem)")
    ap.add_argument("--r", type=float, default=None,
                    help="GetFEM's augmentation parameter r (default: the value that equals "
                         "signorini's eps = E0 / h in the fine zone: 9 E0 l / (4 h) with "
                         "--contact obstacle, l the block's side, E0 / h with basic)")
    ap.add_argument("--penalty", type=float, default=1e10,
                    help="penalisation of the symmetry conditions, in units of E0 h")
    ap.add_argument("--lsolver", default="mumps", choices=("mumps", "auto"),
                    help="GetFEM's linear solver (mumps: non-symmetric MUMPS; auto: MUMPS, "
                         "symmetric when the model is, i.e. with --aug-version 2; GetFEM's "
                         "superlu crashes on this model)")
    ap.add_argument("--max-iter", type=int, default=100)
    ap.add_argument("--max-res", type=float, default=1e-10,
                    help="Newton's tolerance (GetFEM: residual 1-norm over the external load's)")
    ap.add_argument("--closed-tol", type=float, default=1e-9,
                    help="a node is in contact when p_N > this times p0")
    ap.add_argument("--noisy", action="store_true",
                    help="GetFEM's Newton log and its traces (quiet otherwise)")
    ap.add_argument("--csv", metavar="FILE", help="append a row of the results to FILE")
    ap.add_argument("--compare", metavar="DIR",
                    help="the output folder of `signorini hertz3d --n-fine N --no-fd --out DIR`: "
                         "print the differences from its summary.json and contact.csv")
    args = ap.parse_args(argv)
    if args.n_fine < 1:
        ap.error("--n-fine must be >= 1")

    if not args.noisy:
        gf.util_trace_level(0)
        gf.util_warning_level(0)
    res = solve(args)
    t_script = time.perf_counter() - _T0
    age = process_age()
    cmp = compare(res, args.compare) if args.compare else {}
    res.update({"time_wall_script_s": t_script, "time_wall_process_s": age})
    print(f"GetFEM Hertz 3-D quarter model, --n-fine {res['n_fine']}, overlap {res['overlap']} "
          f"(delta = {res['delta']:.4g}): {res['dofs']} DOFs ({res['nodes']} nodes, "
          f"{res['contact_nodes']} contact nodes, {res['cells']} cells)")
    print(f"  p0 = {res['p0']:.13g} (Hertz {res['p0_hertz']:.5g}, "
          f"{100 * res['p0_rel_error']:+.2f} %), a = {res['a']:.4g} (Hertz {res['a_hertz']:.4g}), "
          f"{res['closed_nodes']} nodes in contact, contact force {res['resultant']:.10g} "
          f"(P/4 = {res['resultant_expected']:g})")
    print(f"  Newton iterations {res['newton_iterations']}"
          + ("" if res["converged"] is None else f" (converged: {res['converged']})")
          + f"; contact brick {res['contact_brick']}, augmentation version "
          f"{res['aug_version']}, r = {res['r']:.4g}; lsolver {res['lsolver']}; |u.n| on the "
          f"symmetry planes <= {res['max_sym_displacement']:.1e}")
    print(f"  times: import numpy {T_IMPORT_NUMPY:.2f} s, getfem {T_IMPORT:.2f} s, setup "
          f"{res['time_setup_s']:.2f} s, solve {res['time_solve_s']:.2f} s, post "
          f"{res['time_post_s']:.2f} s; whole process "
          + (f"{age:.2f} s (since exec), " if age is not None else "")
          + f"{t_script:.2f} s (since the script's first line)")
    if cmp:
        print(f"  signorini ({args.compare}): {cmp['signorini_dofs']} DOFs, p0 = "
              f"{cmp['signorini_p0']:.13g}, a = {cmp['signorini_a']:.4g}, Newton iterations "
              f"{cmp['signorini_newton_iterations']}; GetFEM - signorini: p0 "
              f"{cmp['p0_rel_diff']:+.2e} (relative), a {cmp['a_diff']:+.2e}"
              + (f", p_N max |diff| / p0 {cmp['p_N_max_abs_diff_over_p0']:.2e} over "
                 f"{cmp['nodes_matched']} nodes" if cmp.get("nodes_matched") else ""))
    if args.csv:
        row = {k: val for k, val in res.items() if k != "contact"}
        row.update({k: cmp.get(k) for k in COMPARE_KEYS})
        new = not os.path.exists(args.csv) or os.path.getsize(args.csv) == 0
        with open(args.csv, "a", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(row))
            if new:
                w.writeheader()
            w.writerow(row)
    return 0 if res["converged"] in (True, None) else 1


if __name__ == "__main__":
    sys.exit(main())
