"""What the band PSD and the readings say about the laser: the power-law levels, the
Lorentzian and beta-separation linewidths, and the drift, each with its uncertainty.

- :func:`fit_power_law`: generalised least squares of the band PSD on the expected Welch
  estimate of each term (:func:`~wavemeter.analysis.power_law.welch_expectation`), the
  meter's floor subtracted; a fit the chi-square test rejects (p < ``MISFIT_P_VALUE``) has
  its standard deviations scaled and is warned about.
- :func:`lorentzian_linewidth`: ``pi h0``, or its upper limit where ``h0`` is not
  ``UPPER_LIMIT_SIGMAS`` standard deviations above the floor.
- :func:`beta_linewidth`: the beta-separation linewidth (Di Domenico, Schilt, Thomann,
  Appl. Opt. 49, 4801 (2010)) from ``1 / T_obs``, its spread over ``BETA_DRAWS`` draws of
  the bands; an upper limit unless the area above the line passes a test against noise at
  ``BETA_P_VALUE``, a lower limit when the PSD is above the line at the highest band.
- :func:`fit_drift`: the least-squares slope of the measured readings against time, its
  standard deviation through the slope's transfer function
  (:func:`~wavemeter.analysis.power_law.slope_variance`).

Theory (the fit, the limits, and the simulations behind the thresholds): the docs' noise
page (``docs/theory/noise.rst``, "The power-law fit and the linewidths").
"""

from __future__ import annotations

import math
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
BETA_DRAWS = 2000
BETA_SEED = 14
#: the beta area is significant, and the FWHM a number, when noise alone makes one at
#: least as large with at most this probability (a normal's one-sided 3 sigma)
BETA_P_VALUE = 0.5 * math.erfc(3.0 / math.sqrt(2.0))
#: else the FWHM's upper limit is this quantile of its draws (one-sided UPPER_LIMIT_SIGMAS)
BETA_UPPER_QUANTILE = 0.5 * math.erfc(-UPPER_LIMIT_SIGMAS / math.sqrt(2.0))


def beta_separation_line_hz2_per_hz(freqs_hz) -> np.ndarray:
    """The beta separation line ``8 ln2 f / pi^2`` (Hz^2/Hz) at ``freqs_hz`` (Hz).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.analysis import beta_separation_line_hz2_per_hz
    >>> line = beta_separation_line_hz2_per_hz(np.array([1e3, 1e6]))  # 8 ln2 f / pi^2
    >>> print([f"{value:.1f}" for value in line])  # Hz^2/Hz
    ['561.8', '561843.9']
    """
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

    fwhm_hz: float  # the upper limit when ``upper_limit``
    std_hz: float
    lower_limit: bool
    upper_limit: bool
    area_hz2: float
    p_value: float  # of a band area at least this large from noise alone
    extrapolated: bool  # the integral starts below the lowest band


@dataclass(frozen=True)
class _AreaAboveLine:
    """The area above the beta line of a PSD given at band centres, interpolated linearly
    between them and held at the outer levels out to the edges, from ``nodes_hz[0]``."""

    nodes_hz: np.ndarray  # the integral's start, the band centres above it, the top (J,)
    weights: np.ndarray  # the PSD at the nodes from the band levels (J, K)
    cap: np.ndarray  # the highest band levels (K,) that keep the PSD under the line

    @classmethod
    def of_bands(cls, freqs_hz, low_hz, high_hz, start_hz: float) -> _AreaAboveLine:
        begin = max(start_hz, low_hz[0])
        inside = np.flatnonzero(freqs_hz > begin)
        nodes = np.concatenate(([begin], freqs_hz[inside], [high_hz[-1]]))
        weights = np.zeros((nodes.size, freqs_hz.size))
        weights[np.arange(1, nodes.size - 1), inside] = 1.0
        weights[-1, -1] = 1.0
        # the start: interpolated between the centres about it, held beyond the outer ones
        weights[0] = [np.interp(begin, freqs_hz, unit) for unit in np.eye(freqs_hz.size)]
        cap = BETA_SLOPE * np.asarray(freqs_hz, dtype=float)
        cap[0] = BETA_SLOPE * min(freqs_hz[0], begin)
        return cls(nodes, weights, cap)

    def __call__(self, level: np.ndarray) -> np.ndarray:
        """Area (Hz^2) of band levels (..., K) above the line, (...)."""
        psd = level @ self.weights.T
        excess = psd - BETA_SLOPE * self.nodes_hz
        left, right = excess[..., :-1], excess[..., 1:]
        with np.errstate(divide="ignore", invalid="ignore"):  # where left == right
            crossing = np.clip(np.where(left != right, left / (left - right), 0.0), 0.0, 1.0)
        enter = np.where(left > 0, 0.0, crossing)  # the share of each segment above the line
        leave = np.maximum(np.where(right > 0, 1.0, crossing), enter)
        start, rise = psd[..., :-1], np.diff(psd, axis=-1)
        mean = start + rise * (enter + leave) / 2.0
        return np.sum((leave - enter) * np.diff(self.nodes_hz) * mean, axis=-1)


def _fwhm_hz(area_hz2):
    return np.sqrt(8.0 * np.log(2.0) * np.clip(area_hz2, 0.0, None))


def beta_linewidth(
    spectrum: Spectrum,
    corrected: np.ndarray,
    delay_band: np.ndarray,
    fit: PowerLawFit,
    floor_std: float,
    observation_time_s: float,
) -> BetaLinewidth:
    """Beta-separation-line FWHM from ``1 / T_obs`` of the ``corrected`` band PSD (K,), or
    its upper limit when the area is not significant (see the module's notes)."""
    valid = np.flatnonzero(np.isfinite(corrected))
    start_hz = 1.0 / observation_time_s
    low, high = spectrum.edges_hz[valid], spectrum.edges_hz[valid + 1]
    level = corrected[valid]
    area_of = _AreaAboveLine.of_bands(spectrum.freqs_hz[valid], low, high, start_hz)
    extrapolated = bool(start_hz < low[0])
    below, below_std = 0.0, 0.0  # the fitted power law from 1 / T_obs to the lowest band
    if extrapolated:
        gradient = np.array(
            [low[0] - start_hz, np.log(low[0] / start_hz), 1.0 / start_hz - 1.0 / low[0]]
        )
        below = float(fit.levels @ gradient)
        below_std = float(np.sqrt(gradient @ fit.covariance @ gradient))
    measured = float(area_of(level))  # over the bands
    area = measured + below
    # the bands' errors (correlated normal, chi-square spread), the floor's (common to all
    # bands) and the extrapolation's, seeded: the result is reproducible
    rng = np.random.default_rng(BETA_SEED)
    spread = spectrum.psd[valid] * np.sqrt(2.0 / spectrum.dof[valid]) / delay_band[valid]
    factor = np.linalg.cholesky(spectrum.correlation[np.ix_(valid, valid)])
    errors = spread * (rng.standard_normal((BETA_DRAWS, valid.size)) @ factor.T)
    errors += (floor_std / delay_band[valid]) * rng.standard_normal((BETA_DRAWS, 1))
    below_errors = below_std * rng.standard_normal(BETA_DRAWS)
    fwhms = _fwhm_hz(area_of(level + errors) + below + below_errors)
    # the same errors about the null closest to the data: the PSD nowhere above the line
    null = area_of(np.clip(level, 0.0, area_of.cap) + errors)
    p_value = float(np.mean(null >= measured))
    fwhm = float(_fwhm_hz(area))
    last = valid[-1]
    lower_limit = bool(corrected[last] > BETA_SLOPE * spectrum.freqs_hz[last])
    bound = max(fwhm, float(np.quantile(fwhms, BETA_UPPER_QUANTILE)))
    significant = measured > 0 and p_value <= BETA_P_VALUE
    upper_limit = not (lower_limit or significant) and bound > 0
    return BetaLinewidth(
        fwhm_hz=bound if upper_limit else fwhm,
        std_hz=float(np.std(fwhms)),
        lower_limit=lower_limit,
        upper_limit=upper_limit,
        area_hz2=area,
        p_value=p_value,
        extrapolated=extrapolated,
    )


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
