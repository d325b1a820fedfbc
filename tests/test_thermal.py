"""The thermally compensated calibration (issue 10): rates, uncertainty, flags, re-anchoring.

Tolerances are statistical: fitted rates within 4 of their standard errors of the truth;
``z = error / frequency_std_hz`` of unit standard deviation within the sampling error of a
standard deviation over M readings (``4 / sqrt(2 M)``).
"""

from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.models.thermal_fit import thermal_phase_rad

from .helpers import NOISE_W, POWER_W, THERMAL_SWEEP_TEMPERATURES_K, thermal_sweep

SENSOR_STD_K = 1e-3
TEST_READINGS = 3000
Z_TOLERANCE = 4.0 / math.sqrt(2 * TEST_READINGS)


def true_rates(device: wm.Interferometer, cal: wm.ThermalCalibrator) -> tuple[float, float]:
    """The device's bias rate at the calibration's centre (rad/K) and delay rate (1/K),
    referred to the calibration's reference temperature."""
    stretch = 1 + device.thermal_delay_per_k * (
        cal.reference_temperature_k_ - device.reference_temperature_k
    )
    phase_rate = (
        device.thermal_phase_rad_per_k
        + (2 * np.pi * (cal.center_hz_ - device.center_hz) * device.delay_s)
        * device.thermal_delay_per_k
    )
    return phase_rate, device.thermal_delay_per_k / stretch


def readings_at(device, frequency_hz, temperature_k, rng):
    """One reading per (frequency, temperature) pair."""
    return np.vstack(
        [
            device.powers([f], POWER_W, NOISE_W, rng=rng, temperature_k=t)
            for f, t in zip(frequency_hz, temperature_k, strict=True)
        ]
    )


@pytest.fixture(scope="module")
def sin_device():
    return wm.Interferometer.table1(3, seed=7).with_thermal("sin")


@pytest.fixture(scope="module")
def calibrated(sin_device):
    powers, frequency, temperature = thermal_sweep(sin_device, 2000, NOISE_W, rng=1)
    measured = temperature + np.random.default_rng(2).normal(0, SENSOR_STD_K, temperature.size)
    cal = wm.ThermalCalibrator(temperature_std_k=SENSOR_STD_K)
    return cal.fit(powers, frequency, temperature_k=measured)


@pytest.fixture(scope="module")
def test_readings(sin_device, calibrated):
    """Readings at random frequencies and temperatures inside the calibrated range."""
    rng = np.random.default_rng(3)
    low, high = calibrated.temperature_range_k_
    temperature = rng.uniform(low, high, TEST_READINGS)
    half = sin_device.true_fsr_hz / 2
    frequency = sin_device.center_hz + rng.uniform(-half, half, TEST_READINGS)
    powers = readings_at(sin_device, frequency, temperature, rng)
    measured = temperature + rng.normal(0, SENSOR_STD_K, TEST_READINGS)
    return powers, frequency, measured


@pytest.mark.slow
def test_rates_and_fsr_are_recovered_within_their_standard_errors(sin_device, calibrated):
    thermal = calibrated.diagnostics_["thermal"]
    phase_rate, delay_rate = true_rates(sin_device, calibrated)
    assert (
        abs(calibrated.thermal_phase_rad_per_k_ - phase_rate)
        <= 4 * thermal["thermal_phase_std_rad_per_k"]
    )
    assert (
        abs(calibrated.thermal_delay_per_k_ - delay_rate) <= 4 * thermal["thermal_delay_std_per_k"]
    )
    true_fsr = float(sin_device.true_fsr_hz_at(calibrated.reference_temperature_k_))
    assert abs(calibrated.fsr_hz_ - true_fsr) <= 4 * calibrated.summary()["fsr_hz"].stderr
    assert thermal["fringe_shift_hz_per_k"] == pytest.approx(2.6e9, rel=1e-3)
    assert thermal["temperatures_k"] == pytest.approx(THERMAL_SWEEP_TEMPERATURES_K, abs=1e-3)
    assert thermal["smallest_step_k"] == pytest.approx(1.5, abs=1e-3)
    assert thermal["unambiguous_phase_rate_rad_per_k"] == pytest.approx(np.pi / 1.5, rel=1e-3)
    assert calibrated.reference_temperature_k_ == pytest.approx(293.15, abs=1e-4)


@pytest.mark.slow
def test_readings_at_any_calibrated_temperature_have_honest_uncertainties(
    sin_device, calibrated, test_readings
):
    powers, frequency, measured = test_readings
    predicted = calibrated.predict(powers, temperature_k=measured)
    error = wm.frequency_error_hz(predicted, frequency, sin_device.true_fsr_hz)
    std = calibrated.frequency_std_hz(powers, temperature_k=measured)
    z = error / std
    assert abs(np.std(z) - 1) <= Z_TOLERANCE + 0.02  # + the first-order approximation
    assert abs(np.mean(z)) <= 4 / math.sqrt(TEST_READINGS)
    # a plain calibration at the reference temperature is off by the fringe shift
    sweep_hz = sin_device.sweep_hz(1000)
    sweep = sin_device.powers(sweep_hz, POWER_W, NOISE_W, rng=4, temperature_k=293.15)
    plain_error = wm.frequency_error_hz(
        wm.Calibrator().fit(sweep, sweep_hz).predict(powers), frequency, sin_device.true_fsr_hz
    )
    assert np.sqrt(np.mean(plain_error**2)) > 100 * np.sqrt(np.mean(error**2))


def test_the_uncertainty_includes_the_temperature_sensor(calibrated, test_readings):
    powers, _, measured = test_readings
    noisy = copy.deepcopy(calibrated).set_params(temperature_std_k=0.1)
    extra = noisy.frequency_std_hz(powers, temperature_k=measured) ** 2 - (
        calibrated.frequency_std_hz(powers, temperature_k=measured) ** 2
    )
    shift_hz_per_k = calibrated.diagnostics_["thermal"]["fringe_shift_hz_per_k"]
    # df/dT = -(alpha + s beta / (1 + beta dT)) / (2 pi tau): within 1e-3 of the shift
    np.testing.assert_allclose(extra, (0.1**2 - SENSOR_STD_K**2) * shift_hz_per_k**2, rtol=1e-3)


def test_predict_is_the_pure_thermal_formula(calibrated, test_readings):
    powers, _, measured = test_readings
    offset = measured - calibrated.reference_temperature_k_
    phase = wm.retrieve_phase_rad(powers, calibrated.map_pinv_)
    corrected = wm.wrap_phase_rad(phase - calibrated.thermal_phase_rad_per_k_ * offset)
    delay = calibrated.delay_s_ * (1 + calibrated.thermal_delay_per_k_ * offset)
    expected = calibrated.center_hz_ + corrected / (2 * np.pi * delay)
    np.testing.assert_allclose(
        calibrated.predict(powers, temperature_k=measured), expected, rtol=1e-15, atol=1e-3
    )
    np.testing.assert_allclose(calibrated.fsr_hz_at(measured), 1 / delay, rtol=1e-15)


def test_the_model_phase_is_the_simulators(sin_device):
    frequency = sin_device.sweep_hz(50)
    temperature = np.linspace(285, 300, 50)
    reference = sin_device.reference_temperature_k
    model = thermal_phase_rad(
        frequency,
        temperature,
        sin_device.center_hz,
        reference,
        sin_device.delay_s,
        sin_device.thermal_phase_rad_per_k,
        sin_device.thermal_delay_per_k,
    )
    simulator = sin_device.phase_rad(frequency, temperature) + sin_device.bias_at(temperature)
    np.testing.assert_allclose(model, simulator - sin_device.bias_phase_rad, atol=1e-12)


def test_predict_and_fit_need_the_temperature(sin_device, calibrated, test_readings):
    powers, frequency, _ = test_readings
    with pytest.raises(wm.InputError, match="needs temperature_k"):
        calibrated.predict(powers)
    with pytest.raises(wm.InputError, match="needs temperature_k"):
        wm.ThermalCalibrator().fit(powers, frequency)
    with pytest.raises(wm.InputError, match="temperature_k contains NaN"):
        calibrated.predict(powers[:2], temperature_k=[293.0, np.nan], errors="raise")
    # by default a reading without its temperature gets NaN and INVALID, the other is read
    found = calibrated.readout(powers[:2], temperature_k=[293.0, np.nan])
    assert np.isfinite(found.frequency_hz[0]) and np.isnan(found.frequency_hz[1])
    assert found.flags[1] & wm.ReadingFlag.INVALID
    with pytest.raises(wm.InputError, match="Celsius"):
        wm.ThermalCalibrator().fit(powers, frequency, temperature_k=-5.0)


def test_readings_beyond_the_calibrated_temperatures_are_flagged(calibrated, test_readings):
    powers, _, _ = test_readings
    low, high = calibrated.temperature_range_k_
    margin = 0.1 * (high - low)
    inside = calibrated.flags(powers[:100], temperature_k=high + 0.9 * margin)
    outside = calibrated.flags(powers[:100], temperature_k=high + 1.1 * margin)
    below = calibrated.flags(powers[:100], temperature_k=low - 1.1 * margin)
    assert not np.any(inside & wm.ReadingFlag.TEMPERATURE_RANGE)
    assert np.all(outside & wm.ReadingFlag.TEMPERATURE_RANGE)
    assert np.all(below & wm.ReadingFlag.TEMPERATURE_RANGE)


@pytest.mark.slow
def test_a_recording_during_a_ramp_of_repeated_sweeps_fits_without_warnings():
    device = wm.Interferometer.table1(4, seed=3).with_thermal("sin")
    rng = np.random.default_rng(5)
    frequency = np.tile(device.sweep_hz(1000), 5)
    temperature = np.linspace(288, 298, frequency.size)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng, temperature_k=temperature)
    measured = temperature + rng.normal(0, SENSOR_STD_K, temperature.size)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        cal = wm.ThermalCalibrator().fit(powers, frequency, temperature_k=measured)
    thermal = cal.diagnostics_["thermal"]
    phase_rate, delay_rate = true_rates(device, cal)
    assert (
        abs(cal.thermal_phase_rad_per_k_ - phase_rate) <= 4 * thermal["thermal_phase_std_rad_per_k"]
    )
    assert abs(cal.thermal_delay_per_k_ - delay_rate) <= 4 * thermal["thermal_delay_std_per_k"]
    assert thermal["unambiguous_phase_rate_rad_per_k"] is None
    assert len(thermal["temperatures_k"]) == 1


def test_temperatures_that_cannot_separate_the_rates_are_refused(sin_device):
    frequency = sin_device.sweep_hz(1000)
    powers = sin_device.powers(frequency, POWER_W, NOISE_W, rng=6, temperature_k=293.0)
    with pytest.raises(wm.InputError, match="spread too little.*0.01 K is needed") as equal:
        wm.ThermalCalibrator().fit(powers, frequency, temperature_k=293.0)
    assert equal.value.parameter == "temperature_k"
    # one sweep during a linear ramp: the temperature follows the frequency
    ramp = np.linspace(290, 292, frequency.size)
    ramped = sin_device.powers(frequency, POWER_W, NOISE_W, rng=6, temperature_k=ramp)
    with pytest.raises(wm.InputError, match="changes together with the frequency"):
        wm.ThermalCalibrator().fit(ramped, frequency, temperature_k=ramp)


def test_too_little_spread_for_the_rate_says_how_much_is_needed(sin_device):
    temperatures = (293.0, 293.03)
    powers, frequency, temperature = thermal_sweep(
        sin_device, 1000, NOISE_W, rng=7, temperatures_k=temperatures
    )
    with pytest.raises(wm.InputError, match=r"bias rate would be known to") as error:
        wm.ThermalCalibrator().fit(powers, frequency, temperature_k=temperature)
    needed = float(str(error.value).split(" K is needed")[0].split("and ")[-1])
    # the rate's error falls as 1/spread: the needed spread must be larger than the given
    assert needed > np.std(temperatures)


def test_sweeps_too_far_apart_for_the_plausible_rates_warn(sin_device):
    temperatures = (290.0, 295.0, 300.0)
    powers, frequency, temperature = thermal_sweep(
        sin_device, 1000, NOISE_W, rng=8, temperatures_k=temperatures
    )
    with pytest.warns(wm.CalibrationWarning, match="resolved only within") as caught:
        cal = wm.ThermalCalibrator().fit(powers, frequency, temperature_k=temperature)
    assert [note.message.cause for note in caught] == ["thermal_ambiguity"]
    assert cal.diagnostics_["thermal"]["unambiguous_phase_rate_rad_per_k"] == pytest.approx(
        np.pi / 5
    )
    assert [record["cause"] for record in cal.diagnostics_["warnings"]] == ["thermal_ambiguity"]


@pytest.mark.slow
def test_a_noisy_sensor_is_named_and_its_noise_kept_out_of_the_detectors(sin_device):
    sensor_std_k = 5e-3
    powers, frequency, temperature = thermal_sweep(sin_device, 2000, NOISE_W, rng=9)
    measured = temperature + np.random.default_rng(10).normal(0, sensor_std_k, temperature.size)
    with pytest.warns(wm.CalibrationWarning) as caught:
        cal = wm.ThermalCalibrator(temperature_std_k=sensor_std_k).fit(
            powers, frequency, temperature_k=measured
        )
    assert [note.message.cause for note in caught] == ["temperature_noise"]
    # what the sensor adds to each port: (A u'(t) dt/dT)^2 sensor_std^2, over the sweep
    phase = thermal_phase_rad(
        frequency,
        temperature,
        cal.center_hz_,
        cal.reference_temperature_k_,
        cal.delay_s_,
        cal.thermal_phase_rad_per_k_,
        cal.thermal_delay_per_k_,
    )
    rate = cal.thermal_phase_rad_per_k_ + (
        2 * np.pi * (frequency - cal.center_hz_) * cal.delay_s_ * cal.thermal_delay_per_k_
    )
    tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=1)
    sensor_variance = sensor_std_k**2 * np.mean((tangent @ cal.map_.T * rate[:, None]) ** 2, 0)
    detector_share = NOISE_W**2 / (NOISE_W**2 + sensor_variance)
    assert np.all(detector_share < 0.85)  # the sensor's share is large enough to test
    # the detector variance is the residual's less the sensor's: the relative error of a
    # variance on (at worst the model-free) 0.51 N degrees of freedom over the detectors'
    # share; 4 standard errors, halved for the standard deviation
    tolerance = 0.5 * 4 * np.sqrt(2 / (0.51 * frequency.size)) / detector_share
    assert np.all(np.abs(cal.port_noise_std_w_ / NOISE_W - 1) <= tolerance)


def test_reanchoring_a_plain_calibration_moves_a_5_k_offset_back_to_the_noise(sin_device):
    frequency = sin_device.sweep_hz(2000)
    sweep = sin_device.powers(frequency, POWER_W, NOISE_W, rng=11, temperature_k=293.0)
    plain = wm.Calibrator().fit(sweep, frequency)
    rng = np.random.default_rng(12)
    half = sin_device.true_fsr_hz / 2
    test_hz = sin_device.center_hz + rng.uniform(-half / 2, half / 2, TEST_READINGS)
    test = sin_device.powers(test_hz, POWER_W, NOISE_W, rng=rng, temperature_k=298.0)
    before = wm.frequency_error_hz(plain.predict(test), test_hz, sin_device.true_fsr_hz)
    line_hz = sin_device.center_hz + 3e9
    line = sin_device.powers(np.full(50, line_hz), POWER_W, NOISE_W, rng=rng, temperature_k=298.0)
    anchored = plain.reanchor(line, line_hz)
    after = wm.frequency_error_hz(anchored.predict(test), test_hz, sin_device.true_fsr_hz)
    assert np.sqrt(np.mean(before**2)) > 10e9  # 5 K x 2.6 GHz/K
    z = after / anchored.frequency_std_hz(test)
    assert abs(np.std(z) - 1) <= Z_TOLERANCE + 0.05  # the delay, not refitted, moved by 7e-5
    assert abs(np.mean(z)) <= 4 / math.sqrt(TEST_READINGS) + 0.15  # one line's own error
    assert plain.diagnostics_.get("reanchor") is None  # the original is untouched


def test_reanchoring_a_thermal_calibration_corrects_an_aged_bias(sin_device, calibrated):
    from dataclasses import replace

    aged = replace(sin_device, bias_phase_rad=sin_device.bias_phase_rad + 0.4)
    rng = np.random.default_rng(13)
    line_hz = sin_device.center_hz - 5e9
    line = aged.powers(np.full(50, line_hz), POWER_W, NOISE_W, rng=rng, temperature_k=295.0)
    anchored = calibrated.reanchor(line, line_hz, temperature_k=295.0)
    record = anchored.diagnostics_["reanchor"]
    assert record["temperature_k"] == 295.0
    assert abs(record["phase_shift_rad"] - 0.4) <= 5 * record["phase_shift_std_rad"]
    # readings at another temperature are right again
    test_hz = sin_device.center_hz + rng.uniform(-10e9, 10e9, 1000)
    test = aged.powers(test_hz, POWER_W, NOISE_W, rng=rng, temperature_k=291.0)
    error = wm.frequency_error_hz(
        anchored.predict(test, temperature_k=291.0), test_hz, sin_device.true_fsr_hz
    )
    z = error / anchored.frequency_std_hz(test, temperature_k=291.0)
    assert np.sqrt(np.mean(z**2)) <= 1.2
    with pytest.raises(wm.InputError, match="needs temperature_k"):
        calibrated.reanchor(line, line_hz)


def test_the_file_keeps_the_rates(calibrated, tmp_path):
    path = tmp_path / "thermal.wmcal.json"
    calibrated.save(path)
    loaded = wm.load_calibration(path)
    for name in (
        "thermal_phase_rad_per_k_",
        "thermal_delay_per_k_",
        "reference_temperature_k_",
        "temperature_range_k_",
    ):
        assert getattr(loaded, name) == getattr(calibrated, name)
    np.testing.assert_array_equal(loaded.parameter_covariance_, calibrated.parameter_covariance_)
    assert loaded.diagnostics_["thermal"] == calibrated.diagnostics_["thermal"]


@pytest.mark.slow
def test_a_drift_the_temperature_does_not_explain_is_still_named(sin_device):
    """With the 1 mK sensor's phase scatter expected by the diagnostics, a slow extra bias
    drift (0.02 rad, 1.5x the reading phase noise over ~2000 readings) is still found."""
    temperatures = np.repeat(THERMAL_SWEEP_TEMPERATURES_K, 2000)
    frequency = np.tile(sin_device.sweep_hz(2000), 4)
    drift = 0.02 * np.sin(np.linspace(0, 3 * np.pi, frequency.size))
    powers = sin_device.powers(
        frequency, POWER_W, NOISE_W, rng=14, temperature_k=temperatures, bias_drift_rad=drift
    )
    measured = temperatures + np.random.default_rng(15).normal(0, SENSOR_STD_K, frequency.size)
    with pytest.warns(wm.CalibrationWarning) as caught:
        wm.ThermalCalibrator().fit(powers, frequency, temperature_k=measured)
    assert "phase_drift" in [note.message.cause for note in caught]
