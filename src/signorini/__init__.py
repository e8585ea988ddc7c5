"""signorini: contact mechanics with the Alart-Curnier augmented Lagrangian and
exact sensitivities (DDM and adjoint).

The names below are the public API, by topic; each lives in the package of its
layer (docs/architecture.md). Importing signorini configures JAX for float64
on the CPU (:mod:`signorini._jax`, the one place that does) and registers the
0.1 module paths as deprecated aliases of the new ones
(:mod:`signorini._compat`); it has no other side effect.
"""

from . import _jax  # noqa: F401  (float64 before anything else touches JAX)
from . import _compat
from ._version import __version__
from .algorithms.newton import NewtonOptions
from .algorithms.solution import Solution
from .algorithms.stepping import Start, solve
from .contact import AugmentedLagrangian, Contact, Coulomb, Penalty, equivalent_areas
from .contact.obstacles import Circle, Line
from .design.finite_differences import finite_difference
from .design.gradient import Gradient, gradient
from .errors import (
    ConvergenceError, InputError, InvertedElementError, NonDifferentiableError, ResourceError,
    SignoriniError, SignoriniWarning, SingularTangentError, SolverError, UnknownParameterError)
from .fem.element import FBar, Standard
from .fem.kinematics import Axisymmetric, PlaneStrain
from .fem.loads import Fixed, Pressure, Traction
from .fem.mesh import Mesh, graded_coordinates, rectangle
from .fem.meshfile import read_mesh
from .materials import J2Plasticity, LinearElastic, NeoHooke
from .model.problem import Problem
from .post.files import write_pvd, write_vtu
from .sensitivity.methods import DDM, Adjoint, FiniteDifferences

__all__ = [
    # the problem: mesh, kinematics, element, material, supports and loads, contact
    "Mesh", "rectangle", "graded_coordinates", "read_mesh",
    "PlaneStrain", "Axisymmetric", "Standard", "FBar",
    "LinearElastic", "NeoHooke", "J2Plasticity",
    "Fixed", "Pressure", "Traction",
    "Circle", "Line", "Contact", "AugmentedLagrangian", "Coulomb", "Penalty", "equivalent_areas",
    "Problem",
    # solving
    "solve", "NewtonOptions", "Start", "Solution",
    # derivatives
    "DDM", "Adjoint", "FiniteDifferences", "gradient", "Gradient", "finite_difference",
    # results
    "write_vtu", "write_pvd",
    # errors and warnings
    "SignoriniError", "InputError", "UnknownParameterError", "InvertedElementError",
    "ConvergenceError", "SingularTangentError", "SolverError", "NonDifferentiableError",
    "ResourceError", "SignoriniWarning",
    "__version__",
]

_compat.install()


def __getattr__(name):
    """The 0.1 module names (``sg.io``, ...): the new module, with a DeprecationWarning."""
    return _compat.module_attribute(name)
