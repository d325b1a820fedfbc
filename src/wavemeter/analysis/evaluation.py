"""Evaluation of calibrations on readings of known frequency.

Errors are taken against the true frequency as given (absolute): a single-FSR calibration
returns the alias within half an FSR of its centre, so a reading whose truth lies outside
the calibrated span is wrong by whole FSRs and counts as such. The error modulo each
calibration's FSR is reported beside it, labelled, for the precision within one FSR.
"""

from __future__ import annotations

import numpy as np

from ..calibration.contract.flags import flag_counts
from ..exceptions import InputError
from ..model.errors import error_summary_hz, frequency_error_hz
from ..validation import check_frequency, check_per_reading, check_powers

__all__ = ["crlb_per_reading_hz", "evaluate_calibrations"]


def _reading_inputs(calibration, coarse_hz, temperature_k=None) -> dict:
    """Keyword inputs besides the powers that ``calibration`` needs per reading."""
    inputs = {"coarse_hz": coarse_hz} if "coarse_hz" in calibration.requires else {}
    if "temperature_k" in calibration.requires:
        if temperature_k is None:
            raise InputError(
                f"a {calibration.method_label} calibration needs the chip temperature of "
                "each test reading: give temperature_k (K)",
                parameter="temperature_k",
            )
        inputs["temperature_k"] = temperature_k
    return inputs


def _calibrated_range_hz(calibration) -> tuple[float, float]:
    """Lowest and highest frequency (Hz) the calibration was fitted for: the sweep span of
    a single calibration (one FSR, or a wide band), the range its parts cover (a set's
    windows)."""
    parts = calibration.parts()
    if parts:
        ranges = np.array([part.range_hz for part in parts])
        low, high = calibration.span_hz_
        return min(float(ranges.min()), low), max(float(ranges.max()), high)
    low, high = calibration.span_hz_
    return float(low), float(high)


def crlb_per_reading_hz(
    calibration, powers_w, frequency_hz, temperature_k=None
) -> np.ndarray | None:
    """Per-reading Cramer-Rao standard deviation (Hz) at the true frequency.

    The bound under the calibration's own model: its fitted map, FSR and noise (estimated
    from the calibration residual), at the phase the true frequency has under that map
    (:meth:`~wavemeter.Calibrator.crlb_hz` with ``phase_rad``). A calibration
    set evaluates each reading under the window its true frequency falls in; a wide-band
    calibration at its model phase of the truth (``model_phase_rad``), the truth as the
    coarse frequency.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration; one without the ``"crlb"`` capability gives None.
    powers_w : array_like, shape (N, n)
        Port readings, in the unit of the calibration sweep.
    frequency_hz : array_like, shape (N,)
        True frequency of each reading (Hz).
    temperature_k : None or array_like, shape (N,)
        Chip temperature of each reading (K), for a calibration that needs it (its FSR
        and phase follow the temperature).

    Returns
    -------
    ndarray, shape (N,), Hz, or None
        NaN for readings the calibration cannot read (a true frequency outside the range a
        set's windows cover, more than half an FSR outside a wide band).

    Raises
    ------
    InputError
        When the readings or frequencies are malformed.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.analysis import crlb_per_reading_hz
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(device.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)
    >>> test = device.powers(f_hz[:4], 1e-3, 5e-7, rng=2)

    The bound under the calibration's own map and noise: near the 14 MHz of the device

    >>> print(np.round(crlb_per_reading_hz(cal, test, f_hz[:4]) / 1e6, 1))
    [13.3 13.2 13.2 13.2]
    """
    if "crlb" not in calibration.capabilities:
        return None
    readings = check_powers(powers_w)
    truth = check_frequency(frequency_hz, readings.shape[0])
    inputs = _reading_inputs(calibration, truth, temperature_k)
    return calibration.crlb_hz(readings, frequency_hz=truth, **inputs)


def _noise_std_w(calibration) -> float | None:
    """Detector noise (W) a calibration states (a set: the mean over its windows)."""
    noise = calibration.summary().values.get("noise_std_w")
    return None if noise is None else float(noise.value)


def _method_figures(calibration, readings, truth, coarse, temperature_k) -> dict:
    """Absolute and modulo-FSR error figures of one calibration over the readings it can
    read, and the others counted by flag (see evaluate_calibrations)."""
    inputs = _reading_inputs(calibration, coarse, temperature_k)
    found = calibration.readout(readings, **inputs)
    read = np.isfinite(found.frequency_hz)
    if not read.any():
        raise InputError(
            f"a {calibration.method_label} calibration cannot read any of the {truth.size} "
            "readings (outside the range it has maps for): give readings inside it",
            parameter="powers",
        )
    predicted, truth_read = found.frequency_hz[read], truth[read]
    error = predicted - truth_read
    absolute = error_summary_hz(error)
    low, high = _calibrated_range_hz(calibration)
    fsr = calibration.fsr_hz_
    mod_fsr = frequency_error_hz(predicted, truth_read, fsr)
    return {
        "readings": int(np.count_nonzero(read)),
        "unread": flag_counts(found.flags[~read]),
        "flagged": flag_counts(found.flags),
        "flagged_readings": int(np.count_nonzero(found.flags)),
        "rms_abs_hz": absolute["rms_hz"],
        "max_abs_hz": absolute["max_hz"],
        "p95_abs_hz": absolute["p95_hz"],
        "p99_abs_hz": absolute["p99_hz"],
        "rms_mod_fsr_hz": error_summary_hz(mod_fsr)["rms_hz"],
        "fsr_hz": float(fsr),
        "span_hz": [low, high],
        "outside_span_fraction": float(np.mean((truth < low) | (truth > high))),
        "gross_error_fraction": float(np.mean(np.abs(error) > 0.5 * fsr)),
    }


def evaluate_calibrations(
    calibrations, powers_w, frequency_hz, *, coarse_hz=None, temperature_k=None
) -> dict:
    """Frequency errors of calibrations on readings of known frequency, against the CRLB.

    Each calibration retrieves every reading as it would in use; the error is the
    retrieved minus the true frequency as given (absolute). A single-FSR calibration
    returns the alias within half an FSR of its centre, so a reading whose truth lies
    outside the calibrated span is wrong by whole FSRs, and so is every reading of a
    calibration whose FSR is an alias of the device's. The error modulo the calibration's
    FSR shows the precision within one FSR.

    Parameters
    ----------
    calibrations : mapping of str to BaseCalibrator
        Fitted calibrations by label, e.g. ``{"learned": cal, "conventional": conv}``.
    powers_w : array_like, shape (N, n)
        Port readings, in the unit of the calibration sweeps.
    frequency_hz : array_like, shape (N,)
        True frequency of each reading (Hz).
    coarse_hz : None or array_like, shape (N,)
        Coarse frequency of each reading (Hz) for calibrations that need one
        (``"coarse_hz"`` in ``requires``: a calibration set, where it picks the window, or
        a wide-band calibration, where it picks the fringe order); default: the true
        frequency, which tests the calibration but not the coarse values one would have in
        use.
    temperature_k : None, float or array_like, shape (N,)
        Chip temperature of each reading (K), for calibrations that need it (a thermal
        one); an error when one does and it is None.

    Returns
    -------
    dict
        JSON-ready. ``"methods"``: per label ``rms_abs_hz``, ``max_abs_hz``,
        ``p95_abs_hz``, ``p99_abs_hz`` (absolute error, Hz), ``rms_mod_fsr_hz`` (error
        modulo the calibration's FSR, Hz), ``fsr_hz``, ``span_hz`` (calibrated span, a
        set: the range its windows cover), ``outside_span_fraction`` (share of readings
        whose truth lies outside it; a wide band: its sweep span),
        ``gross_error_fraction`` (share of the readings it reads with an absolute error
        over half an FSR), ``readings`` (how many it reads), ``unread`` (those it cannot
        read, by flag: a coarse value outside the range its maps cover is
        ``OUTSIDE_SPAN``), ``flagged`` (every reading's flags, counted by bit as
        ``measure`` counts them) and ``flagged_readings`` (readings with any bit) and,
        when a bound is known, ``rms_abs_over_crlb`` and
        ``rms_mod_fsr_over_crlb``; the error figures are over the readings it reads. At the
        top level: ``samples``; ``coarse_from`` (``"coarse_hz"``, ``"truth"``, or None when
        no calibration needs one); ``crlb_rms_hz`` (RMS of :func:`crlb_per_reading_hz` under
        the first calibration with the ``"crlb"`` capability, over the readings it reads),
        ``crlb_method`` (its label) and ``noise_std_w`` (its noise estimate, W), all None
        when none has it.

    Raises
    ------
    InputError
        When no calibration is given, the readings or frequencies are malformed, or a
        calibration cannot retrieve them (wrong port count) or reads none of them.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.analysis import evaluate_calibrations
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, 1e-3, 5e-7, rng=1)
    >>> calibrations = {
    ...     "learned": wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz),
    ...     "conventional": wm.ConventionalCalibrator(fsr_hz=50e9).fit(powers, f_hz),
    ... }
    >>> test_hz = f_hz[5::10] + 1e8
    >>> test = device.powers(test_hz, 1e-3, 5e-7, rng=2)
    >>> result = evaluate_calibrations(calibrations, test, test_hz)

    The learned map reads at the bound, the conventional one tens of times above it:

    >>> for label, numbers in result["methods"].items():
    ...     print(f"{label}: {numbers['rms_abs_hz'] / 1e6:.0f} MHz RMS")
    learned: 13 MHz RMS
    conventional: 543 MHz RMS
    """
    if not calibrations:
        raise InputError("no calibration to evaluate; give at least one", parameter="calibrations")
    readings = check_powers(powers_w)
    truth = check_frequency(frequency_hz, readings.shape[0])
    coarse = truth
    if coarse_hz is not None:
        coarse = check_per_reading("coarse_hz", coarse_hz, truth.size)
    temperature = None
    if temperature_k is not None:
        temperature = check_per_reading("temperature_k", temperature_k, truth.size)
    coarse_from = None
    if any("coarse_hz" in calibration.requires for calibration in calibrations.values()):
        coarse_from = "truth" if coarse_hz is None else "coarse_hz"
    methods = {
        label: _method_figures(calibration, readings, truth, coarse, temperature)
        for label, calibration in calibrations.items()
    }
    summary = {
        "samples": int(truth.size),
        "coarse_from": coarse_from,
        "crlb_rms_hz": None,
        "crlb_method": None,
        "noise_std_w": None,
        "methods": methods,
    }
    bounded = [
        label for label, calibration in calibrations.items() if "crlb" in calibration.capabilities
    ]
    if bounded:
        label = bounded[0]
        bound = crlb_per_reading_hz(calibrations[label], readings, truth, temperature)
        crlb_rms = float(np.sqrt(np.nanmean(bound**2)))
        summary.update(
            crlb_rms_hz=crlb_rms,
            crlb_method=label,
            noise_std_w=_noise_std_w(calibrations[label]),
        )
        for figures in methods.values():
            figures["rms_abs_over_crlb"] = figures["rms_abs_hz"] / crlb_rms
            figures["rms_mod_fsr_over_crlb"] = figures["rms_mod_fsr_hz"] / crlb_rms
    return summary
