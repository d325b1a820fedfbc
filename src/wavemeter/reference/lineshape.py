"""The shape of a gas absorption line: a Voigt profile in Beer-Lambert transmission.

A line of integrated absorbance ``S`` (Hz), Gaussian (Doppler) standard deviation ``sigma``
and Lorentzian (pressure) half width ``gamma`` (Hz) takes ``exp(-S V(f - f0))`` of the light,
``V`` the area-normalised Voigt profile (:func:`scipy.special.voigt_profile`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError

__all__ = [
    "AVOGADRO_PER_MOL",
    "BOLTZMANN_J_PER_K",
    "doppler_sigma_hz",
    "voigt_absorbance",
    "voigt_fwhm_hz",
]

BOLTZMANN_J_PER_K = 1.380649e-23
AVOGADRO_PER_MOL = 6.02214076e23
_SPEED_OF_LIGHT_M_S = 299_792_458.0


def doppler_sigma_hz(center_hz, temperature_k: float, mass_u: float) -> np.ndarray:
    """Gaussian standard deviation (Hz) of Doppler broadening: ``f0 sqrt(k T / (m c^2))``.

    Parameters
    ----------
    center_hz : float or array_like
        Line centre(s) (Hz).
    temperature_k : float
        Gas temperature (K), > 0.
    mass_u : float
        Molecular mass (unified atomic mass units, g/mol), > 0.
    """
    if not (temperature_k > 0 and mass_u > 0):
        raise InputError(f"temperature_k and mass_u must be > 0, got {temperature_k}, {mass_u}")
    mass_kg = mass_u * 1e-3 / AVOGADRO_PER_MOL
    velocity = np.sqrt(BOLTZMANN_J_PER_K * temperature_k / mass_kg)
    return np.asarray(center_hz, dtype=float) * velocity / _SPEED_OF_LIGHT_M_S


def voigt_absorbance(offset_hz, area_hz, sigma_hz, gamma_hz) -> np.ndarray:
    """Absorbance ``S V(offset; sigma, gamma)`` of one line at detunings (dimensionless).

    Parameters
    ----------
    offset_hz : array_like
        Detuning from the line centre (Hz).
    area_hz : float
        Integrated absorbance ``S`` (Hz): the absorbance's integral over frequency.
    sigma_hz, gamma_hz : float
        Gaussian standard deviation and Lorentzian half width at half maximum (Hz), >= 0,
        not both 0.
    """
    from scipy.special import voigt_profile

    return area_hz * voigt_profile(np.asarray(offset_hz, dtype=float), sigma_hz, gamma_hz)


def voigt_fwhm_hz(sigma_hz: float, gamma_hz: float) -> float:
    """Full width at half maximum (Hz) of a Voigt profile (Olivero and Longbothum's
    approximation, J. Quant. Spectrosc. Radiat. Transfer 17, 233 (1977), to 0.02 %)."""
    gaussian = 2.0 * np.sqrt(2.0 * np.log(2.0)) * sigma_hz
    lorentzian = 2.0 * gamma_hz
    return float(0.5346 * lorentzian + np.sqrt(0.2166 * lorentzian**2 + gaussian**2))
