"""Factorisations per increment, before and after: whole ``signorini`` processes.

Each row is one fresh process (spawn to exit, peak resident memory from
``wait4``), run with the package in ``--tree`` (default: the installed one) and,
with ``--before TREE``, the same command with the package from another source
tree (say a worktree of an older commit), the two alternating ``--repeat``
times so that both see the same machine. Columns: wall time, peak memory,
Newton iterations, factorisations and Krylov iterations on a kept factor (from
``summary.json``; absent before they were reported), p0 or c/a.

Cases (``--cases``):

* ``hertz3d-89k``: ``signorini hertz3d --n-fine 19 --no-fd`` (89,298 DOFs, the
  size of the GetFEM comparison: GetFEM's whole process 33.7 s at best);
* ``hertz3d-89k-rest``: the same with ``--no-coarse-start`` (Newton from rest);
* ``tet-89k``: the same problem on an unstructured tetrahedral mesh read from a
  gmsh file by ``signorini run`` (no coarser mesh: the algebraic coarse start);
* ``friction-43k``: ``hertz3d --n-fine 4 --refine 1 --set mu=0.3 --steps 10``
  (with the FD check, as a user runs it);
* ``hertz-friction``, ``forging``: the 2-D commands at their defaults.

Writes ``results/factorizations.csv`` (or ``--csv``) and prints the table::

    python3 benchmarks/bench_factorizations.py --before /tmp/old/src --repeat 2
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

CASES = {
    "hertz3d-89k": ["hertz3d", "--n-fine", "19", "--no-fd"],
    "hertz3d-89k-rest": ["hertz3d", "--n-fine", "19", "--no-fd", "--no-coarse-start"],
    "tet-89k": ["run", "{tet}"],
    "friction-43k": ["hertz3d", "--n-fine", "4", "--refine", "1", "--set", "mu=0.3", "--steps", "10"],
    "hertz-friction": ["hertz-friction"],
    "forging": ["forging"],
}


def tet_problem(where: Path, n_fine: int = 19) -> Path:
    """The ``hertz3d`` problem at ``n_fine`` on an unstructured tetrahedral mesh
    (the graded grid's points jittered by up to a fifth of the spacing, then
    Delaunay), written as a gmsh file and a problem file; returns the latter."""
    import meshio

    from signorini.problems.hertz3d import DEFAULTS, grid, tetrahedral_block

    block = tetrahedral_block(n_fine=n_fine)
    P, cells = block.nodes, block.cells
    xs = grid(n_fine=n_fine)[0]
    groups = ("x0", "y0", "z0", "z1")
    tri = [block.face_sets[name] for name in groups]
    tags = [np.full(len(t), k + 2) for k, t in enumerate(tri)]
    mesh = meshio.Mesh(P, [("tetra", cells), ("triangle", np.concatenate(tri))],
                       cell_data={"gmsh:physical": [np.ones(len(cells), int), np.concatenate(tags)],
                                  "gmsh:geometrical": [np.ones(len(cells), int),
                                                       np.concatenate(tags)]})
    mesh.field_data = {"block": np.array([1, 3]),
                       **{name: np.array([k + 2, 2]) for k, name in enumerate(groups)}}
    msh = where / "block_tets.msh"
    meshio.write(msh, mesh, file_format="gmsh22", binary=False)
    h_fine = float(xs[1] - xs[0])
    toml = where / "tets.toml"
    toml.write_text(f'''title = "sphere on a block, unstructured tetrahedra (hertz3d at n_fine {n_fine})"
[params]
E = {DEFAULTS["E"]}
nu = {DEFAULTS["nu"]}
P = {DEFAULTS["P"]}
R = {DEFAULTS["R"]}
eps = {DEFAULTS["E"] / h_fine}
[mesh]
file = "{msh.name}"
[material]
type = "linear_elastic"
E = "E"
nu = "nu"
[[fixed]]
set = "x0"
component = "x"
[[fixed]]
set = "y0"
component = "y"
[[load]]
type = "pressure"
faces = "z0"
value = "0.25 * P"
resultant = true
[[contact]]
faces = "z1"
method = "al"
eps = "eps"
obstacle = {{ type = "sphere", radius = "R", centre = [0.0, 0.0, "R"] }}
[solve]
steps = 1
rtol = 1e-10
sensitivities = ["R", "E"]
''')
    return toml


def run(tree: str | None, args: list[str], out: Path) -> dict:
    env = dict(os.environ)
    if tree:
        env["PYTHONPATH"] = tree
    main = "import sys; from signorini.app.cli import main; sys.exit(main(sys.argv[1:]))"
    cmd = [sys.executable, "-c", main, *args, "--out", str(out), "-q"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{err[-2000:]}")
    s = json.loads((out / "summary.json").read_text())
    f = s.get("factorizations")
    row = {"wall_s": round(wall, 2), "peak_mb": round(usage.ru_maxrss / 1024),
           "dofs": (s.get("mesh") or {}).get("dofs", s.get("dofs", "")),
           "increments": len(s.get("newton_iterations", [])),
           "newton_iterations": sum(s.get("newton_iterations", [])),
           "factorizations": sum(f) if f is not None else "",
           "factorizations_per_increment": round(sum(f) / len(f), 2) if f else "",
           "krylov_iterations": sum(s.get("kept_factor_krylov_iterations", []) or [0]),
           "solve_s": round((s.get("timings") or {}).get("solve_s", float("nan")), 2),
           "compile_s": round((s.get("timings") or {}).get("compile_s", float("nan")), 2)}
    for key in ("p0", "c_over_a"):
        v = s.get(key)
        if isinstance(v, dict):
            v = v.get("computed")
        if isinstance(v, (int, float)):
            row[key] = v
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--tree", default=None, help="source tree of 'after' (default: installed)")
    ap.add_argument("--before", default=None, help="source tree of 'before' (e.g. /tmp/old/src)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--csv", default=str(HERE / "results" / "factorizations.csv"))
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tet = tet_problem(tmp) if "tet-89k" in a.cases else None
        for case in a.cases:
            args = [x.replace("{tet}", str(tet)) for x in CASES[case]]
            for k in range(a.repeat):
                for label, tree in (("before", a.before), ("after", a.tree)):
                    if label == "before" and a.before is None:
                        continue
                    out = tmp / f"{case}-{label}-{k}"
                    try:
                        row = run(tree, args, out)
                    except RuntimeError as e:
                        row = {"error": str(e).splitlines()[-1][:200]}
                    row = {"case": case, "version": label, "run": k + 1, **row}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    Path(a.csv).parent.mkdir(parents=True, exist_ok=True)
    with open(a.csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {a.csv} ({time.strftime('%Y-%m-%d')})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
