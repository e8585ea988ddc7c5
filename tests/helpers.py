"""Helpers shared by several test modules (tests/conftest.py puts this folder on
sys.path: ``from helpers import pressed_block``). Fixtures go to a conftest.py
instead; a helper used by one module stays in that module."""

import numpy as np

from signorini.contact import AugmentedLagrangian, Contact
from signorini.contact.obstacles import Circle
from signorini.fem.loads import Fixed
from signorini.fem.mesh import rectangle
from signorini.materials import LinearElastic
from signorini.model.problem import Problem


def pressed_block(friction: bool):
    """A block whose base is moved up by a prescribed displacement d into a cylinder
    (with friction: a sideways base motion s too): the prescribed values depend on
    parameters, so their adjoint path (VJP of the prescribed values) is exercised."""
    from signorini.contact import Coulomb

    mesh = rectangle(np.linspace(0.0, 2.0, 9), np.linspace(-1.0, 0.0, 5))
    law = Coulomb("mu", "eps", "eps") if friction else AugmentedLagrangian("eps")
    return Problem(mesh=mesh, material=LinearElastic(),
                   params={"E": 100.0, "nu": 0.3, "R": 1.0, "d": 0.02, "s": 0.004, "mu": 0.3,
                           "eps": 400.0},
                   fixed=(Fixed("bottom", 1, "d"), Fixed("bottom", 0, "s")),
                   contact=(Contact(Circle(radius="R", centre=(1.0, lambda p: p["R"])), "top", law),))
