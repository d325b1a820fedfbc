"""Simulated interferometers with the impairments of the paper's Table 1 and hardware faults,
lasers with power-law frequency noise to measure with them, laser sweeps as recorded (true
and logged axis), a reference gas cell recorded beside the ports, and the scenarios
``wavemeter simulate`` records (:class:`Scenario`)."""

from .cascade import ISSUE_CASCADE_FSRS_HZ, CascadeInterferometer
from .drift import flicker_power_noise, slow_power_drift, thermal_ramp_rad
from .interferometer import Interferometer
from .laser import laser_frequency_hz
from .reference_cell import CELL_PRESETS, ReferenceCell, simulated_band_lines
from .scenario import Scenario
from .spectral_presets import SPECTRAL_PRESETS, SpectralPreset
from .sweep_axis import SWEEP_PRESETS, LaserSweep, SweepPreset, laser_sweep
from .thermal_presets import THERMAL_PRESETS, ThermalPreset

__all__ = [
    "Interferometer",
    "CascadeInterferometer",
    "ISSUE_CASCADE_FSRS_HZ",
    "ThermalPreset",
    "THERMAL_PRESETS",
    "SpectralPreset",
    "SPECTRAL_PRESETS",
    "slow_power_drift",
    "flicker_power_noise",
    "thermal_ramp_rad",
    "laser_frequency_hz",
    "Scenario",
    "LaserSweep",
    "SweepPreset",
    "SWEEP_PRESETS",
    "laser_sweep",
    "ReferenceCell",
    "CELL_PRESETS",
    "simulated_band_lines",
]
