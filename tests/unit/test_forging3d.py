"""``signorini forging3d``: the rounded-square billet upset between flat dies
(finite-strain J2, F-bar hexahedra, Coulomb friction): DDM = FD for every
parameter through the path, adjoint = DDM, the preform's shape, the volume."""

from __future__ import annotations

import json

import numpy as np
import pytest

import signorini as sg
from signorini._jax import jax
from signorini.app.cli import main
from signorini.errors import ResourceError
from signorini.linsolve import memory as resources
from signorini.problems import forging3d as f3


def test_forging3d_cli_ddm_equals_fd_for_every_parameter(tmp_path):
    """Every reported parameter (three shape parameters, mu, sigma_y): DDM =
    central FD of the whole process to 1e-5; the volume changes only by the
    elastic compressibility; the die force grows with the stroke."""
    out = tmp_path / "f"
    assert main(["forging3d", "--out", str(out), "--mesh", "3x3", "--steps", "6", "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["ddm_vs_fd_rel_diff"]) == set(f3.REPORTED)
    assert max(s["ddm_vs_fd_rel_diff"].values()) < 1e-5
    assert all(abs(d) > 0 for d in s["dF_ddm"].values())
    vol = s["volume"]
    assert abs(vol["ratio"] - vol["elastic_estimate"]) < 0.3 * abs(1 - vol["elastic_estimate"])
    assert 1 - vol["ratio"] > 1e-4
    force = np.loadtxt(out / "force.csv", delimiter=",", skiprows=1)
    assert np.all(np.diff(force[:, 1]) > 0) and force[-1, 0] == pytest.approx(f3.DEFAULTS["stroke"])
    assert force[0, 0] == 0.0 and force[0, 1] == 0.0 and len(force) == 7
    for name in ("sensitivities.csv", "lateral.csv", "force.png", "forging3d.pvd"):
        assert (out / name).is_file(), name


def test_forging3d_adjoint_equals_ddm():
    """J2 plasticity with friction in 3-D: the adjoint gradient of the out-of-roundness
    equals the DDM's for every parameter, and its nodal-coordinate gradient projected
    on a shape parameter's design velocity equals that parameter's DDM derivative."""
    pb = f3.forging3d_problem(mesh=(3, 3))  # the command's test problem: the same programs
    lat = pb.mesh.node_set("lateral")
    names = list(f3.REPORTED)
    G = lambda m: f3.out_of_round(m, lat)  # noqa: E731
    kw = dict(steps=6, options=f3.options())
    ddm = sg.gradient(pb, G, names, method=sg.DDM(), **kw)
    adj = sg.gradient(pb, G, names + ["nodes"], method=sg.Adjoint(), **kw)
    for n in names:
        assert adj.grad[n] == pytest.approx(ddm.grad[n], rel=1e-8), n
    V = pb.shape["bulge"]
    assert np.sum(adj.grad["nodes"] * V) == pytest.approx(ddm.grad["bulge"], rel=1e-8)


def test_forging3d_preform_shapes():
    """The section is exactly a circle of radius `round` when square = 0, and the
    design velocities are exact: the mesh at other values is the preform's."""
    pb = f3.forging3d_problem({"square": 0.0, "round": 0.6})
    X = pb.mesh.nodes
    # the mesh is built at the nominal shape and moved along the design velocities
    Xp = X + sum((pb.params[k] - f3.DEFAULTS[k]) * pb.shape[k] for k in f3.SHAPE)
    lat = pb.mesh.node_set("lateral")
    assert np.allclose(np.hypot(Xp[lat, 0], Xp[lat, 1]), 0.6, rtol=0, atol=1e-14)
    nominal = f3.forging3d_problem()
    on_x = lat[np.abs(nominal.mesh.nodes[lat, 1]) < 1e-14]
    assert np.allclose(nominal.mesh.nodes[on_x, 0], 0.7, atol=1e-14)  # half-width 0.45 + 0.25
    with pytest.raises(sg.InputError, match="round \\+ bulge > 0"):
        f3.forging3d_problem({"round": 0.0})


def test_size_guard_counts_the_plastic_kernels_and_the_history_of_every_increment(monkeypatch):
    """The forging's peak memory is not the linear solver's alone: ``--mesh 20x20
    --steps 2 --no-fd`` (PARDISO, 8,000 cells, 10 increments after its step cuts)
    peaked at 2,740,872 kB (2.61 GiB) against 0.76 GiB for the solver's model. The
    estimate covers it, and the history kept for every increment and sensitivity
    (738 bytes a cell, measured on the 3x3 mesh) makes --steps count: at 40x40 with
    12 GB available the default 20 steps are refused (the solver's model alone,
    4.9 GiB, would have passed), 2 steps pass."""
    monkeypatch.setattr(resources, "available_memory", lambda: 64.0 * resources.GB)
    measured = 2_740_872 * 1024 / resources.GB
    estimate = f3.check_mesh_size((20, 20), steps=2, sensitivities=5, solver="pardiso") / resources.GB
    assert measured <= estimate <= 1.3 * measured
    alone = resources.estimated_peak_memory(3 * 41**2 * 41, "pardiso", dim=3) / resources.GB
    assert 4.5 < alone < 5.5
    monkeypatch.setattr(resources, "available_memory", lambda: 12.0 * resources.GB)
    with pytest.raises(ResourceError, match=r"3-D forging mesh.*--mesh\) or fewer --steps"):
        f3.check_mesh_size((40, 40), sensitivities=6, solver="pardiso")
    with pytest.raises(ResourceError, match="3-D forging mesh"):
        f3.forging3d_problem(mesh=(40, 40), solver="pardiso")
    f3.check_mesh_size((40, 40), steps=2, sensitivities=6, solver="pardiso")
    # one state and one sensitivity per increment, as the estimate counts them
    def nbytes(tree):
        return sum(np.asarray(a).nbytes for a in jax.tree_util.tree_leaves(tree))
    pb = f3.forging3d_problem(mesh=(3, 3))
    sol = sg.solve(pb, steps=1, wrt=["mu", "sigma_y"])
    inc = sol.increments[-1]
    assert nbytes(inc.state) <= f3.HISTORY_BYTES_PER_CELL * pb.mesh.n_cells
    assert nbytes(inc.state_sens) <= 2 * f3.HISTORY_BYTES_PER_CELL * pb.mesh.n_cells
