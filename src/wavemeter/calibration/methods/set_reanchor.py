"""Re-anchoring a calibration set: each window with lines by its own, the others between.

:func:`reanchored_set` gives each reading to the window of its known frequency, re-anchors
every window with readings by its own ``reanchor``, and gives a window without a line the
phase shift interpolated linearly in window centre frequency between the nearest
re-anchored ones (held beyond the outermost), its delay kept.
"""

from __future__ import annotations

import copy

import numpy as np

from ...exceptions import InputError
from ...validation import check_fitted, check_per_reading
from ..models.reanchor import ReanchorFit, check_reference_readings, reanchored_copy

__all__ = ["reanchored_set"]


def reanchored_set(calibration, powers, frequency_hz, coarse_hz=None, temperature_k=None):
    """A copy of a fitted calibration set whose windows are re-anchored to readings of
    reference lines (see :meth:`CalibrationSet.reanchor`)."""
    check_fitted(calibration)
    raw, frequency, temperature = check_reference_readings(
        powers, frequency_hz, calibration.n_ports_, temperature_k
    )
    if coarse_hz is not None:
        try:
            check_per_reading("coarse_hz", coarse_hz, frequency.size)
        except InputError as exc:
            raise InputError(str(exc), parameter="coarse_hz") from exc
    low, high = calibration.covered_hz()
    outside = (frequency < low) | (frequency > high)
    if outside.any():
        raise InputError(
            f"frequency_hz {frequency[outside][0]!r} Hz is outside the calibrated span "
            f"{low / 1e12:.6f} to {high / 1e12:.6f} THz: no window to re-anchor there",
            parameter="frequency_hz",
        )
    if "reanchor" not in calibration.windows_[0].capabilities:
        raise InputError(
            f"windows of method {type(calibration.windows_[0]).method!r} cannot be re-anchored",
            parameter="window",
        )
    readings = raw - calibration._reading_offset_w()
    index = calibration.window_index(frequency)
    windows = list(calibration.windows_)
    anchored = np.unique(index)
    for number in anchored:
        rows = index == number
        windows[number] = calibration.windows_[number].reanchor(
            readings[rows],
            frequency[rows],
            temperature_k=None if temperature is None else temperature[rows],
        )
        windows[number].diagnostics_["reanchor"]["interpolated_from"] = []
    centers = np.array([window.center_hz_ for window in calibration.windows_])
    records = [windows[number].diagnostics_["reanchor"] for number in anchored]
    shifts = np.unwrap([record["phase_shift_rad"] for record in records])
    variances = np.square([record["phase_shift_std_rad"] for record in records])
    for number in np.setdiff1d(np.arange(len(windows)), anchored):
        # weight of each re-anchored window: linear interpolation, held beyond the ends
        weight = np.array(
            [np.interp(centers[number], centers[anchored], unit) for unit in np.eye(anchored.size)]
        )
        shift_std = float(np.sqrt(weight**2 @ variances))
        fit = ReanchorFit(
            phase_shift_rad=float(weight @ shifts),
            phase_shift_std_rad=shift_std,
            delay_change_s=None,
            delay_change_std_s=None,
            covariance=np.diag([shift_std**2, 0.0]),
            lines_hz=(),
            readings=0,
        )
        source = anchored[weight > 0].tolist()
        windows[number] = reanchored_copy(
            calibration.windows_[number], fit, {**fit.record(), "interpolated_from": source}
        )
    corrected = copy.deepcopy(calibration)
    corrected.windows_ = windows
    corrected.diagnostics_ = {
        **(corrected.diagnostics_ or {}),
        "reanchor": {
            "lines_hz": np.unique(frequency).tolist(),
            "readings": int(frequency.size),
            "windows": [window.diagnostics_["reanchor"] for window in windows],
        },
    }
    return corrected
