"""Frequency-error figures of merit shared by tests, benchmarks, the CLI and reports."""

from __future__ import annotations

import numpy as np

from ..model.cone import wrap_to_period

__all__ = ["frequency_error_hz", "error_summary_hz"]


def frequency_error_hz(predicted_hz, true_hz, fsr_hz: float) -> np.ndarray:
    """Retrieved minus true frequency (Hz), wrapped to [-FSR/2, FSR/2).

    A single interferometer measures frequency modulo its FSR; an estimate one FSR away is
    the same reading, so errors are compared on the circle.
    """
    error = np.asarray(predicted_hz, dtype=float) - np.asarray(true_hz, dtype=float)
    return wrap_to_period(error, fsr_hz)


def error_summary_hz(error_hz) -> dict[str, float]:
    """RMS, max |.|, and 95th/99th percentile of |error| (Hz)."""
    error = np.abs(np.asarray(error_hz, dtype=float))
    return {
        "rms_hz": float(np.sqrt(np.mean(error**2))),
        "max_hz": float(error.max()),
        "p95_hz": float(np.percentile(error, 95)),
        "p99_hz": float(np.percentile(error, 99)),
    }
