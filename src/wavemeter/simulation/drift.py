"""Per-sample drift series of a sweep: source power and bias phase that wander in time.

Each function returns one value per reading of a sweep, in reading order, to pass to
:meth:`Interferometer.powers <wavemeter.simulation.interferometer.Interferometer.powers>`:
a power factor multiplies ``power_w``, a bias phase goes to ``bias_drift_rad``. Random
series are drawn from ``rng`` (None, an int seed or a numpy Generator) and are reproducible
from it.
"""

from __future__ import annotations

import numbers

import numpy as np

from ..exceptions import InputError, shown
from ..validation import as_rng, check_choice, check_finite, check_positive

__all__ = ["slow_power_drift", "flicker_power_noise", "thermal_ramp_rad", "THERMAL_SHAPES"]

#: number of harmonics summed by :func:`slow_power_drift`
DRIFT_HARMONICS = 4
#: time profiles of :func:`thermal_ramp_rad`
THERMAL_SHAPES = ("ramp", "cycle")


def _check_samples(samples, minimum: int = 1) -> int:
    if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) or samples < minimum:
        raise InputError(
            f"samples must be an integer >= {minimum}, got {shown(samples)}", parameter="samples"
        )
    return int(samples)


def _check_fraction(name: str, value) -> float:
    value = check_finite(name, value)
    if not 0 <= value < 1:
        raise InputError(
            f"{name} must be in [0, 1) so that the source power stays > 0, got {value!r}",
            parameter=name,
        )
    return value


def slow_power_drift(samples: int, relative_amplitude: float, rng=None, cycles: float = 1.0):
    """A slow, smooth drift of the source power over a sweep, as a factor of the power.

    ``1 + relative_amplitude * s(k)``, where ``s`` is a sum of :data:`DRIFT_HARMONICS`
    cosines of ``cycles * j / DRIFT_HARMONICS`` periods over the sweep (``j = 1..``), with
    amplitudes ``1 / j`` and phases uniform in [0, 2 pi) drawn from ``rng``, scaled so that
    ``max |s| = 1``.

    Parameters
    ----------
    samples : int
        Readings in the sweep ``N`` (>= 1).
    relative_amplitude : float
        Peak relative excursion of the power, in [0, 1) (the power stays > 0).
    rng : None, int or numpy.random.Generator
        Source of the phases.
    cycles : float
        Periods of the fastest harmonic over the sweep (> 0).

    Returns
    -------
    ndarray, shape (N,)
        Power factor (dimensionless), in ``[1 - relative_amplitude, 1 + relative_amplitude]``
        with one of the bounds reached.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import slow_power_drift
    >>> factor = slow_power_drift(2001, 0.02, rng=3)  # a source power wandering by about 2 %
    >>> factor.shape
    (2001,)
    >>> print(f"{factor.min():.3f} to {factor.max():.3f}")
    0.980 to 1.014
    >>> print(np.abs(np.diff(factor)).max() < 1e-3)  # slow: tiny steps from reading to reading
    True
    """
    samples = _check_samples(samples)
    relative_amplitude = _check_fraction("relative_amplitude", relative_amplitude)
    cycles = check_positive("cycles", cycles)
    order = np.arange(1, DRIFT_HARMONICS + 1)
    phases_rad = as_rng(rng).uniform(0.0, 2.0 * np.pi, DRIFT_HARMONICS)
    sweep_fraction = np.arange(samples) / samples
    angle_rad = 2.0 * np.pi * np.outer(sweep_fraction, cycles * order / DRIFT_HARMONICS)
    curve = np.cos(angle_rad + phases_rad) @ (1.0 / order)
    return 1.0 + relative_amplitude * curve / np.abs(curve).max()


def flicker_power_noise(samples: int, relative_std: float, rng=None) -> np.ndarray:
    """Flicker (1/f, pink) fluctuation of the source power, as a factor of the power.

    ``1 + relative_std * x``: white Gaussian noise from ``rng`` is shaped in the frequency
    domain (``numpy.fft``) by ``1 / sqrt(f)``, so that its power spectral density is
    ``S(f) ~ 1 / f`` from one cycle per sweep up to the Nyquist frequency (the mean, ``f = 0``,
    is removed), then normalised to unit sample standard deviation.

    Parameters
    ----------
    samples : int
        Readings in the sweep ``N`` (>= 2).
    relative_std : float
        Standard deviation of the relative power fluctuation (>= 0).
    rng : None, int or numpy.random.Generator
        Source of the white noise.

    Returns
    -------
    ndarray, shape (N,)
        Power factor (dimensionless), mean 1, standard deviation ``relative_std``.

    Raises
    ------
    InputError
        When ``relative_std`` is so large that this draw takes the power to zero or below.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import flicker_power_noise
    >>> factor = flicker_power_noise(4096, 0.01, rng=3)  # 1 % pink fluctuation of the power
    >>> print(f"mean {factor.mean():.3f}, std {factor.std():.3f}")
    mean 1.000, std 0.010
    """
    samples = _check_samples(samples, minimum=2)
    relative_std = check_finite("relative_std", relative_std)
    if relative_std < 0:
        raise InputError(
            f"relative_std must be >= 0, got {shown(relative_std)}", parameter="relative_std"
        )
    spectrum = np.fft.rfft(as_rng(rng).standard_normal(samples))
    frequency = np.fft.rfftfreq(samples)  # cycles per sample
    spectrum[0] = 0.0
    spectrum[1:] /= np.sqrt(frequency[1:])
    pink = np.fft.irfft(spectrum, n=samples)
    factor = 1.0 + relative_std * pink / pink.std()
    if np.any(factor <= 0):
        raise InputError(
            f"relative_std {shown(relative_std)} takes the source power to <= 0 in this draw "
            f"(min factor {factor.min():.3g}); use a smaller relative_std",
            parameter="relative_std",
        )
    return factor


def thermal_ramp_rad(
    samples: int, total_k: float, rad_per_k: float, shape: str = "ramp", cycles: float = 1.0
) -> np.ndarray:
    """Bias phase drift (rad) of a chip whose temperature changes during a sweep.

    ``shape="ramp"``: the temperature rises linearly by ``total_k`` from the first reading
    (0 K change) to the last (``total_k``). ``shape="cycle"``: it swings sinusoidally
    (a thermostat cycling), ``total_k / 2 * sin(2 pi cycles k / N)``, peak-to-peak
    ``total_k``. Either is multiplied by ``rad_per_k``.

    Parameters
    ----------
    samples : int
        Readings in the sweep ``N`` (>= 1).
    total_k : float
        Temperature change over the ramp, or peak-to-peak of the cycle (K); may be negative.
    rad_per_k : float
        Bias phase change per kelvin (rad/K), e.g.
        ``Interferometer.thermal_phase_rad_per_k``.
    shape : {"ramp", "cycle"}
        Time profile of the temperature.
    cycles : float
        Periods of the cycle over the sweep (> 0); unused by the ramp.

    Returns
    -------
    ndarray, shape (N,), rad
        To pass as ``bias_drift_rad``.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import thermal_ramp_rad
    >>> drift = thermal_ramp_rad(5, total_k=0.5, rad_per_k=0.3)  # a 0.5 K rise during the sweep
    >>> print(np.round(drift, 4))
    [0.     0.0375 0.075  0.1125 0.15  ]
    >>> cycle = thermal_ramp_rad(200, total_k=0.5, rad_per_k=0.3, shape="cycle", cycles=3)
    >>> print(f"{np.ptp(cycle):.3f} rad peak to peak")
    0.150 rad peak to peak
    """
    samples = _check_samples(samples)
    total_k = check_finite("total_k", total_k)
    rad_per_k = check_finite("rad_per_k", rad_per_k)
    check_choice("shape", shape, THERMAL_SHAPES)
    cycles = check_positive("cycles", cycles)
    if shape == "ramp":
        temperature_k = total_k * np.linspace(0.0, 1.0, samples)
    else:
        temperature_k = 0.5 * total_k * np.sin(2.0 * np.pi * cycles * np.arange(samples) / samples)
    return rad_per_k * temperature_k
