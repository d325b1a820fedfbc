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

Steps of :func:`frequency_noise`:

- NaN readings are excluded: those at the ends are dropped, runs of up to
  ``MAX_BRIDGED_RUN`` inside are bridged by linear interpolation (a longer gap is an
  error: analyse the parts on either side), counted and warned about.
- PSD: ``scipy.signal.welch`` (Hann window, 50 % overlap, linear detrend per segment,
  one-sided density) with segments of the largest power of two <= ``N / 8`` samples (at
  least ``MIN_SEGMENT``), so it reaches down to 16 to 32 over the record length ``T``.
  The bins from the second (``FIRST_BIN``; the first is halved by the detrend) to below
  Nyquist are averaged in ``BANDS_PER_DECADE`` log-spaced bands, so high frequencies have
  many degrees of freedom. A band's equivalent degrees of freedom ``nu = 2 / v`` come
  from the window: ``v`` is the variance of the band mean relative to its square for a
  spectrum locally white over the band, ``sum_d sum_Delta (K - |d|) (M - |Delta|) |C(d s,
  Delta)|^2 / (K M)^2`` over segment offsets ``d`` (step ``s``) and bin offsets ``Delta``
  of the ``K`` segments and ``M`` bins, ``C`` the window's normalised overlap spectrum
  (Welch 1967; the detrend's two lost degrees of freedom per segment are neglected). Bins
  more than ``BIN_SPREAD`` apart are uncorrelated, so only neighbouring bands correlate.
  The confidence interval at ``confidence`` is chi-square with ``nu`` degrees of freedom.
- Delay: the interferometer's delay ``tau_d = 1 / FSR`` averages the frequency over
  ``tau_d``, ``|H(f)|^2 = sinc^2(f / FSR)``. The corrected PSD is ``(PSD - floor) /
  sinc^2(f / FSR)`` up to ``DELAY_CORRECTION_MAX_FSR`` of the FSR (where ``|H|^2 >=
  0.81``) and NaN above, excluded from the fits. The detectors' bandwidth and any
  anti-aliasing filter are not corrected: the readings are taken as sample-interval means.
- Power law: generalised least squares of the band PSD (the bands' correlation included)
  on the exact expectation of the Welch estimate of each term passed through the delay's
  ``sinc^2`` (the window's leakage and the detrend included:
  :func:`~wavemeter.analysis.power_law.welch_expectation`), the floor's expectation
  subtracted, with variances ``2 E^2 / nu`` from the model, iterated ``FIT_ITERATIONS``
  times (the first from the data). The covariance gives the standard deviations, and the
  floor's uncertainty (``meter_floor_rel_std`` times it) adds to ``h0``'s variance. A fit
  that the chi-square test rejects (p < ``MISFIT_P_VALUE``) has its standard deviations
  scaled by ``sqrt(chi2 / dof)`` and is warned about.
- Lorentzian linewidth ``pi h0``. It is an upper limit when the floor is unknown (not
  subtracted) or ``h0`` is not above both the floor and ``UPPER_LIMIT_SIGMAS`` standard
  deviations (the laser is at or below the meter's floor, or not significant); the
  field then holds ``pi (max(h0, 0) + 2 std)``.
- Beta-separation linewidth (Di Domenico, Schilt, Thomann, Appl. Opt. 49, 4801 (2010)):
  ``A`` = the integral from ``1 / T_obs`` of the corrected PSD where it lies above ``8 ln2
  f / pi^2``, FWHM ``sqrt(8 ln2 A)``. On the bands the PSD is taken constant over each band
  (so a white level's crossing is exact). ``T_obs`` defaults to the inverse of the lowest
  band's lower edge (``1.5`` Welch bins, a twelfth to a sixth of the record), the longest
  time the PSD measures; a longer ``T_obs`` (up to the record) integrates the fitted power
  law below the lowest band, linearly (unbiased; the line is negligible there), and warns:
  extrapolating ``h_-2 / f^2`` down an octave or more dominates the uncertainty (a 100 kHz
  white-FM laser, 2^16 readings at 10 MHz, 40 seeds: 11 % scatter at ``T_obs = T``, 6 %
  at the default). The area is not smooth in the bands where the PSD meets the line (a
  band enters or leaves), so its standard deviation is the spread of the FWHM over
  ``BETA_DRAWS`` draws of the bands (normal, with their chi-square spread and correlation,
  from a fixed seed: reproducible), with the floor's uncertainty and the fit's (below the
  lowest band) added. When the PSD is still above the line at the highest corrected band,
  the value is a lower limit; when it is nowhere above the line, the FWHM is 0.
- Drift: least-squares slope of the measured (not bridged) readings against time; its
  standard deviation is the fitted noise (floor included) propagated through the slope's
  transfer function (:func:`~wavemeter.analysis.power_law.slope_variance`), not the
  white-noise formula, which flicker and random walk would make far too small.
- Allan family of the fractional frequency ``(nu - nu0) / nu0``, ``nu0`` the mean reading,
  bridged readings included: ``allantools.oadev``, ``mdev`` and ``ohdev`` (the overlapping
  Hadamard deviation; same expectation as ``hdev``, tighter) at octave averaging times
  ``tau = 2^j / rate`` with at least ``MIN_AVERAGES`` record lengths ``T / tau``;
  confidence intervals from Greenhall's equivalent degrees of freedom
  (``allantools.edf_greenhall``, ``confidence_interval``) for the noise type the fitted
  model says dominates at each ``tau``.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from ..exceptions import CalibrationWarning, InputError
from ..validation import check_non_negative, check_positive
from .power_law import deviation_variances, slope_variance, welch_expectation

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
#: Welch segments: the largest power of two <= N / SEGMENT_DIVISOR, and >= MIN_SEGMENT
SEGMENT_DIVISOR = 8
MIN_SEGMENT = 32
#: first Welch bin used (the first is halved by the per-segment linear detrend)
FIRST_BIN = 2
#: log-spaced PSD bands per decade of frequency
BANDS_PER_DECADE = 20
#: Welch bins further apart than this are uncorrelated (Hann: |C|^2 < 1e-6 beyond)
BIN_SPREAD = 8
#: the PSD is corrected for the delay's sinc^2 up to this fraction of the FSR
DELAY_CORRECTION_MAX_FSR = 0.25
#: fewest record lengths T / tau at an averaging time of the Allan family
MIN_AVERAGES = 10
#: a linewidth's upper limit is pi (max(h0, 0) + UPPER_LIMIT_SIGMAS std)
UPPER_LIMIT_SIGMAS = 2.0
#: reweighting rounds of the power-law fit
FIT_ITERATIONS = 3
#: a power-law fit whose chi-square has a smaller p-value is a misfit
MISFIT_P_VALUE = 1e-3
#: slope of the beta separation line, 8 ln2 / pi^2 (Hz^2/Hz per Hz)
BETA_SLOPE = 8.0 * np.log(2.0) / np.pi**2
#: draws of the PSD bands for the beta linewidth's standard deviation, and their seed
BETA_DRAWS = 400
BETA_SEED = 14
#: ``to_dict`` format name and version
FORMAT = "wavemeter-noise"
FORMAT_VERSION = 1
#: Allan-family noise types (allantools' alpha) of white, flicker, random-walk FM, drift
_ALPHAS = (0, -1, -2, -2)
#: cause of each warning -> what it means
WARNING_CAUSES = {
    "excluded_readings": "NaN readings were dropped at the ends or bridged inside",
    "floor_unknown": "the meter's noise is unknown: its floor is not subtracted",
    "below_floor": "the laser's white FM is not significantly above the meter's floor",
    "beta_lower_limit": "the PSD is above the beta line up to the highest frequency",
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
        Beta-separation-line FWHM (Hz) and its standard deviation.
    beta_observation_time_s : float
        Observation time ``T_obs`` it is for (s): the integral starts at ``1 / T_obs``.
        The one given, else the longest the PSD measures (``1 /`` the lowest band's lower
        edge, a twelfth to a sixth of the record).
    beta_linewidth_is_lower_limit : bool
        The PSD is above the line up to the highest corrected frequency.
    drift_hz_per_s, drift_std_hz_per_s : float
        Least-squares drift (Hz/s) and its standard deviation under the fitted noise.
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


def beta_separation_line_hz2_per_hz(freqs_hz) -> np.ndarray:
    """The beta separation line ``8 ln2 f / pi^2`` (Hz^2/Hz) at ``freqs_hz`` (Hz)."""
    return BETA_SLOPE * np.asarray(freqs_hz, dtype=float)


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


# --- PSD ---------------------------------------------------------------------------------


def _segment_length(samples: int) -> int:
    longest = max(samples // SEGMENT_DIVISOR, 1)
    return max(1 << (longest.bit_length() - 1), MIN_SEGMENT)


def _band_covariance(
    window: np.ndarray, step: int, segments: int, first_bins: np.ndarray, widths: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Equivalent degrees of freedom (K,) and correlation matrix (K, K) of the band means
    of a locally white spectrum (see the module's notes)."""
    length = window.size
    norm = np.sum(window**2)
    # kernel(Delta) = sum over segment pairs of |C(d s, Delta)|^2, Delta = 0..BIN_SPREAD
    kernel = np.zeros(BIN_SPREAD + 1)
    for d, shift in enumerate(range(0, min(length, segments * step), step)):
        pairs = segments if d == 0 else 2 * (segments - d)
        overlap = np.fft.fft(window[: length - shift] * window[shift:], length)
        kernel += pairs * np.abs(overlap[: BIN_SPREAD + 1]) ** 2 / norm**2
    bands = widths.size
    covariance = np.zeros((bands, bands))
    ends = first_bins + widths
    for a in range(bands):
        offsets = np.arange(-min(widths[a] - 1, BIN_SPREAD), min(widths[a], BIN_SPREAD + 1))
        covariance[a, a] = (widths[a] - np.abs(offsets)) @ kernel[np.abs(offsets)]
        for b in range(a + 1, bands):
            if first_bins[b] - (ends[a] - 1) > BIN_SPREAD:
                break
            offsets = np.arange(first_bins[b] - ends[a] + 1, BIN_SPREAD + 1)
            counts = np.minimum(ends[a], ends[b] - offsets) - np.maximum(
                first_bins[a], first_bins[b] - offsets
            )
            covariance[a, b] = covariance[b, a] = np.clip(counts, 0, None) @ kernel[offsets]
    scale = np.sqrt(np.diag(covariance))
    dof = 2.0 * (segments * widths) ** 2 / np.diag(covariance)
    return dof, covariance / np.outer(scale, scale)


@dataclass(frozen=True)
class _Spectrum:
    freqs_hz: np.ndarray  # band mean frequency (K,)
    psd: np.ndarray  # band mean Welch PSD (K,)
    dof: np.ndarray  # (K,)
    correlation: np.ndarray  # of the band means (K, K)
    design: np.ndarray  # expected band PSD of each term at unit level, delay applied (K, 3)
    floor_gain: np.ndarray  # expected band PSD of unit white meter noise (K,)
    edges_hz: np.ndarray  # band edges (K + 1,)


def _spectrum(series: np.ndarray, rate_hz: float, fsr_hz: float | None) -> _Spectrum:
    from scipy.signal import get_window, welch

    length = _segment_length(series.size)
    step = length // 2
    window = get_window("hann", length)
    bin_freqs, psd = welch(
        series, fs=rate_hz, window=window, noverlap=length - step, detrend="linear"
    )
    segments = (series.size - length) // step + 1
    expected = welch_expectation(window, rate_hz)
    bins = np.arange(FIRST_BIN, length // 2)
    band_of_bin = np.floor(BANDS_PER_DECADE * np.log10(bins / FIRST_BIN) + 1e-9).astype(int)
    starts = np.flatnonzero(np.diff(np.concatenate(([-1], band_of_bin))))
    widths = np.diff(np.concatenate((starts, [bins.size])))
    delay = np.ones_like(bin_freqs) if fsr_hz is None else np.sinc(bin_freqs / fsr_hz) ** 2

    def band_mean(values: np.ndarray) -> np.ndarray:
        return np.add.reduceat(values[..., bins], starts, axis=-1) / widths

    resolution = rate_hz / length
    first_bins = bins[starts]
    edges = np.concatenate((first_bins, [bins[-1] + 1])) - 0.5
    dof, correlation = _band_covariance(window, step, segments, first_bins, widths)
    return _Spectrum(
        freqs_hz=band_mean(bin_freqs),
        psd=band_mean(psd),
        dof=dof,
        correlation=correlation,
        design=band_mean(expected * delay).T,
        floor_gain=band_mean(expected[0]),
        edges_hz=edges * resolution,
    )


# --- power-law fit, linewidths, drift ---------------------------------------------------


@dataclass(frozen=True)
class _Fit:
    levels: np.ndarray  # h0, h_-1, h_-2 of the laser (3,)
    covariance: np.ndarray  # (3, 3), floor uncertainty and misfit scaling included
    chi2: float
    dof: int
    misfit: bool


def _fit_power_law(
    spectrum: _Spectrum, usable: np.ndarray, floor: float | None, floor_std: float
) -> _Fit:
    from scipy.stats import chi2 as chi_square

    design = spectrum.design[usable]
    offset = (floor or 0.0) * spectrum.floor_gain[usable]
    measured = spectrum.psd[usable]
    target = measured - offset
    spread = np.sqrt(2.0 / spectrum.dof[usable])
    # generalised least squares: whiten with the Cholesky factor of the band correlation
    factor = np.linalg.cholesky(spectrum.correlation[np.ix_(usable, usable)])
    expected = measured
    for _ in range(FIT_ITERATIONS):
        sigma = expected * spread
        weighted = np.linalg.solve(factor, design / sigma[:, None])
        scale = np.linalg.norm(weighted, axis=0)
        scale[scale == 0] = 1.0
        whitened = np.linalg.solve(factor, target / sigma)
        solution = np.linalg.lstsq(weighted / scale, whitened, rcond=None)[0]
        levels = solution / scale
        model = design @ levels + offset
        expected = np.where(model > 0, model, measured)
    normal = (weighted / scale).T @ (weighted / scale)
    covariance = np.linalg.pinv(normal) / np.outer(scale, scale)
    chi2 = float(np.sum((whitened - weighted @ (levels)) ** 2))
    dof = int(usable.sum()) - 3
    misfit = bool(chi_square.sf(chi2, dof) < MISFIT_P_VALUE)
    if misfit:
        covariance = covariance * (chi2 / dof)
    covariance[0, 0] += floor_std**2
    return _Fit(levels, covariance, chi2, dof, misfit)


@dataclass(frozen=True)
class _Beta:
    fwhm_hz: float
    std_hz: float
    lower_limit: bool
    area_hz2: float
    extrapolated: bool  # the integral starts below the lowest band


def _beta_area(level: np.ndarray, low: np.ndarray, high: np.ndarray, start_hz: float):
    """Area (Hz^2) above the beta line of band levels (..., K) constant over each band."""
    crossing_hz = np.where(level > 0, level / BETA_SLOPE, 0.0)  # the level meets the line
    length = np.clip(np.minimum(high, crossing_hz) - np.maximum(low, start_hz), 0.0, None)
    return np.sum(level * length, axis=-1)


def _beta_linewidth(
    spectrum: _Spectrum,
    corrected: np.ndarray,
    corrected_std: np.ndarray,
    delay_band: np.ndarray,
    fit: _Fit,
    floor_std: float,
    observation_time_s: float,
) -> _Beta:
    """Beta-separation-line FWHM from ``1 / T_obs`` (see the module's notes)."""
    valid = np.flatnonzero(np.isfinite(corrected))
    start_hz = 1.0 / observation_time_s
    low, high = spectrum.edges_hz[valid], spectrum.edges_hz[valid + 1]
    level = corrected[valid]
    area = float(_beta_area(level, low, high, start_hz))
    # the floor's and the extrapolation's uncertainties are linear in the area
    included = np.clip(np.minimum(high, level / BETA_SLOPE) - np.maximum(low, start_hz), 0, None)
    variance = (floor_std * np.sum(included / delay_band[valid])) ** 2
    extrapolated = bool(start_hz < low[0])
    if extrapolated:  # the fitted power law, integrated from 1 / T_obs to the lowest band
        gradient = np.array(
            [low[0] - start_hz, np.log(low[0] / start_hz), 1.0 / start_hz - 1.0 / low[0]]
        )
        area += float(fit.levels @ gradient)
        variance += float(gradient @ fit.covariance @ gradient)
    # the bands' spread: the area is not smooth in them where the PSD meets the line, so
    # draw them (correlated normal, seeded: the result is reproducible) and take the spread
    rng = np.random.default_rng(BETA_SEED)
    factor = np.linalg.cholesky(spectrum.correlation[np.ix_(valid, valid)])
    draws = level + corrected_std[valid] * (
        rng.standard_normal((BETA_DRAWS, valid.size)) @ factor.T
    )
    areas = _beta_area(draws, low, high, start_hz) - _beta_area(level, low, high, start_hz)
    areas += area + np.sqrt(variance) * rng.standard_normal(BETA_DRAWS)
    fwhm = np.sqrt(8.0 * np.log(2.0) * max(area, 0.0))
    std = float(np.std(np.sqrt(8.0 * np.log(2.0) * np.clip(areas, 0.0, None))))
    last = valid[-1]
    lower_limit = bool(corrected[last] > BETA_SLOPE * spectrum.freqs_hz[last])
    return _Beta(float(fwhm), std, lower_limit, area, extrapolated)


def _drift(series: np.ndarray, measured: np.ndarray, rate_hz: float) -> float:
    """Least-squares slope (Hz/s) of the measured (not bridged) readings against time."""
    times = np.flatnonzero(measured) / rate_hz
    values = series[measured]
    centred = times - times.mean()
    return float(centred @ (values - values.mean()) / (centred @ centred))


# --- Allan family ------------------------------------------------------------------------


def _allan_family(
    series: np.ndarray,
    center_hz: float,
    rate_hz: float,
    levels: np.ndarray,
    drift_hz_per_s: float,
    confidence: float,
) -> dict[str, np.ndarray]:
    import allantools

    fractional = (series - center_hz) / center_hz
    samples = fractional.size
    factors = 2 ** np.arange(int(np.log2(samples // MIN_AVERAGES)) + 1)
    taus = factors / rate_hz
    # the noise type that dominates each variance at each tau sets its degrees of freedom
    dominant = deviation_variances(taus, np.maximum(levels, 0.0), drift_hz_per_s, None)
    result = {"taus_s": taus, "n_averages": samples // factors}
    statistics = (
        ("adev", allantools.oadev, 2, False),
        ("mdev", allantools.mdev, 2, True),
        ("hdev", allantools.ohdev, 3, False),
    )
    for name, statistic, order, modified in statistics:
        _, deviation, _, _ = statistic(fractional, rate=rate_hz, data_type="freq", taus=taus)
        alphas = np.array(_ALPHAS)[np.argmax(dominant[name], axis=0)]
        interval = [
            allantools.confidence_interval(
                value,
                allantools.edf_greenhall(
                    alpha=int(alpha),
                    d=order,
                    m=int(m),
                    N=samples + 1,
                    overlapping=True,
                    modified=modified,
                ),
                ci=confidence,
            )
            for value, alpha, m in zip(deviation, alphas, factors, strict=True)
        ]
        result[name] = np.asarray(deviation, dtype=float)
        result[f"{name}_ci"] = np.array(interval, dtype=float).T
    return result


# --- the analysis ------------------------------------------------------------------------


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


def _warning(cause: str, seen: str, remedy: str) -> CalibrationWarning:
    return CalibrationWarning(f"{seen}; {remedy}", cause=cause, remedy=remedy)


def _findings(
    result: FrequencyNoise, dropped: int, bridged: int, fit: _Fit, beta: _Beta, low_hz: float
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
    if beta.area_hz2 <= 0:
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


def frequency_noise(
    frequency_hz,
    rate_hz: float,
    *,
    meter_std_hz=None,
    fsr_hz: float | None = None,
    observation_time_s: float | None = None,
    meter_floor_rel_std: float = 0.05,
    confidence: float = 0.683,
) -> FrequencyNoise:
    """PSD, linewidths, drift and Allan family of a laser from a meter's frequency readings.

    The method, its approximations and the meaning of each field are in the module's
    notes and :class:`FrequencyNoise`.

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
    confidence = _check_fraction("confidence", confidence, upper=1.0)
    center_hz = _check_center(raw)
    series, measured = _bridge(raw)
    duration_s = series.size / rate_hz
    observation_time_s = _check_observation_time(observation_time_s, duration_s)

    spectrum = _spectrum(series - center_hz, rate_hz, fsr_hz)
    if fsr_hz is None:
        delay_band, limit_hz = np.ones_like(spectrum.freqs_hz), None
    else:
        delay_band = np.sinc(spectrum.freqs_hz / fsr_hz) ** 2
        limit_hz = DELAY_CORRECTION_MAX_FSR * fsr_hz
    corrected = (spectrum.psd - (floor or 0.0)) / delay_band
    if limit_hz is not None:
        corrected[spectrum.freqs_hz > limit_hz] = np.nan
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
    from scipy.stats import chi2 as chi_square

    tail = (1.0 - confidence) / 2.0
    psd_ci = spectrum.dof * spectrum.psd / chi_square.ppf([[1.0 - tail], [tail]], spectrum.dof)

    fit = _fit_power_law(spectrum, usable, floor, floor_std)
    stds = np.sqrt(np.diag(fit.covariance))
    h0, h0_std = float(fit.levels[0]), float(stds[0])
    upper = floor is None or not h0 > max(floor, UPPER_LIMIT_SIGMAS * h0_std)
    linewidth = np.pi * (max(h0, 0.0) + UPPER_LIMIT_SIGMAS * h0_std) if upper else np.pi * h0
    corrected_std = spectrum.psd * np.sqrt(2.0 / spectrum.dof) / delay_band
    beta = _beta_linewidth(
        spectrum, corrected, corrected_std, delay_band, fit, floor_std, observation_time_s
    )
    drift = _drift(series, measured, rate_hz)
    reading_levels = fit.levels + np.array([floor or 0.0, 0.0, 0.0])
    drift_std = np.sqrt(slope_variance(series.size, rate_hz, reading_levels))
    allan = _allan_family(series, center_hz, rate_hz, reading_levels, drift, confidence)
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
        psd_ci_hz2_per_hz=psd_ci,
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
        lorentzian_linewidth_hz=float(linewidth),
        lorentzian_linewidth_std_hz=float(np.pi * h0_std),
        linewidth_is_upper_limit=bool(upper),
        beta_linewidth_hz=beta.fwhm_hz,
        beta_linewidth_std_hz=beta.std_hz,
        beta_observation_time_s=float(observation_time_s),
        beta_linewidth_is_lower_limit=beta.lower_limit,
        drift_hz_per_s=drift,
        drift_std_hz_per_s=float(drift_std),
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
