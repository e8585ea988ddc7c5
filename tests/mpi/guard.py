"""The size guard under mpiexec (tests/mpi/test_petsc_mpi.py): ``python guard.py
RATIO``. Rank r is told that (r + 1) x M bytes are available on its machine, M the
estimated peak memory of a 3-D run with the petsc solver divided by RATIO; each
rank prints ``guard <rank> passed`` or ``guard <rank> refused <message>``."""

import sys

from signorini.errors import ResourceError
from signorini.linsolve import memory
from signorini.linsolve.petsc import world

N_DOF = 200_000


def main(ratio: float) -> None:
    rank, _ = world()
    need = memory.estimated_peak_memory(N_DOF, "petsc", 3)
    memory.available_memory = lambda: (rank + 1) * need / ratio
    try:
        memory.check_size(N_DOF, dim=3, solver="petsc", what="the test run")
    except ResourceError as e:
        print(f"guard {rank} refused {e}", flush=True)
    else:
        print(f"guard {rank} passed", flush=True)


if __name__ == "__main__":
    main(float(sys.argv[1]))
