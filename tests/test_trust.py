"""Right or say so, through the calibrators: offsets, flags, honest uncertainty, diagnostics.

The pure functions are tested in test_uncertainty.py, test_misfit.py and test_retrieval.py;
here the calibrators use them: dark readings and fitted offsets, per-reading flags, the
z-scores of ``frequency_std_hz`` over repeated calibrations, and what survives a file.
Tolerances: RMS/CRLB and z-score spreads carry the Monte-Carlo error of the number of test
readings and calibrations used (stated at each assertion).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter import ReadingFlag
from wavemeter.simulation.drift import slow_power_drift

from .helpers import NOISE_W, POWER_W, random_test_frequencies

FSR_HZ = 50e9


def _fit(calibrator, *args, **kwargs):
    """Fit, returning the calibrator and the causes of the warnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wm.CalibrationWarning)
        calibrator.fit(*args, **kwargs)
    causes = [w.message.cause for w in caught if isinstance(w.message, wm.CalibrationWarning)]
    assert causes == [note["cause"] for note in calibrator.diagnostics_["warnings"]]
    return calibrator, causes


def _true_phase(device, frequency_hz):
    return device.phase_rad(frequency_hz)


def _rms_over_crlb(calibrator, device, test_w, test_hz, power_w, noise_w=NOISE_W):
    error = wm.frequency_error_hz(calibrator.predict(test_w), test_hz, device.true_fsr_hz)
    bound = wm.crlb_frequency_std(
        device.true_map(), _true_phase(device, test_hz), power_w, noise_w, device.true_fsr_hz
    )
    return float(np.sqrt(np.mean(error**2) / np.mean(bound**2)))


# ----------------------------------------------------------------------------- offsets
def _offset_device(seed: int, fraction: float):
    """Offsets of +-``fraction`` of the mean port reading; not along the cone axis's image
    (offsets proportional to each port's mean reading would shift only the axis component,
    which the arctangent ignores)."""
    device = wm.Interferometer.table1(3, seed=seed)
    mean = device.powers(device.sweep_hz(64), POWER_W).mean()
    return dataclasses.replace(device, dark_offset_w=fraction * mean * np.array([1.0, -1.0, 0.5]))


def test_dark_readings_remove_offsets_that_cost_accuracy_at_other_powers():
    rng = np.random.default_rng(1)
    device = _offset_device(1, 0.05)
    sweep_hz = device.sweep_hz(2001)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    test_hz = random_test_frequencies(device, 4000, rng)
    power = POWER_W * rng.uniform(0.5, 1.5, test_hz.size)
    test = device.powers(test_hz, power, NOISE_W, rng)
    plain, _ = _fit(wm.Calibrator(FSR_HZ), sweep, sweep_hz)
    remedied, causes = _fit(wm.Calibrator(FSR_HZ), sweep, sweep_hz, dark_w=device.dark_offset_w)
    assert "detector_offset" not in causes
    # 4000 readings: the RMS/CRLB ratio has ~1.1 % statistical error; 1.1 is the target
    assert _rms_over_crlb(remedied, device, test, test_hz, power) < 1.1
    assert _rms_over_crlb(plain, device, test, test_hz, power) > 3.0
    np.testing.assert_array_equal(remedied.dark_w_, device.dark_offset_w)


def test_offsets_are_fitted_when_the_monitor_shows_the_power_varying():
    rng = np.random.default_rng(2)
    device = _offset_device(2, 0.05)
    sweep_hz = device.sweep_hz(2001)
    power = POWER_W * slow_power_drift(sweep_hz.size, 0.4, rng)
    sweep = device.powers(sweep_hz, power, NOISE_W, rng)
    calibrator, causes = _fit(
        wm.Calibrator(FSR_HZ), sweep, sweep_hz, power_monitor_w=device.monitor(power)
    )
    assert "detector_offset" in causes
    # the offsets come back within 5 of their standard errors (the covariance of the fit)
    variances = np.diag(calibrator.parameter_covariance_)[:-1].reshape(3, 4)[:, 3]
    z = (calibrator.offset_w_ - device.dark_offset_w) / np.sqrt(variances)
    assert np.all(np.abs(z) < 5), z
    test_hz = random_test_frequencies(device, 4000, rng)
    test_power = POWER_W * rng.uniform(0.5, 1.5, test_hz.size)
    test = device.powers(test_hz, test_power, NOISE_W, rng)
    assert _rms_over_crlb(calibrator, device, test, test_hz, test_power) < 1.1


def test_dark_readings_must_be_one_number_per_port():
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(64)
    with pytest.raises(wm.InputError, match="dark_w must be 3 finite numbers") as info:
        wm.Calibrator().fit(device.powers(f), f, dark_w=[0.0, 0.0])
    assert info.value.parameter == "dark_w"


# ----------------------------------------------------------------------------- flags
@pytest.fixture(scope="module")
def calibrated():
    rng = np.random.default_rng(3)
    device = wm.Interferometer.table1(4, seed=3)
    sweep_hz = device.sweep_hz(2001)
    calibrator = wm.Calibrator(FSR_HZ).fit(device.powers(sweep_hz, POWER_W, NOISE_W, rng), sweep_hz)
    return device, calibrator, rng


def test_clean_readings_carry_no_flag(calibrated):
    device, calibrator, rng = calibrated
    test_hz = random_test_frequencies(device, 20000, rng)
    flags = calibrator.flags(device.powers(test_hz, POWER_W, NOISE_W, rng))
    # OFF_MODEL at p < 1e-6: 20000 clean readings have a 2 % chance of one false flag
    assert np.count_nonzero(flags) <= 1
    assert flags.dtype == np.int64


def test_flags_mark_invalid_power_range_and_off_model_readings(calibrated):
    device, calibrator, rng = calibrated
    test_hz = random_test_frequencies(device, 6, rng)
    readings = device.powers(test_hz, POWER_W, NOISE_W, rng)
    readings[0, 1] = np.nan  # a sentinel the reader turned into NaN
    readings[1] = 0.0  # no light
    readings[2] *= 3.0  # three times the calibrated power
    readings[3, 2] += 100 * NOISE_W  # one port 100 noise standard deviations off the cone
    readings[4] *= 1.5  # within the factor-2 margin, beyond the 1.05 of unknown offsets
    flags = calibrator.flags(readings)
    assert flags[0] == ReadingFlag.INVALID
    assert flags[1] & ReadingFlag.INVALID
    assert flags[2] & ReadingFlag.POWER_RANGE
    assert flags[3] & ReadingFlag.OFF_MODEL
    # constant power and no dark readings: the offsets are unknown, other powers flagged
    assert flags[4] == ReadingFlag.POWER_RANGE and flags[5] == 0
    sweep_hz = device.sweep_hz(2001)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    dark = wm.Calibrator(FSR_HZ).fit(sweep, sweep_hz, dark_w=np.zeros(4))
    assert dark.flags(readings[[2, 4]]).tolist() == [ReadingFlag.POWER_RANGE, 0]


def test_partial_span_warns_and_flags_readings_outside_it():
    rng = np.random.default_rng(5)
    device = wm.Interferometer.table1(3, seed=5)
    sweep_hz = device.center_hz + device.true_fsr_hz * np.linspace(-0.25, 0.25, 1000)
    calibrator, causes = _fit(
        wm.Calibrator(FSR_HZ), device.powers(sweep_hz, POWER_W, NOISE_W, rng), sweep_hz
    )
    assert "partial_span" in causes
    test_hz = random_test_frequencies(device, 4000, rng)
    flags = calibrator.flags(device.powers(test_hz, POWER_W, NOISE_W, rng))
    outside = np.abs(test_hz - device.center_hz) > 0.3 * device.true_fsr_hz
    inside = np.abs(test_hz - device.center_hz) < 0.25 * device.true_fsr_hz
    assert np.mean(flags[outside] & ReadingFlag.OUTSIDE_SPAN > 0) >= 0.9
    assert np.mean(flags[inside] & ReadingFlag.OUTSIDE_SPAN > 0) < 0.01


def test_set_flags_coarse_values_outside_its_windows():
    rng = np.random.default_rng(6)
    device = wm.Interferometer.table1(3, seed=6)
    sweep_hz = device.sweep_hz(3000, span_fsr=3.0)
    cal = wm.CalibrationSet(FSR_HZ).fit(device.powers(sweep_hz, POWER_W, NOISE_W, rng), sweep_hz)
    readings = device.powers(sweep_hz[:3], POWER_W, NOISE_W, rng)
    low, high = cal.covered_hz()
    flags = cal.flags(readings, coarse_hz=[sweep_hz[0], low - 1e9, high + 1e9])
    assert flags.tolist() == [0, ReadingFlag.OUTSIDE_SPAN, ReadingFlag.OUTSIDE_SPAN]
    with pytest.raises(wm.InputError, match="needs coarse_hz"):
        cal.flags(readings)


# ----------------------------------------------------------------------------- uncertainty
def _z_scores(device, calibrator_factory, *, calibrations, samples, tests, noise_w, seed):
    """(estimate - true) / frequency_std_hz over repeated calibrations of one device."""
    rng = np.random.default_rng(seed)
    sweep_hz = device.sweep_hz(samples)
    scores = []
    for _ in range(calibrations):
        calibrator = calibrator_factory()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", wm.CalibrationWarning)
            calibrator.fit(device.powers(sweep_hz, POWER_W, noise_w, rng), sweep_hz)
        test_hz = random_test_frequencies(device, tests, rng)
        power = POWER_W * rng.uniform(0.7, 1.3, tests)
        readings = device.powers(test_hz, power, noise_w, rng)
        error = wm.frequency_error_hz(calibrator.predict(readings), test_hz, device.true_fsr_hz)
        scores.append(error / calibrator.frequency_std_hz(readings))
    return np.concatenate(scores)


IMPAIRED = {"symmetric_sigma": 0.2, "breaking_sigma": 0.1, "responsivity_sigma": 0.4}


@pytest.mark.slow
@pytest.mark.parametrize("retrieval", ["pinv", "ml"])
@pytest.mark.parametrize(
    ("ports", "impairments", "noise_ratios"),
    [(3, {}, None), (4, IMPAIRED, None), (5, {}, None), (3, {}, (1.0, 3.0, 1.0))],
    ids=["3-table1", "4-impaired", "5-table1", "3-unequal-noise"],
)
def test_frequency_std_gives_unit_z_scores(retrieval, ports, impairments, noise_ratios):
    device = wm.Interferometer.table1(ports, seed=7, **impairments)
    noise = NOISE_W if noise_ratios is None else NOISE_W * np.asarray(noise_ratios)
    z = _z_scores(
        device,
        lambda: wm.Calibrator(FSR_HZ, retrieval=retrieval),
        calibrations=12,
        samples=400,
        tests=1000,
        noise_w=noise,
        seed=8,
    )
    # 12000 scores from 12 calibrations: the calibration share (~3 n / N of the variance)
    # varies between calibrations; the spread of std(z) is below 1.5 %
    assert 0.95 < np.std(z) < 1.05


@pytest.mark.slow
@pytest.mark.parametrize("retrieval", ["pinv", "ml"])
def test_frequency_std_counts_the_calibration_of_few_samples(retrieval):
    device = wm.Interferometer.table1(3, seed=9)
    z = _z_scores(
        device,
        lambda: wm.Calibrator(FSR_HZ, retrieval=retrieval),
        calibrations=300,
        samples=8,
        tests=20,
        noise_w=NOISE_W,
        seed=10,
    )
    without = _z_scores(
        device,
        lambda: _NoiseOnly(FSR_HZ, retrieval=retrieval),
        calibrations=300,
        samples=8,
        tests=20,
        noise_w=NOISE_W,
        seed=10,
    )
    # 300 calibrations of 8 samples: std(z) has ~3 % statistical error (the calibration
    # errors are shared by the 20 readings of one calibration)
    assert 0.92 < np.std(z) < 1.08
    assert np.std(without) > np.std(z) * 1.05


class _NoiseOnly(wm.Calibrator):
    """frequency_std_hz without the calibration's own uncertainty, for comparison."""

    method = ""

    def frequency_std_hz(self, powers, **inputs):
        return super().frequency_std_hz(powers, include_calibration=False, **inputs)


@pytest.mark.slow
def test_set_frequency_std_gives_unit_z_scores():
    rng = np.random.default_rng(11)
    device = wm.Interferometer.table1(3, seed=11)
    sweep_hz = device.sweep_hz(3000, span_fsr=3.0)
    cal = wm.CalibrationSet(FSR_HZ).fit(device.powers(sweep_hz, POWER_W, NOISE_W, rng), sweep_hz)
    test_hz = device.center_hz + device.true_fsr_hz * rng.uniform(-1.4, 1.4, 6000)
    readings = device.powers(test_hz, POWER_W, NOISE_W, rng)
    error = cal.predict(readings, coarse_hz=test_hz) - test_hz
    z = error / cal.frequency_std_hz(readings, coarse_hz=test_hz)
    # 6000 readings over 3 windows of 1000 samples: statistics about 1 %, calibration share 1 %
    assert 0.95 < np.std(z) < 1.05


# ----------------------------------------------------------------------------- files
def test_diagnostics_flags_and_uncertainty_survive_a_file(tmp_path):
    rng = np.random.default_rng(12)
    device = _offset_device(12, 0.02)
    sweep_hz = device.sweep_hz(1000)
    power = POWER_W * slow_power_drift(sweep_hz.size, 0.3, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cal = wm.Calibrator(FSR_HZ, retrieval="ml").fit(
            device.powers(sweep_hz, power, NOISE_W, rng), sweep_hz, device.monitor(power)
        )
    cal.save(tmp_path / "c.wmcal.json")
    loaded = wm.load_calibration(tmp_path / "c.wmcal.json")
    assert loaded.diagnostics_ == cal.diagnostics_
    assert set(cal.diagnostics_["fit"]) >= {"residual_rms_w", "noise_std_w", "condition_number"}
    readings = device.powers(random_test_frequencies(device, 100, rng), POWER_W, NOISE_W, rng)
    readings[0] *= 5
    np.testing.assert_array_equal(loaded.flags(readings), cal.flags(readings))
    np.testing.assert_array_equal(loaded.frequency_std_hz(readings), cal.frequency_std_hz(readings))
    np.testing.assert_array_equal(loaded.predict(readings), cal.predict(readings))
    np.testing.assert_array_equal(loaded.offset_w_, cal.offset_w_)
