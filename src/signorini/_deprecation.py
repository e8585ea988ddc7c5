"""Old keyword spellings kept for one release, with a DeprecationWarning."""

from __future__ import annotations

import warnings

_UNSET = object()


def renamed(old: str, new: str, where: str, stacklevel: int = 3) -> None:
    """Warn that keyword ``old`` of ``where`` is now spelled ``new``."""
    warnings.warn(f"{where}({old}=...) is deprecated since signorini 0.2 and goes in the next "
                  f"release: use {new}", DeprecationWarning, stacklevel=stacklevel + 1)


def pop_old(kwargs: dict, where: str, mapping: dict[str, str]) -> dict:
    """Take the deprecated keywords of ``mapping`` (old -> advice) out of ``kwargs``
    with a warning each; any other leftover keyword is a TypeError, as Python's own."""
    old = {}
    for k in list(kwargs):
        if k in mapping:
            renamed(k, mapping[k], where, stacklevel=3)
            old[k] = kwargs.pop(k)
    if kwargs:
        raise TypeError(f"{where}() got an unexpected keyword argument {next(iter(kwargs))!r}")
    return old
