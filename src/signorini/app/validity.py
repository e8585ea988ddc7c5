"""The validity warnings of a contact command, one family for all of them (issue 49).

A converged run is not a valid one when its contact zone leaves the range the
command's mesh and analytical comparison were made for:

* the contact size is not small against the radius of curvature (a > 0.3 R):
  Hertz's half-space solution assumes a << R;
* the contact zone reaches beyond the fine mesh zone (the cells grow there), a
  quarter of a body's width or depth (the body is no longer a half-space), or
  the edge of a face (the contact then presses on a corner);
* the contact zone holds too few closed nodes (the model's own check at the
  end of every solve, :data:`signorini.model.checks.MIN_CONTACT_NODES`).

:func:`check` issues the first two kinds through :func:`signorini.model.checks.warn`
(so they land in ``Solution.warnings`` and ``summary.json``) and returns every
warning of the family the solution holds, the third included, so that a
command marks its comparison with an analytical solution not valid
(:func:`comparison`, :func:`note`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..model import checks

#: Hertz's half-space solution assumes a small contact zone, a << R
VALID_A_OVER_R = 0.3
#: a finite block acts as a half-space only if it is many times wider and deeper
#: than the contact (docs/theory.md §8.1): `signorini hertz`'s threshold, a quarter
VALID_A_OVER_W = 0.25
#: what the model's closed-node count check says (model/checks.py, IncrementChecks.final)
TOO_FEW = f"closed node(s) at the end (fewer than {checks.MIN_CONTACT_NODES})"
#: what the console line says next to the analytical numbers of a run that warned
NOT_VALID = " (not valid: see warnings)"


@dataclasses.dataclass(frozen=True)
class Limit:
    """An extent the contact zone must stay inside (in the contact size's units,
    measured from the contact's centre).

    ``fraction``: the zone may reach ``fraction`` x ``extent`` (< 1: a
    half-space's width); ``margin``: it must stay this far inside (the edge
    of a face: a closed node within one cell of it). ``what`` names the
    extent, ``because`` (", ...") says what goes wrong beyond it, ``hint``
    what to do (with the option to change)."""
    extent: float
    what: str
    hint: str
    because: str = ""
    fraction: float = 1.0
    margin: float = 0.0

    def exceeded_by(self, size: float) -> bool:
        return size > self.fraction * self.extent - self.margin

    def message(self, symbol: str, size: float) -> str:
        if self.fraction < 1.0:
            where = f"reaches {size / self.extent:.0%} of {self.what} {self.extent:.4g}"
        elif self.margin > 0.0:
            where = (f"reaches the edge of {self.what} (at {self.extent:.4g}: within a cell, "
                     f"{self.margin:.3g}, of it or beyond)")
        else:
            where = f"extends beyond {self.what} ({self.extent:.4g})"
        return f"the contact zone ({symbol} = {size:.4g}) {where}{self.because}; {self.hint}"


def fine_zone(extent: float, hint: str = "widen it (--zone-width) or change the nominal sizes") -> Limit:
    """The uniformly fine mesh zone at the contact, ``extent`` from its centre."""
    return Limit(extent, "the fine mesh zone", hint, ", where the cells grow")


def half_space(extent: float, what: str = "the block width",
               hint: str = "use a larger block (--block)",
               because: str = ", so the block is no longer a half-space") -> Limit:
    """A body's width or depth, which must be large against the contact for the
    body to act as a half-space."""
    return Limit(extent, what, hint, because, fraction=VALID_A_OVER_W)


def edge(extent: float, margin: float, what: str, because: str, hint: str) -> Limit:
    """The edge of a face, ``extent`` from the contact's centre: the zone reaches it
    when a closed node lies within ``margin`` (a cell) of it."""
    return Limit(extent, what, hint, because, margin=margin)


def check(sol, size: float, limits=(), *, symbol: str = "a", label: str = "contact half-width",
          radius: float | None = None, radius_name: str = "R", radius_note: str = "",
          radius_hint: str = "reduce the load P or increase R") -> list[str]:
    """Warn when the contact zone of the solution ``sol`` leaves its range of validity;
    the warnings of the family that ``sol`` holds (this check's and the model's
    too-few-closed-nodes), empty for a valid run.

    ``size``: the computed contact size (half-width or radius, named ``symbol``,
    described by ``label``); ``radius``: the radius of curvature the analytical
    solution assumes large (``radius_name``, with ``radius_note`` after its
    value), None where no such comparison is made; ``limits``: the
    :class:`Limit` extents (:func:`fine_zone`, :func:`half_space`, :func:`edge`),
    each with the option to suggest."""
    issued = []
    if radius is not None and size > VALID_A_OVER_R * radius:
        issued.append(f"the {label} {symbol} = {size:.4g} exceeds {VALID_A_OVER_R} {radius_name} = "
                      f"{VALID_A_OVER_R * radius:.4g}{radius_note}: Hertz's half-space solution "
                      f"(and the comparison with it) assumes {symbol} << {radius_name}; "
                      f"{radius_hint}")
    issued += [lim.message(symbol, size) for lim in limits if lim.exceeded_by(size)]
    for w in issued:
        checks.warn(sol, w)
    return [w for w in sol.warnings if TOO_FEW in w] + issued


def comparison(warnings: list[str]) -> dict:
    """summary.json's ``analytical_comparison``: whether the printed comparison
    with the analytical solution means anything, and why not."""
    return {"valid": not warnings, "why": list(warnings)}


def note(summary: dict) -> str:
    """What the console line says after the analytical numbers: nothing, or that
    they are not valid."""
    c = summary.get("analytical_comparison")
    return NOT_VALID if isinstance(c, dict) and not c.get("valid", True) else ""


def surface_ends(sol) -> list[str]:
    """Warn when a closed node of a 2-D contact surface (rigid obstacle or a pair's
    slave) is an end of the surface: the contact zone then reaches the edge of the
    body's face, and the surface may be too short to hold it (a problem file's
    surface, where no fine zone or block size is known). An end on a symmetry
    line (its displacement along the surface prescribed) is the contact's centre,
    not an edge. Returns the warnings issued."""
    m = sol.model
    if m.dim != 2 or not sol.increments:
        return []
    X = sol.reference()
    pres = set(np.asarray(m.layout.prescribed).tolist())
    issued = []
    for k, s in enumerate(m.surfaces):
        e = np.asarray(s.edges)
        ends, count = np.unique(e, return_counts=True)
        c = sol.contact(surface=k)
        closed = dict(zip(np.asarray(c["node"]).tolist(), np.asarray(c["p_N"]) > 0))
        for n in ends[count == 1]:
            row = e[np.any(e == n, axis=1)][0]
            t = X[row[1]] - X[row[0]]
            symmetry = any(2 * int(n) + j in pres and abs(t[j]) >= abs(t[1 - j]) for j in (0, 1))
            if closed.get(int(n), False) and not symmetry:
                name = s.contact.edges
                issued.append(f"contact {name!r}: the contact zone reaches the end of the contact "
                              f"surface (node {int(n)} at {tuple(round(float(v), 6) for v in X[n])} "
                              "is closed), so the surface may be too short to hold the contact and "
                              "the body's corner carries it; extend the contact surface or reduce "
                              "the load")
    for w in issued:
        checks.warn(sol, w)
    return issued
