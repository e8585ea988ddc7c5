"""Contact with rigid obstacles and between two bodies (mortar pairs): equivalent
areas, contact laws and methods.

Rigid obstacles of a 2-D problem (plane strain, axisymmetry): :mod:`.obstacles`
(``Circle``, ``Line``); of a 3-D one: :mod:`.obstacles3d` (``Plane``, ``Sphere``,
``Cylinder``, and ``Implicit``, a signed distance, in either). The laws
(``AugmentedLagrangian``, ``Penalty``, ``Coulomb``) serve both: ``Coulomb`` has
one tangential multiplier per node in 2-D and two in 3-D (the Coulomb disc,
:mod:`.friction3d`). Pairs of bodies (``pair``): 2-D meshes. Every name a user
needs is also a name of :mod:`signorini` (``sg.Sphere``, ``sg.Coulomb``, ...).
"""

from .area import equivalent_areas
from .friction import Coulomb
from .methods import AugmentedLagrangian, Contact, Penalty
from .mortar import pair

__all__ = ["AugmentedLagrangian", "Contact", "Coulomb", "Penalty", "equivalent_areas", "pair"]
