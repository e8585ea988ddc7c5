#!/usr/bin/env bash
# The optional MPI install (docs/parallel.md): Debian's PETSc (with MUMPS, hypre,
# SuperLU_DIST, ParMETIS/PT-Scotch) and Open MPI, and petsc4py and mpi4py compiled
# against them for the Python that runs signorini. Debian 12 / Ubuntu; about 2.5 min.
set -euo pipefail
PY=${PYTHON:-python3}
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive
# OpenBLAS: Debian's alternatives then give it to MUMPS in place of the reference BLAS
# (MUMPS's dense kernels; measured 4x faster on a 37k-DOF 3-D tangent)
if ! dpkg -s libpetsc-real-dev libopenblas0-pthread >/dev/null 2>&1; then
    $SUDO apt-get update -qq || true
    $SUDO apt-get install -y -qq --no-install-recommends libpetsc-real-dev libopenblas0-pthread >/dev/null
fi
PETSC_DIR=/usr/lib/petsc
version=$(awk '/define PETSC_VERSION_(MAJOR|MINOR|SUBMINOR) /{v=v (v ? "." : "") $3} END {print v}' \
          "$PETSC_DIR/include/petscversion.h")
# petsc4py must match PETSc's version and see this Python's NumPy (no build isolation);
# its 3.18 sources need Cython 2
if ! $PY -c "import petsc4py" 2>/dev/null; then
    $PY -m pip install -q "cython<3" setuptools wheel
    PETSC_DIR=$PETSC_DIR $PY -m pip install -q --no-build-isolation "petsc4py==$version"
fi
# mpi4py compiled with Debian's mpicc: the MPI PETSc was built with
if ! $PY -c "import mpi4py" 2>/dev/null; then
    $PY -m pip install -q --no-binary mpi4py mpi4py
fi
$PY -c "from petsc4py import PETSc; from mpi4py import MPI; print('petsc4py', PETSc.Sys.getVersion(), 'with', MPI.Get_library_version().splitlines()[0])"
