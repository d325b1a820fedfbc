"""The one exception family of the package, the warning a misfit calibration emits, and the
note a reader gives about what it chose.

Library code raises these (never bare ``ValueError``/``TypeError``/``assert``); the command
line catches :class:`WavemeterError` and ``OSError`` only, so anything else is a bug and
shows its traceback. Messages say which value is wrong and what is allowed; they never name
a command-line flag (the CLI adds flag hints where it knows them).
"""

from __future__ import annotations

import contextlib
import warnings

__all__ = [
    "WavemeterError",
    "InputError",
    "FileFormatError",
    "NotFittedError",
    "EdgeMinimumError",
    "CalibrationWarning",
    "InputNote",
    "recorded_calibration_warnings",
]


class WavemeterError(Exception):
    """Base of every error the package raises on purpose."""


class InputError(WavemeterError, ValueError):
    """A value given to the library is wrong: its type, shape, range or content.

    Parameters
    ----------
    message : str
        What is wrong with which value, and what is allowed.
    parameter : str, optional
        The library parameter the value came through (e.g. ``"fsr_hz"``, ``"x_unit"``,
        ``"force"``); the command line uses it to name its own option in a hint.
    """

    def __init__(self, message: str = "", *, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter


class FileFormatError(InputError):
    """A file cannot be read as what it should be: foreign, corrupt, truncated or unsafe."""


class NotFittedError(WavemeterError, ValueError, AttributeError):
    """``predict``/``phase``/``save`` was called on an estimator before ``fit``."""


class EdgeMinimumError(InputError):
    """The delay (FSR) that fits best lies outside the bracket searched.

    Raised when the cost is smallest on the edge of the bracket, or when the best delay
    inside it explains less than half of the fringe power (a side minimum of ``J``).
    """


class CalibrationWarning(UserWarning):
    """A calibration fitted, but the data depart from the model in a way that costs accuracy.

    Parameters
    ----------
    message : str
        What was seen, with numbers, and the remedy.
    cause : str
        One word naming the departure (e.g. ``"power_drift"``, ``"dead_port"``).
    remedy : str
        What the user can do about it.
    """

    def __init__(self, message: str, cause: str = "other_misfit", remedy: str = ""):
        super().__init__(message)
        self.cause = cause
        self.remedy = remedy

    def record(self) -> dict:
        """JSON-ready ``{"cause", "message", "remedy"}``, as ``diagnostics_`` keeps it."""
        return {"cause": self.cause, "message": str(self), "remedy": self.remedy}


class InputNote(UserWarning):
    """How an input was read where the reader chose what the caller did not say (a
    ``;``-separated file read with decimal commas): worth knowing, not a problem. The
    command line prints it as ``note: ...`` on stderr."""


@contextlib.contextmanager
def recorded_calibration_warnings():
    """Record the :class:`CalibrationWarning` s emitted inside, every one, in order.

    Yields a list that holds them once the block has run; any other warning is shown as
    it would have been without the block.
    """
    notes: list[CalibrationWarning] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CalibrationWarning)
        yield notes
    for entry in caught:
        if isinstance(entry.message, CalibrationWarning):
            notes.append(entry.message)
        else:
            warnings.showwarning(
                entry.message, entry.category, entry.filename, entry.lineno, entry.file
            )
