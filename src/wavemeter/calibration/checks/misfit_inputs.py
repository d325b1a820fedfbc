"""The checks of :func:`~wavemeter.calibration.checks.misfit.misfit_report`'s arguments.

Shapes and finite values of the readings, frequencies, delay, map (one, or one per
reading), monitored power, fitted offsets with their standard errors, the design the map
was fitted on and the phase's derivatives by the shared nonlinear parameters; each refusal
an :class:`~wavemeter.exceptions.InputError` naming its parameter.
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError, shown

__all__ = ["checked_vector", "checked_inputs", "checked_design", "checked_phase_derivatives"]


def checked_vector(name: str, value, size: int) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise InputError(
            f"{name} must be {size} finite numbers, got shape {array.shape}", parameter=name
        )
    return array


def checked_inputs(powers, frequency_hz, center_hz, delay_s, map_, scale, offset_w, offset_std_w):
    readings = np.asarray(powers, dtype=float)
    if readings.ndim != 2 or readings.shape[0] < 4 or readings.shape[1] < 3:
        raise InputError(
            f"powers must have shape (N, n) with N >= 4 readings and n >= 3 ports, got "
            f"{readings.shape}",
            parameter="powers",
        )
    if not np.all(np.isfinite(readings)):
        raise InputError("powers must be finite numbers (W)", parameter="powers")
    samples, ports = readings.shape
    frequency = checked_vector("frequency_hz", frequency_hz, samples)
    for name, value in (("center_hz", center_hz), ("delay_s", delay_s)):
        if not np.isfinite(value):
            raise InputError(f"{name} must be a finite number, got {value!r}", parameter=name)
    if not delay_s > 0:
        raise InputError(f"delay_s must be > 0 (s), got {shown(delay_s)}", parameter="delay_s")
    matrix = np.asarray(map_, dtype=float)
    if matrix.shape not in ((ports, 3), (samples, ports, 3)) or not np.all(np.isfinite(matrix)):
        raise InputError(
            f"map_ must be {ports} x 3 finite numbers (one map) or {samples} x {ports} x 3 (the "
            f"map of each reading), got shape {matrix.shape}",
            parameter="map_",
        )
    power = None if scale is None else checked_vector("scale", scale, samples)
    if (offset_w is None) != (offset_std_w is None):
        raise InputError(
            "offset_w and offset_std_w must be given together (fitted offsets with their "
            "standard errors) or both be None",
            parameter="offset_std_w",
        )
    offsets = None if offset_w is None else checked_vector("offset_w", offset_w, ports)
    offset_std = (
        None if offset_std_w is None else checked_vector("offset_std_w", offset_std_w, ports)
    )
    if offset_std is not None and np.any(offset_std < 0):
        raise InputError("offset_std_w must be >= 0 (W)", parameter="offset_std_w")
    return readings, frequency, float(center_hz), float(delay_s), matrix, power, offsets, offset_std


def checked_design(design, samples: int) -> np.ndarray:
    """The columns (N, k) each port's map row was fitted on, checked."""
    columns = np.asarray(design, dtype=float)
    if columns.ndim != 2 or columns.shape[0] != samples or not 1 <= columns.shape[1] < samples:
        raise InputError(
            f"design must have shape (N, k) with N = {samples} readings and 1 <= k < N fitted "
            f"columns, got {columns.shape}",
            parameter="design",
        )
    if not np.all(np.isfinite(columns)):
        raise InputError("design must be finite numbers", parameter="design")
    return columns


def checked_phase_derivatives(derivatives, samples: int) -> np.ndarray:
    """The derivatives (q, N) of the model phase by the shared nonlinear parameters, checked."""
    rows = np.asarray(derivatives, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != samples or rows.shape[0] < 1:
        raise InputError(
            f"phase_derivatives must have shape (q, N) with q >= 1 parameters and N = "
            f"{samples} readings, got {rows.shape}",
            parameter="phase_derivatives",
        )
    if not np.all(np.isfinite(rows)):
        raise InputError("phase_derivatives must be finite numbers", parameter="phase_derivatives")
    return rows
