"""What the band PSD and the readings say about the laser: the power-law levels, the
Lorentzian and beta-separation linewidths, and the drift, each with its uncertainty.

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .noise_spectrum import Spectrum
from .power_law import slope_variance

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


def beta_separation_line_hz2_per_hz(freqs_hz) -> np.ndarray:
    """The beta separation line ``8 ln2 f / pi^2`` (Hz^2/Hz) at ``freqs_hz`` (Hz)."""
    return BETA_SLOPE * np.asarray(freqs_hz, dtype=float)


# --- power law, Lorentzian linewidth -----------------------------------------------------


@dataclass(frozen=True)
class PowerLawFit:
    """The laser's levels fitted to the band PSD, with their covariance and chi-square."""

    levels: np.ndarray  # h0, h_-1, h_-2 of the laser (3,)
    covariance: np.ndarray  # (3, 3), floor uncertainty and misfit scaling included
    chi2: float
    dof: int
    misfit: bool


def fit_power_law(
    spectrum: Spectrum, usable: np.ndarray, floor: float | None, floor_std: float
) -> PowerLawFit:
    """Fit ``h0, h_-1, h_-2`` to the ``usable`` bands (K,) of ``spectrum`` less the meter's
    ``floor`` (Hz^2/Hz; none when None) of standard deviation ``floor_std``."""
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
    return PowerLawFit(levels, covariance, chi2, dof, misfit)


def lorentzian_linewidth(h0: float, h0_std: float, floor: float | None) -> tuple[float, bool]:
    """The Lorentzian linewidth (Hz) of white FM ``h0`` +- ``h0_std`` (Hz^2/Hz) above the
    meter's ``floor`` (Hz^2/Hz; None: unknown), and whether it is an upper limit."""
    upper = floor is None or not h0 > max(floor, UPPER_LIMIT_SIGMAS * h0_std)
    linewidth = np.pi * (max(h0, 0.0) + UPPER_LIMIT_SIGMAS * h0_std) if upper else np.pi * h0
    return float(linewidth), bool(upper)


# --- beta linewidth ----------------------------------------------------------------------


@dataclass(frozen=True)
class BetaLinewidth:
    """The beta-separation-line FWHM, its standard deviation and how to read it."""

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


def beta_linewidth(
    spectrum: Spectrum,
    corrected: np.ndarray,
    delay_band: np.ndarray,
    fit: PowerLawFit,
    floor_std: float,
    observation_time_s: float,
) -> BetaLinewidth:
    """Beta-separation-line FWHM from ``1 / T_obs`` of the ``corrected`` band PSD (K,)
    (see the module's notes)."""
    corrected_std = spectrum.psd * np.sqrt(2.0 / spectrum.dof) / delay_band
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
    return BetaLinewidth(float(fwhm), std, lower_limit, area, extrapolated)


# --- drift -------------------------------------------------------------------------------


def fit_drift(
    series: np.ndarray, measured: np.ndarray, rate_hz: float, reading_levels: np.ndarray
) -> tuple[float, float]:
    """Least-squares slope (Hz/s) of the ``measured`` (not bridged) readings of ``series``
    (N,) against time, and its standard deviation (Hz/s) under the power-law noise of the
    readings ``reading_levels`` (3,) (the laser's with the meter's floor)."""
    times = np.flatnonzero(measured) / rate_hz
    values = series[measured]
    centred = times - times.mean()
    drift = float(centred @ (values - values.mean()) / (centred @ centred))
    return drift, float(np.sqrt(slope_variance(series.size, rate_hz, reading_levels)))
