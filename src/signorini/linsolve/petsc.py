"""One linear solve over MPI ranks: PETSc's parallel matrices and solvers
(``solver="petsc"``; docs/parallel.md).

Every rank runs the same program (``mpiexec -n N signorini ...``): the model,
the assembly and Newton's bookkeeping are the same on every rank, and each
tangent is handed to PETSc as a parallel matrix whose rows are split among the
ranks in contiguous blocks (each rank copies its own rows; nothing is sent).
PETSc's KSP solves it on all the ranks together; the solution is gathered on
every rank, so that the next step of the program is again the same everywhere.

The default is MUMPS's parallel direct factorisation (LU, or LDL^T for a
symmetric tangent), which takes any tangent this package assembles (saddle
points, friction, mortar pairs) and solves it to round-off; the factorisation
serves every right-hand side of the tangent (Newton's correction, the DDM's
columns, the adjoint's transposed solve). Any other KSP and preconditioner is
chosen by PETSc options, given as ``PetscSolver(options="-ksp_type gmres
-pc_type gamg ...")``, ``--petsc-options`` on the command line (PETSc's global
options database), or PETSc's own ``PETSC_OPTIONS`` variable; an iterative choice is then checked like the
``amg`` solver's solves (backward error 1e-10, refined, an error if not
reached).

The package needs petsc4py and mpi4py, an optional install (docs/parallel.md);
without them the solver raises :class:`~signorini.errors.InputError` saying so.
"""

from __future__ import annotations

import contextlib
import logging
import shlex
import sys
import time

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, SingularTangentError, SolverError
from .base import LinearSolver
from .factor import Factor
from .iterative import AMGKrylov
from .multigrid import COARSE_DEGREE, DEGREE, RATIO

log = logging.getLogger("signorini")

INSTALL = ("solver 'petsc' needs petsc4py and mpi4py, an optional install: see docs/parallel.md "
           "(scripts/install-mpi.sh on Debian or Ubuntu)")


def petsc_modules():
    """(PETSc, MPI) from petsc4py and mpi4py, initialised; InputError if absent."""
    try:
        import petsc4py  # noqa: PLC0415  (lazy: an optional install)
        from mpi4py import MPI  # noqa: PLC0415  (lazy, as above)
    except ImportError:
        raise InputError(INSTALL) from None
    if "petsc4py.PETSc" not in sys.modules:
        # PETSc's own handlers would turn an interrupt into a crash report and an abort:
        # ours keep the converged increments (app.cli)
        petsc4py.init(["signorini", "-no_signal_handler"])
    from petsc4py import PETSc  # noqa: PLC0415  (lazy, as above; initialises PETSc once)
    return PETSc, MPI


def world() -> tuple[int, int]:
    """(rank, size) of MPI's world where mpi4py is installed and MPI runs, else (0, 1).

    Imports mpi4py, which starts MPI: called only where a run asked for PETSc."""
    try:
        from mpi4py import MPI  # noqa: PLC0415  (lazy: an optional install)
    except ImportError:
        return 0, 1
    comm = MPI.COMM_WORLD
    return comm.Get_rank(), comm.Get_size()


def per_rank_memory(have: float | None) -> tuple[float | None, int]:
    """(the bytes each rank may count on, the most ranks on one machine) of a run
    under mpiexec, given the bytes ``have`` available on this rank's machine (None:
    unknown). The ranks of one machine share its memory, each holding a model, so a
    rank counts on its machine's share, and every rank on the least share of any
    (one collective): every rank then takes the same decision, for a rank that
    refused a run alone would leave the others waiting for it in their first
    collective. ``(have, 1)`` where MPI runs one rank or is not installed."""
    _, size = world()
    if size < 2:
        return have, 1
    from mpi4py import MPI  # noqa: PLC0415  (lazy: an optional install; world() found it)

    comm = MPI.COMM_WORLD
    machine = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        here = machine.Get_size()
    finally:
        machine.Free()
    least = comm.allreduce(float("inf") if have is None else have / here, op=MPI.MIN)
    most = comm.allreduce(here, op=MPI.MAX)
    return (None if least == float("inf") else least), most


def insert_options(options: str) -> None:
    """Put PETSc options (a string as on PETSc's command line) into PETSc's global
    database, which every :class:`PetscSolver` reads (``--petsc-options``)."""
    PETSc, _ = petsc_modules()
    _put(PETSc.Options(), PetscSolver._parse(options))


def _on_ranks(solver, options: str) -> None:
    """What both PETSc solvers keep: PETSc and MPI, the world's communicator, this
    rank and their number, and their own ``options`` checked and parsed."""
    solver.PETSc, solver.MPI = petsc_modules()
    if not isinstance(options, str):
        raise InputError(f"petsc options must be a string of PETSc options, got {options!r}")
    solver.options, solver._pairs = options, PetscSolver._parse(options)
    solver.comm = solver.PETSc.COMM_WORLD
    solver.rank, solver.size = solver.comm.getRank(), solver.comm.getSize()
    solver.communicator = solver.comm.tompi4py() if solver.size > 1 else None


def collect(solver) -> None:
    """Free the PETSc objects of the solver's earlier tangents that Python has let go.
    petsc4py does not destroy an object of a parallel communicator when Python drops
    it (destroying is collective, Python's collection is not): it waits on PETSc's
    garbage list until ``garbage_cleanup``, collective, called here where every rank
    comes in the same order (each factorisation, each cycle's set-up). Without it
    every factorisation's MUMPS factors stayed until the end of the run (75 MB each
    on 27k unknowns; the 3-D forging's 8,000 hexahedra on 2 ranks reached 13 GB a
    rank and were killed)."""
    cleanup = getattr(solver.PETSc, "garbage_cleanup", None)
    if cleanup is not None:
        cleanup(solver.comm)


def split_rows(n: int, size: int) -> np.ndarray:
    """(size + 1,) starts of the ranks' contiguous blocks of n rows, as even as can be."""
    return (np.arange(size + 1, dtype=np.int64) * n) // size


class PetscSolver(LinearSolver):
    """The tangent solved by PETSc on all the MPI ranks (``solver="petsc"``).

    Args:
        options: PETSc options for this solver's KSP (e.g. ``"-ksp_type gmres
            -pc_type gamg -ksp_rtol 1e-12"``), read after the defaults (MUMPS,
            direct) and after PETSc's global options (``PETSC_OPTIONS``,
            :func:`insert_options`).
    """

    name = "petsc"
    #: the backward error an iterative KSP's solve must reach (the ``amg`` solver's)
    ITERATIVE_REFINE_TOL = 1e-10

    def __init__(self, options: str = ""):
        _on_ranks(self, options)
        self.factorizations = 0
        self.factorize_s = 0.0  # PETSc's factorisations (all ranks together)
        self.solve_s = 0.0      # its solves, the gathering of their solutions included

    @staticmethod
    def _parse(options: str) -> list[tuple[str, str | None]]:
        words = shlex.split(options)
        pairs: list = []
        i = 0
        while i < len(words):
            w = words[i]
            if not w.startswith("-") or len(w) < 2:
                raise InputError(f"petsc options: {w!r} is not an option (options start with '-', "
                                 f"e.g. '-ksp_type gmres'); got {options!r}")
            value = None
            if i + 1 < len(words) and not (words[i + 1].startswith("-")
                                            and not _is_number(words[i + 1])):
                value = words[i + 1]
                i += 1
            pairs.append((w.lstrip("-"), value))
            i += 1
        return pairs

    def describe(self) -> str:
        return f"petsc ({self.size} rank{'s' if self.size > 1 else ''})"

    def mpi_report(self) -> dict:
        """What ``summary.json`` says of the parallel part (``mpi``)."""
        return {"ranks": self.size, "factorizations": self.factorizations,
                "parallel_factorize_s": round(self.factorize_s, 3),
                "parallel_solve_s": round(self.solve_s, 3)}

    # ---------------------------------------------------------------- factor
    def factorize(self, K, symmetric: bool = False) -> Factor:
        PETSc = self.PETSc
        collect(self)
        K = sp.csr_matrix(K)
        n = K.shape[0]
        starts = split_rows(n, self.size)
        r0, r1 = int(starts[self.rank]), int(starts[self.rank + 1])
        A = _local_rows(PETSc, self.comm, K, r0, r1)
        if symmetric:
            A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        ksp = PETSc.KSP().create(comm=self.comm)
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky" if symmetric else "lu")
        pc.setFactorSolverType("mumps")
        t0 = time.perf_counter()
        try:
            with _options(PETSc, self._pairs):
                ksp.setFromOptions()
                direct = ksp.getType() == "preonly"
                ksp.setUp()
        except PETSc.Error as e:
            raise SingularTangentError(
                f"PETSc could not factorise the tangent ({_petsc_message(e)}): a singular tangent "
                "(a body not held, a multiplier no law determines)") from None
        self.factorizations += 1
        self.factorize_s += time.perf_counter() - t0
        x_vec, b_vec = A.createVecs()
        gather = _gatherer(self.comm, self.MPI, starts)

        def one(bj: np.ndarray, transpose: bool, x0=None) -> np.ndarray:
            t0 = time.perf_counter()
            try:
                return _one(bj, transpose, x0)
            finally:
                self.solve_s += time.perf_counter() - t0

        def _one(bj: np.ndarray, transpose: bool, x0=None) -> np.ndarray:
            b_vec.setArray(bj[r0:r1])
            if x0 is not None and not direct:
                ksp.setInitialGuessNonzero(True)
                x_vec.setArray(x0[r0:r1])
            else:
                ksp.setInitialGuessNonzero(False)
            try:
                (ksp.solveTranspose if transpose else ksp.solve)(b_vec, x_vec)
            except PETSc.Error as e:
                raise SolverError(
                    f"PETSc's solve of the tangent failed ({_petsc_message(e)}) with "
                    f"{ksp.getType()}/{ksp.getPC().getType()}: give other options "
                    "(--petsc-options) or drop them for the direct default (MUMPS)") from None
            reason = ksp.getConvergedReason()
            if reason < 0:
                if direct:
                    raise SingularTangentError(
                        f"PETSc's solve of the tangent failed (KSP reason {reason}): a singular "
                        "tangent") from None
                raise SolverError(
                    f"PETSc's iterative solve ({ksp.getType()}, {ksp.getPC().getType()}) did not "
                    f"converge (KSP reason {reason}, {ksp.getIterationNumber()} iterations): "
                    "give other options (--petsc-options) or drop them for the direct default")
            return gather(x_vec)

        def columns(b, transpose=False, x0=None):
            b = np.asarray(b, dtype=float)
            if b.ndim == 1:
                return one(b, transpose, x0)
            return np.column_stack([one(b[:, j], transpose, None if x0 is None else x0[:, j])
                                    for j in range(b.shape[1])])

        f = Factor(columns, K, transposable=True,
                   solve_from=None if direct else (lambda b, x0: columns(b, False, x0)))
        if direct:  # MUMPS's figures: a kept factorisation's worth (linsolve.kept.budget_of)
            f.flops, f.nbytes = _mumps_figures(ksp)
        else:
            f.refine_tol = self.ITERATIVE_REFINE_TOL
        f._petsc = (ksp, A, x_vec, b_vec)  # kept alive with the factor
        return f


def _mumps_figures(ksp) -> tuple[float | None, int | None]:
    """(operations of the elimination, bytes of the factors) that MUMPS reports
    (RINFOG(3); INFOG(9) entries, in millions where negative), or Nones for
    another factorisation."""
    try:
        F = ksp.getPC().getFactorMatrix()
        flops = float(F.getMumpsRinfog(3))
        entries = int(F.getMumpsInfog(9))
    except Exception:  # noqa: BLE001 - not MUMPS (options chose another): no figures
        return None, None
    entries = -entries * 1_000_000 if entries < 0 else entries
    return (flops if flops > 0 else None), (8 * entries if entries > 0 else None)


def _is_number(word: str) -> bool:
    try:
        float(word)
        return True
    except ValueError:
        return False


def _petsc_message(e) -> str:
    return str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__


class PetscAMG(AMGKrylov):
    """The ``amg`` solver with its multigrid cycle on all the MPI ranks
    (``solver="petsc-amg"``): flexible GMRES on the tangent, the contact
    multipliers condensed node by node, as :class:`~signorini.linsolve.AMGKrylov`
    does, and in place of its V-cycle one V-cycle of PETSc's multigrid (PCMG) on
    the displacement block, every level's rows split among the ranks.

    ``hierarchy="own"`` (the default) hands PCMG the ``amg`` solver's own
    hierarchy (smoothed aggregation on aggregates that follow the cells'
    stretching, rigid-body modes as near-null space): its levels and
    prolongators, smoothed by Chebyshev on the nodal diagonal blocks (degree 3 on
    the finest level, 2 below, the ``amg`` solver's), so that the cycle is the
    ``amg`` solver's own and needs as many Krylov iterations. ``"gamg"``: PETSc's
    GAMG builds the hierarchy itself, in parallel, from the matrix and the
    rigid-body modes (2.3-3.6x the Krylov iterations on the graded 3-D Hertz
    mesh, docs/parallel.md). PETSc options (``-mg_levels_ksp_max_it``,
    ``-pc_gamg_threshold``, ...) apply to the cycle.

    Args:
        options: PETSc options for the cycle's KSP and PC (as :class:`PetscSolver`).
        hierarchy: ``"own"`` or ``"gamg"``.
        **kwargs: those of :class:`~signorini.linsolve.AMGKrylov` (``rtol``, ...).
    """

    name = "petsc-amg"
    HIERARCHIES = ("own", "gamg")

    def __init__(self, options: str = "", hierarchy: str = "own", **kwargs):
        super().__init__(**kwargs)
        if hierarchy not in self.HIERARCHIES:
            raise InputError(f"petsc-amg: hierarchy must be one of {self.HIERARCHIES}, got "
                             f"{hierarchy!r}")
        _on_ranks(self, options)
        self.hierarchy = hierarchy
        self.cycles = 0
        self.cycle_s = 0.0      # in PETSc's cycles, their gathering included
        self.setup_s = 0.0      # the hierarchies: pyamg's (every rank) and PETSc's set-up

    def describe(self) -> str:
        return f"petsc-amg ({self.size} rank{'s' if self.size > 1 else ''}, {self.hierarchy})"

    def mpi_report(self) -> dict:
        """What ``summary.json`` says of the parallel part (``mpi``): the cycles run on
        all the ranks; the rest of a solve (GMRES, the condensation, the products with
        the tangent) and the hierarchy's pyamg part run on every rank alike."""
        return {"ranks": self.size, "hierarchy": self.hierarchy, "cycles": self.cycles,
                "parallel_cycle_s": round(self.cycle_s, 3),
                "hierarchy_setup_s": round(self.setup_s, 3)}

    def _cycle(self, full, B):
        t0 = time.perf_counter()
        try:
            return self._petsc_cycle(full, B)
        finally:
            self.setup_s += time.perf_counter() - t0

    def _petsc_cycle(self, full, B):
        PETSc = self.PETSc
        collect(self)
        d = self.structure.dim
        ksp = PETSc.KSP().create(comm=self.comm)
        ksp.setType("preonly")
        pc = ksp.getPC()
        keep: list = []
        if self.hierarchy == "gamg":
            A, starts = self._distributed(full, d)
            ksp.setOperators(A)
            # the near-null space orthonormal, as PETSc asks (the same span)
            Q, _ = np.linalg.qr(B)
            r0, r1 = int(starts[self.rank]), int(starts[self.rank + 1])
            vecs = []
            for j in range(Q.shape[1]):
                v = A.createVecLeft()
                v.setArray(Q[r0:r1, j])
                vecs.append(v)
            A.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=self.comm))
            pc.setType("gamg")
            keep += [A, vecs]
        else:
            ml = self._smoothed_aggregation(full, B)
            if ml is None:  # no larger than a coarse level: solved exactly (every rank)
                return super()._cycle(full, B)
            A, starts = self._levels(pc, ml, B.shape[1], keep)
            ksp.setOperators(A)
            del ml
        # the amg solver's smoothed part of the spectrum, [lambda_max / RATIO, 1.1 lambda_max]
        own = [("mg_levels_ksp_chebyshev_esteig", f"0,{1 / RATIO:.6g},0,1.1")] \
            if self.hierarchy == "own" else []
        with _options(PETSc, own + self._pairs):
            ksp.setFromOptions()
            ksp.setUp()
        x_vec, b_vec = A.createVecs()
        r0, r1 = int(starts[self.rank]), int(starts[self.rank + 1])
        gather = _gatherer(self.comm, self.MPI, starts)

        def cycle(v):
            t0 = time.perf_counter()
            b_vec.setArray(v[r0:r1])
            ksp.solve(b_vec, x_vec)
            self.cycles += 1
            x = gather(x_vec)
            self.cycle_s += time.perf_counter() - t0
            if not np.all(np.isfinite(x)):
                raise SolverError(
                    "PETSc's multigrid cycle returned non-finite values: its options "
                    f"({self.options or 'the defaults'}) do not suit this tangent; drop or change "
                    "--petsc-options, or use solver 'petsc' (MUMPS, direct)")
            return x
        cycle.keep = (ksp, x_vec, b_vec, keep)
        return cycle

    def _distributed(self, M, block: int, cols=None):
        """(M as a parallel matrix, its row starts): rows split in whole blocks of
        ``block``; ``cols`` the column starts (default: as the rows)."""
        starts = split_rows(M.shape[0] // block, self.size) * block
        r0, r1 = int(starts[self.rank]), int(starts[self.rank + 1])
        c = starts if cols is None else cols
        A = _local_rows(self.PETSc, self.comm, sp.csr_matrix(M), r0, r1,
                        block=block if cols is None else 1,
                        cols=int(c[self.rank + 1] - c[self.rank]))
        return A, starts

    def _levels(self, pc, ml, modes: int, keep: list):
        """PCMG set up with pyamg's hierarchy ``ml``: every level's operator and
        prolongator split among the ranks, Chebyshev smoothing on the nodal
        blocks (the ``amg`` solver's degrees), the coarsest level solved
        directly. Returns the finest operator and its row starts."""
        PETSc = self.PETSc
        levels = ml.levels
        L = len(levels)
        pc.setType("mg")
        pc.setMGLevels(L)
        pc.setMGType(PETSc.PC.MGType.MULTIPLICATIVE)
        pc.setMGCycleType(PETSc.PC.MGCycleType.V)
        ops = []
        for i, lv in enumerate(levels):  # pyamg's level 0 is the finest, PETSc's the coarsest
            block = self.structure.dim if i == 0 else modes
            A, starts = self._distributed(_with_unit_empty_rows(lv.A), block)
            ops.append((A, starts))
        for i, lv in enumerate(levels):
            A, _ = ops[i]
            level = L - 1 - i
            if i < L - 1:
                P, _ = self._distributed(lv.P, self.structure.dim if i == 0 else modes,
                                         cols=ops[i + 1][1])
                pc.setMGInterpolation(level, P)
                keep.append(P)
                smoother = pc.getMGSmoother(level)
                smoother.setType("chebyshev")
                smoother.setTolerances(max_it=DEGREE if i == 0 else COARSE_DEGREE)
                smoother.getPC().setType("pbjacobi")
            else:
                smoother = pc.getMGCoarseSolve()
                smoother.setType("preonly")
                smoother.getPC().setType("redundant" if self.size > 1 else "lu")
            smoother.setOperators(A)
            keep.append(A)
        return ops[0]

def _local_rows(PETSc, comm, K: sp.csr_matrix, r0: int, r1: int, block: int = 1,
                cols: int | None = None):
    """The parallel matrix of K (the same on every rank) of which this rank owns rows
    [r0, r1) (and ``cols`` columns of a rectangular K; default r1 - r0): its own rows
    copied, nothing sent."""
    n, m = K.shape
    ip = K.indptr[r0:r1 + 1]
    indptr = (ip - ip[0]).astype(PETSc.IntType)
    indices = K.indices[ip[0]:ip[-1]].astype(PETSc.IntType)
    data = K.data[ip[0]:ip[-1]].astype(PETSc.ScalarType)
    A = PETSc.Mat().create(comm=comm)
    A.setType(PETSc.Mat.Type.AIJ)
    A.setSizes(((r1 - r0, n), (r1 - r0 if cols is None else cols, m)), bsize=block)
    A.setPreallocationCSR((indptr, indices, data))
    A.assemble()
    return A


def _with_unit_empty_rows(A) -> sp.csr_matrix:
    """A with a unit diagonal in its empty rows: a coarse level's unknowns of a
    rigid-body mode an aggregate too small cannot carry (a zero column of the
    prolongator, so an empty row and column), decoupled so that the nodal-block
    Jacobi and the coarse LU see invertible blocks; the cycle is unchanged (the
    restriction gives them zero, the prolongation ignores them)."""
    A = sp.csr_matrix(A)
    empty = np.diff(A.indptr) == 0
    if A.nnz:
        filled = ~empty
        empty[filled] = np.maximum.reduceat(np.abs(A.data), A.indptr[:-1][filled]) == 0
    if not empty.any():
        return A
    return (A + sp.diags(empty.astype(float))).tocsr()


def _put(opts, pairs) -> None:
    """(name, value or None for a flag) pairs into PETSc's options database ``opts``."""
    for key, value in pairs:
        opts[key] = value if value is not None else ""


@contextlib.contextmanager
def _options(PETSc, pairs):
    """``pairs`` (a solver's own options) in PETSc's global database while a KSP
    reads them (its ``setFromOptions`` and its ``setUp``, where MUMPS reads its
    own), the database restored after."""
    opts = PETSc.Options()
    before = {key: opts.getString(key) if opts.hasName(key) else None for key, _ in pairs}
    _put(opts, pairs)
    try:
        yield
    finally:
        for key, value in before.items():
            if value is None:
                del opts[key]
            else:
                opts[key] = value


def _gatherer(comm, MPI, starts: np.ndarray):
    """Vec -> the whole vector on every rank (its blocks owned as ``starts`` says)."""
    n = int(starts[-1])
    counts = np.diff(starts).astype(np.int64)
    displs = np.asarray(starts[:-1], dtype=np.int64)
    mpi = comm.tompi4py()

    def gather(v) -> np.ndarray:
        out = np.empty(n)
        mpi.Allgatherv(np.ascontiguousarray(v.getArray(readonly=True)),
                       [out, counts, displs, MPI.DOUBLE])
        return out
    return gather


#: the solvers whose runs go over the MPI ranks (under mpiexec)
MPI_SOLVERS = (PetscSolver.name, PetscAMG.name)
