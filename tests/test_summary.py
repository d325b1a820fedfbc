"""Fit reports, fitted reprs, set_params/score, and the one argument convention of metrics.

The FSR's standard error comes from the curvature of ``J(tau)`` and the noise estimate:
``var(tau) = 2 s^2 / (N J''(tau))``. It is checked against the curvature of ``J`` by finite
differences and against a Monte Carlo over noise seeds: the spread of 200 fitted FSRs has
a relative standard error of ``1 / sqrt(2 * 199) = 5 %``, so it must match the predicted
sigma within 20 % (4 of those).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.registry import registered
from wavemeter.calibration.models.linear_map import map_cost, object_vectors

from .helpers import NOISE_W, POWER_W, thermal_sweep

MONTE_CARLO_SEEDS = 200
MONTE_CARLO_RTOL = 0.2


@pytest.fixture(scope="module")
def sweep():
    device = wm.Interferometer.table1(3, seed=7)
    frequency = device.sweep_hz(2001)
    return device, frequency, device.powers(frequency, POWER_W, NOISE_W, rng=1)


@pytest.fixture(scope="module")
def fitted(sweep):
    _, frequency, readings = sweep
    return wm.Calibrator(50e9).fit(readings, frequency)


def test_fitted_repr_shows_the_fit(fitted):
    unfitted = repr(wm.Calibrator(50e9))
    assert "fitted" not in unfitted
    text = repr(fitted)
    assert text.startswith(unfitted + " fitted: FSR 51.501")
    assert text.endswith("GHz, 3 ports, 2001 samples, RMS 14.3 MHz")


def test_summary_values_text_and_dict(fitted):
    report = fitted.summary()
    assert report["fsr_hz"].value == fitted.fsr_hz_ and report["fsr_hz"].unit == "Hz"
    assert report["fsr_hz"].stderr == pytest.approx(fitted.fsr_hz_**2 * fitted.delay_std_s_)
    assert report["noise_std_w"].value == fitted.noise_std_w_
    assert report["design_fsr_hz"].value == 50e9
    assert report.settings["retrieval"] == "pinv" and report.samples == 2001
    text = str(report)
    for expected in (
        "method           learned",
        "settings         fsr_hz 50 GHz; fsr_tolerance 0.2; search golden; xtol 1e-12; "
        "retrieval pinv",
        "FSR              51.501110 GHz +- 1.39 MHz (design 50 GHz)",
        "ports            3: p1, p2, p3",
        "samples          2001",
        "noise estimate   5.002e-07 W",
        "calibration RMS  14.2909 MHz",
        "port p2          ok",
        "warnings         none",
    ):
        assert expected in text
    document = json.loads(json.dumps(report.as_dict(), allow_nan=False))
    assert document["values"]["fsr_hz"]["stderr"] == report["fsr_hz"].stderr
    assert document["diagnostics"]["fsr_estimate_hz"] == pytest.approx(fitted.fsr_hz_, rel=1e-4)


def test_the_standard_error_is_the_curvature_of_the_cost(sweep, fitted):
    """var(tau) = 2 s^2 / (N J''): J'' by central differences at the fitted delay."""
    _, frequency, readings = sweep
    tau, step = fitted.delay_s_, 3e-5 * fitted.delay_s_

    def cost(delay_s):
        return map_cost(object_vectors(frequency, fitted.center_hz_, delay_s), readings)[1]

    curvature = (cost(tau + step) - 2 * cost(tau) + cost(tau - step)) / step**2
    variance = 2 * fitted.noise_std_w_**2 / (fitted.n_samples_ * curvature)
    assert fitted.delay_std_s_ == pytest.approx(np.sqrt(variance), rel=0.01)


@pytest.mark.slow
def test_the_standard_error_matches_a_monte_carlo_over_noise_seeds():
    device = wm.Interferometer.table1(3, seed=7)
    frequency = device.sweep_hz(501)
    fsrs, sigmas = [], []
    for seed in range(MONTE_CARLO_SEEDS):
        readings = device.powers(frequency, POWER_W, NOISE_W, rng=100 + seed)
        report = wm.Calibrator(50e9).fit(readings, frequency).summary()
        fsrs.append(report["fsr_hz"].value)
        sigmas.append(report["fsr_hz"].stderr)
    assert np.std(fsrs, ddof=1) == pytest.approx(np.mean(sigmas), rel=MONTE_CARLO_RTOL)
    # and it is unbiased: the mean of 200 fits is within 4 of its standard errors
    assert np.mean(fsrs) == pytest.approx(
        device.true_fsr_hz, abs=4 * np.mean(sigmas) / np.sqrt(MONTE_CARLO_SEEDS)
    )


@pytest.mark.slow
@pytest.mark.parametrize("tag", sorted(registered()))
def test_every_calibrator_has_a_summary(sweep, tag, tmp_path):
    device, frequency, readings = sweep
    cls = registered()[tag]
    inputs = {}
    if tag == "calibration_set":
        frequency = device.sweep_hz(4002, span_fsr=2.0)
        readings = device.powers(frequency, POWER_W, NOISE_W, rng=2)
    if "temperature_k" in cls.requires:
        readings, frequency, temperature = thermal_sweep(
            device.with_thermal("sin"), 1000, NOISE_W, rng=2
        )
        inputs = {"temperature_k": temperature}
    settings = {"fsr_hz": 50e9}
    if tag == "cascade":
        # a two-stage cascade over 4 FSRs of its finest stage
        cascade = wm.CascadeInterferometer.table1((400e9, 50e9), seed=2, spectral=None)
        frequency = cascade.center_hz + np.linspace(-100e9, 100e9, 2001)
        readings = cascade.powers(frequency, POWER_W, NOISE_W, rng=2)
        settings = {"fsr_hz": (400e9, 50e9)}
    cal = cls(**settings).fit(readings, frequency, **inputs)
    report = cal.summary()
    assert report.method == tag and report["fsr_hz"].value == cal.fsr_hz_
    assert "FSR" in report.text and "fitted: FSR" in repr(cal)
    json.dumps(report.as_dict(), allow_nan=False)
    cal.save(tmp_path / "cal.json")
    loaded = wm.load_calibration(tmp_path / "cal.json")
    assert loaded.summary().as_dict() == report.as_dict()
    if tag == "calibration_set":
        assert len(report.windows) == 2 and "windows" in report.text
    if tag == "cascade":
        assert len(report.windows) == 2 and "hand-over 1 to 2 margin (std)" in report.text
        assert "hand-overs:" in report.text and "stage 1 to 2" in report.text
        assert report.windows_are == "stages" and "\n  2 " in report.text


def test_summary_before_fit_raises():
    with pytest.raises(wm.NotFittedError):
        wm.Calibrator().summary()


def test_set_params_and_score(sweep, fitted):
    cal = wm.Calibrator(50e9)
    assert cal.set_params(fsr_tolerance=0.1, retrieval="ml") is cal
    assert cal.get_params()["fsr_tolerance"] == 0.1 and cal.retrieval == "ml"
    with pytest.raises(wm.InputError, match="'colour' is not a setting of Calibrator"):
        cal.set_params(colour="red")
    device, frequency, readings = sweep
    rng = np.random.default_rng(3)
    test_hz = device.center_hz + rng.uniform(-0.5, 0.5, 4000) * device.true_fsr_hz
    test = device.powers(test_hz, POWER_W, NOISE_W, rng)
    error = wm.frequency_error_hz(fitted.predict(test), test_hz, fsr_hz=fitted.fsr_hz_)
    assert fitted.score(test, test_hz) == -np.sqrt(np.mean(error**2))
    # noise-limited: about the Table 1 CRLB of ~10-15 MHz, far from an FSR
    assert -20e6 < fitted.score(test, test_hz) < -8e6


def test_metrics_share_one_argument_convention():
    predicted = np.array([100.0, 250.0, -30.0])
    truth = np.array([0.0, 0.0, 0.0])
    np.testing.assert_array_equal(wm.frequency_error_hz(predicted, truth), predicted)
    np.testing.assert_array_equal(
        wm.frequency_error_hz(predicted, truth, fsr_hz=200.0), [100.0 - 200.0, 50.0, -30.0]
    )
    # the old positional form is the same call
    np.testing.assert_array_equal(
        wm.frequency_error_hz(predicted, truth, 200.0),
        wm.frequency_error_hz(predicted, truth, fsr_hz=200.0),
    )
    absolute = wm.error_summary_hz(predicted, truth)
    assert absolute["max_hz"] == 250.0
    assert absolute["rms_hz"] == pytest.approx(np.sqrt((100**2 + 250**2 + 30**2) / 3))
    wrapped = wm.error_summary_hz(predicted, truth, fsr_hz=200.0)
    assert wrapped["max_hz"] == 100.0
    assert wrapped == wm.error_summary_hz(wm.frequency_error_hz(predicted, truth, fsr_hz=200.0))
    with pytest.raises(wm.InputError, match="fsr_hz needs true_hz"):
        wm.error_summary_hz(predicted, fsr_hz=200.0)
    with pytest.raises(wm.InputError, match="same shape"):
        wm.frequency_error_hz(predicted, truth[:2])
