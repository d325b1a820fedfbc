"""Frequency-noise metrology of a laser from a meter's readings: PSD, linewidths, drift and
the Allan family, each with its uncertainty, and the meter's own noise floor removed.

:func:`frequency_noise` takes uniformly sampled, unwrapped readings (a single
interferometer reads modulo its FSR: unwrap first, as
:func:`wavemeter.jobs.noise.measure_series` does) with their standard deviations, and
returns a :class:`~wavemeter.analysis.noise_result.FrequencyNoise`. Its steps, each in a
module of its own: NaN readings dropped or bridged (:mod:`wavemeter.analysis.noise_inputs`),
the band-averaged Welch PSD with the floor subtracted and the delay corrected
(:mod:`wavemeter.analysis.noise_spectrum`), the power-law fit, linewidths and drift
(:mod:`wavemeter.analysis.noise_fit`), the Allan family (:mod:`wavemeter.analysis.allan`)
and the findings, each a :class:`~wavemeter.exceptions.CalibrationWarning` with a remedy
(:mod:`wavemeter.analysis.noise_findings`).

Theory (the model and the steps): the docs' noise page (``docs/theory/noise.rst``); what
the warnings mean: the user guide's noise page.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ..exceptions import InputError, shown
from ..validation import check_positive
from .allan import MIN_AVERAGES, allan_family
from .noise_findings import findings
from .noise_fit import (
    beta_linewidth,
    beta_separation_line_hz2_per_hz,
    fit_drift,
    fit_power_law,
    lorentzian_linewidth,
)
from .noise_inputs import (
    bridge,
    check_center,
    check_fraction,
    check_meter_std,
    check_observation_time,
    check_series,
    optional_positive,
)
from .noise_result import FrequencyNoise
from .noise_spectrum import DELAY_CORRECTION_MAX_FSR, delay_correction, psd_interval, welch_bands

__all__ = [
    "frequency_noise",
    "beta_separation_line_hz2_per_hz",
    "DELAY_CORRECTION_MAX_FSR",
    "MIN_AVERAGES",
]


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

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from wavemeter.analysis import frequency_noise
    >>> from wavemeter.simulation import laser_frequency_hz
    >>> rate_hz, h0 = 10e6, 3e4  # 10 MHz readings of a laser of white FM 3e4 Hz^2/Hz
    >>> f_hz = laser_frequency_hz(16384, rate_hz, center_hz=193.4e12, white_fm_hz2_per_hz=h0, rng=1)
    >>> with warnings.catch_warnings(record=True) as caught:  # no meter noise: no floor removed
    ...     warnings.simplefilter("always")
    ...     noise = frequency_noise(f_hz, rate_hz)

    White FM of 3e4 Hz^2/Hz is a Lorentzian linewidth of pi h0 = 94 kHz:

    >>> print(f"h0 {noise.white_fm_hz2_per_hz:.2e} +- {noise.white_fm_std_hz2_per_hz:.0e} Hz^2/Hz")
    h0 2.95e+04 +- 4e+02 Hz^2/Hz
    >>> [w.message.cause for w in caught]  # the linewidth is then an upper limit
    ['floor_unknown', 'beta_upper_limit']
    >>> print(f"Lorentzian {noise.lorentzian_linewidth_hz / 1e3:.0f} kHz")
    Lorentzian 95 kHz
    """
    raw = check_series(frequency_hz)
    rate_hz = check_positive("rate_hz", rate_hz)
    floor = check_meter_std(meter_std_hz, raw, rate_hz)
    fsr_hz = optional_positive("fsr_hz", fsr_hz)
    floor_std = check_fraction("meter_floor_rel_std", meter_floor_rel_std) * (floor or 0.0)
    scale_rel_std = check_fraction("scale_rel_std", scale_rel_std)
    confidence = check_fraction("confidence", confidence, upper=1.0)
    center_hz = check_center(raw)
    series, measured = bridge(raw)
    duration_s = series.size / rate_hz
    observation_time_s = check_observation_time(observation_time_s, duration_s)

    spectrum = welch_bands(series - center_hz, rate_hz, fsr_hz)
    corrected, delay_band, limit_hz = delay_correction(spectrum, floor, fsr_hz)
    usable = np.isfinite(corrected)
    if usable.sum() < 4:
        raise InputError(
            f"fsr_hz {shown(fsr_hz)} Hz leaves {int(usable.sum())} PSD bands below its delay "
            f"correction limit ({DELAY_CORRECTION_MAX_FSR:g} FSR); the power-law fit needs "
            "4: check the FSR (Hz) and the rate",
            parameter="fsr_hz",
        )
    if observation_time_s is None:
        observation_time_s = 1.0 / spectrum.edges_hz[0]
    elif 1.0 / observation_time_s >= spectrum.edges_hz[np.flatnonzero(usable)[-1] + 1]:
        raise InputError(
            f"observation_time_s {shown(observation_time_s)} s is too short: 1 / T_obs lies above "
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
    found = findings(
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
