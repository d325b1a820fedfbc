"""Frequency-noise metrology of a laser from a meter's readings: PSD, linewidths, drift and
the Allan family, each with its uncertainty, and the meter's own noise floor removed.

Model. The laser's one-sided frequency-noise PSD is ``S_nu(f) = h0 + h_-1 / f + h_-2 /
f^2`` (Hz^2/Hz; white, flicker and random-walk FM) plus a drift ``D`` (Hz/s); each
reading is the laser's mean frequency over its sample interval ``1 / rate`` (see
:mod:`wavemeter.analysis.power_law`), plus the meter's own white noise of standard
deviation ``sigma_i`` per reading, whose one-sided PSD is the floor ``2 mean(sigma_i^2) /
rate``. The readings must be uniformly sampled and unwrapped (a single interferometer
reads modulo its FSR: unwrap with period FSR first, as
:func:`wavemeter.jobs.noise.measure_series` does).

Steps of :func:`frequency_noise` (each module's notes give its method):

- NaN readings are excluded: those at the ends are dropped, runs of up to
  ``MAX_BRIDGED_RUN`` inside are bridged by linear interpolation (a longer gap is an
  error: analyse the parts on either side), counted and warned about (here).
- PSD: the Welch PSD averaged over log-spaced bands, with each band's degrees of freedom,
  the bands' correlation and chi-square confidence intervals; the meter's floor subtracted
  and the interferometer's delay corrected up to ``DELAY_CORRECTION_MAX_FSR`` of the FSR
  (:mod:`wavemeter.analysis.noise_spectrum`).
- Power-law fit of ``h0, h_-1, h_-2`` to the bands, the Lorentzian linewidth ``pi h0`` (or
  its upper limit), the beta-separation linewidth from ``1 / T_obs`` (or its upper limit
  when the area above the line is not significant) and the drift, each with its standard
  deviation (:mod:`wavemeter.analysis.noise_fit`).
- Allan, modified Allan and Hadamard deviations of the fractional frequency with
  Greenhall's confidence intervals (:mod:`wavemeter.analysis.allan`).
- Findings: what limits or qualifies the results, each issued as a
  :class:`~wavemeter.exceptions.CalibrationWarning` with a remedy (``WARNING_CAUSES``).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from ..exceptions import CalibrationWarning, InputError
from ..validation import check_non_negative, check_positive
from .allan import MIN_AVERAGES, allan_family
from .noise_fit import (
    MISFIT_P_VALUE,
    UPPER_LIMIT_SIGMAS,
    BetaLinewidth,
    PowerLawFit,
    beta_linewidth,
    beta_separation_line_hz2_per_hz,
    fit_drift,
    fit_power_law,
    lorentzian_linewidth,
)
from .noise_spectrum import DELAY_CORRECTION_MAX_FSR, delay_correction, psd_interval, welch_bands

__all__ = [
    "FrequencyNoise",
    "frequency_noise",
    "beta_separation_line_hz2_per_hz",
    "MIN_READINGS",
    "MAX_BRIDGED_RUN",
    "DELAY_CORRECTION_MAX_FSR",
    "MIN_AVERAGES",
    "WARNING_CAUSES",
]

#: fewest finite readings analysed
MIN_READINGS = 100
#: longest run of NaN readings inside the record that is bridged by interpolation
MAX_BRIDGED_RUN = 8
#: ``to_dict`` format name and version
FORMAT = "wavemeter-noise"
FORMAT_VERSION = 1
#: cause of each warning -> what it means
WARNING_CAUSES = {
    "excluded_readings": "NaN readings were dropped at the ends or bridged inside",
    "floor_unknown": "the meter's noise is unknown: its floor is not subtracted",
    "below_floor": "the laser's white FM is not significantly above the meter's floor",
    "beta_lower_limit": "the PSD is above the beta line up to the highest frequency",
    "beta_upper_limit": "the PSD is not significantly above the beta line: an upper limit",
    "beta_below_line": "the PSD is nowhere above the beta line: the beta linewidth is 0",
    "beta_extrapolated": "the beta integral starts below the lowest PSD band",
    "noise_model_misfit": "the PSD departs from h0 + h_-1/f + h_-2/f^2",
}


@dataclass(frozen=True)
class FrequencyNoise:
    """What :func:`frequency_noise` found; arrays are numpy, units in the names.

    Attributes
    ----------
    rate_hz : float
        Sample rate (Hz).
    n_readings : int
        Finite readings analysed.
    n_excluded : int
        NaN readings (dropped at the ends or bridged inside); ``n_readings + n_excluded``
        is the input's length.
    duration_s : float
        Length of the analysed series (bridged readings included) over the rate (s).
    center_frequency_hz : float
        Mean of the finite readings (Hz), ``nu0`` of the fractional frequency.
    confidence : float
        Level of every confidence interval.
    psd_freqs_hz : ndarray, shape (K,)
        Mean Fourier frequency of each band (Hz).
    psd_hz2_per_hz : ndarray, shape (K,)
        Welch PSD of the readings averaged over each band (Hz^2/Hz), floor included.
    psd_ci_hz2_per_hz : ndarray, shape (2, K)
        Its confidence interval, [lower, upper] (Hz^2/Hz).
    meter_floor_hz2_per_hz : float or None
        The meter's white floor ``2 mean(sigma^2) / rate`` (Hz^2/Hz); None when unknown.
    psd_corrected_hz2_per_hz : ndarray, shape (K,)
        The laser's PSD: floor subtracted, delay corrected; NaN above
        ``delay_correction_max_hz``.
    phase_psd_rad2_per_hz : ndarray, shape (K,)
        Phase-noise PSD of the laser, ``psd_corrected / f^2`` (rad^2/Hz).
    delay_correction_max_hz : float or None
        Highest frequency corrected for the delay (``0.25 FSR``); None without an FSR.
    white_fm_hz2_per_hz, white_fm_std_hz2_per_hz : float
        ``h0`` of the laser (Hz^2/Hz) and its standard deviation.
    flicker_fm_hz2, flicker_fm_std_hz2 : float
        ``h_-1`` (Hz^2) and its standard deviation.
    random_walk_fm_hz2_per_s, random_walk_fm_std_hz2_per_s : float
        ``h_-2`` (Hz^2/s) and its standard deviation.
    lorentzian_linewidth_hz, lorentzian_linewidth_std_hz : float
        ``pi h0`` (Hz) and its standard deviation; an upper limit when flagged.
    linewidth_is_upper_limit : bool
        The floor is unknown, or ``h0`` is not above both the floor and twice its std:
        ``lorentzian_linewidth_hz`` then holds ``pi (max(h0, 0) + 2 std)``.
    beta_linewidth_hz, beta_linewidth_std_hz : float
        Beta-separation-line FWHM (Hz) and its standard deviation; an upper limit when
        flagged.
    beta_observation_time_s : float
        Observation time ``T_obs`` it is for (s): the integral starts at ``1 / T_obs``.
        The one given, else the longest the PSD measures (``1 /`` the lowest band's lower
        edge, a twelfth to a sixth of the record).
    beta_linewidth_is_lower_limit : bool
        The PSD is above the line up to the highest corrected frequency.
    beta_linewidth_is_upper_limit : bool
        The area above the line is not significant (noise alone makes one as large with
        a probability above 0.135 %, a normal's 3 sigma): ``beta_linewidth_hz`` then holds
        the 97.7 % quantile (2 sigma) of its draws, an upper limit. Never with a lower
        limit.
    drift_hz_per_s, drift_std_hz_per_s : float
        Least-squares drift (Hz/s) and its standard deviation under the fitted noise
        (with the frequency scale's uncertainty, ``scale_rel_std``).
    taus_s : ndarray, shape (M,)
        Averaging times (s), octaves of the sample interval with ``T / tau >= 10``.
    adev, mdev, hdev : ndarray, shape (M,)
        Overlapping Allan, modified Allan and overlapping Hadamard deviations of the
        fractional frequency (dimensionless).
    adev_ci, mdev_ci, hdev_ci : ndarray, shape (2, M)
        Their confidence intervals, [lower, upper].
    n_averages : ndarray, shape (M,)
        Averaging times that fit in the record, ``N // m`` (``tau = m / rate``), >= 10.
    warnings : tuple of str
        Each a finding and its remedy (also issued as :class:`CalibrationWarning`).
    """

    rate_hz: float
    n_readings: int
    n_excluded: int
    duration_s: float
    center_frequency_hz: float
    confidence: float
    psd_freqs_hz: np.ndarray
    psd_hz2_per_hz: np.ndarray
    psd_ci_hz2_per_hz: np.ndarray
    meter_floor_hz2_per_hz: float | None
    psd_corrected_hz2_per_hz: np.ndarray
    phase_psd_rad2_per_hz: np.ndarray
    delay_correction_max_hz: float | None
    white_fm_hz2_per_hz: float
    white_fm_std_hz2_per_hz: float
    flicker_fm_hz2: float
    flicker_fm_std_hz2: float
    random_walk_fm_hz2_per_s: float
    random_walk_fm_std_hz2_per_s: float
    lorentzian_linewidth_hz: float
    lorentzian_linewidth_std_hz: float
    linewidth_is_upper_limit: bool
    beta_linewidth_hz: float
    beta_linewidth_std_hz: float
    beta_observation_time_s: float
    beta_linewidth_is_lower_limit: bool
    beta_linewidth_is_upper_limit: bool
    drift_hz_per_s: float
    drift_std_hz_per_s: float
    taus_s: np.ndarray
    adev: np.ndarray
    adev_ci: np.ndarray
    mdev: np.ndarray
    mdev_ci: np.ndarray
    hdev: np.ndarray
    hdev_ci: np.ndarray
    n_averages: np.ndarray
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready: every field by name (arrays as lists, NaN as None), plus
        ``"format": "wavemeter-noise"`` and ``"version": 1``."""
        result = {"format": FORMAT, "version": FORMAT_VERSION}
        for item in dataclasses.fields(self):
            result[item.name] = _json_value(getattr(self, item.name))
        return result


def _json_value(value):
    if isinstance(value, np.ndarray):
        return _json_value(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_json_value(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value


# --- inputs ------------------------------------------------------------------------------


def _check_series(frequency_hz) -> np.ndarray:
    try:
        series = np.array(frequency_hz, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"frequency_hz must be numbers (Hz), got {type(frequency_hz).__name__}",
            parameter="frequency_hz",
        ) from exc
    if series.ndim != 1:
        raise InputError(
            f"frequency_hz must be a vector of readings (Hz), got shape {series.shape}",
            parameter="frequency_hz",
        )
    infinite = np.flatnonzero(np.isinf(series))
    if infinite.size:
        raise InputError(
            f"frequency_hz is infinite at reading {int(infinite[0])} (zero-based; "
            f"{infinite.size} in all); mark readings to exclude as NaN",
            parameter="frequency_hz",
        )
    finite = int(np.count_nonzero(np.isfinite(series)))
    if finite < MIN_READINGS:
        raise InputError(
            f"frequency_hz has {finite} finite readings (of {series.size}); a noise "
            f"analysis needs at least {MIN_READINGS}: record longer",
            parameter="frequency_hz",
        )
    return series


def _check_meter_std(meter_std_hz, series: np.ndarray, rate_hz: float) -> float | None:
    """The meter's floor ``2 mean(sigma^2) / rate`` (Hz^2/Hz) over the finite readings."""
    if meter_std_hz is None:
        return None
    try:
        sigma = np.array(meter_std_hz, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"meter_std_hz must be a number or one per reading (Hz), got "
            f"{type(meter_std_hz).__name__}",
            parameter="meter_std_hz",
        ) from exc
    if sigma.ndim == 0:
        sigma = np.full(series.size, float(sigma))
    if sigma.shape != series.shape:
        raise InputError(
            f"meter_std_hz must be one value or one per reading ({series.size}), got shape "
            f"{sigma.shape}",
            parameter="meter_std_hz",
        )
    used = sigma[np.isfinite(series)]
    if not np.all(np.isfinite(used) & (used >= 0)):
        raise InputError(
            "meter_std_hz must be finite and >= 0 (Hz) for every finite reading",
            parameter="meter_std_hz",
        )
    return float(2.0 * np.mean(used**2) / rate_hz)


def _optional_positive(name: str, value) -> float | None:
    return None if value is None else check_positive(name, value)


def _bridge(series: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop NaN at the ends, bridge inner runs of up to ``MAX_BRIDGED_RUN`` NaN linearly:
    the series and which of its readings were measured (not bridged)."""
    finite = np.isfinite(series)
    first, last = np.flatnonzero(finite)[[0, -1]]
    kept = series[first : last + 1].copy()
    measured = finite[first : last + 1]
    if measured.all():
        return kept, measured
    edges = np.diff(np.concatenate(([0], (~measured).astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(stops - starts))
    if stops[longest] - starts[longest] > MAX_BRIDGED_RUN:
        raise InputError(
            f"frequency_hz has a gap of {stops[longest] - starts[longest]} NaN readings "
            f"from reading {first + starts[longest]} (zero-based); at most "
            f"{MAX_BRIDGED_RUN} in a row are bridged: analyse the parts before and after "
            "the gap separately",
            parameter="frequency_hz",
        )
    positions = np.arange(kept.size)
    kept[~measured] = np.interp(positions[~measured], positions[measured], kept[measured])
    return kept, measured


def _check_fraction(name: str, value, *, upper: float | None = None) -> float:
    value = check_non_negative(name, value)
    if upper is not None and not 0 < value < upper:
        raise InputError(f"{name} must be in (0, {upper:g}), got {value!r}", parameter=name)
    return value


def _check_center(raw: np.ndarray) -> float:
    """The mean of the finite readings (Hz), which must be > 0 and not all equal."""
    finite = raw[np.isfinite(raw)]
    center_hz = float(np.mean(finite))
    if center_hz <= 0:
        raise InputError(
            f"frequency_hz must be absolute frequencies (Hz), mean > 0, got mean "
            f"{center_hz!r}: the fractional frequency is relative to it",
            parameter="frequency_hz",
        )
    if np.ptp(finite) == 0:
        raise InputError(
            f"frequency_hz is constant ({center_hz!r} Hz in every reading): there is no "
            "noise to analyse; check that the readings are frequencies, not a fill value",
            parameter="frequency_hz",
        )
    return center_hz


def _check_observation_time(value, duration_s: float) -> float | None:
    if value is None:
        return None
    value = check_positive("observation_time_s", value)
    if value > duration_s * (1 + 1e-9):
        raise InputError(
            f"observation_time_s {value!r} s is longer than the record ({duration_s:.6g} s): "
            "the PSD below 1 / T is not measured; give at most the record length, or record "
            "longer",
            parameter="observation_time_s",
        )
    return value


# --- findings ----------------------------------------------------------------------------


def _warning(cause: str, seen: str, remedy: str) -> CalibrationWarning:
    return CalibrationWarning(f"{seen}; {remedy}", cause=cause, remedy=remedy)


def _findings(
    result: FrequencyNoise,
    dropped: int,
    bridged: int,
    fit: PowerLawFit,
    beta: BetaLinewidth,
    low_hz: float,
) -> list[CalibrationWarning]:
    """The warnings a result calls for, each with its numbers and a remedy."""
    found = []
    series_size = round(result.duration_s * result.rate_hz)
    if dropped or bridged:
        found.append(
            _warning(
                "excluded_readings",
                f"{dropped + bridged} of {result.n_readings + result.n_excluded} readings are "
                f"NaN (excluded): {dropped} at the ends dropped, {bridged} inside bridged by "
                f"linear interpolation ({bridged / series_size:.2%} of the series analysed); "
                "a bridged reading carries no noise of its own, so the PSD's white level is "
                "low by up to about that fraction",
                "find why readings were excluded (flags, glitches, dropouts) and re-measure, "
                "or analyse an unbroken stretch",
            )
        )
    h0, h0_std = result.white_fm_hz2_per_hz, result.white_fm_std_hz2_per_hz
    floor = result.meter_floor_hz2_per_hz
    if floor is None:
        found.append(
            _warning(
                "floor_unknown",
                "the meter's own noise is unknown (no meter_std_hz): its white floor is not "
                "subtracted, so the white FM level and the Lorentzian linewidth, "
                f"< {result.lorentzian_linewidth_hz:.3g} Hz, are upper limits",
                "give each reading's frequency_std_hz (or their RMS) as meter_std_hz",
            )
        )
    elif result.linewidth_is_upper_limit:
        found.append(
            _warning(
                "below_floor",
                f"the laser's white FM level {h0:.3g} +- {h0_std:.3g} Hz^2/Hz is not above "
                f"both the meter's floor {floor:.3g} Hz^2/Hz and {UPPER_LIMIT_SIGMAS:g} "
                "standard deviations: the Lorentzian linewidth is an upper limit, "
                f"< {result.lorentzian_linewidth_hz:.3g} Hz",
                "lower the meter's noise (more optical power, a longer delay) or average "
                "more readings per sample, or measure with a quieter meter",
            )
        )
    if fit.misfit:
        found.append(
            _warning(
                "noise_model_misfit",
                f"the PSD departs from h0 + h_-1/f + h_-2/f^2 (chi-square {fit.chi2:.3g} for "
                f"{fit.dof} degrees of freedom, p < {MISFIT_P_VALUE:g}): the standard "
                f"deviations of the fit are scaled up by {np.sqrt(fit.chi2 / fit.dof):.3g}, "
                "and the levels may still be biased",
                "look at the PSD for peaks or bumps (servo, vibration, mains) or white phase "
                "noise, and analyse a record or band where the power law holds",
            )
        )
    start_hz = 1.0 / result.beta_observation_time_s
    if beta.extrapolated:
        found.append(
            _warning(
                "beta_extrapolated",
                f"the beta integral starts at 1 / T_obs = {start_hz:.3g} Hz, below the lowest "
                f"PSD band ({low_hz:.3g} Hz): the fitted power law stands in there, and its "
                "uncertainty dominates the beta linewidth's",
                f"give an observation time of at most {1 / low_hz:.3g} s (the default), or "
                "record longer",
            )
        )
    if beta.upper_limit:
        found.append(
            _warning(
                "beta_upper_limit",
                "the corrected PSD is not significantly above the beta separation line from "
                f"1 / T_obs = {start_hz:.3g} Hz up (the bands' noise alone gives an area as "
                f"large with probability {beta.p_value:.2g}): only excursions above the line "
                "count, so the area is biased up, and the beta linewidth is an upper limit, "
                f"< {result.beta_linewidth_hz:.3g} Hz",
                "record longer (more averages in the low bands, a longer T_obs), lower the "
                "meter's floor, or use the Lorentzian linewidth",
            )
        )
    elif beta.area_hz2 <= 0:
        found.append(
            _warning(
                "beta_below_line",
                "the laser's corrected PSD is below the beta separation line everywhere from "
                f"1 / T_obs = {start_hz:.3g} Hz up: its frequency noise is too fast or too weak "
                "to broaden the line within T_obs, and the beta linewidth is 0 within its "
                f"uncertainty ({result.beta_linewidth_std_hz:.3g} Hz)",
                "record longer (a longer T_obs reaches slower noise), or use the Lorentzian "
                "linewidth",
            )
        )
    elif beta.lower_limit:
        highest = result.psd_freqs_hz[np.isfinite(result.psd_corrected_hz2_per_hz)][-1]
        found.append(
            _warning(
                "beta_lower_limit",
                "the corrected PSD is still above the beta separation line at the highest "
                f"frequency analysed ({highest:.3g} Hz): the beta linewidth, > "
                f"{beta.fwhm_hz:.3g} Hz, is a lower limit",
                "sample faster so that the PSD reaches the line, or use a larger-FSR meter "
                "when the delay correction limit cuts the band",
            )
        )
    return found


# --- the analysis ------------------------------------------------------------------------


def frequency_noise(
    frequency_hz,
    rate_hz: float,
    *,
    meter_std_hz=None,
    fsr_hz: float | None = None,
    observation_time_s: float | None = None,
    meter_floor_rel_std: float = 0.05,
    scale_rel_std: float = 0.0,
    confidence: float = 0.683,
) -> FrequencyNoise:
    """PSD, linewidths, drift and Allan family of a laser from a meter's frequency readings.

    The method, its approximations and the meaning of each field are in the notes of this
    module and of those it names for each step, and in :class:`FrequencyNoise`.

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
        Readings (Hz), uniformly sampled and unwrapped, in time order; NaN marks a reading
        to exclude. At least ``MIN_READINGS`` finite.
    rate_hz : float
        Sample rate (Hz), > 0.
    meter_std_hz : None, float or array_like (N,)
        The meter's standard deviation (Hz) per reading (each reading's
        ``frequency_std_hz``), or one for all; >= 0. None: the meter's floor is unknown
        and not subtracted (the linewidth is then an upper limit).
    fsr_hz : float, optional
        The meter's FSR (Hz): the PSD is corrected for the delay ``1 / fsr_hz`` up to
        ``DELAY_CORRECTION_MAX_FSR * fsr_hz``. None: no correction.
    observation_time_s : float, optional
        Observation time of the beta-line linewidth (s): the integral starts at ``1 /
        observation_time_s``. At most the record length; above ``1 / (lowest band edge)``
        (a twelfth to a sixth of the record) the fitted power law stands in below the
        lowest band (with a warning). Default: ``1 / (lowest band edge)``, the longest the PSD
        measures.
    meter_floor_rel_std : float
        Relative standard deviation of the meter's floor (>= 0), added to ``h0``'s.
    scale_rel_std : float
        Relative standard deviation of the meter's frequency scale (>= 0): a calibrated
        interferometer's, ``delay_std_s_ / delay_s_``, scales every excursion from its
        phase origin, so ``|drift| * scale_rel_std`` adds to the drift's standard deviation
        (it matters for a drift over many FSRs; the noise levels change by ``2 *
        scale_rel_std`` relative, far inside their uncertainty).
    confidence : float
        Level of every confidence interval, in (0, 1).

    Returns
    -------
    FrequencyNoise

    Raises
    ------
    InputError
        Fewer than ``MIN_READINGS`` finite readings, an infinite reading, a run of more
        than ``MAX_BRIDGED_RUN`` NaN inside the record, a constant or non-positive series,
        a rate, FSR, observation time, floor uncertainty or confidence out of range, a
        ``meter_std_hz`` of the wrong shape or with a negative or non-finite value; each
        names its parameter.
    """
    raw = _check_series(frequency_hz)
    rate_hz = check_positive("rate_hz", rate_hz)
    floor = _check_meter_std(meter_std_hz, raw, rate_hz)
    fsr_hz = _optional_positive("fsr_hz", fsr_hz)
    floor_std = _check_fraction("meter_floor_rel_std", meter_floor_rel_std) * (floor or 0.0)
    scale_rel_std = _check_fraction("scale_rel_std", scale_rel_std)
    confidence = _check_fraction("confidence", confidence, upper=1.0)
    center_hz = _check_center(raw)
    series, measured = _bridge(raw)
    duration_s = series.size / rate_hz
    observation_time_s = _check_observation_time(observation_time_s, duration_s)

    spectrum = welch_bands(series - center_hz, rate_hz, fsr_hz)
    corrected, delay_band, limit_hz = delay_correction(spectrum, floor, fsr_hz)
    usable = np.isfinite(corrected)
    if usable.sum() < 4:
        raise InputError(
            f"fsr_hz {fsr_hz!r} Hz leaves {int(usable.sum())} PSD bands below its delay "
            f"correction limit ({DELAY_CORRECTION_MAX_FSR:g} FSR); the power-law fit needs "
            "4: check the FSR (Hz) and the rate",
            parameter="fsr_hz",
        )
    if observation_time_s is None:
        observation_time_s = 1.0 / spectrum.edges_hz[0]
    elif 1.0 / observation_time_s >= spectrum.edges_hz[np.flatnonzero(usable)[-1] + 1]:
        raise InputError(
            f"observation_time_s {observation_time_s!r} s is too short: 1 / T_obs lies above "
            "the highest frequency analysed; give a longer observation time",
            parameter="observation_time_s",
        )
    fit = fit_power_law(spectrum, usable, floor, floor_std)
    stds = np.sqrt(np.diag(fit.covariance))
    h0, h0_std = float(fit.levels[0]), float(stds[0])
    linewidth, upper = lorentzian_linewidth(h0, h0_std, floor)
    beta = beta_linewidth(spectrum, corrected, delay_band, fit, floor_std, observation_time_s)
    reading_levels = fit.levels + np.array([floor or 0.0, 0.0, 0.0])
    drift, drift_std = fit_drift(series, measured, rate_hz, reading_levels)
    drift_std = float(np.hypot(drift_std, abs(drift) * scale_rel_std))
    allan = allan_family(series, center_hz, rate_hz, reading_levels, drift, confidence)
    n_readings = int(np.count_nonzero(np.isfinite(raw)))
    result = FrequencyNoise(
        rate_hz=rate_hz,
        n_readings=n_readings,
        n_excluded=raw.size - n_readings,
        duration_s=duration_s,
        center_frequency_hz=center_hz,
        confidence=confidence,
        psd_freqs_hz=spectrum.freqs_hz,
        psd_hz2_per_hz=spectrum.psd,
        psd_ci_hz2_per_hz=psd_interval(spectrum, confidence),
        meter_floor_hz2_per_hz=floor,
        psd_corrected_hz2_per_hz=corrected,
        phase_psd_rad2_per_hz=corrected / spectrum.freqs_hz**2,
        delay_correction_max_hz=limit_hz,
        white_fm_hz2_per_hz=h0,
        white_fm_std_hz2_per_hz=h0_std,
        flicker_fm_hz2=float(fit.levels[1]),
        flicker_fm_std_hz2=float(stds[1]),
        random_walk_fm_hz2_per_s=float(fit.levels[2]),
        random_walk_fm_std_hz2_per_s=float(stds[2]),
        lorentzian_linewidth_hz=linewidth,
        lorentzian_linewidth_std_hz=float(np.pi * h0_std),
        linewidth_is_upper_limit=upper,
        beta_linewidth_hz=beta.fwhm_hz,
        beta_linewidth_std_hz=beta.std_hz,
        beta_observation_time_s=float(observation_time_s),
        beta_linewidth_is_lower_limit=beta.lower_limit,
        beta_linewidth_is_upper_limit=beta.upper_limit,
        drift_hz_per_s=drift,
        drift_std_hz_per_s=drift_std,
        **allan,
    )
    found = _findings(
        result,
        dropped=raw.size - series.size,
        bridged=int(np.count_nonzero(~measured)),
        fit=fit,
        beta=beta,
        low_hz=float(spectrum.edges_hz[0]),
    )
    for warning in found:
        warnings.warn(warning, stacklevel=2)
    return dataclasses.replace(result, warnings=tuple(str(warning) for warning in found))
