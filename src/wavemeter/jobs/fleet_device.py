"""A device of a fleet: calibrated without saving, its bad input a result and not an
error (:func:`calibrate_device`), or its result rebuilt from the calibration an earlier run
saved (:func:`saved_result`)."""

from __future__ import annotations

import math
from pathlib import Path

from ..exceptions import WavemeterError
from .calibrate import ERROR, DeviceResult, calibrate_file, result_of

__all__ = ["calibrate_device", "saved_result"]


def calibrate_device(path, *, device: str | None = None, **options) -> DeviceResult:
    r""":func:`calibrate_file` without saving, for a fleet: bad input is a result.

    Parameters
    ----------
    path : str or Path
        The sweep file.
    device : str, optional
        The device's name (default: the file's stem).
    **options
        As :func:`calibrate_file` takes them (``options=`` or keywords).

    Returns
    -------
    DeviceResult
        ``status="ok"`` with the fitted calibration, or ``status="error"`` with the message
        of the :class:`~wavemeter.exceptions.WavemeterError` or ``OSError`` that stopped
        it. Any other exception is a bug and is raised.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.jobs import calibrate_device
    >>> _ = (folder / "broken.csv").write_text("frequency_hz,p1_w\n1,2\n")  # one port only
    >>> results = [calibrate_device(folder / name) for name in ("sweep.csv", "broken.csv")]
    >>> [(result.device, result.status) for result in results]  # one bad file stops nothing
    [('sweep', 'ok'), ('broken', 'error')]
    >>> print(results[1].error.split(": ", 1)[1].split("; ")[0])
    found 1 port column(s) (p1_w)
    """
    name = Path(path).stem if device is None else device
    try:
        return calibrate_file(path, device=name, **options)
    except (WavemeterError, OSError) as exc:
        return DeviceResult(device=name, source=str(path), status=ERROR, error=_message(exc))


def _message(exc: Exception) -> str:
    """An error's message on one line; an OSError's without Python's ``[Errno N]``."""
    text = str(exc) or type(exc).__name__
    if isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    return " ".join(text.split())


def saved_result(cal_path, source, device: str) -> DeviceResult:
    """The result of a device from the calibration an earlier run saved (``resumed``).

    The numbers are those of the run that saved it: FSR, noise, RMS and warnings from the
    calibration, the Cramer-Rao RMS from its metadata (NaN when the file has none).

    Raises
    ------
    FileFormatError
        When the file does not load (missing, corrupt, foreign).
    """
    from ..calibration.files.document import read_calibration_file

    saved = read_calibration_file(cal_path)
    crlb = saved.metadata.get("crlb_rms_hz")
    crlb_rms_hz = float(crlb) if isinstance(crlb, (int, float)) else math.nan
    return result_of(device, source, saved.calibrator, crlb_rms_hz, saved.metadata, resumed=True)
