"""How a derivative is computed: one small object per method, accepted by
:func:`signorini.solve`, :func:`signorini.gradient` and
:class:`signorini.design.optimize.Objective` alike, and named by the CLI's
``--gradient ddm|adjoint|fd``.

* :class:`DDM` -- direct differentiation: after every converged increment,
  one back-substitution per parameter with the converged tangent
  (docs/theory.md §1). Cost grows with the number of parameters.
* :class:`Adjoint` -- one backward pass over the increments for a scalar
  response, whatever the number of parameters (docs/theory.md §11).
* :class:`FiniteDifferences` -- central differences of fresh solves, two per
  parameter: a check, never the default.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError


@dataclass(frozen=True)
class DDM:
    """Direct differentiation.

    Attributes:
        factorization: ``"exact"`` (default): factorise the converged tangent;
            ``"reuse"``: solve with the last Newton factorisation, refined against
            the converged tangent, and factorise afresh only if that falls short.
    """

    factorization: str = "exact"

    def __post_init__(self):
        if self.factorization not in ("exact", "reuse"):
            raise InputError(f"DDM(factorization=...) must be 'exact' or 'reuse', got "
                             f"{self.factorization!r}")


@dataclass(frozen=True)
class Adjoint:
    """The adjoint backward pass (a scalar response).

    Attributes:
        factors: ``"recompute"`` (default: the backward pass factorises each
            increment's converged tangent again; memory: unknowns and states only)
            or ``"store"`` (the forward pass keeps every factorisation).
        checkpoint: keep the history state of every k-th increment only; the
            others are recomputed from the stored unknowns in the backward pass.
    """

    factors: str = "recompute"
    checkpoint: int = 1

    def __post_init__(self):
        if self.factors not in ("recompute", "store"):
            raise InputError(f"Adjoint(factors=...) must be 'recompute' or 'store', got {self.factors!r}")
        if isinstance(self.checkpoint, bool) or not isinstance(self.checkpoint, int) or self.checkpoint < 1:
            raise InputError(f"Adjoint(checkpoint=...) must be a positive integer (keep every k-th "
                             f"state), got {self.checkpoint!r}")


@dataclass(frozen=True)
class FiniteDifferences:
    """Central differences (f(phi + h) - f(phi - h)) / 2h of fresh solves.

    Attributes:
        step: the absolute step h; default ``rel_step * max(|phi|, 1)``.
        rel_step: the relative step used when ``step`` is None.
    """

    step: float | None = None
    rel_step: float = 1e-6

    def __post_init__(self):
        for name, v in (("step", self.step), ("rel_step", self.rel_step)):
            if v is None and name == "step":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < float("inf"):
                raise InputError(f"FiniteDifferences({name}=...) must be a positive number, got {v!r}")

    def step_for(self, value: float) -> float:
        """The step h for a parameter of value ``value``."""
        return float(self.step) if self.step is not None else self.rel_step * max(abs(float(value)), 1.0)


#: the CLI's and the old API's names of the methods
BY_NAME = {"ddm": DDM, "adjoint": Adjoint, "fd": FiniteDifferences}


def method_named(name: str, **kwargs):
    """``"ddm"`` / ``"adjoint"`` / ``"fd"`` -> the method object."""
    if name not in BY_NAME:
        raise InputError(f"the derivative method must be one of {sorted(BY_NAME)}, got {name!r}")
    return BY_NAME[name](**kwargs)


def check_method(method, allowed: tuple, where: str):
    """``method`` if it is an instance of one of ``allowed``, else an InputError that says what is."""
    if isinstance(method, str):
        raise InputError(f"{where}: method={method!r}: pass a method object, e.g. "
                         f"method=signorini.{type(method_named(method)).__name__}()")
    if not isinstance(method, allowed):
        names = " or ".join(f"signorini.{c.__name__}()" for c in allowed)
        raise InputError(f"{where}: method must be {names}, got {method!r}")
    return method


def from_keywords(method, old: dict, where: str, allowed: tuple, mode_key: str, default: str):
    """The method object of a call: ``method=`` itself, or one made from the 0.1
    keywords in ``old`` (``mode_key`` = ``"ddm"``/``"adjoint"``/``"fd"``, ``fd_step``,
    ``factors``, ``checkpoint``), never both."""
    if method is not None:
        if old:
            raise InputError(f"give the method once, as method= ({', '.join(sorted(old))}= are its "
                             "old spellings)")
        return check_method(method, allowed, where)
    mode = old.get(mode_key, default)
    if mode not in BY_NAME:
        raise InputError(f"{mode_key} must be one of {tuple(BY_NAME)}, got {mode!r}")
    if mode != "adjoint" and ("checkpoint" in old or "factors" in old):
        raise InputError("checkpoint= and factors= belong to the adjoint")
    if "fd_step" in old:
        step = old["fd_step"]
        if isinstance(step, bool) or not isinstance(step, (int, float)) or not step > 0:
            raise InputError(f"fd_step must be a positive number, got {step!r}")
    kw = {"adjoint": {k: old[k] for k in ("factors", "checkpoint") if k in old},
          "fd": {"rel_step": old["fd_step"]} if "fd_step" in old else {}, "ddm": {}}[mode]
    return method_named(mode, **kw)
