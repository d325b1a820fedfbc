"""What ``wavemeter simulate`` prints after writing: the device it simulated and how.

A single device: the ``device:`` line (ports, seed, true FSR, centre), a ``spectral:`` line
for a dispersive or wide-band device, a ``thermal:`` line for a thermal one. A cascade: its
``device:`` line (stages, columns, true FSRs, band) and, with a spectral platform, its
``spectral:`` line. A laser record adds a ``laser:`` line.
"""

from __future__ import annotations

import numpy as np

from ..simulation.recording import port_names
from ..simulation.scenario_defaults import DEFAULT_LASER_RATE_HZ
from ._common import frequency_text, fsr_text, optical_text

__all__ = ["summary_lines"]


def summary_lines(scenario, sweep: dict) -> list[str]:
    """The lines describing ``scenario``, whose sweep table is ``sweep``."""
    device = scenario.device
    sweep_hz = scenario.sweep_hz()
    if scenario.is_cascade:
        lines = _cascade_lines(device, (sweep_hz[0], sweep_hz[-1]), scenario)
    else:
        lines = [
            f"device: Table 1, {device.ports} ports, seed {scenario.seed}, true FSR "
            f"{fsr_text(device.true_fsr_hz)}, centre {optical_text(device.center_hz)}"
        ]
        if scenario.spectral_preset is not None or device.dispersion_s2 != 0:
            lines.append(_spectral_line(device, scenario.spectral_preset, sweep_hz, scenario))
        if scenario.platform is not None:
            shift_hz = device.thermal_phase_rad_per_k * device.true_fsr_hz / (2 * np.pi)
            lines.append(
                f"thermal: {scenario.platform}, fringes move {shift_hz / 1e9:.4g} GHz/K, delay "
                f"{device.thermal_delay_per_k:.4g} /K about {device.reference_temperature_k:g} "
                f"K; sweep at {_temperature_text(sweep['temperature_k'])}"
            )
    if scenario.laser:
        lines.append(_laser_line(scenario))
    return lines


def _spectral_line(device, preset, sweep_hz: np.ndarray, scenario) -> str:
    """The ``spectral:`` line: dispersion, slope sigmas, local FSR over the sweep, the
    fringes' FSR at its centre."""
    parts = [scenario.spectral or "custom", f"dispersion {device.dispersion_s2:.3g} s^2"]
    if preset is not None:
        parts.append(
            f"slope sigmas: coupler {preset.coupler_slope_sigma_per_thz:.3g} /THz (symmetry "
            f"breaking {preset.coupler_breaking_sigma_per_thz:.3g} /THz), responsivity "
            f"{preset.responsivity_slope_sigma_per_thz:.3g} /THz"
        )
    local_hz = device.local_fsr_hz(np.array([sweep_hz.min(), sweep_hz.max()]))
    fringe_hz = device.fringe_fsr_hz(0.5 * (sweep_hz.min() + sweep_hz.max()))[0]
    parts.append(
        f"local FSR {fsr_text(local_hz[0])} at the sweep's low end, {fsr_text(local_hz[1])} "
        f"at its high end, the fringes' {fsr_text(fringe_hz)} at its centre (what a wide-band "
        "calibration's FSR estimates)"
    )
    return "spectral: " + ", ".join(parts)


def _cascade_lines(device, band_hz, scenario) -> list[str]:
    """The ``device:`` line of a cascade (stages, columns, FSRs, band) and, with a spectral
    platform, the ``spectral:`` line (each stage's dispersion, the finest stage's local FSR
    at the band's ends)."""
    names = port_names(device)
    columns = ", ".join(f"{names[block[0]]}-{names[block[-1]]}" for block in device.stage_ports)
    low, high = band_hz
    lines = [
        f"device: cascade of {len(device.stages)} Table 1 stages, "
        f"{device.stages[0].ports} ports each (columns {columns}), seed {scenario.seed}, true "
        f"FSRs {', '.join(frequency_text(value) for value in device.true_fsrs_hz)}, band "
        f"{optical_text(low)} to {optical_text(high)}"
    ]
    if scenario.spectral is not None:
        local_hz = device.stages[-1].local_fsr_hz(np.array([low, high]))
        dispersions = ", ".join(f"{stage.dispersion_s2:.3g}" for stage in device.stages)
        lines.append(
            f"spectral: {scenario.spectral}, dispersion {dispersions} s^2 (stage by stage), the "
            f"finest stage's local FSR {fsr_text(local_hz[0])} at the band's low end, "
            f"{fsr_text(local_hz[1])} at its high end"
        )
    return lines


def _temperature_text(temperature_k: np.ndarray) -> str:
    start, end = temperature_k[0], temperature_k[-1]
    return f"{start:.6g} K" if start == end else f"{start:.6g} to {end:.6g} K"


def _laser_line(scenario) -> str:
    """The ``laser:`` line: readings, rate, start frequency, noise levels, drift."""
    rate_hz = scenario.laser_rate_hz or DEFAULT_LASER_RATE_HZ
    center_hz = scenario.laser_center_hz or scenario.device.center_hz
    return (
        f"laser: {scenario.laser} readings at {frequency_text(rate_hz)} "
        f"({scenario.laser / rate_hz:.4g} s) from {optical_text(center_hz)}; white FM "
        f"{scenario.white_fm_hz2_per_hz:.4g} Hz^2/Hz (Lorentzian linewidth "
        f"{frequency_text(np.pi * scenario.white_fm_hz2_per_hz, 4)}), flicker FM "
        f"{scenario.flicker_fm_hz2:.4g} Hz^2, random-walk FM "
        f"{scenario.random_walk_fm_hz2_per_s:.4g} Hz^2/s, drift "
        f"{scenario.laser_drift_hz_per_s:.4g} Hz/s"
    )
