"""Contact laws (signorini.contact.methods): the penalty method's penetration
scales with 1 / eps on the Hertz problem."""

import numpy as np

import signorini as sg
from signorini.problems import hertz

TIGHT = sg.NewtonOptions(rtol=1e-11)


def test_penalty_penetration_scales_with_inverse_eps():
    pb = hertz.hertz_problem(method="penalty")
    eps = pb.params["eps"]
    pen = []
    for f in (1.0, 10.0, 100.0):
        c = sg.solve(pb.with_params(eps=f * eps), options=TIGHT).contact()
        pen.append(-c["gap"].min())
    pen = np.array(pen)
    assert np.all(pen > 0)
    # penetration * eps = p_max converges: ratios 10 within 3 %
    assert np.allclose(pen[:-1] / pen[1:], 10.0, rtol=0.03), pen
