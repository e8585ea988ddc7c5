"""Contact with rigid obstacles: equivalent areas, contact laws and methods."""

from .area import equivalent_areas
from .methods import AugmentedLagrangian, Contact, Penalty

__all__ = ["AugmentedLagrangian", "Contact", "Penalty", "equivalent_areas"]
