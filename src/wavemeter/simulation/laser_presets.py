"""Frequency-noise levels of lasers, for :func:`laser_frequency_hz` and :class:`ActuatedLaser`.

A :class:`LaserNoise` holds the four levels of the laser model (white, flicker and
random-walk FM, and a linear drift); :data:`LASER_PRESETS` names two lasers a lock meets:
a free-running external-cavity diode laser (the laser a lock holds) and a stabilised
reference laser (the one a meter is re-anchored to).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from types import MappingProxyType

from ..validation import check_finite, check_non_negative

__all__ = ["LaserNoise", "LASER_PRESETS"]


@dataclass(frozen=True)
class LaserNoise:
    """The noise of a laser's frequency (see :func:`wavemeter.simulation.laser_frequency_hz`).

    Parameters
    ----------
    white_fm_hz2_per_hz : float
        ``h0`` (Hz^2/Hz): the Lorentzian linewidth (FWHM) is ``pi h0``.
    flicker_fm_hz2 : float
        ``h_-1`` (Hz^2): the Allan deviation's flicker floor is ``sqrt(2 ln 2 h_-1)``.
    random_walk_fm_hz2_per_s : float
        ``h_-2`` (Hz^2/s): the Allan deviation grows as ``sqrt(2 pi^2 h_-2 tau / 3)``.
    drift_hz_per_s : float
        Linear drift (Hz/s), any sign.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import LASER_PRESETS, LaserNoise, laser_frequency_hz
    >>> ecdl = LASER_PRESETS["ecdl"]
    >>> walk_hz = np.sqrt(2 * np.pi**2 * ecdl.random_walk_fm_hz2_per_s / 3)  # at tau = 1 s
    >>> print(f"linewidth {np.pi * ecdl.white_fm_hz2_per_hz / 1e3:.0f} kHz, "
    ...       f"walk ADEV at 1 s {walk_hz / 1e6:.2f} MHz, "
    ...       f"drift {ecdl.drift_hz_per_s * 60 / 1e6:.0f} MHz/min")
    linewidth 94 kHz, walk ADEV at 1 s 0.99 MHz, drift 12 MHz/min

    The levels are :func:`laser_frequency_hz`'s keywords; white FM alone gives readings of
    variance ``h0 rate / 2``:

    >>> white = LaserNoise(white_fm_hz2_per_hz=1e4)
    >>> f_hz = laser_frequency_hz(20_000, 1e6, center_hz=193.4e12, rng=1, **white.levels())
    >>> print(f"std {np.std(f_hz) / 1e3:.1f} kHz, expected {np.sqrt(1e4 * 1e6 / 2) / 1e3:.1f} kHz")
    std 70.4 kHz, expected 70.7 kHz
    """

    white_fm_hz2_per_hz: float = 0.0
    flicker_fm_hz2: float = 0.0
    random_walk_fm_hz2_per_s: float = 0.0
    drift_hz_per_s: float = 0.0

    def __post_init__(self):
        for name in ("white_fm_hz2_per_hz", "flicker_fm_hz2", "random_walk_fm_hz2_per_s"):
            check_non_negative(name, getattr(self, name))
        check_finite("drift_hz_per_s", self.drift_hz_per_s)

    def levels(self) -> dict[str, float]:
        """The levels as keyword arguments of :func:`laser_frequency_hz`."""
        return asdict(self)


#: ``"ecdl"``: a free-running external-cavity diode laser: 94 kHz Lorentzian linewidth
#: (``h0`` 3e4 Hz^2/Hz), a 0.12 MHz flicker floor (``h_-1`` 1e10 Hz^2), a random walk of
#: 1 MHz Allan deviation at 1 s (``h_-2`` 1.5e11 Hz^2/s) and 12 MHz/min of drift: tens of
#: MHz of wander over minutes, which a lock removes. ``"reference"``: a stabilised reference
#: laser (300 Hz linewidth, a 1 kHz flicker floor, no walk, no drift).
LASER_PRESETS = MappingProxyType(
    {
        "ecdl": LaserNoise(
            white_fm_hz2_per_hz=3e4,
            flicker_fm_hz2=1e10,
            random_walk_fm_hz2_per_s=1.5e11,
            drift_hz_per_s=2e5,
        ),
        "reference": LaserNoise(white_fm_hz2_per_hz=1e2, flicker_fm_hz2=1e6),
    }
)
