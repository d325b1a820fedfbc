"""Frequency-error figures of merit shared by tests, benchmarks, the CLI and reports.

Both helpers take the same arguments: ``(predicted_hz, true_hz, *, fsr_hz=None)``. With
``fsr_hz`` the error is taken on the circle of one FSR (a single interferometer measures
frequency modulo its FSR, so an estimate one FSR away is the same reading); without it the
error is absolute. :func:`error_summary_hz` also accepts a vector of errors alone, as
``error_summary_hz(error_hz)``.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..validation import check_positive
from .cone import wrap_to_period

__all__ = ["frequency_error_hz", "error_summary_hz"]


def frequency_error_hz(predicted_hz, true_hz, fsr_hz: float | None = None) -> np.ndarray:
    """Retrieved minus true frequency (Hz), absolute or modulo the FSR.

    Parameters
    ----------
    predicted_hz, true_hz : array_like, shape (N,) (or broadcastable to one shape)
        Retrieved and true frequencies (Hz).
    fsr_hz : float, optional
        FSR (Hz): the error is wrapped to ``[-FSR/2, FSR/2)``. None: the plain difference.
        (May be given by position, as in ``frequency_error_hz(predicted, true, fsr)``.)

    Returns
    -------
    ndarray, shape (N,), Hz

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> true_hz = np.array([193.4e12, 193.4e12])
    >>> predicted_hz = true_hz + np.array([2e6, 50e9 - 1e6])  # the second one an FSR off
    >>> print(wm.frequency_error_hz(predicted_hz, true_hz) / 1e6)
    [2.0000e+00 4.9999e+04]
    >>> print(wm.frequency_error_hz(predicted_hz, true_hz, fsr_hz=50e9) / 1e6)  # modulo the FSR
    [ 2. -1.]
    """
    predicted = np.asarray(predicted_hz, dtype=float)
    truth = np.asarray(true_hz, dtype=float)
    try:
        np.broadcast_shapes(predicted.shape, truth.shape)
    except ValueError as exc:
        raise InputError(
            f"predicted_hz and true_hz must have the same shape, got {predicted.shape} and "
            f"{truth.shape}"
        ) from exc
    error = predicted - truth
    if fsr_hz is None:
        return error
    return wrap_to_period(error, check_positive("fsr_hz", fsr_hz))


def error_summary_hz(predicted_hz, true_hz=None, *, fsr_hz: float | None = None) -> dict:
    """RMS, max |.|, and 95th/99th percentile of |error| (Hz).

    Parameters
    ----------
    predicted_hz : array_like, shape (N,)
        Retrieved frequencies (Hz); or, with ``true_hz`` None, the errors themselves.
    true_hz : None or array_like, shape (N,)
        True frequencies (Hz).
    fsr_hz : float, optional
        FSR (Hz) for errors modulo the FSR (see :func:`frequency_error_hz`).

    Returns
    -------
    dict
        ``rms_hz``, ``max_hz``, ``p95_hz``, ``p99_hz``.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> true_hz = 193.4e12 + np.arange(4) * 1e9
    >>> predicted_hz = true_hz + np.array([3e6, -4e6, 0.0, 5e6])
    >>> summary = wm.error_summary_hz(predicted_hz, true_hz)
    >>> sorted(summary)
    ['max_hz', 'p95_hz', 'p99_hz', 'rms_hz']
    >>> print(f"{summary['rms_hz'] / 1e6:.2f} MHz RMS, {summary['max_hz'] / 1e6:.0f} MHz at most")
    3.54 MHz RMS, 5 MHz at most
    """
    if true_hz is None:
        if fsr_hz is not None:
            raise InputError("fsr_hz needs true_hz: give (predicted_hz, true_hz, fsr_hz=...)")
        error = np.asarray(predicted_hz, dtype=float)
    else:
        error = frequency_error_hz(predicted_hz, true_hz, fsr_hz)
    if error.size == 0:
        raise InputError("no errors to summarise: got an empty array")
    error = np.abs(error)
    return {
        "rms_hz": float(np.sqrt(np.mean(error**2))),
        "max_hz": float(error.max()),
        "p95_hz": float(np.percentile(error, 95)),
        "p99_hz": float(np.percentile(error, 99)),
    }
