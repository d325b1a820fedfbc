"""Thermal coefficients of photonic platforms, for :meth:`Interferometer.with_thermal`.

Temperature moves both the bias phase and the delay imbalance of a chip;
:data:`THERMAL_PRESETS` holds the thermal coefficients of two photonic platforms
(see :class:`wavemeter.simulation.Interferometer`).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["ThermalPreset", "THERMAL_PRESETS"]

#: thermo-optic coefficient of crystalline silicon near 1550 nm (1/K)
SILICON_DN_DT_PER_K = 1.8e-4
#: group index of a silicon-on-insulator strip waveguide near 1550 nm
SOI_GROUP_INDEX = 4.2


@dataclass(frozen=True)
class ThermalPreset:
    """Thermal coefficients of a photonic platform, see :meth:`Interferometer.with_thermal`.

    Parameters
    ----------
    fringe_shift_hz_per_k : float
        How far (Hz) a fringe moves per kelvin of heating, to lower frequency (red shift)
        for a positive value.
    delay_per_k : float
        Relative change of the delay imbalance per kelvin (1/K): ``d tau / (tau dT)``.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.simulation import THERMAL_PRESETS
    >>> preset = THERMAL_PRESETS["soi"]  # silicon on insulator
    >>> print(f"{preset.fringe_shift_hz_per_k / 1e9:.1f} GHz/K, delay {preset.delay_per_k:.1e} /K")
    10.0 GHz/K, delay 4.3e-05 /K
    >>> chip = wm.Interferometer.ideal(ports=3, fsr_hz=50e9).with_thermal("soi")
    >>> shift_hz = chip.thermal_phase_rad_per_k * chip.true_fsr_hz / (2 * np.pi)
    >>> print(f"the chip's fringes move {shift_hz / 1e9:.1f} GHz/K")
    the chip's fringes move 10.0 GHz/K
    """

    fringe_shift_hz_per_k: float
    delay_per_k: float


#: Thermal coefficients by platform. ``"sin"``: silicon nitride, fringes move 2.6 GHz/K and
#: the delay 1.35e-5 /K. ``"soi"``: silicon on insulator, fringes move 10 GHz/K; the delay
#: rate is the thermo-optic coefficient of silicon over the group index, ``1.8e-4 / 4.2``
#: (about 4.3e-5 /K; the dispersion of dn/dT is neglected).
THERMAL_PRESETS = MappingProxyType(
    {
        "sin": ThermalPreset(fringe_shift_hz_per_k=2.6e9, delay_per_k=1.35e-5),
        "soi": ThermalPreset(
            fringe_shift_hz_per_k=10e9, delay_per_k=SILICON_DN_DT_PER_K / SOI_GROUP_INDEX
        ),
    }
)
