"""Simulated sweeps as recorded (true and logged axis) and the reference cell channel."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import SWEEP_PRESETS, ReferenceCell, laser_sweep, simulated_band_lines
from wavemeter.units import SPEED_OF_LIGHT_M_S

BAND_HZ = (191.6e12, 196.3e12)
SAMPLES = 20_000


def wavelength_error_m(sweep) -> np.ndarray:
    return SPEED_OF_LIGHT_M_S / sweep.recorded_hz - SPEED_OF_LIGHT_M_S / sweep.true_hz


@pytest.mark.parametrize(("preset", "peak_m"), [("tls-spec", 10e-12), ("tls-typical", 3.6e-12)])
def test_tunable_laser_error_envelope_and_jitter(preset, peak_m):
    jitter_m = SWEEP_PRESETS[preset].jitter_std_m
    for seed in range(5):
        sweep = laser_sweep(BAND_HZ, SAMPLES, preset, rng=seed)
        assert sweep.true_hz.min() == pytest.approx(BAND_HZ[0], rel=1e-14)
        assert sweep.true_hz.max() == pytest.approx(BAND_HZ[1], rel=1e-14)
        error = wavelength_error_m(sweep)
        # the smooth part peaks at the envelope exactly; the jitter is white on top of it
        smooth = np.convolve(error, np.ones(201) / 201, mode="valid")
        assert np.max(np.abs(smooth)) <= peak_m + 4 * jitter_m / np.sqrt(201)
        assert np.max(np.abs(smooth)) >= 0.8 * peak_m
        jitter = np.diff(error) / np.sqrt(2)
        assert np.std(jitter) == pytest.approx(jitter_m, rel=0.05)


def test_spec_preset_reaches_the_specification_in_frequency():
    sweep = laser_sweep(BAND_HZ, SAMPLES, "tls-spec", rng=2)
    peak_hz = np.max(np.abs(sweep.axis_error_hz))
    # 10 pm is 1.22-1.29 GHz over 1527-1565 nm; the jitter adds a few tens of MHz
    assert 1.1e9 < peak_hz < 1.4e9


def test_current_tuned_laser_is_strongly_nonlinear_and_only_nominal():
    sweep = laser_sweep(BAND_HZ, SAMPLES, "dfb", rng=4)
    wavelength = SPEED_OF_LIGHT_M_S / sweep.true_hz
    time = np.linspace(0, 1, SAMPLES)
    curvature = np.polyfit(time, wavelength, 2)[0]
    span = wavelength[-1] - wavelength[0]
    assert curvature / span == pytest.approx(SWEEP_PRESETS["dfb"].nonlinearity, rel=1e-9)
    # the recorded axis is linear in the current: off by nanometres
    recorded = SPEED_OF_LIGHT_M_S / sweep.recorded_hz
    assert abs(np.polyfit(time, recorded, 2)[0]) < 1e-6 * abs(span)
    assert np.max(np.abs(wavelength_error_m(sweep))) > 1e-9


def test_sweeps_are_seeded_and_take_generators():
    first = laser_sweep(BAND_HZ, 100, "tls-spec", rng=7)
    again = laser_sweep(BAND_HZ, 100, "tls-spec", rng=np.random.default_rng(7))
    assert first.recorded_hz.tobytes() == again.recorded_hz.tobytes()
    other = laser_sweep(BAND_HZ, 100, "tls-spec", rng=8)
    assert first.recorded_hz.tobytes() != other.recorded_hz.tobytes()
    with pytest.raises(wm.InputError, match="preset must be one of"):
        laser_sweep(BAND_HZ, 100, "laser")
    with pytest.raises(wm.InputError, match="samples must be an integer >= 2"):
        laser_sweep(BAND_HZ, 1)
    with pytest.raises(wm.InputError, match="0 < low < high"):
        laser_sweep((196e12, 191e12), 100)


def test_simulated_band_has_two_branches_and_a_gap():
    lines, strength = simulated_band_lines()
    assert len(lines) == 54 and strength.max() == 1.0 and strength.min() > 0.01
    gaps = np.diff(lines.center_hz)
    middle = np.argmax(gaps)  # the band origin: no line between P(1) and R(0)
    assert lines.labels[middle : middle + 2] == ("sim P(1)", "sim R(0)")
    assert gaps[middle] == pytest.approx(2 * np.median(gaps), rel=0.05)


def test_cell_transmission_dips_at_the_shifted_true_centres():
    cell = ReferenceCell.simulated(rng=3, noise_std=0.0, ripple=0.0)
    true = cell.line_centers_hz()
    shift = cell.lines.pressure_shift_hz_per_pa * cell.pressure_pa
    np.testing.assert_allclose(true - cell.true_center_hz, shift)
    assert np.all(np.abs(shift) > 50e6)  # tens of MHz at about 13 kPa
    # the gas's centres differ from the table by its stated uncertainty
    z = (cell.true_center_hz - cell.lines.center_hz) / cell.lines.std_hz
    assert 0.6 < np.std(z) < 1.4
    for center in true[::9]:
        probe = center + np.linspace(-0.3e9, 0.3e9, 601)
        reading = cell.transmission(probe)
        assert abs(probe[np.argmin(reading)] - center) <= 1e6
    # far from every line the gas is transparent (the Lorentz wings of neighbours aside)
    assert cell.transmission([true[0] - 500e9])[0] == pytest.approx(1.0, abs=1e-3)


def test_cell_noise_and_ripple():
    cell = ReferenceCell.simulated(rng=3, noise_std=2e-3, ripple=5e-3, ripple_period_hz=20e9)
    far = np.linspace(180e12, 180.1e12, 20_000)  # no gas line here
    reading = cell.transmission(far, rng=1)
    assert np.std(np.diff(reading)) / np.sqrt(2) == pytest.approx(2e-3, rel=0.05)
    assert np.max(reading) - np.min(reading) > 2 * 5e-3
