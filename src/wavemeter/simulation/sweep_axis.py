"""A laser sweep as recorded: the true frequency of every sample and the one the laser logs.

Presets (:data:`SWEEP_PRESETS`):

- ``"tls-spec"``: a tunable laser at the edge of its specification. The logged vacuum
  wavelength is off by a smooth error (offset, scale and a Legendre series across the
  sweep) whose peak is exactly 10 pm, the absolute wavelength accuracy specified for the
  Agilent 81600B (User's Guide, 4th ed., pp. 37 and 143: +-10 pm specified, +-3.6 pm
  typical, +-4.0 pm typical in a continuous sweep at 5 nm/s), with white jitter on top.
- ``"tls-typical"``: the same laser at its typical accuracy, peak 3.6 pm.
- ``"dfb"``: a laser tuned by its drive current, whose recorded axis is the nominal tuning
  coefficient times the current from a nominal set point: the true tuning is quadratic in
  the current (heating), the coefficient and the set point are off. A DFB tunes a few nm by
  current; a sweep across a whole cell's band stands for a widely tunable current-tuned laser.

The jitter (0.1 pm rms) is a modelling choice, not a specification; the laser's own
frequency noise (kHz to MHz) is left out: the true frequency is smooth in time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError, shown
from ..units import SPEED_OF_LIGHT_M_S
from ..validation import as_rng, check_choice

__all__ = ["LaserSweep", "SweepPreset", "SWEEP_PRESETS", "laser_sweep"]


@dataclass(frozen=True)
class SweepPreset:
    """How a laser's recorded axis departs from the truth.

    Attributes
    ----------
    name, description : str
    tuning : {"wavelength", "current"}
        ``"wavelength"``: a tunable laser logging its wavelength (true wavelength linear in
        time); ``"current"``: a laser tuned by current, the axis computed from the current.
    smooth_error_max_m : float
        Peak |smooth error| of the logged vacuum wavelength over the sweep (m); for a
        current-tuned laser, of the nominal set point.
    smooth_order : int
        Highest Legendre order of the smooth error across the sweep.
    jitter_std_m : float
        White jitter of the logged wavelength (m, rms), independent per sample.
    nonlinearity : float
        Current tuning: share of the quadratic term, ``lambda(I) = a + b ((1 - q) I + q I^2)``
        for the current ``I`` in [0, 1] (0: linear).
    coefficient_error : float
        Current tuning: largest relative error of the nominal tuning coefficient.

    Examples
    --------
    >>> from wavemeter.simulation import SWEEP_PRESETS
    >>> for name, preset in SWEEP_PRESETS.items():
    ...     print(name, preset.tuning, f"{preset.smooth_error_max_m * 1e12:.0f} pm")
    tls-spec wavelength 10 pm
    tls-typical wavelength 4 pm
    dfb current 500 pm
    """

    name: str
    description: str
    tuning: str
    smooth_error_max_m: float
    smooth_order: int = 6
    jitter_std_m: float = 0.0
    nonlinearity: float = 0.0
    coefficient_error: float = 0.0


SWEEP_PRESETS = {
    "tls-spec": SweepPreset(
        "tls-spec",
        "tunable laser at its specified absolute accuracy: smooth error peaking at 10 pm",
        "wavelength",
        smooth_error_max_m=10e-12,
        jitter_std_m=0.1e-12,
    ),
    "tls-typical": SweepPreset(
        "tls-typical",
        "tunable laser at its typical absolute accuracy: smooth error peaking at 3.6 pm",
        "wavelength",
        smooth_error_max_m=3.6e-12,
        jitter_std_m=0.1e-12,
    ),
    "dfb": SweepPreset(
        "dfb",
        "laser tuned by current, nominal coefficient only: quadratic tuning (30 %), "
        "coefficient off by up to 10 %, set point off by up to 0.5 nm",
        "current",
        smooth_error_max_m=0.5e-9,
        smooth_order=0,
        nonlinearity=0.3,
        coefficient_error=0.1,
    ),
}


@dataclass(frozen=True)
class LaserSweep:
    """Frequencies of a sweep's samples, in time order.

    Attributes
    ----------
    true_hz : ndarray, shape (N,)
        The light's frequency at each sample (Hz): what the meter and the cell see.
    recorded_hz : ndarray, shape (N,)
        The frequency the laser's axis gives for each sample (Hz).
    preset : str
        The preset's name.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import laser_sweep
    >>> sweep = laser_sweep((193.0e12, 193.5e12), 1000, "dfb", rng=1)  # tuned by current
    >>> bool(np.all(np.diff(sweep.true_hz) > 0))  # from low to high frequency
    True
    >>> error_hz = sweep.recorded_hz - sweep.true_hz
    >>> print(f"axis error up to {np.abs(error_hz).max() / 1e9:.1f} GHz")
    axis error up to 56.0 GHz
    """

    true_hz: np.ndarray
    recorded_hz: np.ndarray
    preset: str

    @property
    def axis_error_hz(self) -> np.ndarray:
        """Recorded minus true frequency (Hz), shape (N,)."""
        return self.recorded_hz - self.true_hz


def _smooth_error_m(u: np.ndarray, order: int, peak_m: float, rng) -> np.ndarray:
    """A random Legendre series in ``u`` in [-1, 1] (coefficients ``N(0, 1/(1 + k))``)
    scaled to the peak ``peak_m`` (m) over the samples."""
    coefficients = rng.normal(0.0, 1.0 / (1.0 + np.arange(order + 1)))
    error = np.polynomial.legendre.legval(u, coefficients)
    return error * (peak_m / np.max(np.abs(error)))


def laser_sweep(band_hz, samples: int, preset="tls-spec", *, rng=None) -> LaserSweep:
    """Simulate a sweep across a band: the true and the recorded frequency of every sample.

    The sweep runs from the band's longest vacuum wavelength (its low frequency) to its
    shortest, samples evenly in time.

    Parameters
    ----------
    band_hz : (float, float)
        Lowest and highest true frequency of the sweep (Hz).
    samples : int
        Number of samples ``N`` (>= 2).
    preset : str or SweepPreset
        A key of :data:`SWEEP_PRESETS` or a preset.
    rng : None, int or numpy.random.Generator
        Source of the smooth error, the jitter and the current-tuning draws.

    Returns
    -------
    LaserSweep

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import laser_sweep
    >>> sweep = laser_sweep((193.0e12, 193.5e12), 1000, "tls-spec", rng=1)  # a tunable laser
    >>> sweep.true_hz.shape, sweep.preset
    ((1000,), 'tls-spec')
    >>> error_hz = sweep.recorded_hz - sweep.true_hz  # what its logged axis gets wrong
    >>> print(f"{np.abs(error_hz).max() / 1e6:.0f} MHz at most")
    1270 MHz at most
    """
    if isinstance(preset, str):
        preset = SWEEP_PRESETS[check_choice("preset", preset, tuple(SWEEP_PRESETS))]
    try:
        low, high = (float(value) for value in band_hz)
    except (TypeError, ValueError):
        raise InputError(f"band_hz must be (low, high) in Hz, got {shown(band_hz)}") from None
    if not (np.isfinite(low) and np.isfinite(high) and 0 < low < high):
        raise InputError(f"band_hz must be finite with 0 < low < high (Hz), got {shown(band_hz)}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 2:
        raise InputError(f"samples must be an integer >= 2, got {shown(samples)}")
    generator = as_rng(rng)
    longest, shortest = SPEED_OF_LIGHT_M_S / low, SPEED_OF_LIGHT_M_S / high
    time = np.linspace(0.0, 1.0, int(samples))
    if preset.tuning == "wavelength":
        true_m = longest + (shortest - longest) * time
        error_m = _smooth_error_m(
            2 * time - 1, preset.smooth_order, preset.smooth_error_max_m, generator
        )
    else:
        quadratic = preset.nonlinearity
        true_m = longest + (shortest - longest) * ((1 - quadratic) * time + quadratic * time**2)
        coefficient = 1.0 + generator.uniform(-1, 1) * preset.coefficient_error
        set_point = longest + generator.uniform(-1, 1) * preset.smooth_error_max_m
        error_m = set_point + (shortest - longest) * coefficient * time - true_m
    recorded_m = true_m + error_m + generator.normal(0.0, preset.jitter_std_m, time.size)
    return LaserSweep(
        true_hz=SPEED_OF_LIGHT_M_S / true_m,
        recorded_hz=SPEED_OF_LIGHT_M_S / recorded_m,
        preset=preset.name,
    )
