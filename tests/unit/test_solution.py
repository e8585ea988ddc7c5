"""The solution object (signorini.algorithms.solution): reactions are the forces
of the supports on the body, and their sensitivities."""

import numpy as np

import signorini as sg


def test_reactions_are_the_forces_of_the_supports_on_the_body():
    """A unit square under a downward pressure q on its top, bottom fixed: the
    supports push up with the resultant q (equilibrium), so sum r_y = +q."""
    m = sg.rectangle(np.linspace(0, 1, 5), np.linspace(0, 1, 5))
    pb = sg.Problem(m, sg.LinearElastic(), {"E": 10.0, "nu": 0.3, "q": 0.2},
                    fixed=(sg.Fixed("bottom", 0), sg.Fixed("bottom", 1)),
                    loads=(sg.Pressure("top", "q"),))
    sol = sg.solve(pb, wrt=["q"])
    r = sol.reactions()[m.node_set("bottom")]
    assert np.isclose(r[:, 1].sum(), 0.2, rtol=1e-12) and abs(r[:, 0].sum()) < 1e-12
    assert np.isclose(sol.reaction_sensitivity("q")[m.node_set("bottom"), 1].sum(), 1.0, rtol=1e-12)
