"""Re-anchoring a calibration to reference lines: a 5 K offset back to the noise limit.

A silicon-nitride chip whose fringe moves 2.6 GHz/K, calibrated at 293.15 K and read at
298.15 K, is 13 GHz wrong. Tolerances from the physics: after re-anchoring with ``k``
readings of one line the test error is about ``CRLB sqrt(1 + 3/N + 1/k)`` (1.007 CRLB for
N = 1000 training samples, k = 100); the RMS over M = 2000 test readings has a relative
Monte-Carlo standard error ``1 / sqrt(2 M)`` = 1.6 %, so the bound 1.2 CRLB is more than
10 standard errors above the expectation, and still fails for a residual bias of 0.66 CRLB.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.model.cone import wrap_to_period

from .helpers import NOISE_W, POWER_W, random_test_frequencies

REFERENCE_K = 293.15
FRINGE_SHIFT_HZ_PER_K = 2.6e9
SAMPLES = 1000
TEST_READINGS = 2000
LINE_READINGS = 100
MAX_RMS_IN_CRLB = 1.2
#: |estimate - truth| / standard error beyond which a correct estimator is refuted
#: (two-sided Gaussian tail 6e-7)
MAX_Z = 5.0


def thermal_device(seed: int = 3, **changes) -> wm.Interferometer:
    device = wm.Interferometer.table1(3, seed=seed)
    rate = 2.0 * np.pi * FRINGE_SHIFT_HZ_PER_K / device.true_fsr_hz
    return dataclasses.replace(device, thermal_phase_rad_per_k=rate, **changes)


@pytest.fixture(scope="module")
def device():
    return thermal_device()


@pytest.fixture(scope="module")
def calibration(device):
    frequency = device.sweep_hz(SAMPLES)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=4, temperature_k=REFERENCE_K)
    return wm.Calibrator(50e9).fit(readings, frequency)


def readings_at(device, temperature_k, seed):
    rng = np.random.default_rng(seed)
    frequency = random_test_frequencies(device, TEST_READINGS, rng)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng, temperature_k=temperature_k)
    return frequency, readings


def line_readings(device, frequency_hz, temperature_k, count, seed):
    frequency = np.repeat(np.atleast_1d(frequency_hz), count)
    readings = device.powers(frequency, POWER_W, NOISE_W, seed, temperature_k=temperature_k)
    return frequency, readings


def rms_error_hz(calibrator, frequency, readings, fsr_hz, **inputs) -> float:
    error = wrap_to_period(calibrator.predict(readings, **inputs) - frequency, fsr_hz)
    return float(np.sqrt(np.mean(error**2)))


def crlb_rms_hz(device, frequency, temperature_k) -> float:
    bound = wm.crlb_frequency_std(
        device.true_map(temperature_k=temperature_k),
        device.phase_rad(frequency),
        POWER_W,
        NOISE_W,
        device.true_fsr_hz,
    )
    return float(np.sqrt(np.mean(bound**2)))


def test_plain_calibration_is_off_by_the_thermal_shift(device, calibration):
    frequency, readings = readings_at(device, REFERENCE_K + 5.0, seed=5)
    # the shift is 13 GHz; the spread about it is the CRLB (~10 MHz), 0.1 % of it
    rms = rms_error_hz(calibration, frequency, readings, device.true_fsr_hz)
    assert rms == pytest.approx(5.0 * FRINGE_SHIFT_HZ_PER_K, rel=0.01)


@pytest.mark.parametrize("offset_k", [5.0, -5.0, 2.0])
def test_reanchor_moves_a_thermal_offset_back_to_the_noise_limit(device, calibration, offset_k):
    temperature = REFERENCE_K + offset_k
    line_hz = device.center_hz + 0.3 * device.true_fsr_hz
    lines, line_powers = line_readings(device, line_hz, temperature, LINE_READINGS, seed=6)
    anchored = calibration.reanchor(line_powers, lines, temperature_k=temperature)
    frequency, readings = readings_at(device, temperature, seed=7)
    rms = rms_error_hz(anchored, frequency, readings, device.true_fsr_hz)
    assert rms <= MAX_RMS_IN_CRLB * crlb_rms_hz(device, frequency, temperature)
    record = anchored.diagnostics_["reanchor"]
    assert record["delay_change_s"] is None  # one line cannot tell a delay change
    assert record["lines_hz"] == [line_hz] and record["readings"] == LINE_READINGS
    # the frequency uncertainty stays honest: z-scores of unit spread (SE 1.6 %)
    error = wrap_to_period(anchored.predict(readings) - frequency, device.true_fsr_hz)
    assert np.std(error / anchored.frequency_std_hz(readings)) == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize("count", [1, LINE_READINGS])
def test_phase_shift_matches_the_bias_change_within_its_standard_error(device, calibration, count):
    """``count`` < 5: the model's phase variance; else the spread of the readings."""
    temperature = REFERENCE_K + 5.0
    line_hz = device.center_hz - 0.2 * device.true_fsr_hz
    lines, line_powers = line_readings(device, line_hz, temperature, count, seed=8)
    record = calibration.reanchor(line_powers, lines).diagnostics_["reanchor"]
    truth = device.thermal_phase_rad_per_k * 5.0
    # the calibration's own phase error at the line adds to the lines' standard error
    with_calibration, reading_only = (
        calibration.frequency_std_hz(line_powers[:1], include_calibration=flag)[0]
        for flag in (True, False)
    )
    calibration_rad = np.sqrt(with_calibration**2 - reading_only**2) * 2 * np.pi
    calibration_rad /= calibration.fsr_hz_
    std = np.hypot(record["phase_shift_std_rad"], calibration_rad)
    assert abs(wrap_to_period(record["phase_shift_rad"] - truth, 2 * np.pi)) < MAX_Z * std


def test_original_is_untouched(device, calibration):
    frequency, readings = readings_at(device, REFERENCE_K, seed=9)
    before = calibration.predict(readings)
    map_before = calibration.map_.copy()
    lines, line_powers = line_readings(device, device.center_hz, REFERENCE_K + 5.0, 20, seed=10)
    anchored = calibration.reanchor(line_powers, lines)
    np.testing.assert_array_equal(calibration.predict(readings), before)
    np.testing.assert_array_equal(calibration.map_, map_before)
    assert "reanchor" not in calibration.diagnostics_
    assert anchored is not calibration and not np.array_equal(anchored.map_, map_before)


def test_reanchored_calibration_round_trips_through_a_file(device, calibration, tmp_path):
    lines, line_powers = line_readings(device, device.center_hz, REFERENCE_K + 5.0, 20, seed=11)
    anchored = calibration.reanchor(line_powers, lines)
    path = tmp_path / "anchored.wmcal.json"
    anchored.save(path)
    loaded = wm.load_calibration(path)
    _, readings = readings_at(device, REFERENCE_K + 5.0, seed=12)
    np.testing.assert_array_equal(loaded.predict(readings), anchored.predict(readings))
    np.testing.assert_array_equal(
        loaded.frequency_std_hz(readings), anchored.frequency_std_hz(readings)
    )
    assert loaded.diagnostics_["reanchor"] == anchored.diagnostics_["reanchor"]


def test_lines_spread_over_the_fsr_correct_a_delay_change(device, calibration):
    """24 lines x 400 readings pin the delay to ~6e-6 relative, better than the sweep's 2e-5.

    The lines measure the delay the calibrated map needs, whose own error (the sweep's
    delay and map errors, ~2e-5 relative) is common to both devices: the change the lines
    see from the unchanged to the changed device is the device's, within the lines' errors.
    """
    temperature = REFERENCE_K + 5.0
    half = 0.45 * device.true_fsr_hz
    line_hz = device.center_hz + np.linspace(-half, half, 24)
    changed = thermal_device(delay_s=device.delay_s * (1 + 1e-4))
    anchored = {}
    for name, chip, seed in (("same", device, 13), ("changed", changed, 14)):
        lines, line_powers = line_readings(chip, line_hz, temperature, 400, seed=seed)
        anchored[name] = calibration.reanchor(line_powers, lines)
    records = {name: cal.diagnostics_["reanchor"] for name, cal in anchored.items()}
    for record in records.values():
        assert record["delay_change_s"] is not None
        assert record["delay_change_std_s"] < calibration.delay_std_s_
    seen = (records["changed"]["delay_change_s"] - records["same"]["delay_change_s"]) / (
        calibration.delay_s_
    )
    std = np.hypot(*(record["delay_change_std_s"] for record in records.values()))
    std /= calibration.delay_s_
    # no correction (0) is refuted by 5 standard errors while the estimate is within 5
    assert 1e-4 > 2 * MAX_Z * std
    assert abs(seen - 1e-4) < MAX_Z * std
    fitted = anchored["changed"]
    assert fitted.delay_s_ * fitted.fsr_hz_ == pytest.approx(1.0, abs=1e-12)
    assert fitted.delay_std_s_ == records["changed"]["delay_change_std_s"]
    frequency = random_test_frequencies(changed, TEST_READINGS, np.random.default_rng(15))
    readings = changed.powers(frequency, POWER_W, NOISE_W, 16, temperature_k=temperature)
    rms = rms_error_hz(fitted, frequency, readings, changed.true_fsr_hz)
    assert rms <= MAX_RMS_IN_CRLB * crlb_rms_hz(changed, frequency, temperature)


def test_one_line_keeps_the_delay(device, calibration):
    lines, line_powers = line_readings(device, device.center_hz, REFERENCE_K + 5.0, 400, seed=17)
    anchored = calibration.reanchor(line_powers, lines)
    assert anchored.diagnostics_["reanchor"]["delay_change_s"] is None
    assert anchored.delay_s_ == calibration.delay_s_ and anchored.fsr_hz_ == calibration.fsr_hz_


@pytest.fixture(scope="module")
def calibration_set(device):
    frequency = device.center_hz + device.true_fsr_hz * np.linspace(-1.5, 1.5, 900)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=16, temperature_k=REFERENCE_K)
    return wm.CalibrationSet(50e9).fit(readings, frequency)


def set_test_data(device, calibration_set, temperature_k, seed):
    low, high = calibration_set.window_edges_hz_[[0, -1]]
    rng = np.random.default_rng(seed)
    frequency = rng.uniform(low, high, TEST_READINGS)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng, temperature_k=temperature_k)
    return frequency, readings


@pytest.mark.parametrize("line_windows", [(0, 2), (1,)])
def test_a_set_reanchors_its_windows(device, calibration_set, tmp_path, line_windows):
    """Lines in some windows; the others interpolated (between) or held (beyond)."""
    assert len(calibration_set.windows_) == 3
    temperature = REFERENCE_K + 5.0
    centers = [calibration_set.windows_[k].center_hz_ for k in line_windows]
    lines, line_powers = line_readings(device, centers, temperature, LINE_READINGS, seed=17)
    anchored = calibration_set.reanchor(line_powers, lines, temperature_k=temperature)
    frequency, readings = set_test_data(device, calibration_set, temperature, seed=18)
    before = calibration_set.predict(readings, coarse_hz=frequency)
    rms = rms_error_hz(anchored, frequency, readings, device.true_fsr_hz, coarse_hz=frequency)
    assert rms <= MAX_RMS_IN_CRLB * crlb_rms_hz(device, frequency, temperature)
    np.testing.assert_array_equal(calibration_set.predict(readings, coarse_hz=frequency), before)
    records = anchored.diagnostics_["reanchor"]["windows"]
    for index, record in enumerate(records):
        assert record["readings"] == (LINE_READINGS if index in line_windows else 0)
        expected = [] if index in line_windows else sorted({min(line_windows), max(line_windows)})
        assert record["interpolated_from"] == expected
    path = tmp_path / "set.wmcal.json"
    anchored.save(path)
    loaded = wm.load_calibration(path)
    np.testing.assert_array_equal(
        loaded.predict(readings, coarse_hz=frequency),
        anchored.predict(readings, coarse_hz=frequency),
    )


def _some_readings(device, count=10):
    return line_readings(device, device.center_hz, REFERENCE_K, count, seed=19)


@pytest.mark.parametrize(
    ("change", "parameter"),
    [
        (lambda p, f: (np.empty((0, 3)), f[:0]), "powers"),
        (lambda p, f: (np.where(np.arange(p.size).reshape(p.shape) == 4, np.nan, p), f), "powers"),
        (lambda p, f: (p[:, :2], f), "powers"),
        (lambda p, f: (p, np.where(np.arange(f.size) == 3, np.nan, f)), "frequency_hz"),
        (lambda p, f: (p, f[:-1]), "frequency_hz"),
        (lambda p, f: (p, None), "frequency_hz"),
    ],
)
def test_bad_reference_readings_are_refused(device, calibration, change, parameter):
    powers, frequency = change(*_some_readings(device)[::-1])
    with pytest.raises(wm.InputError) as caught:
        calibration.reanchor(powers, frequency)
    assert caught.value.parameter == parameter


def test_bad_temperature_and_unfitted_are_refused(device, calibration):
    frequency, powers = _some_readings(device)
    with pytest.raises(wm.InputError) as caught:
        calibration.reanchor(powers, frequency, temperature_k=np.nan)
    assert caught.value.parameter == "temperature_k"
    with pytest.raises(wm.NotFittedError):
        wm.Calibrator().reanchor(powers, frequency)


def test_set_refuses_lines_outside_its_span(device, calibration_set):
    frequency, powers = _some_readings(device)
    low, high = calibration_set.covered_hz()
    with pytest.raises(wm.InputError) as caught:
        calibration_set.reanchor(powers, frequency + (high - low))
    assert caught.value.parameter == "frequency_hz"
    with pytest.raises(wm.InputError) as caught:
        calibration_set.reanchor(powers, frequency, coarse_hz=np.full(3, low))
    assert caught.value.parameter == "coarse_hz"
