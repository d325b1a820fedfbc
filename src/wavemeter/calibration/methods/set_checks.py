"""A calibration set's maps on the neighbouring FSRs (paper Fig. 9), and its check record.

:func:`adjacent_evaluation` reads each window's neighbours with the window's map, beside
the conventional method fitted on the window; :func:`adjacent_check` is what a set
declares of it for its reports (``evaluation_checks``).
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...model.errors import error_summary_hz, frequency_error_hz
from ...validation import MIN_SAMPLES, check_frequency
from ..contract.params import clone
from ..contract.summary import Check, Table
from ..files.registry import calibrator_class

__all__ = ["adjacent_check", "adjacent_evaluation", "window_label"]


def window_label(edges_hz: np.ndarray, index: int) -> str:
    """``window 3 (193.400000 to 193.450000 THz)``."""
    return f"window {index} ({edges_hz[index] / 1e12:.6f} to {edges_hz[index + 1] / 1e12:.6f} THz)"


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
        Unfitted baseline calibrator cloned per window (default the conventional
        calibrator, port phases equally spaced in port order).

    Returns
    -------
    dict
        JSON-ready. ``"windows"``: one entry per evaluated window with ``window``
        (index), ``center_hz``, ``fsr_hz``, ``samples_own``, ``samples_adjacent`` and
        error summaries (``rms_hz``, ``max_hz``, ``p95_hz``, ``p99_hz``, Hz) ``own``,
        ``adjacent``, ``conventional_own``, ``conventional_adjacent``, plus
        ``degradation_rms`` (adjacent over own RMS) and ``conventional_degradation_rms``
        (the same for the conventional method). The same summaries over all
        evaluated windows at the top level, with ``method`` and ``windows_evaluated``.

    Raises
    ------
    InputError
        When no window has at least 4 readings of its own and one in a neighbour.
    """
    template = calibrator_class("conventional")() if baseline is None else baseline
    readings = calibration._corrected(powers)
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
                **_degradations(summaries),
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
        **_degradations(totals),
        "windows": entries,
    }


def _degradations(summaries: dict) -> dict:
    """Adjacent over own RMS error, of the calibration and of the conventional baseline."""
    return {
        "degradation_rms": summaries["adjacent"]["rms_hz"] / summaries["own"]["rms_hz"],
        "conventional_degradation_rms": summaries["conventional_adjacent"]["rms_hz"]
        / summaries["conventional_own"]["rms_hz"],
    }


def adjacent_check(calibration, powers_w, frequency_hz) -> Check:
    """The adjacent-window evaluation as a check of the set; where the readings hold no
    window with a neighbour, a record of why it could not be made."""
    title = "Maps applied to the neighbouring FSRs ([1], Fig. 9)"
    try:
        record = adjacent_evaluation(calibration, powers_w, frequency_hz)
    except InputError as exc:
        return Check("adjacent", title, {"unavailable": str(exc)}, f"Not available: {exc}")
    columns = (
        "window",
        "centre (THz)",
        "own RMS (MHz)",
        "own max (MHz)",
        "adjacent RMS (MHz)",
        "adjacent max (MHz)",
        "conventional adjacent max (MHz)",
    )
    rows = tuple(
        (
            entry["window"],
            f"{entry['center_hz'] / 1e12:.6f}",
            entry["own"]["rms_hz"] / 1e6,
            entry["own"]["max_hz"] / 1e6,
            entry["adjacent"]["rms_hz"] / 1e6,
            entry["adjacent"]["max_hz"] / 1e6,
            entry["conventional_adjacent"]["max_hz"] / 1e6,
        )
        for entry in record["windows"]
    )
    text = f"Adjacent over own RMS: {record['degradation_rms']:.3g}."
    return Check("adjacent", title, record, text, Table("adjacent", title, columns, rows))
