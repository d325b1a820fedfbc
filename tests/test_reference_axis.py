"""Line-centre fits against the simulated truth, and the axis correction against its budget.

The meter's phase here is the device's true phase plus white noise of 1.3 mrad (what a
calibrated 3-port meter gives at Table 1 noise), so that these checks need no calibrator
fit; benchmarks/absolute.py runs the whole chain with calibrators.
"""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.reference import (
    BUDGET_TERMS,
    correct_sweep_axis,
    fit_absorption_lines,
    fit_axis_correction,
    smooth_sweep_phase,
)
from wavemeter.simulation import ReferenceCell, laser_sweep

#: lines P(7) .. R(6) of the simulated band: across its origin gap
FIRST, LAST = 20, 33
SAMPLES = 15_000
PHASE_NOISE_RAD = 1.3e-3


def sub_band(cell):
    return (cell.lines.center_hz[FIRST] - 40e9, cell.lines.center_hz[LAST] + 40e9)


def record(seed: int, preset: str = "tls-spec"):
    cell = ReferenceCell.simulated(rng=seed)
    sweep = laser_sweep(sub_band(cell), SAMPLES, preset, rng=seed + 1000)
    transmission = cell.transmission(sweep.true_hz, rng=seed + 2000)
    return cell, sweep, transmission


def meter_phase(sweep, seed: int):
    device = wm.Interferometer.table1(3, seed=seed).with_spectral("sin", seed=seed)
    noise = np.random.default_rng(seed + 3000).normal(0, PHASE_NOISE_RAD, sweep.true_hz.size)
    return device.phase_rad(sweep.true_hz) + noise


@pytest.mark.slow
def test_line_centre_errors_have_unit_z_over_seeds():
    z, depth = [], []
    for seed in range(20):
        cell, sweep, transmission = record(seed)
        fitted = fit_absorption_lines(transmission, sweep.true_hz)
        truth = cell.line_centers_hz()[FIRST : LAST + 1]
        assert len(fitted) == truth.size
        order = np.argsort(fitted.center)
        z.append((fitted.center[order] - truth) / fitted.center_std[order])
        depth.append(fitted.depth[order])
    z = np.concatenate(z)
    # 280 errors: the standard deviation of z is within 1 +- 0.13 at 3 standard errors
    assert 0.87 < np.std(z) < 1.13
    assert abs(np.mean(z)) < 3 / np.sqrt(z.size)
    assert np.max(np.abs(z)) < 4.5


def test_line_fit_in_a_phase_coordinate_and_index():
    cell, sweep, transmission = record(1)
    phase, _ = smooth_sweep_phase(meter_phase(sweep, 1))
    fitted = fit_absorption_lines(transmission, phase)
    by_index = fit_absorption_lines(transmission, np.arange(SAMPLES, dtype=float))
    np.testing.assert_allclose(fitted.index, by_index.index, atol=0.05)
    assert np.all(fitted.fwhm > 0) and np.all(fitted.depth > 0)
    with pytest.raises(wm.InputError, match="strictly monotonic"):
        fit_absorption_lines(transmission, np.sin(np.arange(SAMPLES)))
    with pytest.raises(wm.InputError, match="no absorption line found"):
        fit_absorption_lines(
            np.ones(SAMPLES) + np.random.default_rng(0).normal(0, 1e-3, SAMPLES), sweep.true_hz
        )


def test_axis_correction_is_exact_on_noiseless_lines():
    """Lines at a cubic in phase with tiny errors: the fit returns the cubic, and the
    information criterion does not pick a higher order."""
    cell = ReferenceCell.simulated(rng=0)
    lines = cell.lines
    phase = np.linspace(-30, 30, len(lines))
    u = phase / 30
    target = lines.center_hz
    truth = np.polynomial.legendre.legfit(u, target - target.mean(), 3)
    exact = target.mean() + np.polynomial.legendre.legval(u, truth)
    fake = wm.ReferenceLines(lines.labels, exact, np.full(len(lines), 1.0))
    correction = fit_axis_correction(
        phase, fake, center_std_rad=np.zeros(len(lines)), phase_std_rad=np.zeros(len(lines))
    )
    assert correction.order == 3
    np.testing.assert_allclose(
        correction.frequency_hz(phase), exact, rtol=0, atol=0.1
    )  # ulp 1/32 Hz
    budget = correction.budget_hz(np.array([0.0, 10.0]))
    assert set(budget) == set(BUDGET_TERMS) | {"total"}
    assert np.all(budget["total"] > 0) and np.all(budget["total"] < 1.0)


def test_axis_correction_refuses_what_it_cannot_do():
    lines = ReferenceCell.simulated(rng=0).lines
    with pytest.raises(wm.InputError, match="give the cell's pressure_pa"):
        fit_axis_correction(
            np.arange(54.0), lines, center_std_rad=np.zeros(54), phase_std_rad=np.zeros(54)
        )
    with pytest.raises(wm.InputError, match="at least 2 identified lines"):
        fit_axis_correction(
            [1.0], lines.take([0]), center_std_rad=[0], phase_std_rad=[0], pressure_pa=1e4
        )


@pytest.mark.slow
def test_corrected_axis_agrees_with_its_budget_over_seeds():
    """The corrected axis's error at the middle of the band, over 40 seeds, against the
    budget: its z-scores have unit spread (40 values: 1 +- 0.3 at about 2.7 standard
    errors), and the recorded axis was off by the laser's error."""
    z, recorded, budgets = [], [], []
    for seed in range(40):
        cell, sweep, transmission = record(seed)
        phase = meter_phase(sweep, seed)
        axis = correct_sweep_axis(
            None,
            sweep.recorded_hz,
            transmission,
            cell.lines,
            phase_of=lambda _powers, phase=phase: phase,
            axis_error_hz=1.35e9,
            pressure_pa=cell.nominal_pressure_pa,
            pressure_std_pa=cell.pressure_std_pa,
        )
        assert axis.identification.method == "nearest"
        assert list(axis.identification.table_index) == list(range(FIRST, LAST + 1))
        middle = SAMPLES // 2
        error = axis.frequency_hz - sweep.true_hz
        # the smoothed phase's own error is in the budget's phase term; average the sample
        # noise of the true frequency's jitter-free axis over a few samples
        local = slice(middle - 50, middle + 51)
        budget = axis.budget_hz()["total"][middle]
        z.append(np.mean(error[local]) / budget)
        budgets.append(budget)
        recorded.append(np.sqrt(np.mean(sweep.axis_error_hz**2)))
    assert 0.7 < np.std(z) < 1.3
    assert abs(np.mean(z)) < 3 * 1.3 / np.sqrt(len(z))
    assert np.median(budgets) < 10e6  # MHz-level, against GHz-level recorded errors
    assert np.median(recorded) > 100 * np.median(budgets)


def test_budget_terms_say_how_they_were_computed():
    cell, sweep, transmission = record(5)
    phase = meter_phase(sweep, 5)
    axis = correct_sweep_axis(
        None,
        sweep.recorded_hz,
        transmission,
        cell.lines,
        phase_of=lambda _p: phase,
        axis_error_hz=1.35e9,
        pressure_pa=cell.nominal_pressure_pa,
        pressure_std_pa=cell.pressure_std_pa,
    )
    budget = axis.budget_hz()
    for name in BUDGET_TERMS:
        assert np.all(budget[name] > 0)
        assert len(BUDGET_TERMS[name]) > 40
    total = np.sqrt(sum(budget[name] ** 2 for name in BUDGET_TERMS))
    np.testing.assert_allclose(budget["total"], total, rtol=1e-12)
    at = axis.budget_at_hz(axis.frequency_hz[::1000])
    np.testing.assert_allclose(at["total"], budget["total"][::1000], rtol=1e-9)
    assert axis.fsr_hz == pytest.approx(
        wm.Interferometer.table1(3, seed=5).with_spectral("sin", seed=5).true_fsr_hz, rel=1e-3
    )
