"""signorini: contact mechanics with the Alart-Curnier augmented Lagrangian and
exact sensitivities (DDM and adjoint).

The names below are the public API, by topic; each lives in the package of its
layer (docs/architecture.md) and is imported when first used, so ``import
signorini`` itself is quick. Importing signorini configures JAX for float64 on
the CPU (before JAX is imported, through JAX's environment settings; after, by
:mod:`signorini._jax`, which every module using JAX imports first) and
registers the 0.1 module paths as deprecated aliases of the new ones
(:mod:`signorini._compat`); it has no other side effect.
"""

import importlib as _importlib
import os as _os
import sys as _sys

from . import _compat
from ._version import __version__

# float64 on the CPU, set for JAX before it is imported (by the first name below
# that needs it: signorini._jax configures it again then, and is the one place
# that does when JAX was imported first)
if "jax" in _sys.modules:
    from . import _jax  # noqa: F401
else:
    _os.environ.setdefault("JAX_PLATFORMS", "cpu")
    _os.environ["JAX_ENABLE_X64"] = "1"

#: public name -> the module that defines it; each module is imported when one
#: of its names is first asked for (``signorini.Problem``, ``from signorini import
#: solve``), so that ``import signorini`` and the ``signorini`` command start fast
_WHERE = {
    **dict.fromkeys(("NewtonOptions",), "algorithms.newton"),
    **dict.fromkeys(("Solution",), "algorithms.solution"),
    "Start": "algorithms.start", "solve": "algorithms.stepping",
    **dict.fromkeys(("AugmentedLagrangian", "Contact", "Coulomb", "Penalty", "equivalent_areas",
                     "pair"), "contact"),
    **dict.fromkeys(("Circle", "Line"), "contact.obstacles"),
    **dict.fromkeys(("Cylinder", "Implicit", "Plane", "Sphere"), "contact.obstacles3d"),
    **dict.fromkeys(("finite_difference",), "design.finite_differences"),
    **dict.fromkeys(("Gradient", "gradient"), "design.gradient"),
    **dict.fromkeys(("Objective", "minimize"), "design.optimize"),
    "fit": "design.fit",
    **dict.fromkeys(("Curve", "FitResult"), "design.fit_result"),
    **dict.fromkeys(("ConvergenceError", "InputError", "InvertedElementError",
                     "NonDifferentiableError", "ResourceError", "SignoriniError",
                     "SignoriniWarning", "SingularTangentError", "SolverError",
                     "UnknownParameterError"), "errors"),
    **dict.fromkeys(("FBar", "Standard"), "fem.element"),
    **dict.fromkeys(("Axisymmetric", "PlaneStrain"), "fem.kinematics"),
    **dict.fromkeys(("Fixed", "Pressure", "Ramp", "Table", "Traction"), "fem.loads"),
    **dict.fromkeys(("Mesh", "graded_coordinates", "merge", "rectangle"), "fem.mesh"),
    **dict.fromkeys(("Mesh3D", "box", "tetrahedra"), "fem.mesh3d"),
    **dict.fromkeys(("read_mesh",), "fem.meshfile"),
    **dict.fromkeys(("Bodies", "J2Plasticity", "LinearElastic", "NeoHooke"), "materials"),
    **dict.fromkeys(("Problem",), "model.problem"),
    **dict.fromkeys(("write_pvd", "write_vtu"), "post.files"),
    **dict.fromkeys(("DDM", "Adjoint", "FiniteDifferences"), "sensitivity.methods"),
}

#: public modules, reached as attributes (``sg.responses.contact_force(...)``)
_SUBPACKAGES = ("responses",)

__all__ = [
    # the problem: mesh (2-D, 3-D, from a file), kinematics (2-D only), element, material,
    # supports and loads, contact (2-D obstacles, 3-D obstacles, laws, pairs of bodies)
    "Mesh", "rectangle", "graded_coordinates", "merge", "Mesh3D", "box", "tetrahedra", "read_mesh",
    "PlaneStrain", "Axisymmetric", "Standard", "FBar",
    "LinearElastic", "NeoHooke", "J2Plasticity", "Bodies",
    "Fixed", "Pressure", "Traction", "Ramp", "Table",
    "Circle", "Line", "Plane", "Sphere", "Cylinder", "Implicit",
    "Contact", "AugmentedLagrangian", "Coulomb", "Penalty", "equivalent_areas", "pair",
    "Problem",
    # solving
    "solve", "NewtonOptions", "Start", "Solution",
    # derivatives
    "DDM", "Adjoint", "FiniteDifferences", "gradient", "Gradient", "finite_difference",
    # what to differentiate (sg.responses.contact_force, reaction, ...), optimisation with it
    "responses", "Objective", "minimize",
    # identification of parameters from measured curves, with standard errors
    "fit", "Curve", "FitResult",
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
    """A public name, imported from its module when first asked for; or one of the
    0.1 module names (``sg.io``, ...): the new module, with a DeprecationWarning."""
    if name in _SUBPACKAGES:  # sg.responses: the module itself
        value = globals()[name] = _importlib.import_module(f"{__name__}.{name}")
        return value
    where = _WHERE.get(name)
    if where is None:
        return _compat.module_attribute(name)
    value = getattr(_importlib.import_module(f"{__name__}.{where}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
