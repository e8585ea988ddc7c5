"""Without the optional MPI install (petsc4py, mpi4py), ``solver="petsc"`` and
``--solver petsc`` end with an error that says how to install it, never a
traceback; the solver's options are checked when it is made."""

import sys

import pytest

from signorini.app.cli import main
from signorini.errors import InputError
from signorini.linsolve import available, get_solver
from signorini.linsolve.petsc import PetscSolver, split_rows


@pytest.fixture
def absent(monkeypatch):
    for name in ("petsc4py", "petsc4py.PETSc", "mpi4py", "mpi4py.MPI"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError


@pytest.mark.parametrize("name", ["petsc", "petsc-amg"])
def test_solver_says_how_to_install(absent, name):
    with pytest.raises(InputError, match=r"petsc4py and mpi4py.*docs/parallel.md"):
        get_solver(name)
    assert "petsc" not in available()


def test_cli_error_not_traceback(absent, tmp_path, capsys):
    code = main(["hertz3d", "--n-fine", "4", "--no-fd", "-q", "--solver", "petsc",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert "signorini: error: solver 'petsc' needs petsc4py and mpi4py" in err
    assert "Traceback" not in err


def test_options_are_checked():
    with pytest.raises(InputError, match="'gmres' is not an option"):
        PetscSolver._parse("gmres -pc_type gamg")
    assert PetscSolver._parse("-ksp_type gmres -ksp_rtol 1e-12 -ksp_monitor -pc_gamg_threshold -1") \
        == [("ksp_type", "gmres"), ("ksp_rtol", "1e-12"), ("ksp_monitor", None),
            ("pc_gamg_threshold", "-1")]


def test_rows_split_evenly():
    assert split_rows(10, 3).tolist() == [0, 3, 6, 10]
    assert split_rows(2, 3).tolist() == [0, 0, 1, 2]  # a rank may own no row


def test_the_command_line_knows_the_solvers_that_run_over_ranks():
    """The command line's list (written out: it loads no solver) names the PETSc
    solvers, which the size guard counts per rank."""
    from signorini.app import cli
    from signorini.linsolve import petsc

    assert cli.MPI_SOLVERS == petsc.MPI_SOLVERS == ("petsc", "petsc-amg")
