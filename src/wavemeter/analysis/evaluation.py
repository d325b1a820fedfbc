"""Evaluation of calibrations on readings of known frequency."""

from __future__ import annotations

import numpy as np

from ..calibration.baselines import ConventionalCalibrator
from ..calibration.set import clone, window_label
from ..exceptions import InputError
from ..validation import MIN_SAMPLES, check_frequency
from .metrics import error_summary_hz, frequency_error_hz

__all__ = ["adjacent_evaluation"]


def adjacent_evaluation(calibration, powers, frequency_hz, baseline=None) -> dict:
    """Each window's map on its own FSR and on the neighbouring FSRs (paper Fig. 9).

    For every window with readings in it and in at least one neighbour, the window's
    calibration retrieves the readings of its own window and of the adjacent windows
    (the frequency alias nearest the truth), and the conventional method does the
    same: it is fitted on the window's own readings of this data (its origin,
    direction and FSR) and applied to both.

    Parameters
    ----------
    calibration : CalibrationSet
        A fitted calibration set.
    powers : array_like, shape (N, n)
        Port readings over several windows (test data, or the sweep itself).
    frequency_hz : array_like, shape (N,)
        True frequency of each reading (Hz).
    baseline : None or calibrator
        Unfitted baseline calibrator cloned per window (default
        ``ConventionalCalibrator()``, port phases equally spaced in port order).

    Returns
    -------
    dict
        JSON-ready. ``"windows"``: one entry per evaluated window with ``window``
        (index), ``center_hz``, ``fsr_hz``, ``samples_own``, ``samples_adjacent`` and
        error summaries (``rms_hz``, ``max_hz``, ``p95_hz``, ``p99_hz``, Hz) ``own``,
        ``adjacent``, ``conventional_own``, ``conventional_adjacent``, plus
        ``degradation_rms`` (adjacent over own RMS). The same summaries over all
        evaluated windows at the top level, with ``method`` and ``windows_evaluated``.

    Raises
    ------
    InputError
        When no window has at least 4 readings of its own and one in a neighbour.
    """
    template = ConventionalCalibrator() if baseline is None else baseline
    readings = calibration._check_readings(powers)
    frequency = check_frequency(frequency_hz, readings.shape[0])
    position = np.floor((frequency - calibration.window_edges_hz_[0]) / calibration.fsr_hz_)
    pooled = {"own": [], "adjacent": [], "conventional_own": [], "conventional_adjacent": []}
    entries = []
    for index, window in enumerate(calibration.windows_):
        own = position == index
        neighbours = [k for k in (index - 1, index + 1) if 0 <= k < len(calibration.windows_)]
        adjacent = np.isin(position, neighbours)
        if own.sum() < MIN_SAMPLES or not adjacent.any():
            continue
        try:
            conventional = clone(template, fsr_hz=window.fsr_hz_).fit(readings[own], frequency[own])
        except InputError as exc:
            raise type(exc)(
                f"{window_label(calibration.window_edges_hz_, index)}, conventional baseline: {exc}"
            ) from exc
        errors = {
            name: frequency_error_hz(
                calibrator.predict(readings[rows]), frequency[rows], calibrator.fsr_hz_
            )
            for name, calibrator, rows in (
                ("own", window, own),
                ("adjacent", window, adjacent),
                ("conventional_own", conventional, own),
                ("conventional_adjacent", conventional, adjacent),
            )
        }
        for name, error in errors.items():
            pooled[name].append(error)
        summaries = {name: error_summary_hz(error) for name, error in errors.items()}
        entries.append(
            {
                "window": index,
                "center_hz": window.center_hz_,
                "fsr_hz": window.fsr_hz_,
                "samples_own": int(own.sum()),
                "samples_adjacent": int(adjacent.sum()),
                **summaries,
                "degradation_rms": summaries["adjacent"]["rms_hz"] / summaries["own"]["rms_hz"],
            }
        )
    if not entries:
        raise InputError(
            f"adjacent evaluation needs readings in a window (at least {MIN_SAMPLES}) and in "
            "a neighbouring window; the data given covers no such pair of the set's "
            f"{len(calibration.windows_)} windows"
        )
    totals = {name: error_summary_hz(np.concatenate(parts)) for name, parts in pooled.items()}
    return {
        "method": type(calibration.windows_[0]).method,
        "windows_evaluated": len(entries),
        **totals,
        "degradation_rms": totals["adjacent"]["rms_hz"] / totals["own"]["rms_hz"],
        "windows": entries,
    }
