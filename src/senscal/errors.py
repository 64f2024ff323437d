"""Exceptions raised by senscal.

Every user mistake raises a subclass of :class:`SenscalError` whose message is
one line that says what was wrong and what to do about it.  The command line
turns these into a single line on stderr and the exception's ``exit_code``
(2 for a user error), never a traceback.
"""

from __future__ import annotations

__all__ = [
    "SenscalError",
    "InputError",
    "FileFormatError",
    "UnknownChannelError",
    "DataError",
    "TooFewSamplesError",
    "ConvergenceError",
    "DegenerateGeometryError",
    "UnobservableError",
    "DiagnosticError",
]


class SenscalError(Exception):
    """Base class of every error senscal raises on purpose.

    Attributes
    ----------
    exit_code : int
        Exit code the command line uses for this error (2: user error).
    """

    exit_code = 2

    def __init__(self, message: str):
        # One line only: the CLI prints the message as is.
        super().__init__(" ".join(str(message).split()))


class InputError(SenscalError, ValueError):
    """An argument is out of range, inconsistent or of the wrong shape."""


class FileFormatError(InputError):
    """A file is missing, empty, unreadable or not in the expected layout."""


class UnknownChannelError(InputError):
    """A channel name that the recording does not hold."""


class DataError(InputError):
    """The data themselves are unusable: NaN/inf, non-monotonic time, ..."""


class TooFewSamplesError(DataError):
    """Fewer samples (or periods, revolutions, poses) than the model needs."""


class ConvergenceError(SenscalError):
    """An iterative estimator did not converge."""


class DegenerateGeometryError(InputError):
    """A sensor layout or set of orientations cannot determine the unknowns."""


class UnobservableError(InputError):
    """A state-space model has states the measurements cannot determine."""


class DiagnosticError(SenscalError):
    """Data do not support the requested result and ``strict`` was asked for."""

    exit_code = 3
