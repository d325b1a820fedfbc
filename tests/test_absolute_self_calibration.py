"""Self-calibration: no frequency axis, a reference cell, the band; and the reference-free
phase of a wide sweep."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration import self_calibrate, sweep_phase_reference_free
from wavemeter.simulation import ReferenceCell, laser_sweep

POWER_W = 1e-3
NOISE_W = 5e-7


def setup(seed: int, first: int, last: int, samples: int, ports: int = 3):
    cell = ReferenceCell.simulated(rng=seed)
    band = (cell.lines.center_hz[first] - 40e9, cell.lines.center_hz[last] + 40e9)
    sweep = laser_sweep(band, samples, "dfb", rng=seed)
    device = wm.Interferometer.table1(ports, seed=seed).with_spectral("sin", seed=seed)
    powers = device.powers(sweep.true_hz, POWER_W, NOISE_W, rng=seed + 1)
    transmission = cell.transmission(sweep.true_hz, rng=seed + 2)
    return cell, band, sweep, device, powers, transmission


@pytest.mark.slow
def test_windowed_phase_is_smooth_in_frequency_across_a_wide_band():
    """Over 4.8 THz of a dispersive device with coupler slopes, the reference-free phase
    is the true phase up to a smooth function (removed by a Legendre series of order 12 in
    frequency, which cannot follow the 96 fringes) and the reading noise: what a
    fringe-periodic error adds stays below 1.1x the per-reading noise."""
    cell, band, sweep, device, powers, _ = setup(3, 0, 53, 40_000)
    phase, _ = sweep_phase_reference_free(powers)
    truth = device.phase_rad(sweep.true_hz)
    sign = np.sign(np.corrcoef(phase, truth)[0, 1])
    difference = sign * phase - truth
    x = 2 * (sweep.true_hz - sweep.true_hz.min()) / np.ptp(sweep.true_hz) - 1
    smooth = np.polynomial.legendre.legfit(x, difference, 12)
    residual = difference - np.polynomial.legendre.legval(x, smooth)
    noise = np.std(np.diff(residual)) / np.sqrt(2)  # white reading noise
    assert np.sqrt(np.mean(residual**2)) < 1.1 * noise
    assert noise < 3e-3


def test_self_calibration_of_the_whole_band():
    cell, band, sweep, device, powers, transmission = setup(1, 0, 53, 40_000)
    result = self_calibrate(
        powers,
        transmission,
        cell.lines,
        band,
        fsr_hz=50e9,
        pressure_pa=cell.nominal_pressure_pa,
        pressure_std_pa=cell.pressure_std_pa,
    )
    identification = result.axis.identification
    assert identification.method == "pattern"
    np.testing.assert_array_equal(identification.table_index, np.arange(54))
    error = result.frequency_hz - sweep.true_hz
    budget = result.axis.budget_hz()["total"]
    # the axis's error, smoothed over 101 samples (the per-sample reading noise left in the
    # phase is not the axis's), lies within 4 of its budget everywhere between the lines
    smooth = np.convolve(error, np.ones(101) / 101, mode="same")[200:-200]
    assert np.max(np.abs(smooth) / budget[200:-200]) < 4
    assert np.median(budget) < 5e6
    middle = cell.lines.center_hz[26:28].mean()
    assert result.fsr_hz == pytest.approx(
        2 * np.pi / (2 * np.pi * device.group_delay_s(middle)), rel=2e-4
    )
    assert result.delay_s * result.fsr_hz == pytest.approx(1.0, rel=1e-12)
    assert result.dispersion_s2 == pytest.approx(4e-28, rel=0.25)  # the SiN preset's
    assert result.cone.map_w().shape == (3, 3)


def test_a_stretch_of_one_branch_is_refused_with_the_reason():
    cell, band, sweep, device, powers, transmission = setup(2, 8, 16, 8_000)
    whole = (cell.lines.center_hz[0] - 40e9, cell.lines.center_hz[-1] + 40e9)
    with pytest.raises(wm.InputError, match="cannot be identified uniquely") as caught:
        self_calibrate(
            powers,
            transmission,
            cell.lines,
            whole,
            fsr_hz=50e9,
            pressure_pa=cell.nominal_pressure_pa,
        )
    assert "band origin gap or a band end" in str(caught.value)
    with pytest.raises(wm.InputError, match="needs band_hz"):
        self_calibrate(powers, transmission, cell.lines, None)
