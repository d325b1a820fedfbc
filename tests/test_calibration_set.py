"""Calibration sets: a map per FSR over a 950 GHz sweep (paper Fig. 8), and its neighbours (Fig. 9).

Tolerances from physics: the per-reading Cramer-Rao bound of the true map (detector noise
5e-7 W at 1 mW), and the FSR bound of :mod:`tests.test_delay_search`.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods.set import WINDOW_FSR_TOLERANCE
from wavemeter.calibration.methods.set_checks import adjacent_evaluation
from wavemeter.model.cone import delay_phase_rad

from .helpers import NOISE_W, POWER_W, fsr_crlb_std_hz

SPAN_HZ = 950e9
SAMPLES_PER_FSR = 400
TEST_PER_WINDOW = 60
DEVICE_SEED = 11  # true FSR 50.52 GHz: 18.8 FSRs in 950 GHz, so the outer windows are partial
# |error| < 5 CRLB: for a correct calibration P(|z| > 5 / 1.1) ~ 5e-6 per reading (the
# per-reading bound varies by < 10 % over the phase), ~ 1 % over the 1140 test readings.
MAX_ERROR_IN_CRLB = 5.0


@pytest.fixture(scope="module")
def device():
    return wm.Interferometer.table1(3, seed=DEVICE_SEED)


@pytest.fixture(scope="module")
def sweep(device):
    frequency = device.center_hz + np.linspace(-SPAN_HZ / 2, SPAN_HZ / 2, 19 * SAMPLES_PER_FSR)
    return frequency, device.powers(frequency, POWER_W, NOISE_W, rng=1)


@pytest.fixture(scope="module")
def calibration_set(device, sweep):
    frequency, readings = sweep
    return wm.CalibrationSet(50e9).fit(readings, frequency)


@pytest.fixture(scope="module")
def test_data(device, calibration_set):
    """``TEST_PER_WINDOW`` readings uniform inside each window: (frequency, readings)."""
    rng = np.random.default_rng(2)
    edges = calibration_set.window_edges_hz_
    frequency = np.concatenate(
        [
            rng.uniform(low, high, TEST_PER_WINDOW)
            for low, high in zip(edges[:-1], edges[1:], strict=True)
        ]
    )
    return frequency, device.powers(frequency, POWER_W, NOISE_W, rng)


def crlb_hz(device, frequency_hz):
    phase = delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    return wm.crlb_frequency_std(device.true_map(), phase, POWER_W, NOISE_W, device.true_fsr_hz)


def rms(values):
    return float(np.sqrt(np.mean(np.square(values))))


@pytest.mark.slow
def test_windows_are_one_fitted_fsr_wide_centred_on_the_sweep(device, sweep, calibration_set):
    frequency, _ = sweep
    edges = calibration_set.window_edges_hz_
    assert len(calibration_set.windows_) == round(SPAN_HZ / device.true_fsr_hz) == 19
    np.testing.assert_allclose(np.diff(edges), calibration_set.fsr_hz_, rtol=1e-12)
    assert (edges[0] + edges[-1]) / 2 == pytest.approx(device.center_hz, abs=1e3)
    sigma = fsr_crlb_std_hz(device, frequency)
    assert abs(calibration_set.fsr_hz_ - device.true_fsr_hz) < 4 * sigma
    for low, high, window in zip(edges[:-1], edges[1:], calibration_set.windows_, strict=True):
        assert low <= window.span_hz_[0] < window.span_hz_[1] < high
        inside = (frequency >= low) & (frequency < high)
        assert window.n_samples_ == inside.sum()
        # each window refits its own delay: within 4.5 of its own Cramer-Rao sigma
        assert abs(window.fsr_hz_ - device.true_fsr_hz) < 4.5 * fsr_crlb_std_hz(
            device, frequency[inside]
        )


def test_each_window_is_the_calibration_of_its_own_readings(sweep, calibration_set):
    frequency, readings = sweep
    edges = calibration_set.window_edges_hz_
    for index in (0, 9, 18):
        inside = (frequency >= edges[index]) & (frequency < edges[index + 1])
        alone = wm.Calibrator(calibration_set.fsr_hz_, fsr_tolerance=WINDOW_FSR_TOLERANCE)
        alone.fit(readings[inside], frequency[inside])
        np.testing.assert_array_equal(calibration_set.windows_[index].map_, alone.map_)


def test_every_window_is_at_the_crlb(device, calibration_set, test_data):
    frequency, readings = test_data
    error = calibration_set.predict(readings, coarse_hz=frequency) - frequency
    bound = crlb_hz(device, frequency)
    window = calibration_set.window_index(frequency)
    for index in range(len(calibration_set.windows_)):
        rows = window == index
        assert rows.sum() == TEST_PER_WINDOW
        assert np.abs(error[rows]).max() < MAX_ERROR_IN_CRLB * rms(bound[rows])
    # and as a whole the RMS is the bound's (estimator a few % above it, 2 % scatter)
    assert 0.9 < rms(error) / rms(bound) < 1.15


def test_a_coarse_value_off_by_up_to_a_third_fsr_gives_the_same_frequency(
    device, calibration_set, test_data
):
    frequency, readings = test_data
    offset = np.random.default_rng(3).uniform(-1 / 3, 1 / 3, frequency.size) * device.true_fsr_hz
    low, high = calibration_set.covered_hz()
    coarse = np.clip(frequency + offset, low, high)
    error = calibration_set.predict(readings, coarse_hz=coarse) - frequency
    assert np.abs(error).max() < MAX_ERROR_IN_CRLB * rms(crlb_hz(device, frequency))


def test_adjacent_windows_degrade_little_and_stay_far_below_conventional(
    device, calibration_set, test_data
):
    frequency, readings = test_data
    baseline = wm.ConventionalCalibrator(port_phases_rad=device.design_port_phases_rad)
    report = adjacent_evaluation(calibration_set, readings, frequency, baseline)
    assert report["windows_evaluated"] == len(calibration_set.windows_) == len(report["windows"])
    bound_rms = rms(crlb_hz(device, frequency))
    for entry in report["windows"]:
        # the simulated map is the same in every FSR: a neighbour's map differs only by
        # its one-FSR delay error extrapolated by one FSR (~ 0.3 CRLB)
        assert entry["adjacent"]["max_hz"] < MAX_ERROR_IN_CRLB * bound_rms
        assert entry["adjacent"]["max_hz"] < entry["conventional_adjacent"]["max_hz"]
        assert entry["adjacent"]["max_hz"] < entry["conventional_own"]["max_hz"]
        assert entry["samples_own"] == TEST_PER_WINDOW
    # RMS of 1080 readings: sqrt(1 + 0.3^2) plus 3 % scatter
    assert report["degradation_rms"] < 1.15
    # the paper's claim: the learned maps are over an order of magnitude better
    assert report["conventional_adjacent"]["rms_hz"] > 10 * report["adjacent"]["rms_hz"]
    json.dumps(report)  # JSON-ready for `wavemeter evaluate --adjacent --json`


def test_adjacent_evaluation_needs_two_neighbouring_windows(calibration_set, test_data):
    frequency, readings = test_data
    first = calibration_set.window_index(frequency) == 0
    with pytest.raises(ValueError, match="neighbouring window"):
        adjacent_evaluation(calibration_set, readings[first], frequency[first])


def test_save_load_round_trip_predicts_bit_for_bit(calibration_set, test_data, tmp_path):
    frequency, readings = test_data
    path = tmp_path / "set.wmcal.json"
    calibration_set.save(path)
    document = json.loads(path.read_text())
    assert document["method"] == "calibration_set"
    assert document["params"]["window"]["method"] == "learned"
    loaded = wm.load_calibration(path)
    assert isinstance(loaded, wm.CalibrationSet)
    assert loaded.get_params_for_file() == calibration_set.get_params_for_file()
    np.testing.assert_array_equal(loaded.window_edges_hz_, calibration_set.window_edges_hz_)
    np.testing.assert_array_equal(
        loaded.predict(readings, coarse_hz=frequency),
        calibration_set.predict(readings, coarse_hz=frequency),
    )
    np.testing.assert_array_equal(
        loaded.phase(readings, coarse_hz=frequency),
        calibration_set.phase(readings, coarse_hz=frequency),
    )
    for name in calibration_set.common_attributes:
        assert getattr(loaded, name) == getattr(calibration_set, name)


def test_a_file_with_a_missing_window_is_refused(calibration_set, tmp_path):
    path = tmp_path / "set.wmcal.json"
    calibration_set.save(path)
    document = json.loads(path.read_text())
    del document["state"]["windows"][3]
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match="set.wmcal.json: invalid 'calibration_set'.*19 calib"):
        wm.load_calibration(path)


def test_a_corrupt_window_is_named(calibration_set, tmp_path):
    path = tmp_path / "set.wmcal.json"
    calibration_set.save(path)
    document = json.loads(path.read_text())
    document["state"]["windows"][4]["fsr_hz"] = "fifty"
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match="window 4: field 'fsr_hz' must be a finite number"):
        wm.load_calibration(path)


def test_predict_without_coarse_frequency_says_what_is_needed(calibration_set, test_data):
    _, readings = test_data
    with pytest.raises(ValueError, match="needs coarse_hz.*laser set point"):
        calibration_set.predict(readings)
    with pytest.raises(ValueError, match="needs coarse_hz"):
        calibration_set.phase(readings)


@pytest.mark.parametrize("where", ["below", "above"])
def test_coarse_frequency_outside_every_window_is_refused(calibration_set, test_data, where):
    _, readings = test_data
    low, high = calibration_set.covered_hz()
    coarse = low - 1e9 if where == "below" else high + 1e9
    with pytest.raises(ValueError, match="coarse_hz .* outside the calibrated span .* THz"):
        calibration_set.predict(readings, coarse_hz=coarse, errors="raise")
    # by default: NaN and OUTSIDE_SPAN for each of them, the others read as usual
    assert np.isnan(calibration_set.predict(readings, coarse_hz=coarse)).all()
    assert np.all(calibration_set.flags(readings, coarse_hz=coarse) == wm.ReadingFlag.OUTSIDE_SPAN)


@pytest.mark.parametrize(
    ("coarse", "error", "match"),
    [
        ([193.4e12, 193.4e12], ValueError, r"one value or one per reading \(1140\)"),
        (float("nan"), ValueError, "NaN or inf"),
        ("193.4 THz", wm.InputError, "coarse_hz must be a number"),
    ],
)
def test_bad_coarse_values_are_refused(calibration_set, test_data, coarse, error, match):
    _, readings = test_data
    with pytest.raises(error, match=match):
        calibration_set.predict(readings, coarse_hz=coarse, errors="raise")


def test_a_reading_without_a_coarse_value_gets_nan_and_invalid(calibration_set, test_data):
    frequency, readings = test_data
    coarse = frequency.copy()
    coarse[[3, 8]] = np.nan
    found = calibration_set.readout(readings, coarse_hz=coarse)
    assert np.isnan(found.frequency_hz[[3, 8]]).all()
    assert np.all(found.flags[[3, 8]] & wm.ReadingFlag.INVALID)
    kept = np.isfinite(coarse)
    np.testing.assert_array_equal(
        found.frequency_hz[kept], calibration_set.predict(readings[kept], coarse_hz=frequency[kept])
    )


def test_scalar_coarse_value_applies_to_every_reading(calibration_set, test_data):
    frequency, readings = test_data
    rows = calibration_set.window_index(frequency) == 9
    centre = calibration_set.windows_[9].center_hz_
    np.testing.assert_array_equal(
        calibration_set.predict(readings[rows], coarse_hz=centre),
        calibration_set.predict(readings[rows], coarse_hz=np.full(rows.sum(), centre)),
    )


def test_unfitted_set_raises_not_fitted(tmp_path):
    unfitted = wm.CalibrationSet()
    with pytest.raises(wm.NotFittedError):
        unfitted.predict(np.ones((2, 3)), coarse_hz=193.4e12)
    with pytest.raises(wm.NotFittedError):
        unfitted.save(tmp_path / "x.json")


def test_a_window_that_is_not_a_single_fsr_calibrator_is_refused(sweep):
    frequency, readings = sweep
    for window in ("golden", wm.CalibrationSet()):
        with pytest.raises(wm.InputError, match="window must be an unfitted single-FSR"):
            wm.CalibrationSet(window=window).fit(readings, frequency)


def test_sweep_shorter_than_half_an_fsr_is_refused(device):
    frequency = device.sweep_hz(200, span_fsr=0.4)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=4)
    with pytest.raises(ValueError, match="less than half the fitted FSR"):
        wm.CalibrationSet().fit(readings, frequency)


def test_true_fsr_far_outside_the_bracket_is_not_fitted_to_a_side_minimum():
    far = wm.Interferometer.table1(3, seed=DEVICE_SEED, fsr_hz=70e9, delay_sigma=0.0)
    frequency = far.sweep_hz(4000, span_fsr=20)
    readings = far.powers(frequency, POWER_W, NOISE_W, rng=5)
    with pytest.raises(wm.EdgeMinimumError, match="side minimum"):
        wm.CalibrationSet(50e9).fit(readings, frequency)


@pytest.mark.slow
def test_conventional_windows_and_power_monitor(device, sweep):
    frequency, _ = sweep
    rng = np.random.default_rng(6)
    source = POWER_W * (1 + 0.1 * rng.standard_normal(frequency.size))
    readings = device.powers(frequency, source, NOISE_W, rng)
    before = readings.copy()
    monitored = wm.CalibrationSet(50e9).fit(readings, frequency, device.monitor(source))
    np.testing.assert_array_equal(readings, before)  # inputs are not modified
    window = wm.ConventionalCalibrator(port_phases_rad=device.design_port_phases_rad)
    conventional = wm.CalibrationSet(50e9, window=window).fit(readings, frequency)
    assert all(isinstance(w, wm.ConventionalCalibrator) for w in conventional.windows_)
    # the calibration RMS: learned with a monitor at the noise level (~ CRLB at 1 mW),
    # conventional an order of magnitude worse
    bound = rms(crlb_hz(device, frequency))
    assert monitored.calibration_rms_hz_ < 1.2 * bound
    assert conventional.calibration_rms_hz_ > 10 * monitored.calibration_rms_hz_


@pytest.mark.slow
def test_windows_follow_a_local_fsr_that_drifts_across_the_band(device):
    """Dispersion: phase ``2 pi tau (d + beta d^2)``, ``d = f - f0``, local FSR off by +-0.3 %.

    Each window refits its delay, so it follows the local FSR ``FSR / (1 + 2 beta d)`` and
    stays at the bound; one map and one delay over the band cannot.
    """
    half_span = SPAN_HZ / 2
    beta = 0.003 / (2 * half_span)

    def readings_at(frequency, rng):
        offset = frequency - device.center_hz
        return device.powers(frequency + beta * offset**2, POWER_W, NOISE_W, rng)

    frequency = device.center_hz + np.linspace(-half_span, half_span, 19 * SAMPLES_PER_FSR)
    readings = readings_at(frequency, np.random.default_rng(7))
    dispersive = wm.CalibrationSet(50e9).fit(readings, frequency)
    edges = dispersive.window_edges_hz_
    for index, window in enumerate(dispersive.windows_):
        local_fsr = device.true_fsr_hz / (1 + 2 * beta * (window.center_hz_ - device.center_hz))
        inside = (frequency >= edges[index]) & (frequency < edges[index + 1])
        sigma = fsr_crlb_std_hz(device, frequency[inside])
        assert abs(window.fsr_hz_ - local_fsr) < 4 * sigma, index
    rng = np.random.default_rng(8)
    test_hz = rng.uniform(edges[0], edges[-1], 19 * TEST_PER_WINDOW)
    test = readings_at(test_hz, rng)
    bound = rms(crlb_hz(device, test_hz + beta * (test_hz - device.center_hz) ** 2))
    error = dispersive.predict(test, coarse_hz=test_hz) - test_hz
    assert np.abs(error).max() < MAX_ERROR_IN_CRLB * bound
    single = wm.Calibrator(50e9).fit(readings, frequency)
    single_error = wm.frequency_error_hz(single.predict(test), test_hz, single.fsr_hz_)
    assert rms(single_error) > 10 * rms(error)


def test_windows_copy_the_window_calibrators_settings(device, sweep):
    frequency, readings = sweep[0][:4000], sweep[1][:4000]
    template = wm.Calibrator(retrieval="ml")
    ml_set = wm.CalibrationSet(50e9, window=template).fit(readings, frequency)
    assert all(window.retrieval == "ml" for window in ml_set.windows_)
    assert all(window.fsr_tolerance == WINDOW_FSR_TOLERANCE for window in ml_set.windows_)
    assert not hasattr(template, "fsr_hz_")  # the template itself is never fitted


def test_a_version_0_1_set_file_still_loads(calibration_set, test_data, tmp_path):
    """0.1 wrote the window method as ``method`` with ``retrieval`` and port phases."""
    frequency, readings = test_data
    path = tmp_path / "old.wmcal.json"
    calibration_set.save(path)
    document = json.loads(path.read_text())
    document["params"] = {
        "fsr_hz": 50e9,
        "fsr_tolerance": 0.2,
        "method": "learned",
        "port_phases_rad": None,
        "retrieval": "pinv",
    }
    path.write_text(json.dumps(document))
    loaded = wm.load_calibration(path)
    np.testing.assert_array_equal(
        loaded.predict(readings, coarse_hz=frequency),
        calibration_set.predict(readings, coarse_hz=frequency),
    )
