"""Dispersion and spectral slopes of photonic platforms, and the draw of the slopes.

Across a wide band (the C band is about 88 FSRs of 50 GHz) the output coupler and the
receivers change slowly with frequency: linear slopes per THz of each coupler entry and of
each responsivity, drawn like Table 1's static spread. :data:`SPECTRAL_PRESETS` holds
realistic dispersion and slopes of a silicon-nitride chip (see
:meth:`Interferometer.with_spectral`).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from ..exceptions import InputError
from .coupler_draws import orbit_changes

__all__ = ["SpectralPreset", "SPECTRAL_PRESETS", "draw_spectral_slopes"]


@dataclass(frozen=True)
class SpectralPreset:
    """Dispersion and spectral slopes of a photonic platform, see
    :meth:`Interferometer.with_spectral`.

    Parameters
    ----------
    dispersion_s2 : float
        Group-delay dispersion of the delay imbalance (s^2), see
        :attr:`Interferometer.dispersion_s2`.
    coupler_slope_sigma_per_thz : float
        Standard deviation (1/THz) of the relative slope of the real and imaginary parts of
        the output-coupler entries, shared by the entries the MMI symmetry makes equal.
    coupler_breaking_sigma_per_thz : float
        Standard deviation (1/THz) of the symmetry-breaking slope, drawn per entry.
    responsivity_slope_sigma_per_thz : float
        Standard deviation (1/THz) of the relative slope of each receiver's responsivity.
    reference_delay_s : float
        The delay imbalance (s) ``dispersion_s2`` is that of: ``beta_2 L`` grows with the
        imbalance length, so a device of delay ``tau`` has ``dispersion_s2 tau /
        reference_delay_s`` (as :meth:`CascadeInterferometer.table1` scales it).

    Examples
    --------
    >>> import wavemeter as wm
    >>> from wavemeter.simulation import SPECTRAL_PRESETS
    >>> preset = SPECTRAL_PRESETS["sin"]  # silicon nitride
    >>> print(f"GDD {preset.dispersion_s2:.1e} s^2, delay {preset.reference_delay_s * 1e12:.0f} ps")
    GDD 4.0e-28 s^2, delay 20 ps
    >>> chip = wm.Interferometer.table1(ports=3, seed=7).with_spectral(preset, seed=3)

    Dispersion makes the FSR change across the C band:

    >>> for f_hz in (191e12, 196e12):
    ...     print(f"{f_hz / 1e12:.0f} THz: FSR {chip.local_fsr_hz(f_hz) / 1e9:.3f} GHz")
    191 THz: FSR 51.519 GHz
    196 THz: FSR 51.486 GHz
    """

    dispersion_s2: float
    coupler_slope_sigma_per_thz: float
    coupler_breaking_sigma_per_thz: float
    responsivity_slope_sigma_per_thz: float
    reference_delay_s: float = 20e-12

    def __post_init__(self):
        if not np.isfinite(self.dispersion_s2):
            raise InputError(
                f"dispersion_s2 must be a finite number (s^2), got {self.dispersion_s2}",
                parameter="dispersion_s2",
            )
        for name in (
            "coupler_slope_sigma_per_thz",
            "coupler_breaking_sigma_per_thz",
            "responsivity_slope_sigma_per_thz",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise InputError(
                    f"{name} must be a finite number >= 0 (1/THz), got {value}", parameter=name
                )
        if not (np.isfinite(self.reference_delay_s) and self.reference_delay_s > 0):
            raise InputError(
                f"reference_delay_s must be a finite number > 0 (s), got {self.reference_delay_s}",
                parameter="reference_delay_s",
            )


#: Dispersion and spectral slopes by platform; ``"sin"``: silicon nitride near 1550 nm.
#:
#: - ``dispersion_s2`` 4e-28 s^2: a SiN strip waveguide has a group-velocity dispersion
#:   ``beta_2`` of about 1.2e-25 s^2/m (120 ps^2/km, normal); a 20 ps (50 GHz) imbalance
#:   is ``c tau / n_g`` = 3.3 mm of it at group index 1.8 (SiN's dn/dT, 2.45e-5 /K, over
#:   the delay rate 1.35e-5 /K of the SiN thermal preset), and ``beta_2 L`` = 4e-28 s^2. The
#:   local FSR then moves by 2.7e-4 of itself 2.2 THz from the centre (the C band's edge).
#: - ``coupler_slope_sigma_per_thz`` 0.01: a SiN MMI's self-imaging length scales with the
#:   wavelength, so its entries change by a few percent across the C band (4.4 THz): about
#:   1 %/THz, the same for the entries its symmetry makes equal (as Table 1's spread).
#: - ``coupler_breaking_sigma_per_thz`` 0.002: fabrication asymmetry breaks that symmetry
#:   by a fifth of it, 0.2 %/THz per entry.
#: - ``responsivity_slope_sigma_per_thz`` 0.005: an InGaAs photodiode's responsivity
#:   ``eta e / (h f)`` falls by ``1/f`` = 0.5 %/THz at 193 THz. That common slope scales all
#:   ports as the source power does; the ports differ by as much through their quantum
#:   efficiencies and the couplers to the detectors, 0.5 %/THz per port.
SPECTRAL_PRESETS = MappingProxyType(
    {
        "sin": SpectralPreset(
            dispersion_s2=4e-28,
            coupler_slope_sigma_per_thz=0.01,
            coupler_breaking_sigma_per_thz=0.002,
            responsivity_slope_sigma_per_thz=0.005,
        ),
    }
)


def draw_spectral_slopes(
    ports: int, preset: SpectralPreset, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Draw the spectral slopes of a ``ports``-port device from ``preset``.

    Coupler slopes are drawn as Table 1 draws the coupler's spread (:func:`orbit_changes`):
    a relative slope of the real and of the imaginary part of each entry, ``g + e`` with
    ``g ~ N(0, coupler_slope_sigma_per_thz)`` shared by the entries the MMI symmetry makes
    equal and ``e ~ N(0, coupler_breaking_sigma_per_thz)`` per entry; then one
    responsivity slope per port, ``N(0, responsivity_slope_sigma_per_thz)``.

    Parameters
    ----------
    ports : int
        Number of egress ports ``n``.
    preset : SpectralPreset
        The standard deviations of the slopes.
    rng : numpy.random.Generator
        Source of the slopes.

    Returns
    -------
    coupler_slope_per_thz : ndarray of complex, shape (n, n), 1/THz
    responsivity_slope_per_thz : ndarray, shape (n,), 1/THz
    """
    shared, own = orbit_changes(
        ports,
        rng,
        preset.coupler_slope_sigma_per_thz,
        preset.coupler_breaking_sigma_per_thz,
    )
    return shared + own, rng.normal(0.0, preset.responsivity_slope_sigma_per_thz, ports)
