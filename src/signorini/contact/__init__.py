"""Contact with rigid obstacles and between two bodies (mortar pairs): equivalent
areas, contact laws and methods."""

from .area import equivalent_areas
from .friction import Coulomb
from .methods import AugmentedLagrangian, Contact, Penalty
from .mortar import pair

__all__ = ["AugmentedLagrangian", "Contact", "Coulomb", "Penalty", "equivalent_areas", "pair"]
