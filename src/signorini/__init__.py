"""signorini: contact mechanics with the Alart-Curnier augmented Lagrangian and
exact DDM sensitivities (Stupkiewicz).

Importing the package enables JAX float64 (in :mod:`signorini._jax`, the one
place where JAX is configured); it has no other side effect.
"""

from . import _jax  # noqa: F401  (float64 before anything else touches JAX)
from .contact import AugmentedLagrangian, Contact, Coulomb, Penalty, equivalent_areas
from .errors import (ConvergenceError, InputError, InvertedElementError, NonDifferentiableError,
                     ResourceError, SignoriniError, SignoriniWarning, SingularTangentError, SolverError,
                     UnknownParameterError)
from .element import FBar, Standard
from .kinematics import Axisymmetric, PlaneStrain
from .loads import Fixed, Pressure, Traction
from .materials import J2Plasticity, LinearElastic, NeoHooke
from .mesh import Mesh, graded_coordinates, rectangle
from .newton import NewtonOptions
from .obstacles import Circle, Line
from .problem import Problem
from .sensitivity import finite_difference
from .solution import Solution
from .solve import solve
from .gradient import Gradient, gradient
from . import io  # noqa: E402  (read_mesh, write_vtu, ...)

__version__ = "0.1.0"

__all__ = [
    "AugmentedLagrangian", "Axisymmetric", "Circle", "FBar", "J2Plasticity", "PlaneStrain", "Standard", "Contact", "ConvergenceError", "Coulomb", "Fixed", "InputError",
    "InvertedElementError", "LinearElastic", "NonDifferentiableError", "Line", "Mesh", "NeoHooke", "NewtonOptions",
    "Penalty", "Pressure", "Problem", "ResourceError", "SignoriniError", "SignoriniWarning", "SingularTangentError", "Solution",
    "SolverError", "Traction", "UnknownParameterError", "equivalent_areas", "finite_difference",
    "graded_coordinates", "rectangle", "solve", "gradient", "Gradient",
]
