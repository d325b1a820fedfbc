"""The one exception family of the package, the warning a misfit calibration emits, and the
note a reader gives about what it chose.

Library code raises these (never bare ``ValueError``/``TypeError``/``assert``); the command
line catches :class:`WavemeterError` and ``OSError`` only, so anything else is a bug and
shows its traceback. Messages say which value is wrong and what is allowed; they never name
a command-line flag (the CLI adds flag hints where it knows them).
"""

from __future__ import annotations

import contextlib
import json
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
    """Base of every error the package raises on purpose.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> try:
    ...     wm.Calibrator(fsr_hz=50e9).fit(powers[:, :2], f_hz)  # two ports cannot fix the cone
    ... except wm.WavemeterError as error:  # every error the package raises on purpose
    ...     print(type(error).__name__, "|", error)
    InputError | port powers need at least 3 ports (columns), got 2
    """


class InputError(WavemeterError, ValueError):
    """A value given to the library is wrong: its type, shape, range or content.

    Parameters
    ----------
    message : str
        What is wrong with which value, and what is allowed.
    parameter : str, optional
        The library parameter the value came through (e.g. ``"fsr_hz"``, ``"x_unit"``,
        ``"force"``); the command line uses it to name its own option in a hint.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> try:
    ...     wm.Calibrator(fsr_hz=50).fit(powers, f_hz)  # 50 Hz typed for 50 GHz
    ... except wm.InputError as error:
    ...     print(error.parameter)
    ...     print(str(error).split("; ")[-1])  # the message ends with what to do
    fsr_hz
    the sweep's own fringes repeat every 51.5076 GHz: set fsr_hz to about 5.15076e+10 Hz
    >>> isinstance(wm.InputError(), ValueError)
    True
    """

    def __init__(self, message: str = "", *, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter


class FileFormatError(InputError):
    """A file cannot be read as what it should be: foreign, corrupt, truncated or unsafe.

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> path = Path(tempfile.mkdtemp()) / "chip.wmcal.json"
    >>> _ = path.write_text(json.dumps({"format": "something.else"}))
    >>> try:
    ...     wm.load_calibration(path)
    ... except wm.FileFormatError as error:
    ...     print(str(error).split(": ", 1)[1])  # after the file's name
    not a wavemeter calibration file (no format 'wavemeter.calibration')
    """


class NotFittedError(WavemeterError, ValueError, AttributeError):
    """``predict``/``phase``/``save`` was called on an estimator before ``fit``.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> try:
    ...     wm.Calibrator().predict(powers)
    ... except wm.NotFittedError as error:
    ...     print(str(error).split(": ")[-1])
    call fit(powers, frequency_hz) or load a calibration file first
    """


class EdgeMinimumError(InputError):
    """The delay (FSR) that fits best lies outside the bracket searched.

    Raised when the cost is smallest on the edge of the bracket, or when the best delay
    inside it explains less than half of the fringe power (a side minimum of ``J``).

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> import textwrap
    >>> try:  # the device's FSR, 51.5 GHz, is outside 40 GHz +- 10 %
    ...     wm.Calibrator(fsr_hz=40e9, fsr_tolerance=0.1).fit(powers, f_hz)
    ... except wm.EdgeMinimumError as error:
    ...     print(textwrap.fill(str(error), width=88))
    the delay fit is best at the last delay scanned, at an FSR of 46.5882 GHz, 5.88 % beyond
    the edge of the FSR bracket (fsr_hz=40 GHz, fsr_tolerance=0.1: 36 GHz to 44 GHz): the
    true FSR is outside the bracket, at or beyond that; widen fsr_tolerance or correct
    fsr_hz
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

    Examples
    --------
    >>> import warnings
    >>> import wavemeter as wm
    >>> from wavemeter.simulation import slow_power_drift
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(400, span_fsr=2)
    >>> drift = slow_power_drift(400, 0.05, rng=3)  # the source power wanders by about 5 %
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1) * drift[:, None]
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> notes = [w.message for w in caught if issubclass(w.category, wm.CalibrationWarning)]
    >>> [note.cause for note in notes]
    ['power_drift']
    >>> print(notes[0].remedy[:60])
    record the source power with a power monitor during the swee
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
    command line prints it as ``note: ...`` on stderr.

    Examples
    --------
    >>> import tempfile, warnings
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.io import read_table
    >>> path = Path(tempfile.mkdtemp()) / "sweep.csv"
    >>> lines = ["frequency_THz;P1_mW;P2_mW;P3_mW", "193,40;0,5;0,25;0,25", "193,41;0,25;0,5;0,25"]
    >>> with open(path, "w") as file:  # a lab CSV: semicolons and decimal commas
    ...     for line in lines:
    ...         print(line, file=file)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     table = read_table(path)
    >>> notes = [str(w.message) for w in caught if issubclass(w.category, wm.InputNote)]
    >>> print(notes[0].split(": ", 1)[1])
    read as ';'-separated with decimal commas
    >>> print(table.x_hz, table.powers_w[0])  # in Hz and W
    [1.9340e+14 1.9341e+14] [0.0005  0.00025 0.00025]
    """


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


#: longest text of a value :func:`shown` quotes (longer ones are cut, ``...`` marking it)
SHOWN_CHARACTERS = 80


def shown(value, *, as_in_file: bool = False) -> str:
    """A value as a message shows it: numbers as people write them (``0.0515``, never
    ``np.float64(0.0515)``), a text in quotes (cut to 80 characters), a sequence item by
    item (the first 8), anything else by its kind.

    With ``as_in_file``, a value read from a file as the file holds it (JSON: every digit
    of a number, lists in brackets, objects in braces, ``null``, ``NaN``), so that the
    message quotes what a search of the file finds; cut to 80 characters.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.exceptions import shown
    >>> shown(np.float64(0.0515011)), shown(np.int64(3)), shown("nm"), shown((1.0, np.nan))
    ('0.0515011', '3', "'nm'", '(1, nan)')
    >>> shown([1.23456789e-07, None], as_in_file=True), shown(None, as_in_file=True)
    ('[1.23456789e-07, null]', 'null')
    """
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()  # a numpy scalar
    if as_in_file and not isinstance(value, str):
        text = json.dumps(value, allow_nan=True, default=_plain)
        return text if len(text) <= SHOWN_CHARACTERS else text[: SHOWN_CHARACTERS - 3] + "..."
    if isinstance(value, bool) or value is None:
        return str(value).lower() if value is not None else "nothing"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return repr(value[:SHOWN_CHARACTERS])
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        items = ", ".join(shown(item) for item in list(value)[:8])
        return f"({items}{', ...' if len(value) > 8 else ''})"
    return f"a {type(value).__name__}"


def _plain(value):
    """What JSON cannot write, as plain values: numpy's scalars and arrays; else its kind."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return f"a {type(value).__name__}"
