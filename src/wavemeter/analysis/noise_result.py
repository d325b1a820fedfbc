"""What :func:`~wavemeter.analysis.noise.frequency_noise` found, and its JSON form.

:class:`FrequencyNoise` holds the PSD and its intervals, the fitted noise levels, the
linewidths and their limits, the drift and the Allan family, units in the names;
:meth:`FrequencyNoise.to_dict` gives every field as JSON-ready values under the format name
``"wavemeter-noise"`` and its version.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

__all__ = ["FrequencyNoise", "FORMAT", "FORMAT_VERSION"]

#: ``to_dict`` format name and version
FORMAT = "wavemeter-noise"
FORMAT_VERSION = 1


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
    >>> noise.n_readings, noise.rate_hz
    (16384, 10000000.0)
    >>> print(f"{noise.duration_s * 1e3:.2f} ms, {noise.psd_freqs_hz.size} PSD bands")
    1.64 ms, 49 PSD bands

    The Allan deviation of white FM falls as tau^-1/2:

    >>> print(f"{noise.adev[0] / noise.adev[2]:.1f}")
    2.0
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
