"""Contact with rigid obstacles: equivalent areas, contact laws and methods."""

from .area import equivalent_areas
from .friction import Coulomb
from .methods import AugmentedLagrangian, Contact, Penalty

__all__ = ["AugmentedLagrangian", "Contact", "Coulomb", "Penalty", "equivalent_areas"]
