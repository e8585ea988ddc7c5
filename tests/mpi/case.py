"""One solve run by every rank under mpiexec (tests/mpi/test_petsc_mpi.py):
``python case.py CASE SOLVER OUT.npz [RTOL]`` (RTOL: an iterative solver's). Rank 0 saves the converged unknowns of
every increment, their DDM sensitivities, and the adjoint and DDM gradients of
the case's response (the contact work unless it names another); the other ranks
compute the same and save nothing. A case named ``NAME-cells`` evaluates the
element kernels through the kinds' programs (as on large meshes), which the ranks
and the contact kernels through theirs, which the ranks share out, and saves the
cells and contact nodes each rank evaluated for a tangent, the contact nodes
closed at the end and the rows of the contact nodes' unknowns in the tangent."""

import sys

import numpy as np

import signorini as sg
from signorini.design.gradient import gradient
from signorini.linsolve import AMGKrylov
from signorini.linsolve.petsc import PetscAMG, PetscSolver, world
from signorini.model import chunks
from signorini.model.cells import CellKernels
from signorini.model.kernels import Model
from signorini.model.nodes import NodeKernels
from signorini.problems import forging3d as f3
from signorini.problems.hertz3d import hertz3d_problem
from signorini.problems.spheres import spheres_problem
from signorini.responses import contact_work, displacement

CASES = {
    # (problem, steps, names, response, Newton options)
    "frictionless": (lambda: hertz3d_problem({}, n_fine=4), 1, ["R", "E", "P"], None, None),
    "friction": (lambda: hertz3d_problem({"mu": 0.3}, n_fine=4), 3, ["R", "E", "mu"], None, None),
    # two elastic spheres: a mortar pair (rows coupling a slave node to its master nodes)
    # with Coulomb friction along Cattaneo-Mindlin's path, P over the first two increments
    # then Q; n_fine 3: 6 to 9 closed slave nodes, sticking and slipping at every increment.
    # The response: the lower body's tangential displacement where Q acts (held by friction
    # alone); the contact work would trace the pair's clipping once more in every process
    # (5 to 8 s more CPU per process on this 2-core machine)
    "pairs": (lambda: spheres_problem({"mu": 0.3, "Q": 0.015}, n_fine=3), 4, ["E1", "R1", "mu"],
              lambda pb: displacement("lower.z0", 0), None),
    # J2 plasticity with friction, path-dependent in both
    "forging3d": (lambda: f3.forging3d_problem(mesh=(3, 3)), 6, ["square", "bulge", "mu", "sigma_y"],
                  lambda pb: (lambda m: f3.out_of_round(m, pb.mesh.node_set("lateral"))),
                  f3.options()),
}


def items_per_tangent() -> dict[str, list[int]]:
    """Count the cells and the contact nodes of every element- and contact-tangent
    evaluation of this process (the kinds' programs, Chunked.start): a rank that
    shares them out counts its own."""
    counts = {"cells": [], "nodes": []}
    start = chunks.Chunked.start

    def counted(self, name, outs, items, shared):
        kind = "cells" if isinstance(self, CellKernels) else "nodes" if isinstance(self, NodeKernels) else None
        if name == "tangent" and kind is not None:
            counts[kind].append(chunks._count(items))
        return start(self, name, outs, items, shared)
    chunks.Chunked.start = counted
    return counts


def main(case: str, solver: str, out: str, rtol: str | None = None) -> None:
    counts = None
    if case.endswith("-cells"):
        # the element and contact kernels through the kinds' programs (as on meshes of
        # more than Model.WHOLE_MESH_UP_TO cells), which the ranks share out among them
        case = case[:-len("-cells")]
        Model.WHOLE_MESH_UP_TO = 0
        counts = items_per_tangent()
    build, steps, names, response, options = CASES[case]
    if solver == "petsc-gamg":  # the amg solver's Krylov method with PETSc's GAMG cycle
        solver = PetscAMG(hierarchy="gamg", rtol=float(rtol or 1e-11))
    elif solver.startswith("petsc:"):  # PETSc's own KSP, chosen by options
        solver = PetscSolver(options=solver.split(":", 1)[1])
    elif rtol is not None:  # an iterative solver's relative residual
        solver = {"amg": AMGKrylov, "petsc-amg": PetscAMG}[solver](rtol=float(rtol))
    pb = build()
    resp = contact_work() if response is None else response(pb)
    kw = dict(steps=steps, increments="all", solver=solver)
    if options is not None:
        kw["options"] = options
    d = gradient(pb, resp, names, method=sg.DDM(), **kw)
    sol = d.solution
    a = gradient(pb, resp, names, method=sg.Adjoint(), solution=sol, **kw)
    rank, size = world()
    # the cells and contact nodes each rank evaluated for a tangent, at most (every
    # rank's, on rank 0)
    seen = [[max(v) if v else 0 for v in counts.values()] if counts else [0, 0]]
    if size > 1:
        from mpi4py import MPI

        seen = MPI.COMM_WORLD.gather(seen[0], root=0)
    m, surface = sol.model, sol.model.surfaces[0]
    closed = np.asarray(sol.contact(-1)["p_N"]) > 0
    # the rows of the free-free tangent (the matrix the PETSc solvers split among the
    # ranks in contiguous blocks) that hold a contact node's unknowns
    rows = np.flatnonzero(np.isin(m.free, surface.dofs.ravel()))
    if rank == 0:
        seen = np.array(seen)
        np.savez(out, w=np.stack([inc.w for inc in sol.increments]),
                 sens=np.stack([[inc.sens[n] for n in names] for inc in sol.increments]),
                 ddm=np.array([d[n] for n in names]), adjoint=np.array([a[n] for n in names]),
                 value=d.value, ranks=size,
                 newton=np.array([inc.newton.iterations for inc in sol.increments]),
                 cells=len(pb.mesh.cells), seen=seen[:, 0], nodes=surface.nodes.size,
                 seen_nodes=seen[:, 1], closed=closed, contact_rows=rows, n_rows=len(m.free))

if __name__ == "__main__":
    main(*sys.argv[1:5])
