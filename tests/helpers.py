"""Helpers shared by several test modules (tests/conftest.py puts this folder on
sys.path: ``from helpers import pressed_block``). Fixtures go to a conftest.py
instead; a helper used by one module stays in that module."""

import numpy as np

from signorini.contact import AugmentedLagrangian, Contact
from signorini.contact.obstacles import Circle
from signorini.fem.loads import Fixed
from signorini.fem.mesh import rectangle
from signorini.materials import LinearElastic
from signorini.model.problem import Problem


def pressed_block(friction: bool):
    """A block whose base is moved up by a prescribed displacement d into a cylinder
    (with friction: a sideways base motion s too): the prescribed values depend on
    parameters, so their adjoint path (VJP of the prescribed values) is exercised."""
    from signorini.contact import Coulomb

    mesh = rectangle(np.linspace(0.0, 2.0, 9), np.linspace(-1.0, 0.0, 5))
    law = Coulomb("mu", "eps", "eps") if friction else AugmentedLagrangian("eps")
    return Problem(mesh=mesh, material=LinearElastic(),
                   params={"E": 100.0, "nu": 0.3, "R": 1.0, "d": 0.02, "s": 0.004, "mu": 0.3,
                           "eps": 400.0},
                   fixed=(Fixed("bottom", 1, "d"), Fixed("bottom", 0, "s")),
                   contact=(Contact(Circle(radius="R", centre=(1.0, lambda p: p["R"])), "top", law),))


# ------------------------------------------------------------------ ironing, 2-D and 3-D
def read_csv(path) -> dict:
    """The columns of a command's CSV file: floats, but the status column's text."""
    import csv

    with open(path) as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return {k: (v if k == "status" else v.astype(float)) for k, v in cols.items()}


def die_forces(sol, die_force) -> np.ndarray:
    """(F_N, F_T) of an ironing path at every increment, from the problem module's
    ``die_force``."""
    f = [die_force(sol, i) for i in range(len(sol.increments))]
    return np.array([[r["F_N"], r["F_T"]] for r in f])


def check_ironing_run(out, name: str, steps: int, sol, die_force, names, fd_names) -> tuple:
    """What both ironing commands write after a run of the API's path ``sol``: every
    file (one VTU per body and increment), the DDM against the command's own
    central differences for ``fd_names`` (<= 1e-6), the partner changes, per-body
    entries, and force.csv's die force and DDM to ``names`` equal to the API's.
    Returns (summary.json, force.csv's columns)."""
    import json

    last = f"{steps:04d}"
    for f in ("force.csv", "contact.csv", "summary.json", "force.png", "sensitivity.png",
              f"{name}.pvd", f"{name}_block_{last}.vtu", f"{name}_die_{last}.vtu"):
        assert (out / f).is_file(), f
    s = json.loads((out / "summary.json").read_text())
    assert set(s["ddm_vs_fd_rel_diff"]) == set(fd_names)
    assert max(s["ddm_vs_fd_rel_diff"].values()) <= 1e-6, s["ddm_vs_fd_rel_diff"]
    assert s["partner_changes"] and s["partner_change_count"] > 0
    assert set(s["bodies"]) == {"block", "die"}
    F = read_csv(out / "force.csv")
    api = [die_force(sol, i, names) for i in range(len(sol.increments))]
    for k in ["F_N", "F_T"] + [f"dF_{c}_d{n}" for n in names for c in "NT"]:
        ref = np.array([r[k] for r in api])
        assert np.abs(F[k] - ref).max() <= 1e-9 * np.abs(ref).max(), k  # 1e-12 when written
    pvd = (out / f"{name}.pvd").read_text()
    assert pvd.count('part="1"') == steps and f"{name}_die_0001.vtu" in pvd
    return s, F


def check_fd_of_two_runs(tmp_path, argv, name: str, value: float, h: float) -> None:
    """The central difference of F_T from two command runs (``argv``, ``--out`` and
    ``--no-fd`` added) with ``name`` = value +- h equals the DDM of the run at
    ``value``, at every increment (to 1e-6 of its largest)."""
    from signorini.app.cli import main

    out = tmp_path / "nominal"
    assert main(argv + ["--out", str(out), "--no-fd"]) == 0
    ddm = read_csv(out / "force.csv")[f"dF_T_d{name}"]
    runs = []
    for sign in (1, -1):
        o = tmp_path / f"{name}{sign}"
        assert main(argv + ["--out", str(o), "--no-fd", "--set", f"{name}={value + sign * h!r}"]) == 0
        runs.append(read_csv(o / "force.csv")["F_T"])
    fd = (runs[0] - runs[1]) / (2 * h)
    assert np.abs(fd - ddm).max() <= 1e-6 * np.abs(ddm).max()


def misfit_matches_central_differences(m, x, g, J, rel=1e-4, tol=1e-6) -> None:
    """A fit's misfit ``m`` (signorini.design.fit.Misfit) at ``x``: its gradient ``g``
    and the residuals' Jacobian ``J`` equal central differences (step ``rel`` x_i)
    of the misfit and of the residuals to ``tol`` relative."""
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = h = rel * x[i]
        fd = (m(x + e) - m(x - e)) / (2 * h)
        fd_r = (m.residuals(x + e) - m.residuals(x - e)) / (2 * h)
        assert abs(fd / g[i] - 1) < tol, (x, i, g[i], fd)
        assert np.abs(fd_r - J[:, i]).max() < tol * np.abs(J[:, i]).max(), (x, i)


def adjoint_misfit_is_ddms_and_central_differences(m, obj, x) -> None:
    """The adjoint objective ``obj`` of a fit's misfit ``m`` at ``x``: its value is
    r^T r (1e-13), its gradient the DDM's 2 J^T r (1e-10) and the central
    differences (step 1e-4 x_i) of its own value (1e-6), relative."""
    F, g = obj.value_and_grad(x)
    assert abs(F / m(x) - 1) < 1e-13
    assert np.abs(g / m.gradient(x) - 1).max() < 1e-10
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = h = 1e-4 * x[i]
        fd = (obj(x + e) - obj(x - e)) / (2 * h)
        assert abs(fd / g[i] - 1) < 1e-6, (x, i, g[i], fd)
