"""The kernels shared out among more ranks than items (tests/mpi/test_petsc_mpi.py):
``mpiexec -n 3 python shares.py``. Two contact nodes and two cells of the 3-D
forging over 3 ranks: rank 0 owns none of either, ranks 1 and 2 one each. Every
rank evaluates the contact and element kernels (values, JVPs, VJPs) shared out
and alone; rank 0 prints the largest difference relative to the largest value
(one line: ``shares <difference> <each rank's items>``)."""

import jax
import numpy as np
from mpi4py import MPI

from signorini.model.kernels import Model
from signorini.model.share import CellShare
from signorini.problems import forging3d as f3

tree_map = jax.tree_util.tree_map


def first(tree, n: int = 2):
    return tree_map(lambda a: np.asarray(a)[:n], tree)


def main() -> None:
    comm = MPI.COMM_WORLD
    Model.WHOLE_MESH_UP_TO = 0  # the kinds' programs, as on a large mesh
    pb = f3.forging3d_problem(mesh=(3, 3))
    m = Model(pb)
    params = {k: np.float64(v) for k, v in pb.params.items()}
    state = m.initial_state(np.zeros(m.n_dof), params)
    rng = np.random.default_rng(7)  # the same numbers on every rank
    w = 1e-3 * rng.standard_normal(m.n_dof)
    share = CellShare(comm, 2)
    pairs = []  # (alone, shared) outputs

    # the contact kernels of two nodes of the die surface, the die pressed in (t = 0.5)
    geometry = m.contact_geometry(params, 0.5)[1]
    items, shared = m._node_items(0, w, geometry, state)
    items = first(items)
    nodes = m.node_kernels[0]
    for name, outs in (("tangent", (0, 1)), ("residual", (0,)), ("fields", (0, 1, 2))):
        pairs.append((nodes(name, outs, items, shared), share.over(nodes)(name, outs, items, shared)))
    dots = (rng.standard_normal((3, 2, 3)), rng.standard_normal((3, 2, 3))) + (None,) * (len(items) - 2)
    dots += (None,)
    pairs.append((nodes.jvp("residual", (0,), items, shared, dots),
                  share.over(nodes).jvp("residual", (0,), items, shared, dots)))
    cot = (rng.standard_normal((2, 6)),)
    pairs.append((nodes.vjp("residual", (0,), items, shared, cot),
                  share.over(nodes).vjp("residual", (0,), items, shared, cot)))

    # the element kernels of two cells: values, the JVP along the displacements, the
    # VJP (the material values' cotangents summed over the ranks)
    ue, Xe, mp, he = m._cell_arrays(w, params, state)
    cells_items = first((ue, Xe, he))
    cells = m.cells
    pairs.append((cells("tangent", (0, 1), cells_items, mp),
                  share.over(cells)("tangent", (0, 1), cells_items, mp)))
    du = rng.standard_normal((2,) + ue[:2].shape)
    cdots = (du, None, None, None)
    pairs.append((cells.jvp("update", (0,), cells_items, mp, cdots),
                  share.over(cells).jvp("update", (0,), cells_items, mp, cdots)))
    ccot = (rng.standard_normal((2, ue.shape[1] * ue.shape[2])),)
    pairs.append((cells.vjp("update", (0,), cells_items, mp, ccot),
                  share.over(cells).vjp("update", (0,), cells_items, mp, ccot)))

    worst = 0.0
    for alone, together in pairs:
        a_leaves, b_leaves = leaves(alone), leaves(together)
        assert len(a_leaves) == len(b_leaves)
        for a, b in zip(a_leaves, b_leaves):
            assert a.shape == b.shape, (a.shape, b.shape)
            scale = max(float(np.max(np.abs(a))) if a.size else 0.0, 1e-300)
            worst = max(worst, float(np.max(np.abs(a - b))) / scale if a.size else 0.0)
    counts = comm.gather(share.hi - share.lo, root=0)
    worst = comm.reduce(worst, op=MPI.MAX, root=0)
    if comm.Get_rank() == 0:
        print("shares", repr(worst), *counts, flush=True)


def leaves(tree) -> list[np.ndarray]:
    return [np.asarray(x) for x in jax.tree_util.tree_leaves(tree)]


if __name__ == "__main__":
    main()
