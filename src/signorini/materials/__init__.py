"""Materials: each is a pure constitutive update at a material point.

``update(H, h_n, mp) -> (P, h)``: the first Piola-Kirchhoff stress P (3, 3) at
the displacement gradient H = F - I (3, 3; plane strain: H33 = 0, axisymmetric:
H33 = u_r / R) given the history h_n (n_state,) at the end of the previous
increment, and the updated history h. Hyperelastic materials have
``n_state = 0`` and P = dW/dF. The consistent tangent is JAX's derivative of
``update`` in H at fixed h_n.
"""

from .elastic import LinearElastic, NeoHooke, det_minus_one
from .j2 import J2Plasticity
from .bodies import Bodies

__all__ = ["Bodies", "J2Plasticity", "LinearElastic", "NeoHooke", "det_minus_one"]
