"""One solve over MPI ranks on PETSc (solver="petsc": MUMPS; "petsc-amg": the amg
solver with GAMG's cycle): the converged unknowns, the DDM sensitivities and the
adjoint gradient equal the serial run's, for a frictionless and a frictional
(path-dependent) 3-D Hertz problem and the 3-D forging (J2 plasticity with
friction), on 2 and 3 ranks (oversubscribed on a
2-core machine). Skipped where the optional MPI install is absent."""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
CASE = HERE / "case.py"

MISSING = [m for m in ("petsc4py", "mpi4py") if importlib.util.find_spec(m) is None]
pytestmark = pytest.mark.skipif(
    bool(MISSING) or shutil.which("mpiexec") is None,
    reason="the optional MPI install is absent (scripts/install-mpi.sh, docs/parallel.md): "
           + (", ".join(MISSING) or "mpiexec") + " not found")


def launcher(n: int) -> list[str]:
    """mpiexec for n ranks, more ranks than cores allowed (Open MPI asks for it)."""
    out = subprocess.run(["mpiexec", "--version"], check=False, capture_output=True, text=True).stdout
    extra = ["--oversubscribe"] if ("Open MPI" in out or "OpenRTE" in out) else []
    return ["mpiexec", "-n", str(n), *extra]


def env() -> dict:
    e = dict(os.environ)
    # Open MPI refuses to start as root without these (CI runs as root); one thread
    # per rank where the ranks share the cores
    e.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
             OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return e


def run(cmd: list[str], timeout: float = 600) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, env=env(), timeout=timeout)
    assert r.returncode == 0, f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}"
    return r


def case(tmp: Path, name: str, solver: str, ranks: int | None):
    out = tmp / f"{name}-{solver}-{ranks}.npz"
    # an iterative solve is as accurate as its tolerance: the amg solver's default
    # (1e-11) leaves frictional sensitivities 1.6e-9 (serial amg) and 1.0e-9
    # (petsc-amg, 2 ranks) from the direct solve's, 1e-13 leaves 5e-11 and 4e-11
    tight = ["1e-13"] if solver.endswith("amg") else []
    cmd = [sys.executable, str(CASE), name, solver, str(out), *tight]
    run(cmd if ranks is None else launcher(ranks) + cmd)
    return dict(np.load(out))


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("serial")
    return {name: case(tmp, name, "superlu", None) for name in ("frictionless", "friction",
                                                                 "forging3d")}


def rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


@pytest.mark.parametrize("name,solver,ranks", [
    ("frictionless", "petsc", 2),
    ("friction", "petsc", 3),
    ("frictionless", "petsc-amg", 3),
    ("friction", "petsc-amg", 2),
    ("frictionless", "petsc-gamg", 2),
    ("forging3d", "petsc", 2),
    ("forging3d", "petsc-amg", 3),
])
def test_parallel_solve_equals_serial(serial, tmp_path, name, solver, ranks):
    ref = serial[name]
    got = case(tmp_path, name, solver, ranks)
    assert int(got["ranks"]) == ranks
    assert rel(got["w"], ref["w"]) <= 1e-9
    # every increment's DDM sensitivities (path-dependent with friction)
    for k in range(ref["sens"].shape[1]):
        assert rel(got["sens"][:, k], ref["sens"][:, k]) <= 1e-9, k
    assert rel(got["ddm"], ref["ddm"]) <= 1e-9
    assert rel(got["adjoint"], ref["adjoint"]) <= 1e-9
    # adjoint = DDM through the parallel solves
    assert rel(got["adjoint"], got["ddm"]) <= 1e-10


def test_cli_under_mpiexec_writes_once(tmp_path):
    """``mpiexec -n 2 signorini hertz3d --solver petsc``: rank 0 alone prints and
    writes; the result equals the serial command's."""
    entry = "import sys; from signorini.app.cli import entry; sys.argv[0] = 'signorini'; entry()"
    cli = [sys.executable, "-c", entry, "hertz3d", "--n-fine", "4", "--no-fd", "-q"]
    run(cli + ["--out", str(tmp_path / "serial")])
    r = run(launcher(2) + cli + ["--solver", "petsc", "--out", str(tmp_path / "mpi")])
    assert r.stdout.count("results in") == 1  # one rank printed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mpi", "serial"]
    a = json.loads((tmp_path / "serial" / "summary.json").read_text())
    b = json.loads((tmp_path / "mpi" / "summary.json").read_text())
    assert b["solver"] == "petsc"
    assert sorted(p.name for p in (tmp_path / "mpi").iterdir()) == \
        sorted(p.name for p in (tmp_path / "serial").iterdir())
    assert b["p0"]["computed"] == pytest.approx(a["p0"]["computed"], rel=1e-10)


def test_iterative_petsc_options_that_fail_say_so(tmp_path):
    """PETSc's own KSP chosen by options (GMRES with point Jacobi, which the
    multipliers' zero diagonal defeats): an error naming the options' failure,
    not a traceback from PETSc."""
    out = tmp_path / "x.npz"
    cmd = launcher(2) + [sys.executable, str(CASE), "frictionless",
                         "petsc:-ksp_type gmres -pc_type jacobi -ksp_max_it 20", str(out)]
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, env=env(), timeout=600)
    assert r.returncode != 0 and not out.exists()
    assert "SolverError" in r.stderr or "SingularTangentError" in r.stderr \
        or "ConvergenceError" in r.stderr, r.stderr[-3000:]
    assert "petsc4py/PETSc" not in r.stderr  # not raised from inside petsc4py
