"""What a component must provide: one :class:`typing.Protocol` per kind.

A material, a contact law, an obstacle, a kinematics and an element
formulation are plain objects; the model calls only the members listed here.
Optional capabilities are attributes that are ``None`` where a component does
not have them (a material without plastic history has ``yield_ratio = None``),
so the model asks ``if material.yield_ratio is not None`` instead of probing
with ``hasattr``. The built-in components inherit these defaults from the
small ``...Defaults`` classes below; a component of your own may do the same,
or define every member itself. :func:`require` checks an object against its
protocol when a model is built and names what is missing.

Everything an obstacle, material or contact law computes is a pure JAX
function of its inputs, so the model differentiates it (tangent, DDM
pseudo-loads, adjoint) without further code (docs/theory.md §1.4).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol, runtime_checkable

from .errors import InputError

Array = Any  #: a JAX or NumPy array
Params = Mapping[str, Any]  #: parameter name -> value


@runtime_checkable
class Material(Protocol):
    """A constitutive law at a Gauss point, with or without history."""

    #: number of history variables per Gauss point (0: no history)
    n_state: int
    #: True for finite-strain laws (finite contact kinematics by default)
    finite_strain: bool
    #: True if the stress is linear in H (a constant element stiffness is kept)
    linear: bool
    #: name of the constant the stress is proportional to (at fixed others), or None
    stress_proportional_to: str | None
    #: ``yield_ratio(H, h_n, mp)`` (switch points of plasticity), or None
    yield_ratio: Callable | None
    #: ``equivalent_plastic_strain(h)`` for the output files, or None
    equivalent_plastic_strain: Callable | None

    def specs(self) -> tuple: ...
    def values(self, params: Params) -> dict: ...
    def check(self, params: Params) -> None: ...
    def initial_state(self) -> Array: ...
    def update(self, H: Array, h_n: Array, mp: dict) -> tuple: ...


@runtime_checkable
class ContactLaw(Protocol):
    """How the multipliers of a contact node enforce the contact conditions."""

    #: multipliers per contact node (0: a penalty law)
    n_multipliers: int
    #: True if the law keeps a history (friction's slip coordinate)
    has_history: bool
    #: a solution algorithm of its own (e.g. Uzawa's loops), or None for solve()
    driver: str | None
    #: ``status(...)`` -> (open / stick / slip code, slip) for friction, or None
    status: Callable | None
    #: ``stick_margin(...)`` -> distance from the stick/slip switch, or None
    stick_margin: Callable | None

    def specs(self) -> tuple: ...
    def values(self, params: Params) -> dict: ...
    def check(self, params: Params) -> None: ...
    def residual(self, x, lam, A, geo, obstacle, cp, hist) -> tuple: ...
    def tractions(self, x, lam, A, geo, obstacle, cp) -> tuple: ...
    def row_scale(self, cp) -> Any: ...


@runtime_checkable
class Obstacle(Protocol):
    """A rigid obstacle: gap, normal, projection and slip coordinate of a point."""

    def specs(self) -> tuple: ...
    def check(self, params: Params) -> None: ...
    def geometry(self, params: Params, t) -> dict: ...
    def gap(self, x: Array, geo: dict) -> Array: ...
    def normal(self, x: Array, geo: dict) -> Array: ...
    def project(self, x: Array, geo: dict) -> Array: ...
    def coordinate(self, x: Array, geo: dict) -> Array: ...


@runtime_checkable
class Kinematics(Protocol):
    """How H, the volume, loads and contact areas follow from the nodal values."""

    name: str
    #: the components of H that can be non-zero
    active: tuple

    def check_mesh(self, X) -> None: ...
    def displacement_gradients(self, ue, Xe, N, dNdX) -> Array: ...
    def volume_weights(self, Xe, N, w_ref) -> Array: ...
    def hoop_functions(self, Xe, N) -> Array | None: ...
    def edge_factors(self, Xa, Xb) -> Array: ...
    def contact_areas(self, X, edges, nodes) -> Array: ...


@runtime_checkable
class ElementFormulation(Protocol):
    """How the element modifies the displacement gradient (F-bar) or not."""

    name: str
    #: True if H at the Gauss points is linear in the nodal displacements
    linear: bool

    def modify(self, H: Array, H0: Array) -> Array: ...


class MaterialDefaults:
    """The optional members of :class:`Material`, absent."""

    n_state = 0
    finite_strain = True
    linear = False
    stress_proportional_to = None
    yield_ratio = None
    equivalent_plastic_strain = None


class ContactLawDefaults:
    """The optional members of :class:`ContactLaw`, absent."""

    has_history = False
    driver = None
    status = None
    stick_margin = None


def require(obj, protocol: type, role: str) -> None:
    """InputError naming the members of ``protocol`` that ``obj`` lacks."""
    names = [n for n in dir(protocol) if not n.startswith("_")]
    names += list(getattr(protocol, "__annotations__", {}))
    missing = sorted({n for n in names if not hasattr(obj, n)})
    if missing:
        raise InputError(f"the {role} {type(obj).__name__} does not provide {', '.join(missing)} "
                         f"(see signorini.interfaces.{protocol.__name__}; the built-in "
                         f"components inherit the optional ones from "
                         f"signorini.interfaces.{protocol.__name__}Defaults where there is one)")
