"""The learned calibration: recovery of a known device, the search, retrieval, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wavemeter as wm
from wavemeter.calibration.models.learned_fit import predict_frequency_hz
from wavemeter.calibration.models.linear_map import fit_map, map_cost, object_vectors

from .helpers import NOISE_W, POWER_W, random_test_frequencies


def _rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.fixture(scope="module")
def noisy_fit():
    device = wm.Interferometer.table1(3, seed=11)
    rng = np.random.default_rng(11)
    f = device.sweep_hz(2001)
    cal = wm.Calibrator(50e9).fit(device.powers(f, POWER_W, NOISE_W, rng), f)
    return device, cal


@pytest.mark.parametrize("ports", [3, 4, 5, 8])
def test_noiseless_fit_recovers_the_device(ports):
    device = wm.Interferometer.table1(ports, seed=ports)
    f = device.sweep_hz(301)
    cal = wm.Calibrator(50e9).fit(device.powers(f, POWER_W), f)
    assert cal.fsr_hz_ == pytest.approx(device.true_fsr_hz, rel=1e-11)
    # the learned map is the true map at the calibration power, rotated to the sweep centre
    rotation = _rotation(2 * np.pi * (cal.center_hz_ - device.center_hz) * device.delay_s)
    np.testing.assert_allclose(cal.map_, POWER_W * device.true_map() @ rotation, atol=1e-15)
    assert cal.residual_rms_ < 1e-12 * POWER_W  # phase error below 1e-12 rad
    assert cal.map_.shape == (ports, 3) and cal.map_pinv_.shape == (3, ports)


def test_noisy_fit_statistics(noisy_fit):
    device, cal = noisy_fit
    # FSR: the slope of 2001 phases with sigma_t ~ 1.2e-3 rad over 2 pi has a relative
    # standard error sigma_t sqrt(12 / N) / (2 pi) ~ 1.5e-5; allow 5 of them
    sigma_t = 2 * np.pi * wm.crlb_ideal_frequency_std(3, POWER_W, NOISE_W, 50e9) / 50e9
    fsr_se = sigma_t * np.sqrt(12 / cal.n_samples_) / (2 * np.pi)
    assert abs(cal.fsr_hz_ / device.true_fsr_hz - 1) < 5 * fsr_se
    # the noise estimate from the residual: 6003 readings, relative standard error ~ 1 %
    assert cal.noise_std_w_ == pytest.approx(NOISE_W, rel=0.05)
    assert cal.residual_rms_ < cal.noise_std_w_


def test_pure_functions_agree_with_the_class(noisy_fit, rng):
    device, cal = noisy_fit
    f = random_test_frequencies(device, 5000, rng)
    readings = device.powers(f, POWER_W, NOISE_W, rng)
    np.testing.assert_allclose(
        predict_frequency_hz(readings, cal.map_, cal.center_hz_, cal.fsr_hz_),
        cal.predict(readings),
        rtol=1e-12,
        atol=0,
    )
    np.testing.assert_allclose(
        wm.retrieve_phase_rad(readings, np.linalg.pinv(cal.map_)), cal.phase(readings), atol=1e-12
    )
    objects = object_vectors(f, cal.center_hz_, cal.delay_s_)
    np.testing.assert_allclose(fit_map(objects, readings), map_cost(objects, readings)[0])


def test_map_solves_the_normal_equations(noisy_fit, rng):
    """A = Ryx Rxx^-1 (Eq. 23), checked against the textbook formula on noisy data."""
    device, cal = noisy_fit
    f = device.sweep_hz(500)
    readings = device.powers(f, POWER_W, NOISE_W, rng)
    x = object_vectors(f, device.center_hz, device.delay_s)
    ryx, rxx = readings.T @ x / len(f), x.T @ x / len(f)
    np.testing.assert_allclose(fit_map(x, readings), ryx @ np.linalg.inv(rxx), rtol=1e-10)


def test_brent_and_golden_agree():
    device = wm.Interferometer.table1(4, seed=3)
    f = device.sweep_hz(201)
    readings = device.powers(f, POWER_W)
    golden = wm.Calibrator(50e9, search="golden").fit(readings, f)
    brent = wm.Calibrator(50e9, search="brent").fit(readings, f)
    assert brent.fsr_hz_ == pytest.approx(golden.fsr_hz_, rel=1e-10)
    assert golden.fsr_hz_ == pytest.approx(device.true_fsr_hz, rel=1e-10)


def test_minimum_on_bracket_edge_is_an_error():
    device = wm.Interferometer.ideal(3, fsr_hz=50e9)
    f = device.sweep_hz(201)
    with pytest.raises(wm.EdgeMinimumError, match="widen fsr_tolerance or correct fsr_hz"):
        wm.Calibrator(fsr_hz=65e9, fsr_tolerance=0.1).fit(device.powers(f, POWER_W), f)


def test_branch_cut_outside_a_partial_span():
    """A sweep over 60 % of an FSR maps continuously; the cut sits in the unswept part."""
    device = wm.Interferometer.table1(3, seed=4)
    f = device.sweep_hz(400, span_fsr=0.6) + 0.3 * device.true_fsr_hz
    cal = wm.Calibrator(50e9).fit(device.powers(f, POWER_W), f)
    predicted = cal.predict(device.powers(f, POWER_W))
    assert np.all(np.diff(predicted) > 0)
    np.testing.assert_allclose(predicted, f, atol=1.0)
    assert cal.center_hz_ == pytest.approx((f.min() + f.max()) / 2)


def test_power_monitor_makes_calibration_immune_to_fluctuations(rng):
    device = wm.Interferometer.table1(3, seed=8)
    f = device.sweep_hz(1001)
    power = POWER_W * rng.uniform(0.5, 1.5, f.size)
    readings = device.powers(f, power)
    with_monitor = wm.Calibrator(50e9).fit(readings, f, power_monitor_w=device.monitor(power))
    without = wm.Calibrator(50e9).fit(readings, f)
    test_f = random_test_frequencies(device, 2000, rng)
    test = device.powers(test_f, POWER_W)
    errors = {
        name: np.abs(wm.frequency_error_hz(cal.predict(test), test_f, device.true_fsr_hz)).max()
        for name, cal in (("monitor", with_monitor), ("none", without))
    }
    assert errors["monitor"] < 1.0  # noiseless: exact
    assert errors["none"] > 1e3 * errors["monitor"]  # off the cone: the map is biased


@pytest.mark.slow
@settings(max_examples=30, deadline=None)
@given(scale=st.floats(1e-3, 1e3), index=st.integers(0, 499))
def test_phase_is_invariant_to_source_power(noisy_fit, scale, index):
    device, cal = noisy_fit
    readings = device.powers(device.sweep_hz(500), POWER_W)[index : index + 1]
    assert cal.phase(readings * scale)[0] == pytest.approx(cal.phase(readings)[0], abs=1e-12)


def test_single_reading_and_list_input(noisy_fit):
    device, cal = noisy_fit
    reading = device.powers([device.center_hz + 1e9], POWER_W)
    assert cal.predict(reading[0].tolist()).shape == (1,)
    # a noiseless reading through a map learned from noisy data: the calibration error is
    # about CRLB * sqrt(3 / N) ~ 0.4 MHz; allow 8 of them
    assert cal.predict(reading[0])[0] == pytest.approx(device.center_hz + 1e9, abs=3e6)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"fsr_hz": -1.0}, "fsr_hz must be a finite number > 0"),
        ({"fsr_tolerance": 1.5}, r"fsr_tolerance must be in \(0, 1.0\)"),
        ({"search": "newton"}, "search must be one of 'golden', 'brent'; got 'newton'"),
        ({"fsr_hz": "50GHz"}, "fsr_hz must be a real number"),
    ],
)
def test_parameter_errors_name_the_parameter(params, match):
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(20)
    with pytest.raises((ValueError, TypeError), match=match):
        wm.Calibrator(**params).fit(device.powers(f), f)


def test_bad_input_errors():
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(50)
    readings = device.powers(f, POWER_W)
    cal = wm.Calibrator(50e9)
    with pytest.raises(wm.NotFittedError, match="not fitted"):
        cal.predict(readings)
    bad = readings.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match=r"NaN or inf in rows \[7\]"):
        cal.fit(bad, f)
    with pytest.raises(ValueError, match="at least 4 samples"):
        cal.fit(readings[:3], f[:3])
    with pytest.raises(ValueError, match="at least 3 ports"):
        cal.fit(readings[:, :2], f)
    with pytest.raises(ValueError, match="sum to zero or less"):
        cal.fit(-readings, f)
    with pytest.raises(ValueError, match="vector of 50 values"):
        cal.fit(readings, f[:-1])
    with pytest.raises(ValueError, match="less than 0.1 of the FSR"):
        cal.fit(readings[:5], f[:5])
    cal.fit(readings, f)
    with pytest.raises(ValueError, match="have 4 ports but the calibration has 3"):
        cal.predict(np.ones((2, 4)))


@pytest.mark.parametrize("true_fsr_hz", [35e9, 70e9])
def test_long_sweep_with_fsr_far_outside_the_bracket_is_an_error(true_fsr_hz):
    """On 20 FSRs a side minimum of J may lie inside the bracket; it must not pass as a fit."""
    device = wm.Interferometer.ideal(3, fsr_hz=true_fsr_hz)
    f = device.sweep_hz(4000, span_fsr=20)
    readings = device.powers(f, POWER_W, NOISE_W, np.random.default_rng(1))
    with pytest.raises(wm.EdgeMinimumError, match="widen fsr_tolerance or correct fsr_hz"):
        wm.Calibrator(fsr_hz=50e9).fit(readings, f)
