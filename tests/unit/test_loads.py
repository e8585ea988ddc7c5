"""Load ramps (signorini.fem.loads.Ramp): values, a load path in phases, bad
input, and the content key that lets a problem built again with them share its
compiled programs across processes."""

import numpy as np
import pytest

import signorini as sg
from signorini.model.identity import stable_digest, structure_key


def test_ramp_values():
    r = sg.Ramp(0.2, 0.6)
    t = np.array([0.0, 0.2, 0.3, 0.6, 0.9])
    assert np.allclose(np.asarray(r(t)), [0.0, 0.0, 0.25, 1.0, 1.0], rtol=0, atol=1e-15)
    assert float(sg.Ramp()(0.37)) == pytest.approx(0.37, abs=1e-15)


@pytest.mark.parametrize("start, end", [(0.5, 0.5), (0.6, 0.2), (0.0, float("nan")), (True, 1.0),
                                        ("0", 1.0)])
def test_bad_ramps(start, end):
    with pytest.raises(sg.InputError, match="Ramp"):
        sg.Ramp(start, end)


def _block(ramps):
    m = sg.rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    return sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0, "s": 1.0},
                      fixed=(sg.Fixed("bottom", 1), sg.Fixed("bottom", 0)),
                      loads=(sg.Pressure("top", "q", ramp=ramps[0]),
                             sg.Traction("top", ("s", 0.0), ramp=ramps[1])))


def test_loads_in_phases_and_their_content_key():
    """A pressure over the first half of the path, then a shear: the shear is zero
    while the pressure grows, the pressure constant while the shear grows (the
    block is linear: the displacement of a corner follows the ramps); two problems
    built with equal ramps have one stable digest, a plain function is known by
    identity only."""
    pb = _block((sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)))
    sol = sg.solve(pb, steps=4)
    corner = int(np.argmax(pb.mesh.nodes[:, 0] + pb.mesh.nodes[:, 1]))
    u = np.array([sol.displacement(i)[corner] for i in range(4)])
    assert np.allclose(u[1], 2 * u[0], rtol=1e-12, atol=0)  # the pressure alone, linearly
    assert np.allclose(u[3] - u[1], 2 * (u[2] - u[1]), rtol=1e-12, atol=1e-15)  # then the shear
    shear_only = sg.solve(_block((sg.Ramp(0.0, 1e-9), sg.Ramp(0.5, 1.0))), steps=4)
    assert np.allclose(u[3] - u[1], shear_only.displacement(3)[corner] - shear_only.displacement(1)[corner],
                       rtol=1e-12, atol=1e-15)
    assert np.linalg.norm(u[3] - u[1]) > 0.1 * np.linalg.norm(u[1])
    a = stable_digest(structure_key(pb))
    assert a is not None and a == stable_digest(structure_key(_block((sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)))))
    assert a != stable_digest(structure_key(_block((sg.Ramp(0.0, 0.4), sg.Ramp(0.5, 1.0)))))
    assert stable_digest(structure_key(_block((lambda t: np.minimum(2 * t, 1.0), sg.Ramp(0.5, 1.0))))) is None
