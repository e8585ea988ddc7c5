"""One solve over MPI ranks on PETSc (solver="petsc": MUMPS; "petsc-amg": the amg
solver with GAMG's cycle): the converged unknowns, the DDM sensitivities and the
adjoint gradient equal the serial run's, for a frictionless and a frictional
(path-dependent) 3-D Hertz problem, the 3-D forging (J2 plasticity with
friction; also with its element and contact kernels shared out among the
ranks, each rank evaluating its own cells and contact nodes) and two elastic spheres (a frictional mortar pair of two bodies), on 2
and 3 ranks (oversubscribed on a 2-core machine); an interrupted run under
mpiexec keeps its converged increments' series and leaves no rank's private
directory. Skipped where the optional MPI install is absent."""

import importlib.util
import itertools
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from signorini.linsolve.petsc import split_rows

HERE = Path(__file__).parent
CASE = HERE / "case.py"
#: the ``signorini`` command as the console command runs it
ENTRY = "import sys; from signorini.app.cli import entry; sys.argv[0] = 'signorini'; entry()"

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
                                                                 "forging3d", "forging3d-cells",
                                                                 "pairs")}


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
    ("forging3d-cells", "petsc", 2),
    ("forging3d-cells", "petsc-amg", 3),
    ("pairs", "petsc", 2),
    ("pairs", "petsc-amg", 3),
])
def test_parallel_solve_equals_serial(serial, tmp_path, name, solver, ranks):
    ref = serial[name]
    got = case(tmp_path, name, solver, ranks)
    assert int(got["ranks"]) == ranks
    if name.endswith("-cells"):
        # each rank evaluated the element kernels of its own cells and the contact
        # kernels of its own contact nodes
        for key, count in (("seen", "cells"), ("seen_nodes", "nodes")):
            n = int(ref[count])
            assert list(ref[key]) == [n]
            assert list(got[key]) == list(np.diff(split_rows(n, ranks))), key
        # the contact zone is split across the ranks: the closed nodes lie in the
        # blocks of several ranks' contact kernels
        blocks = split_rows(int(ref["nodes"]), ranks)
        closed = [int(np.sum(ref["closed"][a:b])) for a, b in itertools.pairwise(blocks)]
        assert list(got["closed"]) == list(ref["closed"])
        assert sum(c > 0 for c in closed) >= 2, closed
    if solver == "petsc":
        # the rows of the tangent MUMPS factorises (contiguous blocks, one a rank) that
        # hold a contact node's unknowns: on the 3-D Hertz problem all in the last
        # rank's block (the others own no contact node), on the forging in every one
        blocks = split_rows(int(ref["n_rows"]), ranks)
        owned = np.histogram(ref["contact_rows"], blocks)[0]
        if name == "friction":
            assert list(owned[:-1]) == [0] * (ranks - 1) and owned[-1] > 0, owned
        elif name.startswith("forging3d"):
            assert min(owned) > 0, owned
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
    cli = [sys.executable, "-c", ENTRY, "hertz3d", "--n-fine", "4", "--no-fd", "-q"]
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


def test_cli_shares_the_cells_and_rank_0_writes_its_series_alone(tmp_path):
    """``mpiexec -n 2 signorini forging3d --solver petsc`` with the element kernels
    through the kinds' programs (as on a mesh of more than Model.WHOLE_MESH_UP_TO
    cells): the ranks share out the cells, and rank 0, which alone writes each
    increment's VTU file as it converges (the stresses and their sensitivities
    from the element kernels), evaluates them on every cell by itself (were it to
    share them, its gathers would meet no other rank's: MPI_ERR_TRUNCATE, a
    corrupted heap). The outputs equal the serial command's."""
    entry = ENTRY.replace("from signorini", "from signorini.model.kernels import Model; "
                          "Model.WHOLE_MESH_UP_TO = 0; from signorini", 1)
    cli = [sys.executable, "-c", entry, "forging3d", "--mesh", "3x3", "--steps", "3", "--no-fd", "-q"]
    run(cli + ["--out", str(tmp_path / "serial")])
    run(launcher(2) + cli + ["--solver", "petsc", "--out", str(tmp_path / "mpi")])
    a = json.loads((tmp_path / "serial" / "summary.json").read_text())
    b = json.loads((tmp_path / "mpi" / "summary.json").read_text())
    assert b["mpi"]["ranks"] == 2 and b["status"] == a["status"] == "converged"
    assert b["F"] == pytest.approx(a["F"], rel=1e-9)
    for name, d in a["dF_ddm"].items():
        assert b["dF_ddm"][name] == pytest.approx(d, rel=1e-9, abs=1e-9 * max(map(abs, a["dF_ddm"].values())))
    meshio = pytest.importorskip("meshio")
    last = max(p.name for p in (tmp_path / "serial").glob("forging3d_*.vtu"))
    x, y = (meshio.read(tmp_path / d / last).cell_data for d in ("serial", "mpi"))
    assert sorted(x) == sorted(y) and "dcauchy_stress_dsigma_y" in x
    for key in x:
        assert rel(y[key][0], x[key][0]) <= 1e-9 if np.any(x[key][0]) else not np.any(y[key][0]), key


def test_a_rank_with_no_item_of_its_own_takes_part_with_nothing():
    """Two contact nodes and two cells shared out among 3 ranks: rank 0 owns none
    (it evaluates a stand-in item and drops it), and every output (contact and
    element values, JVPs, VJPs with the material values' cotangents summed over the
    ranks) equals the kernels' evaluated alone."""
    out = run(launcher(3) + [sys.executable, str(HERE / "shares.py")]).stdout.split()
    assert out[0] == "shares" and out[2:] == ["0", "1", "1"], out
    assert float(out[1]) <= 1e-13


@pytest.mark.parametrize("ratio,verdict", [(0.6, "refused"), (0.3, "passed")])
def test_the_size_guard_counts_the_ranks_of_a_machine_and_decides_once(ratio, verdict):
    """Two ranks on one machine, each holding a model: the guard counts a rank on half
    the machine's memory, and on the least of any rank's, so both take the same
    decision. Told M and 2 M bytes available, M = the estimate E / ``ratio``: at 0.6
    each would have passed alone (0.85 M = 1.42 E and 2.83 E) and both refuse (a
    rank's share: 0.85 M / 2 = 0.71 E); at 0.3 both pass (0.85 M / 2 = 1.42 E)."""
    out = run(launcher(2) + [sys.executable, str(HERE / "guard.py"), str(ratio)]).stdout
    lines = sorted(line for line in out.splitlines() if line.startswith("guard "))
    assert [line.split()[:3] for line in lines] == [["guard", "0", verdict], ["guard", "1", verdict]]
    if verdict == "refused":
        assert "on each rank" in lines[0] and "2 ranks share a machine" in lines[0], lines[0]
        assert lines[0].split(" ", 3)[3] == lines[1].split(" ", 3)[3]  # the same message


@pytest.mark.parametrize("ranks", [1, 2])
def test_a_dropped_factorisation_frees_its_memory(ranks):
    """petsc4py leaves an object of a parallel communicator that Python drops on
    PETSc's garbage list (destroying it is collective); the solver frees that list
    at each factorisation. Ten factorisations of one tangent, each dropped as the
    next is made, hold about two factors' worth: before, every factorisation's
    MUMPS factors stayed (75 MB each here; the 3-D forging's 8,000 hexahedra on 2
    ranks grew to 13 GB a rank and were killed)."""
    cmd = [sys.executable, str(HERE / "factors.py")]
    out = run(cmd if ranks == 1 else launcher(ranks) + cmd).stdout
    for line in out.strip().splitlines():
        rss = [float(x) for x in line.split()[1:]]
        one = rss[1] - rss[0]  # what the first factor left held
        assert one > 0.02, line  # the factors are large enough to be seen
        assert rss[-1] - rss[3] < 2.5 * one, line  # six more factorisations: before, 6x


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


# ------------------------------------------------------------------ interrupts
def open_mpi() -> bool:
    out = subprocess.run(["mpiexec", "--version"], check=False, capture_output=True, text=True).stdout
    return "Open MPI" in out or "OpenRTE" in out


def interrupt(cmd: list[str], tmp: Path, marker: str) -> tuple[int, str, list[str]]:
    """Run ``cmd`` (under mpiexec) with its temporary directory ``tmp`` and send
    mpiexec SIGINT (Ctrl-C) once rank 0's log shows ``marker``: (exit status, the
    log, the ranks' private directories in ``tmp`` at the signal)."""
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         env={**env(), "TMPDIR": str(tmp), "PYTHONUNBUFFERED": "1"})
    lines, private = [], None
    try:
        for line in iter(p.stderr.readline, ""):  # mpiexec passes stderr on unbuffered
            lines.append(line)
            if marker in line:
                private = sorted(d.name for d in tmp.glob("signorini-rank*"))
                p.send_signal(signal.SIGINT)
                break
        lines.append(p.communicate(timeout=300)[1])
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    log = "".join(lines)
    assert private is not None, f"{marker!r} never came:\n{log[-3000:]}"
    return p.returncode, log, private


@pytest.mark.timeout(600)
@pytest.mark.skipif(not shutil.which("mpiexec") or not open_mpi(),
                    reason="Open MPI's mpiexec ends a job's ranks as this test expects")
def test_an_interrupt_keeps_the_converged_series_and_no_private_directory(tmp_path):
    """Ctrl-C to ``mpiexec -n 2 signorini hertz3d --set mu=0.3 --steps 60 --solver
    petsc`` once 3 increments have converged: Open MPI sends every rank SIGTERM a
    second later and SIGKILL a second after that. summary.json says 'interrupted'
    with the n converged increments, the .pvd series lists all n, each VTU whole
    (rank 0 writes the series as it converges: there is no time to compute it
    then), nothing half-written, and rank 1's private directory is gone."""
    tmp = Path(tempfile.mkdtemp(prefix="sg-"))  # short: Open MPI's sockets live there too
    out = tmp_path / "run"
    try:
        cmd = launcher(2) + [sys.executable, "-c", ENTRY, "hertz3d", "--n-fine", "4", "--set",
                             "mu=0.3", "--steps", "60", "--no-fd", "--solver", "petsc",
                             "--out", str(out)]
        _, log, private = interrupt(cmd, tmp, "[base] increment 3 ")
        assert len(private) == 1 and private[0].startswith("signorini-rank1-"), private
        assert not list(tmp.glob("signorini-rank*")), log[-3000:]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and "SIGTERM" in s["reason"], s.get("reason")
    n = s["converged_increments"]
    assert 3 <= n < 60 and s["load_factor_reached"] == pytest.approx(n / 60)
    assert s["files"] == ["hertz3d.pvd"]
    assert f"kept {n} converged increments (hertz3d.pvd)" in log
    sets = ET.parse(out / "hertz3d.pvd").getroot().find("Collection")
    files = [d.get("file") for d in sets]
    assert files == [f"hertz3d_{k:04d}.vtu" for k in range(1, n + 1)]
    for f in files:
        ET.parse(out / f)
    assert sorted(p.name for p in out.iterdir()) == sorted(["hertz3d.pvd", "summary.json", *files])


#: a command whose rank 0 waits inside a PETSc call for rank 1 when the signal comes,
#: rank 1 behind in Python until half a second after its SIGTERM; then both call
#: PETSc in turn, as a solve does
WAITS = '''
import os, signal, sys, time
from signorini.app import cli, registry
from signorini.app.runner import prepare_output
from signorini.linsolve.petsc import petsc_modules, world

mod = type(sys)("waits")
def add_parser(sub):
    p = sub.add_parser("waits")
    p.add_argument("--out", required=True)
    p.add_argument("--solver", default="petsc")
    p.add_argument("-q", "--quiet", action="store_true")
    p.add_argument("-v", "--verbose", action="store_true")
def execute(args):
    prepare_output(args.out)
    PETSc = petsc_modules()[0]
    v = PETSc.Vec().createMPI(8, comm=PETSc.COMM_WORLD)
    v.set(1.0)
    v.dot(v)  # both ranks are here
    if world()[0] == 0:
        print("rank 0 waits inside PETSc", file=sys.stderr, flush=True)
    else:
        noted, before = [], signal.getsignal(signal.SIGTERM)
        def note(signum, frame):
            noted.append(time.monotonic())
            before(signum, frame)
        signal.signal(signal.SIGTERM, note)
        while not noted or time.monotonic() < noted[0] + 0.5:
            time.sleep(0.01)
    while True:
        v.dot(v)  # a collective call, which holds the interpreter's lock while it waits
        time.sleep(0.01)
mod.add_parser, mod.execute = add_parser, execute
sys.modules["waits"] = mod
registry.COMMANDS["waits"] = "waits"
code = cli.main(["waits", "--out", sys.argv[1]])
sys.stderr.flush()
os._exit(code)
'''


@pytest.mark.timeout(300)
@pytest.mark.skipif(not shutil.which("mpiexec") or not open_mpi(),
                    reason="Open MPI's mpiexec ends a job's ranks as this test expects")
def test_rank_0_waiting_for_another_rank_inside_petsc_still_reports(tmp_path):
    """SIGTERM reaches rank 0 inside a PETSc call that waits for rank 1 (it holds the
    interpreter's lock: no handler runs until it returns) while rank 1 is behind,
    in Python. Rank 1 does not leave on SIGTERM: it goes on into the call, rank 0
    gets out, writes its report and removes rank 1's private directory, rank 1
    then waiting in its next PETSc call for a rank 0 that has left. (A rank 1 that
    left at once, as before, kept rank 0 inside the call until it was killed, with
    no summary.json.) The launcher's kill comes 3 s after its SIGTERM here, not 1 s,
    so that a loaded machine does not decide the outcome."""
    tmp = Path(tempfile.mkdtemp(prefix="sg-"))
    out = tmp_path / "run"
    try:
        cmd = launcher(2) + ["--mca", "odls_base_sigkill_timeout", "3", sys.executable, "-c",
                             WAITS, str(out)]
        _, log, private = interrupt(cmd, tmp, "rank 0 waits inside PETSc")
        assert len(private) == 1 and private[0].startswith("signorini-rank1-"), private
        assert not list(tmp.glob("signorini-rank*")), log[-3000:]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and "SIGTERM" in s["reason"]
    assert "interrupted by SIGTERM" in log and "Traceback" not in log
