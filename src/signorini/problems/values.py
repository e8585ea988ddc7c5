"""The parameter values of a problem builder: its defaults updated by the
caller's, every name known, every value a finite number, some positive."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from ..errors import InputError, UnknownParameterError


def checked_values(problem: str, defaults: Mapping, params: Mapping | None, *, extra: Iterable = (),
                   positive: Iterable = (), nonnegative: Iterable = (), tag: str | None = None) -> dict:
    """``defaults`` updated by ``params``, checked.

    Args:
        problem: what the messages call the problem ("the Hertz problem" reads
            "unknown parameter 'x' for the Hertz problem").
        defaults: the builder's named parameters and their default values.
        params: the caller's values (None: none).
        extra: further names allowed without a default (e.g. eps, eps_t).
        positive, nonnegative: names whose value must be > 0, >= 0.
        tag: the prefix of the value messages (default ``problem``).

    Raises :class:`~signorini.errors.UnknownParameterError` for a name the
    problem does not define and :class:`~signorini.errors.InputError` for a
    value that is not a finite number or has the wrong sign.
    """
    tag = problem if tag is None else tag
    known = set(defaults) | set(extra)
    for k in params or {}:
        if k not in known:
            raise UnknownParameterError(
                f"unknown parameter {k!r} for the {problem}; defined parameters: {sorted(known)}")
    values = dict(defaults)
    values.update(params or {})
    for k, v in values.items():
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                or not np.isfinite(v):
            raise InputError(f"{tag}: parameter {k} must be a finite number, got {v!r}")
    for k in positive:
        if not values[k] > 0:
            raise InputError(f"{tag}: {k} must be positive, got {values[k]}")
    for k in nonnegative:
        if not values[k] >= 0:
            raise InputError(f"{tag}: {k} must be >= 0, got {values[k]}")
    return values


def check_partial_slip(problem: str, values: Mapping) -> None:
    """Q must stay below mu P (Mindlin's partial slip) where a tangential force Q
    follows the normal force P of a two-body example."""
    if values["Q"] > 0 and not values["Q"] < values["mu"] * values["P"]:
        raise InputError(f"{problem}: Q = {values['Q']} must stay below mu P = "
                         f"{values['mu'] * values['P']} (Mindlin's partial slip; at Q >= mu P the "
                         "upper body slides away)")
