"""What one compiled program per element kind would cost: the element kernel
(internal forces and tangent blocks) over every cell of a mesh, as today (one
program per mesh: a ``vmap`` over all cells, the forces assembled inside it)
against one program for a fixed chunk of C cells, called chunk after chunk from
NumPy (the cells gathered, the forces scattered by ``np.bincount``; the last
chunk padded with copies of cell 0). The chunked program is compiled once for
every mesh; the whole-mesh one once per mesh size. The variant ``package`` is what the
package runs (``Model.element_tangents``: chunks of ``CellKernels.SIZES``,
4096 then 512 for the rest).

Meshes: the plane-strain Hertz block (``signorini.problems.hertz``) at
``--refines`` (0..4: 3.6k, 14k, 56k, 225k, 0.9M DOFs), neo-Hookean finite strain
(the heavier kernel, ``--material neohooke``) or linear elastic. Per mesh and
variant: compile time, then the median of ``--repeat`` warm calls (after two
untimed ones), in ns per cell and relative to the whole-mesh program. Results
(forces and blocks) are checked equal to the whole-mesh ones.

    python benchmarks/study_chunking.py [--refines 0,1,2,3,4] [--chunks 1024,4096,16384,65536]
        [--material neohooke|linear] [--repeat 7] [--csv benchmarks/results/chunking.csv]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import os
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

import signorini as sg
from signorini._jax import jax, jnp, to_device
from signorini.fem import element
from signorini.model.cells import CellKernels
from signorini.params import as_jax
from signorini.problems import hertz

RESULTS = Path(__file__).resolve().parent / "results"


def _kernel(model, mp):
    kin, form, mat = model.kinematics, model.formulation, model.material
    return lambda ue, Xe: element.element_residual_tangent(ue, Xe, mat, mp, None, kin, form)[:2]


def whole_program(model, mp):
    """Today's shape: every cell in one vmap, R assembled inside the program."""
    f = _kernel(model, mp)
    conn, edofs, n_dof = np.asarray(model.conn), np.asarray(model.edofs), model.n_dof

    @jax.jit
    def run(u, X):
        r, K = jax.vmap(f)(u[conn], X[conn])
        return jnp.zeros(n_dof).at[edofs.ravel()].add(r.ravel()), K
    return run


def chunk_program(model, mp):
    """One program for C cells, whatever the mesh (compiled once per C)."""
    return jax.jit(jax.vmap(_kernel(model, mp)))


def run_chunked(prog, size, u, X, conn, edofs, n_dof):
    n = len(conn)
    k = -(-n // size)
    R = np.zeros(n_dof)
    K = np.empty((n, 8, 8))
    for c in range(k):
        cells = np.arange(c * size, min((c + 1) * size, n))
        idx = conn[cells]
        if len(cells) < size:  # pad the last chunk with copies of its first cell
            idx = np.concatenate([idx, np.repeat(idx[:1], size - len(cells), axis=0)])
        r, Kc = prog(to_device(u[idx]), to_device(X[idx]))
        r, Kc = np.asarray(r)[:len(cells)], np.asarray(Kc)[:len(cells)]
        R += np.bincount(edofs[cells].ravel(), weights=r.ravel(), minlength=n_dof)
        K[cells] = Kc
    return R, K


def _time(fn, repeat):
    fn()
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--refines", default="0,1,2,3,4")
    ap.add_argument("--chunks", default="1024,4096,16384,65536")
    ap.add_argument("--material", choices=["neohooke", "linear"], default="neohooke")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--csv", default=str(RESULTS / "chunking.csv"))
    args = ap.parse_args()
    chunks = [int(c) for c in args.chunks.split(",")]
    rows, progs = [], {}
    for refine in (int(r) for r in args.refines.split(",")):
        pb = hertz.hertz_problem(refine=refine, finite_strain=args.material == "neohooke",
                                 force_size=True)
        model = sg.algorithms.stepping.model_for(pb)
        params = as_jax(pb.params)
        mp = model.material.values(params)
        X = np.asarray(model.reference(params))
        # a smooth displacement (random nodal values would invert the smallest cells)
        u_nodes = np.column_stack([1e-3 * X[:, 0] + 1e-4 * np.sin(X[:, 1]),
                                   -2e-3 * X[:, 1] + 1e-4 * np.cos(X[:, 0])])
        conn, edofs, n = np.asarray(model.conn), np.asarray(model.edofs), len(model.conn)
        whole = whole_program(model, mp)
        uj, Xj = to_device(u_nodes), to_device(X)
        t0 = time.perf_counter()
        R0, K0 = jax.block_until_ready(whole(uj, Xj))
        t_whole_compile = time.perf_counter() - t0
        R0, K0 = np.asarray(R0), np.asarray(K0)
        assert np.all(np.isfinite(R0)) and np.all(np.isfinite(K0))
        t_whole = _time(lambda: jax.block_until_ready(whole(uj, Xj)), args.repeat)
        base = {"date": datetime.date.today().isoformat(), "material": args.material,
                "refine": refine, "dofs": model.n_dof, "cells": n}
        rows.append({**base, "variant": "whole mesh", "chunk": n, "compile_s": t_whole_compile,
                     "time_s": t_whole, "ns_per_cell": 1e9 * t_whole / n, "ratio": 1.0})
        for size in chunks:
            if size > 4 * n and size != min(chunks):
                continue
            first = size not in progs
            if first:
                progs[size] = chunk_program(model, mp)
            t0 = time.perf_counter()
            R1, K1 = run_chunked(progs[size], size, u_nodes, X, conn, edofs, model.n_dof)
            t_compile = time.perf_counter() - t0 if first else 0.0
            # the same sums in another order: equal to round-off
            np.testing.assert_allclose(R1, R0, rtol=1e-10, atol=1e-10 * np.abs(R0).max())
            np.testing.assert_allclose(K1, K0, rtol=1e-10, atol=1e-10 * np.abs(K0).max())
            t = _time(lambda: run_chunked(progs[size], size, u_nodes, X, conn, edofs, model.n_dof),
                      args.repeat)
            rows.append({**base, "variant": "chunks", "chunk": size, "compile_s": t_compile,
                         "time_s": t, "ns_per_cell": 1e9 * t / n, "ratio": t / t_whole})
        # the package's own path: Model.element_tangents through the element kind's
        # programs (chunks of CellKernels.SIZES, NumPy gather and scatter)
        w = np.zeros(model.n_dof)
        w[: 2 * model.n_nodes] = u_nodes.ravel()
        first = "package" not in progs
        progs["package"] = True
        t0 = time.perf_counter()
        R2, K2 = model.element_tangents(w, params)
        t_compile = time.perf_counter() - t0 if first else 0.0
        np.testing.assert_allclose(R2, R0, rtol=1e-10, atol=1e-10 * np.abs(R0).max())
        np.testing.assert_allclose(K2, K0, rtol=1e-10, atol=1e-10 * np.abs(K0).max())
        t = _time(lambda: model.element_tangents(w, params), args.repeat)
        rows.append({**base, "variant": "package", "chunk": "+".join(map(str, CellKernels.SIZES)),
                     "compile_s": t_compile, "time_s": t, "ns_per_cell": 1e9 * t / n,
                     "ratio": t / t_whole})
        for r in rows[-(2 + len(chunks)):]:
            if r["refine"] == refine:
                print(f"{r['dofs']:>8} DOFs {r['variant']:>10} C={r['chunk']:>7}: "
                      f"{r['ns_per_cell']:8.0f} ns/cell  x{r['ratio']:.3f}  "
                      f"(compile {r['compile_s']:.2f} s)", flush=True)
    out = Path(args.csv)
    out.parent.mkdir(parents=True, exist_ok=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=Path(__file__).parent).stdout.strip()
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) + ["commit", "cpus"])
        w.writeheader()
        for r in rows:
            w.writerow({**r, "commit": commit, "cpus": os.cpu_count()})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
