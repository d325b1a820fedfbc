"""The reference-free cone: phase from the powers alone, on simulated devices and on
measured 3x3 fibre-coupler data.

Phase is compared after removing what no label-free method can know, and nothing else:
the direction (the better of the two signs) and the origin (the circular mean of the
difference).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration import cone_phase_rad, fit_cone

POWER_W = 1e-3
NOISE_W = 5e-7
MINIPTI = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
#: issue 32: agreement with MiniPTI's published phase on the measured data (rad RMS)
MINIPTI_AGREEMENT_RAD = 5e-3


def wrapped(phase):
    return np.angle(np.exp(1j * np.asarray(phase)))


def aligned_error(phase, truth):
    """Phase error (rad) after the better sign and the circular-mean offset."""
    best = None
    for sign in (1, -1):
        difference = wrapped(sign * np.asarray(phase) - truth)
        error = wrapped(difference - np.angle(np.mean(np.exp(1j * difference))))
        if best is None or np.mean(error**2) < np.mean(best**2):
            best = error
    return best


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def sweep(ports, kind="table1", samples=2000):
    device = (
        wm.Interferometer.ideal(ports)
        if kind == "ideal"
        else wm.Interferometer.table1(ports, seed=7)
    )
    frequency = device.sweep_hz(samples)
    return device, frequency, 2 * np.pi * (frequency - device.center_hz) * device.delay_s


@pytest.mark.parametrize("ports", [3, 4, 5])
def test_noiseless_constant_power_is_exact_up_to_origin_and_direction(ports):
    device, frequency, phase = sweep(ports)
    readings = device.powers(frequency, POWER_W, 0.0)
    fit = fit_cone(readings)
    assert rms(aligned_error(cone_phase_rad(fit, readings), phase)) < 1e-12
    assert fit.power_spread < 1e-12 and fit.frame_std_rad < 1e-12
    # retrieval is invariant to the source power: any power, same phase
    scaled = readings * np.linspace(0.2, 5.0, frequency.size)[:, None]
    assert rms(wrapped(cone_phase_rad(fit, scaled) - cone_phase_rad(fit, readings))) < 1e-12


@pytest.mark.parametrize("ports", [3, 5])
def test_varying_power_with_a_monitor_is_exact(ports):
    device, frequency, phase = sweep(ports)
    power = POWER_W * (1 + 0.3 * np.random.default_rng(1).uniform(-1, 1, frequency.size))
    readings = device.powers(frequency, power, 0.0)
    fit = fit_cone(readings, power=power)
    assert rms(aligned_error(cone_phase_rad(fit, readings), phase)) < 1e-12


def test_random_power_without_a_monitor_leaves_the_stated_frame_error():
    """The cone is Lorentz invariant: with a power varying at random the frame is a
    statistical estimate. Over 20 draws, (error / frame_std_rad)^2 is chi-square of 2
    degrees over 2: its mean lies in 0.45-1.8 (chi-square 40 / 40 at 0.1 % each side)."""
    device, frequency, phase = sweep(3)
    ratios = []
    for seed in range(20):
        power = POWER_W * (1 + 0.3 * np.random.default_rng(seed).uniform(-1, 1, frequency.size))
        readings = device.powers(frequency, power, 0.0)
        fit = fit_cone(readings)
        ratios.append(rms(aligned_error(cone_phase_rad(fit, readings), phase)) / fit.frame_std_rad)
    assert 0.45 < np.mean(np.square(ratios)) < 1.8


@pytest.mark.slow
@pytest.mark.parametrize(
    "ports", [3, pytest.param(4, marks=pytest.mark.slow), pytest.param(5, marks=pytest.mark.slow)]
)
def test_detector_offsets_are_fitted_when_the_power_varies(ports):
    device, frequency, phase = sweep(ports)
    power = POWER_W * (1 + 0.3 * np.random.default_rng(2).uniform(-1, 1, frequency.size))
    offsets = np.random.default_rng(3).uniform(1e-5, 5e-5, ports)
    readings = device.powers(frequency, power, 0.0) + offsets
    fit = fit_cone(readings, power=power, offsets="fit")
    np.testing.assert_allclose(fit.vertex_w, offsets, rtol=0, atol=1e-12 * POWER_W)
    assert rms(aligned_error(cone_phase_rad(fit, readings), phase)) < 1e-9


@pytest.mark.slow
def test_offsets_at_constant_power_are_refused_with_the_reason():
    device, frequency, _ = sweep(3)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1) + 2e-5
    with pytest.raises(wm.InputError, match="the source power must vary") as caught:
        fit_cone(readings, offsets="fit")
    assert caught.value.parameter == "offsets"


@pytest.mark.parametrize(
    ("ports", "kind"), [(3, "ideal"), (3, "table1"), (4, "table1"), (5, "table1")]
)
def test_noisy_phase_is_at_the_first_order_bound(ports, kind):
    """Table 1 noise: the RMS phase error of test readings is the first-order noise of a
    linear retrieval with the true map, |A+^T u_t| sigma / P, within the calibration excess
    sqrt(1 + 13/N) and the statistics of 20,000 readings; and never below the Cramer-Rao
    bound."""
    device, frequency, _ = sweep(ports, kind)
    fit = fit_cone(device.powers(frequency, POWER_W, NOISE_W, rng=11))
    test_hz = np.random.default_rng(13).uniform(frequency[0], frequency[-1], 20_000)
    truth = 2 * np.pi * (test_hz - device.center_hz) * device.delay_s
    error = rms(
        aligned_error(cone_phase_rad(fit, device.powers(test_hz, POWER_W, NOISE_W, rng=12)), truth)
    )
    matrix = device.true_map()
    tangent = np.stack([-np.sin(truth), np.cos(truth), np.zeros_like(truth)], axis=-1)
    first_order = rms(np.linalg.norm(tangent @ np.linalg.pinv(matrix), axis=1)) * NOISE_W / POWER_W
    statistics = 4 / math.sqrt(2 * truth.size)
    assert error <= first_order * math.sqrt(1 + 13 / frequency.size) * (1 + statistics)
    bound = rms(wm.crlb_frequency_std(matrix, truth, POWER_W, NOISE_W, 2 * np.pi))
    assert error >= bound * (1 - statistics)


def test_readings_that_span_no_cone_are_refused():
    device, frequency, _ = sweep(3)
    readings = device.powers(frequency, POWER_W, 0.0)
    readings[:, 2] = readings[:, 0] + readings[:, 1]  # a port that is the sum of two others
    with pytest.raises(wm.InputError, match="span fewer than 3 dimensions"):
        fit_cone(readings)
    with pytest.raises(wm.InputError, match="shape"):
        fit_cone(np.ones((3, 3)))


# ---------------------------------------------------------------------- the calibrator
def test_label_free_fit_has_the_documented_origin_and_direction():
    device, frequency, phase = sweep(3)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    cal = wm.ReferenceFreeCalibrator().fit(readings)
    found = cal.phase(readings)
    assert found[0] == pytest.approx(0.0, abs=1e-12)  # origin: the first reading of the fit
    assert np.unwrap(found)[-1] > np.unwrap(found)[0]  # growing along the record
    # the record grows in frequency here, so the phase is the true one less its first value
    assert rms(wrapped(found - (phase - phase[0]))) < 5e-3
    reversed_cal = wm.ReferenceFreeCalibrator().fit(readings[::-1])
    assert rms(wrapped(reversed_cal.phase(readings[::-1]) + (phase[::-1] - phase[-1]))) < 5e-3
    assert cal.diagnostics_["labels"] is False
    with pytest.raises(wm.InputError, match="gives phase only"):
        cal.predict(readings[:3])
    with pytest.raises(wm.InputError, match="not saved"):
        cal.save("never-written.json")
    with pytest.raises(wm.InputError, match="no calibration summary"):
        cal.summary()
    assert cal.diagnostics_["cone"]["frame_std_rad"] >= 0
    assert np.all(cal.flags(readings[:10]) == 0)


def test_label_free_frequency_from_an_fsr_and_an_anchor():
    device, frequency, _ = sweep(3)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    cal = wm.ReferenceFreeCalibrator(fsr_hz=device.true_fsr_hz, anchor_hz=frequency[0])
    cal.fit(readings)
    error = wm.frequency_error_hz(cal.predict(readings[1:-1]), frequency[1:-1], device.true_fsr_hz)
    assert rms(error) < 0.05 * device.true_fsr_hz / (2 * np.pi)  # 0.05 rad


def test_short_record_warns_that_its_direction_is_weak():
    device, frequency, _ = sweep(3)
    readings = device.powers(frequency[:300], POWER_W, NOISE_W, rng=1)  # 0.15 of a fringe
    with pytest.warns(wm.CalibrationWarning, match="direction convention"):
        try:
            wm.ReferenceFreeCalibrator().fit(readings)
        except wm.InputError:
            pytest.skip("so short a record does not fix a cone here")


# ---------------------------------------------------------------------- measured data
def read_columns(path: Path, names: list[str]) -> np.ndarray:
    with path.open(newline="") as handle:
        header = next(csv.reader(handle))
    columns = [header.index(name) for name in names]
    return np.loadtxt(path, delimiter=",", skiprows=1, usecols=columns, ndmin=2)


@pytest.fixture(scope="module")
def minipti():
    if not MINIPTI.is_dir():
        pytest.skip(f"measured MiniPTI data not found at {MINIPTI}")
    readings_v = read_columns(MINIPTI / "Decimation_Comercial.csv", ["DC CH1", "DC CH2", "DC CH3"])
    published = read_columns(MINIPTI / "PTI_Inversion_Comercial.csv", ["Interferometric Phase"])
    return readings_v, published[:, 0]


def test_measured_phase_agrees_with_the_published_phase(minipti):
    """Issue 32: <= 5 mrad RMS after removing the direction and the origin only."""
    readings_v, published_rad = minipti
    cal = wm.ReferenceFreeCalibrator().fit(readings_v)
    assert rms(aligned_error(cal.phase(readings_v), published_rad)) <= MINIPTI_AGREEMENT_RAD
    assert cal.cone_.power_spread < 1e-2  # the record's power is nearly constant


@pytest.mark.slow
def test_measured_offsets_cannot_be_told_and_are_refused(minipti):
    readings_v, _ = minipti
    with pytest.raises(wm.InputError, match="the source power must vary"):
        wm.ReferenceFreeCalibrator(offsets="fit").fit(readings_v)
