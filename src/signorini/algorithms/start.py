"""Where Newton starts: :class:`Start` (a first iterate, or a coarser solve of the
same load path that guides every increment) and the guide's interpolation to
the fine model. Only the start changes, never the converged result."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from ..errors import InputError
from .prolongation import Prolongation
from .solution import Solution


@dataclasses.dataclass(frozen=True)
class Start:
    """Where the Newton iterations of :func:`solve` start. Only the start changes,
    not the converged result.

    Attributes:
        initial: (n_dof,) first Newton iterate of the first increment (e.g. a
            coarse solution interpolated by
            :func:`signorini.algorithms.coarse_to_fine.prolong`, or a converged
            solution of nearby parameters).
        guide: a solve of the same problem on a coarser mesh along the same load
            steps (:func:`signorini.algorithms.coarse_to_fine.solve_coarse_to_fine`).
            Increment n+1 then starts from w_n + P(w^c_{n+1} - w^c_n), P the
            interpolation to this mesh
            (:class:`~signorini.algorithms.coarse_to_fine.Prolongation`), the first
            from P(w^c_1) unless ``initial`` is given; between the guide's load
            factors (after a step cut) w^c is interpolated linearly in t, and past
            its last one (a guide that stopped early) the predictor of the
            :class:`NewtonOptions` is used.
    """

    initial: np.ndarray | None = None
    guide: Solution | None = None

    @classmethod
    def of(cls, start, initial=None, guide=None) -> "Start":
        """``start`` as a :class:`Start` (an array is ``initial``, a
        :class:`Solution` the ``guide``), merged with the deprecated keywords."""
        if start is None:
            start = cls()
        elif isinstance(start, Solution):
            start = cls(guide=start)
        elif not isinstance(start, cls):
            if isinstance(start, (str, bytes, Mapping)) or not hasattr(start, "__len__"):
                raise InputError(f"start must be a signorini.Start, an array (the first iterate) "
                                 f"or a Solution (a coarse guide), got {type(start).__name__}")
            start = cls(initial=start)
        if initial is not None or guide is not None:
            if start.initial is not None or start.guide is not None:
                raise InputError("give the start once, as start= (initial= and guide= are its "
                                 "old spellings)")
            start = cls(initial=initial, guide=guide)
        return start


class _Guide:
    """The increments of a coarser solve of the same path, interpolated to this
    model when needed (one sparse product each); between the guide's load
    factors (after a step cut) linear in t, from w = 0 at t = 0."""

    def __init__(self, guide, model):
        if not isinstance(guide, Solution):
            raise InputError(f"guide must be a Solution of the same problem on a coarser mesh "
                             f"(signorini.algorithms.coarse_to_fine.solve_coarse_to_fine), got {type(guide).__name__}")
        self.prolong = Prolongation.between(guide.model, model)
        self.w = {round(inc.t, 12): inc.w for inc in guide.increments}
        self.times = np.array(sorted(self.w))
        self.cache: dict = {}

    def covers(self, t_new) -> bool:
        return bool(self.times.size) and round(t_new, 12) <= self.times[-1]

    def _at(self, t):
        key = round(t, 12)
        if key in self.cache:
            return self.cache[key]
        if key in self.w:
            return self.prolong(self.w[key])
        j = int(np.searchsorted(self.times, key))  # times[j-1] < t < times[j]
        ta = self.times[j - 1] if j > 0 else 0.0
        wa = self.w[ta] if j > 0 else np.zeros_like(self.w[self.times[0]])
        theta = (key - ta) / (self.times[j] - ta)
        return self.prolong((1.0 - theta) * np.asarray(wa) + theta * np.asarray(self.w[self.times[j]]))

    def start(self, t, t_new, w, first):
        end = self._at(t_new)
        begin = None if first else self._at(t)
        self.cache = {round(t_new, 12): end}  # the next increment begins here
        return end if first else w + (end - begin)
