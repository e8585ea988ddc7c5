"""The checked parameter values of the problem builders (problems/values.py)."""

import pytest

from signorini.errors import InputError, UnknownParameterError
from signorini.problems.values import checked_values

DEFAULTS = {"E": 100.0, "mu": 0.3}


def test_defaults_updated_and_checked():
    v = checked_values("test problem", DEFAULTS, {"E": 2, "eps": 5.0}, extra=("eps",), positive=("E",),
                       nonnegative=("mu",))
    assert v == {"E": 2, "mu": 0.3, "eps": 5.0}
    assert checked_values("test problem", DEFAULTS, None) == DEFAULTS


@pytest.mark.parametrize("params,error,match", [
    ({"G": 1.0}, UnknownParameterError, r"unknown parameter 'G' for the test problem; defined parameters: \['E', 'mu'\]"),
    ({"E": float("nan")}, InputError, "tag: parameter E must be a finite number"),
    ({"E": "100"}, InputError, "parameter E must be a finite number"),
    ({"E": True}, InputError, "parameter E must be a finite number"),
    ({"E": 0.0}, InputError, "tag: E must be positive, got 0.0"),
    ({"mu": -0.1}, InputError, "tag: mu must be >= 0, got -0.1"),
])
def test_bad_values_are_named(params, error, match):
    with pytest.raises(error, match=match):
        checked_values("test problem", DEFAULTS, params, positive=("E",), nonnegative=("mu",), tag="tag")
