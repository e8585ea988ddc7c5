"""Exceptions raised by signorini.

Every error names the problem and what to do about it. They all derive from
:class:`SignoriniError` (itself a ``ValueError`` or ``RuntimeError`` where that
is the natural category) so callers can catch one type.
"""

from __future__ import annotations


class SignoriniError(Exception):
    """Base class of all errors raised by signorini."""


class InputError(SignoriniError, ValueError):
    """Inconsistent or invalid input (mesh, sets, parameters, options)."""


class InvertedElementError(InputError):
    """An element has a non-positive Jacobian in the reference configuration."""


class UnknownParameterError(InputError, KeyError):
    """A parameter name is not defined by the problem."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class SolverError(SignoriniError, RuntimeError):
    """The nonlinear or linear solver failed."""


class SingularTangentError(SolverError):
    """The tangent matrix could not be factorised."""


class ConvergenceError(SolverError):
    """Newton did not converge, even after cutting the load step.

    Attributes:
        partial: the :class:`~signorini.algorithms.solution.Solution` holding every
            increment converged before the failure (may have no increments).
    """

    def __init__(self, message: str, partial=None):
        super().__init__(message)
        self.partial = partial


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal: SIGINT (Ctrl-C, Python's own
    ``KeyboardInterrupt``) or SIGTERM (what a batch scheduler sends at its time
    limit; the ``signorini`` command turns it into this exception). The command
    keeps what converged and exits with 128 + the signal's number.

    Attributes:
        signum: the signal's number (2 for SIGINT, 15 for SIGTERM).
        partial: the load path's :class:`~signorini.algorithms.solution.Solution`
            with the increments converged before the signal, when it came during a
            solve (set by the solve).
    """

    def __init__(self, signum: int = 2):
        super().__init__(signum)
        self.signum = int(signum)


class NonDifferentiableError(InputError):
    """A design sensitivity is not finite: some expression of the problem is not
    differentiable at the parameter values (JAX's tangent through it is NaN)."""


class ResourceError(InputError):
    """The problem is estimated to need more memory than the machine has."""


class SignoriniWarning(UserWarning):
    """A result that may not be what the user expects (coarse contact zone,
    deep initial penetration, tunnelling, a load path too coarse for friction).

    Every such warning is also logged on the ``signorini`` logger and kept in
    :attr:`signorini.algorithms.solution.Solution.warnings` (and so in ``summary.json``).
    """
