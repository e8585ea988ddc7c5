"""signorini: contact mechanics with the Alart-Curnier augmented Lagrangian and
exact DDM sensitivities (Stupkiewicz).

Importing the package enables JAX float64 (in :mod:`signorini._jax`, the one
place where JAX is configured); it has no other side effect.
"""

from . import _jax  # noqa: F401  (float64 before anything else touches JAX)
from .contact import AugmentedLagrangian, Contact, Coulomb, Penalty, equivalent_areas
from .errors import (
    ConvergenceError, InputError, InvertedElementError, NonDifferentiableError, ResourceError,
    SignoriniError, SignoriniWarning, SingularTangentError, SolverError, UnknownParameterError)
from .fem.element import FBar, Standard
from .fem.kinematics import Axisymmetric, PlaneStrain
from .fem.loads import Fixed, Pressure, Traction
from .materials import J2Plasticity, LinearElastic, NeoHooke
from .fem.mesh import Mesh, graded_coordinates, rectangle
from .algorithms.newton import NewtonOptions
from .contact.obstacles import Circle, Line
from .model.problem import Problem
from .design.finite_differences import finite_difference
from .algorithms.solution import Solution
from .algorithms.stepping import solve
from .design.gradient import Gradient, gradient
from . import _compat

from ._version import __version__  # noqa: E402

_compat.install()


def __getattr__(name):
    """The 0.1 module names (``sg.io``, ...): the new module, with a DeprecationWarning."""
    return _compat.module_attribute(name)

__all__ = [
    "AugmentedLagrangian", "Axisymmetric", "Circle", "FBar", "J2Plasticity", "PlaneStrain", "Standard", "Contact", "ConvergenceError", "Coulomb", "Fixed", "InputError",
    "InvertedElementError", "LinearElastic", "NonDifferentiableError", "Line", "Mesh", "NeoHooke", "NewtonOptions",
    "Penalty", "Pressure", "Problem", "ResourceError", "SignoriniError", "SignoriniWarning", "SingularTangentError", "Solution",
    "SolverError", "Traction", "UnknownParameterError", "equivalent_areas", "finite_difference",
    "graded_coordinates", "rectangle", "solve", "gradient", "Gradient",
]
