"""Find absorption lines in a transmission record and fit each centre with its error.

:func:`find_absorption_lines` finds the dips of a record (by prominence over the record's
own noise, after a light smoothing). :func:`fit_absorption_lines` fits each dip with a
Voigt line in Beer-Lambert transmission on a cubic baseline, in a smooth coordinate
given per sample (the meter's smoothed phase, a frequency axis, or the sample index), by
non-linear least squares (:func:`scipy.optimize.least_squares`); each centre's standard
error is that of the fit (Jacobian covariance scaled by the residual variance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .lineshape import voigt_absorbance

__all__ = [
    "FittedLines",
    "LINE_PROMINENCE_NOISE",
    "find_absorption_lines",
    "fit_absorption_lines",
    "record_noise_std",
]

#: a dip counts as a line when its prominence exceeds this many noise standard deviations
#: of the smoothed record (no noise excursion of a million samples reaches it)
LINE_PROMINENCE_NOISE = 12.0
#: the fit window reaches this many half widths either side of a dip (fewer where the next
#: line is closer: half the distance to it)
WINDOW_HALF_WIDTHS = 6.0
#: fewest samples across a line's half width for a fit (below it the shape is not sampled)
MIN_SAMPLES_PER_HALF_WIDTH = 2.0
#: Gaussian smoothing (samples, standard deviation) of the record before the search
SMOOTHING_SAMPLES = 2.0
#: a line's width lies within this factor of the median width of the most prominent dips
WIDTH_RATIO = 3.0
#: how many of the most prominent dips set the typical width
PROMINENT_DIPS = 5


@dataclass(frozen=True)
class FittedLines:
    """Centres of absorption lines fitted in a record, in record order.

    Attributes
    ----------
    index : ndarray, shape (M,)
        Fractional sample position of each centre.
    center : ndarray, shape (M,)
        Centre in the coordinate of the fit (its unit: rad for a phase, Hz for a frequency).
    center_std : ndarray, shape (M,)
        Standard error of each centre from the fit (coordinate unit).
    depth : ndarray, shape (M,)
        Peak absorbance of each fitted line.
    fwhm : ndarray, shape (M,)
        Full width at half maximum of each fitted line (coordinate unit, > 0).
    residual_std : ndarray, shape (M,)
        RMS residual of each fit (transmission units).
    """

    index: np.ndarray
    center: np.ndarray
    center_std: np.ndarray
    depth: np.ndarray
    fwhm: np.ndarray
    residual_std: np.ndarray

    def __len__(self) -> int:
        return self.index.size


def record_noise_std(values) -> float:
    """White-noise standard deviation of a smooth record from its second differences
    (median absolute deviation, robust to the lines): ``MAD / 0.6745 / sqrt(6)``."""
    second = np.diff(np.asarray(values, dtype=float), 2)
    return float(np.median(np.abs(second - np.median(second))) / 0.6745 / np.sqrt(6.0))


def _checked_record(transmission) -> np.ndarray:
    record = np.asarray(transmission, dtype=float)
    if record.ndim != 1 or record.size < 16:
        raise InputError(
            f"reference_transmission must be one value per sample (at least 16), got shape "
            f"{record.shape}",
            parameter="reference_transmission",
        )
    if not np.all(np.isfinite(record)):
        bad = np.flatnonzero(~np.isfinite(record))[:5].tolist()
        raise InputError(
            f"reference_transmission has NaN or inf at samples {bad} (zero-based)",
            parameter="reference_transmission",
        )
    return record


def find_absorption_lines(transmission, *, min_depth: float = 0.0) -> np.ndarray:
    """Sample indices of the absorption dips of a record, in record order.

    The record is smoothed with a Gaussian of 2 samples; a local minimum is a line when its
    prominence exceeds ``LINE_PROMINENCE_NOISE`` times the smoothed record's noise (from
    the raw record's second differences) and ``min_depth``, its half width spans at least
    ``MIN_SAMPLES_PER_HALF_WIDTH`` samples, and its width is within ``WIDTH_RATIO`` of the
    median width of the most prominent dips (the lines of one cell share their Doppler and
    pressure widths; a much wider dip is baseline ripple, a much narrower one a spike).

    Parameters
    ----------
    transmission : array_like, shape (N,)
        Detector reading behind the cell, one per sample (any linear unit).
    min_depth : float
        Smallest dip to count, in the record's unit (0: the noise decides).

    Returns
    -------
    ndarray of int, shape (M,)
    """
    from scipy.ndimage import gaussian_filter1d
    from scipy.signal import find_peaks

    record = _checked_record(transmission)
    smooth = gaussian_filter1d(record, SMOOTHING_SAMPLES)
    # white noise of std s has std s / sqrt(2 sqrt(pi) w) after a Gaussian of w samples
    noise = record_noise_std(record) / np.sqrt(2.0 * np.sqrt(np.pi) * SMOOTHING_SAMPLES)
    prominence = max(LINE_PROMINENCE_NOISE * noise, float(min_depth), 1e-12 * np.ptp(record))
    peaks, props = find_peaks(
        -smooth, prominence=prominence, width=2 * MIN_SAMPLES_PER_HALF_WIDTH, rel_height=0.5
    )
    if peaks.size == 0:
        return peaks
    strongest = np.argsort(props["prominences"])[::-1][:PROMINENT_DIPS]
    typical = float(np.median(props["widths"][strongest]))
    keep = (props["widths"] <= WIDTH_RATIO * typical) & (props["widths"] >= typical / WIDTH_RATIO)
    return peaks[keep]


def _transmission_model(params, x, reference):
    """Cubic baseline ``b0 + b1 u + b2 u^2 + b3 u^3`` times ``exp(-S V(x - x0))``,
    ``u = x - reference``."""
    center, log_area, log_sigma, log_gamma, b0, b1, b2, b3 = params
    u = x - reference
    absorbance = voigt_absorbance(
        x - center, np.exp(log_area), np.exp(log_sigma), np.exp(log_gamma)
    )
    return (b0 + u * (b1 + u * (b2 + u * b3))) * np.exp(-absorbance)


def _fit_one(x: np.ndarray, y: np.ndarray, guess_center: float, guess_hwhm: float):
    """Least-squares Voigt fit of one window in its own scaled coordinate; returns the
    centre, its standard error, peak absorbance, FWHM and RMS residual (coordinate of x)."""
    from scipy.optimize import least_squares

    from .lineshape import voigt_fwhm_hz

    scale = guess_hwhm
    xs = (x - guess_center) / scale
    edges = np.r_[y[:3], y[-3:]]
    baseline = float(np.median(edges))
    depth = max(1.0 - float(y.min()) / baseline, 1e-3)
    # a Lorentzian of HWHM 1 (scaled) and peak absorbance -ln(1 - depth)
    peak_absorbance = -np.log(max(1.0 - depth, 1e-3))
    start = np.array(
        [0.0, np.log(np.pi * peak_absorbance), np.log(0.3), np.log(0.7), baseline, 0, 0, 0]
    )
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            result = least_squares(
                lambda p: _transmission_model(p, xs, 0.0) - y, start, method="lm", x_scale="jac"
            )
    except (ValueError, FloatingPointError):  # a window that is no line drives it to inf
        return None
    if not (result.success and np.all(np.isfinite(result.x))):
        return None
    params = result.x
    residual = result.fun
    dof = max(xs.size - params.size, 1)
    variance = float(residual @ residual) / dof
    jacobian = result.jac
    try:
        covariance = np.linalg.inv(jacobian.T @ jacobian) * variance
    except np.linalg.LinAlgError:
        return None
    center_std = np.sqrt(covariance[0, 0]) if covariance[0, 0] > 0 else np.nan
    sigma, gamma = np.exp(params[2]), np.exp(params[3])
    peak = float(voigt_absorbance(0.0, np.exp(params[1]), sigma, gamma))
    return (
        guess_center + scale * params[0],
        scale * center_std,
        peak,
        scale * voigt_fwhm_hz(sigma, gamma),
        np.sqrt(variance),
    )


def fit_absorption_lines(transmission, coordinate, indices=None, *, min_depth: float = 0.0):
    """Fit the centre of every line of a record in a smooth per-sample coordinate.

    Parameters
    ----------
    transmission : array_like, shape (N,)
        Detector reading behind the cell, one per sample, in sweep order.
    coordinate : array_like, shape (N,)
        A smooth, strictly monotonic coordinate of each sample (the meter's smoothed
        unwrapped phase in rad, a frequency axis in Hz, or the index): the centres come
        in its unit.
    indices : None or array_like of int, shape (M,)
        Sample indices of the dips (default: :func:`find_absorption_lines`).
    min_depth : float
        Passed to :func:`find_absorption_lines`.

    Returns
    -------
    FittedLines
        The lines whose fit converged inside its window, with a finite standard error.

    Raises
    ------
    InputError
        When the arrays differ in length, the coordinate is not finite and strictly
        monotonic, or no line is found.
    """
    record = _checked_record(transmission)
    x = np.asarray(coordinate, dtype=float)
    if x.shape != record.shape or not np.all(np.isfinite(x)):
        raise InputError(
            f"the coordinate must be {record.size} finite values, one per sample, got shape "
            f"{x.shape}"
        )
    step = np.diff(x)
    if not (np.all(step > 0) or np.all(step < 0)):
        raise InputError(
            "the coordinate must be strictly monotonic along the sweep (a smoothed unwrapped "
            "phase or frequency axis)"
        )
    dips = find_absorption_lines(record, min_depth=min_depth) if indices is None else indices
    dips = np.sort(np.asarray(dips, dtype=int))
    if dips.size == 0:
        raise InputError(
            "no absorption line found in reference_transmission: check the cell channel",
            parameter="reference_transmission",
        )
    from scipy.ndimage import gaussian_filter1d
    from scipy.signal import peak_widths

    half_width = peak_widths(-gaussian_filter1d(record, SMOOTHING_SAMPLES), dips, 0.5)[0] / 2.0
    found = []
    for k, dip in enumerate(dips):
        reach = WINDOW_HALF_WIDTHS * max(half_width[k], MIN_SAMPLES_PER_HALF_WIDTH)
        if k > 0:
            reach = min(reach, (dip - dips[k - 1]) / 2.0)
        if k + 1 < dips.size:
            reach = min(reach, (dips[k + 1] - dip) / 2.0)
        low, high = max(int(dip - reach), 0), min(int(dip + reach) + 1, record.size)
        if high - low < 12:
            continue
        window_x, window_y = x[low:high], record[low:high]
        guess_hwhm = abs(window_x[-1] - window_x[0]) / (high - low) * max(half_width[k], 1.0)
        fitted = _fit_one(window_x, window_y, x[dip], guess_hwhm)
        if fitted is None:
            continue
        center, std, peak, fwhm, residual = fitted
        inside = min(window_x[0], window_x[-1]) < center < max(window_x[0], window_x[-1])
        if not (inside and np.isfinite(std) and std > 0 and peak > 0):
            continue
        fraction = np.interp(
            center,
            window_x if step[0] > 0 else window_x[::-1],
            np.arange(low, high, dtype=float)[:: 1 if step[0] > 0 else -1],
        )
        found.append((fraction, center, std, peak, fwhm, residual))
    if not found:
        raise InputError(
            "no absorption line of reference_transmission could be fitted",
            parameter="reference_transmission",
        )
    columns = np.array(found).T
    # the lines of one cell share their widths: a fit far wider or narrower is no line
    width = np.abs(columns[4])
    typical = np.median(width)
    keep = (width <= WIDTH_RATIO * typical) & (width >= typical / WIDTH_RATIO)
    return FittedLines(*columns[:, keep])
