"""Cone-constrained maximum-likelihood retrieval and the per-reading uncertainty."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.model.cone import delay_phase_rad
from wavemeter.model.retrieval import cone_ml_phase_rad, source_power_ratio

from .conftest import NOISE_W, POWER_W, random_test_frequencies


def _noisy(device, rng, samples=20000, power_w=POWER_W):
    sweep_hz = device.sweep_hz(2001)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    test_hz = random_test_frequencies(device, samples, rng)
    return sweep, sweep_hz, device.powers(test_hz, power_w, NOISE_W, rng), test_hz


def _rms_over_crlb(cal, device, test, test_hz, power_w=POWER_W):
    error = wm.frequency_error_hz(cal.predict(test), test_hz, device.true_fsr_hz)
    phase = delay_phase_rad(test_hz, device.center_hz, device.delay_s)
    bound = wm.crlb_frequency_std(device.true_map(), phase, power_w, NOISE_W, device.true_fsr_hz)
    return np.sqrt(np.mean(error**2) / np.mean(bound**2))


@pytest.mark.parametrize("ports", [3, 4, 8])
def test_noiseless_readings_converge_to_the_true_phase(ports):
    device = wm.Interferometer.table1(ports, seed=ports)
    f = random_test_frequencies(device, 500, np.random.default_rng(0))
    readings = device.powers(f, POWER_W)
    truth = wm.wrap_phase_rad(delay_phase_rad(f, device.center_hz, device.delay_s))
    matrix = POWER_W * device.true_map()
    start = truth + np.random.default_rng(1).uniform(-0.3, 0.3, f.size)
    phase = cone_ml_phase_rad(readings, matrix, start, iterations=6)
    np.testing.assert_allclose(wm.wrap_phase_rad(phase - truth), 0.0, atol=1e-12)
    np.testing.assert_allclose(source_power_ratio(readings * 0.7, matrix, truth), 0.7, rtol=1e-12)


def test_class_and_pure_functions_agree():
    rng = np.random.default_rng(2)
    device = wm.Interferometer.table1(3, seed=2)
    sweep, sweep_hz, test, _ = _noisy(device, rng, samples=1000)
    cal = wm.Calibrator(50e9, retrieval="ml").fit(sweep, sweep_hz)
    start = wm.retrieve_phase_rad(test, np.linalg.pinv(cal.map_))
    np.testing.assert_allclose(
        cal.phase(test), cone_ml_phase_rad(test, cal.map_, start), atol=1e-12
    )
    np.testing.assert_allclose(cal.phase(test * 3.0), cal.phase(test), atol=1e-12)


def test_ml_attains_the_bound_where_the_pseudo_inverse_does_not():
    """A 30 % responsivity draw with a weak port: the pinv phase is 16 % above the bound.

    20000 test samples estimate each ratio to 0.5 %; the calibration adds sqrt(1 + 3/N).
    """
    rng = np.random.default_rng(0)
    device = wm.Interferometer.table1(3, seed=0, responsivity_sigma=0.3)
    sweep, sweep_hz, test, test_hz = _noisy(device, rng)
    pinv = wm.Calibrator(50e9).fit(sweep, sweep_hz)
    ml = wm.Calibrator(50e9, retrieval="ml").fit(sweep, sweep_hz)
    assert _rms_over_crlb(pinv, device, test, test_hz) > 1.10
    assert 0.97 < _rms_over_crlb(ml, device, test, test_hz) < 1.03


def test_per_reading_uncertainty_is_calibrated():
    """Errors divided by frequency_std_hz have unit RMS, also with per-sample power."""
    rng = np.random.default_rng(4)
    device = wm.Interferometer.table1(4, seed=4, responsivity_sigma=0.3)
    sweep_hz = device.sweep_hz(2001)
    cal = wm.Calibrator(50e9, retrieval="ml").fit(
        device.powers(sweep_hz, POWER_W, NOISE_W, rng), sweep_hz
    )
    test_hz = random_test_frequencies(device, 20000, rng)
    power = POWER_W * rng.uniform(0.3, 1.5, test_hz.size)
    test = device.powers(test_hz, power, NOISE_W, rng)
    error = wm.frequency_error_hz(cal.predict(test), test_hz, device.true_fsr_hz)
    std = cal.frequency_std_hz(test)
    # the per-reading std spans a factor ~5 (power 0.3-1.5 mW); normalised errors are
    # unit-variance to 0.5 % statistics plus the sqrt(1 + 3/N) calibration share
    assert std.max() > 4 * std.min()
    assert np.sqrt(np.mean((error / std) ** 2)) == pytest.approx(1.0, abs=0.03)


def test_retrieval_parameter_is_checked_and_saved(tmp_path):
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(64)
    with pytest.raises(ValueError, match="retrieval must be one of 'pinv', 'ml'; got 'mle'"):
        wm.Calibrator(retrieval="mle").fit(device.powers(f), f)
    cal = wm.Calibrator(retrieval="ml").fit(device.powers(f), f)
    cal.save(tmp_path / "c.json")
    assert wm.load_calibration(tmp_path / "c.json").retrieval == "ml"
