"""The wide-band calibration: orders, gaps, held-out FSRs, the coarse frequency, files.

Tolerances come from the statistics of the noise: an RMS over ``M`` Gaussian errors has a
relative standard error ``1 / sqrt(2 M)``; a fitted coefficient lies within a few of its
standard errors of the truth; the per-reading bound is the calibration's own Cramer-Rao
bound at the true frequency.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods.wideband import ORDER_MARGIN_FSR

POWER_W = 1e-3
NOISE_W = 5e-7
FSR_COUNT = 16
PER_FSR = 400


#: 4 standard errors of an RMS over M Gaussian errors
def rms_band(count: int) -> float:
    return 4.0 / math.sqrt(2 * count)


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def band_hz(device, fsr_count=FSR_COUNT, per_fsr=PER_FSR, every=1) -> np.ndarray:
    """Frequencies over ``fsr_count`` FSRs about the centre, ``per_fsr`` each; only every
    ``every``-th FSR (the others left out as a gap)."""
    index = np.arange(fsr_count * per_fsr)
    frequency = device.center_hz + (index / per_fsr - fsr_count / 2) * device.true_fsr_hz
    keep = (index // per_fsr) % every == 0
    return frequency[keep]


@functools.cache
def dispersive(ports=3, dispersion_s2=1e-26, seed=3):
    return dataclasses.replace(
        wm.Interferometer.table1(ports, seed=seed), dispersion_s2=dispersion_s2
    )


def fitted(device, frequency_hz, noise_w=NOISE_W, **settings):
    readings = device.powers(frequency_hz, POWER_W, noise_w, rng=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        return wm.WidebandCalibrator(**settings).fit(readings, frequency_hz)


def held_out(device, low_hz, high_hz, count=4000, seed=5):
    frequency = np.random.default_rng(seed).uniform(low_hz, high_hz, count)
    return device.powers(frequency, POWER_W, NOISE_W, rng=seed + 1), frequency


@pytest.mark.slow
def test_linear_phase_device_gives_order_one_and_the_papers_result():
    device = wm.Interferometer.table1(3, seed=4)
    frequency = band_hz(device, fsr_count=8)
    cal = fitted(device, frequency)
    assert (cal.phase_order_, cal.map_order_) == (1, 0)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    plain = wm.Calibrator().fit(readings, frequency)
    # the same cost minimised over the same delay: equal to the optimisers' tolerance
    assert cal.delay_s_ == pytest.approx(plain.delay_s_, rel=1e-10)
    test, truth = held_out(device, frequency[0], frequency[-1])
    wideband = cal.predict(test, coarse_hz=truth)
    paper = plain.predict(test)
    # 1e-10 of the delay moves a reading 4 FSRs out by 1e-10 x 4 FSR = 20 Hz at most
    np.testing.assert_allclose(
        wm.frequency_error_hz(wideband, paper, cal.fsr_hz_), 0.0, atol=1e-10 * 4 * 50e9
    )


@pytest.mark.slow
def test_dispersion_is_found_as_phase_order_two():
    device = dispersive()
    cal = fitted(device, band_hz(device))
    assert cal.phase_order_ == 2
    std = cal.diagnostics_["wideband"]["phase_coefficients_std_s"]
    assert abs(cal.phase_coefficients_[1] - device.dispersion_s2) < 5 * std[1]
    assert abs(cal.delay_s_ - device.delay_s) < 5 * std[0]
    assert cal.n_parameters_ == 3 * 3 * (cal.map_order_ + 1) + cal.phase_order_


@pytest.mark.slow
def test_coupler_slopes_are_found_as_a_map_order():
    device = dataclasses.replace(
        wm.Interferometer.table1(4, seed=6).with_spectral("sin", seed=2), dispersion_s2=0.0
    )
    cal = fitted(device, band_hz(device, fsr_count=40, per_fsr=200))
    assert cal.map_order_ >= 1
    candidates = cal.diagnostics_["wideband"]["orders"]["candidates"]
    constant = next(c for c in candidates if (c["phase_order"], c["map_order"]) == (1, 0))
    chosen = next(c for c in candidates if c["chosen"])
    assert chosen["cv_rms_hz"] < constant["cv_rms_hz"]


def test_noiseless_band_is_recovered_to_rounding():
    device = dispersive()
    frequency = band_hz(device, fsr_count=8, per_fsr=100)
    cal = fitted(device, frequency, noise_w=0.0, phase_order=2, map_order=0)
    truth = np.linspace(frequency[0], frequency[-1], 500)
    predicted = cal.predict(device.powers(truth, POWER_W), coarse_hz=truth)
    assert np.max(np.abs(predicted - truth)) < 10.0
    assert cal.phase_coefficients_[1] == pytest.approx(device.dispersion_s2, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("retrieval", ["pinv", pytest.param("ml", marks=pytest.mark.slow)])
def test_held_out_fsrs_of_a_sweep_with_gaps_are_read_at_the_bound(retrieval):
    """Calibrated on every 4th FSR, read in the FSRs between: the error and its stated
    standard deviation agree with the calibration's own bound."""
    device = dispersive()
    frequency = band_hz(device, fsr_count=32, per_fsr=400, every=4)
    cal = fitted(device, frequency, retrieval=retrieval)
    test, truth = held_out(device, frequency[0], frequency[-1])
    gap = (np.floor((truth - frequency[0]) / device.true_fsr_hz) % 4) != 0
    test, truth = test[gap], truth[gap]
    error = cal.predict(test, coarse_hz=truth) - truth
    bound = rms(cal.crlb_hz(test, coarse_hz=truth, frequency_hz=truth))
    stated = cal.frequency_std_hz(test, coarse_hz=truth)
    band = rms_band(truth.size)
    assert bound * (1 - band) <= rms(error) <= rms(stated) * (1 + band)
    if retrieval == "ml":  # efficient: the bound, and the calibration's own excess
        excess = math.sqrt(1 + cal.n_parameters_ / frequency.size)
        assert rms(error) <= bound * excess * (1 + band)
    assert abs(np.std(error / stated) - 1.0) < band


@pytest.mark.slow
def test_coarse_frequency_picks_the_order_and_flags_a_far_one():
    device = dispersive()
    frequency = band_hz(device)
    cal = fitted(device, frequency)
    test, truth = held_out(device, frequency[100], frequency[-100], count=300)
    fsr = cal.fsr_hz_at(truth)
    near = cal.predict(test, coarse_hz=truth + 0.2 * fsr)
    assert rms(near - truth) < 1e9
    assert not np.any(cal.flags(test, coarse_hz=truth + 0.2 * fsr) & wm.ReadingFlag.ORDER_AMBIGUOUS)
    off = truth + 0.6 * fsr
    far = cal.predict(test, coarse_hz=off)
    # the neighbouring order: one local FSR away, and flagged
    np.testing.assert_allclose(far - truth, cal.fsr_hz_at(far), rtol=1e-3)
    flags = cal.flags(test, coarse_hz=off)
    assert np.all(flags & wm.ReadingFlag.ORDER_AMBIGUOUS)
    assert ORDER_MARGIN_FSR == 0.25


@pytest.mark.slow
def test_coarse_missing_or_outside_the_band_is_refused_and_flagged():
    device = dispersive()
    frequency = band_hz(device)
    cal = fitted(device, frequency)
    test = device.powers(frequency[:5], POWER_W, NOISE_W, rng=3)
    with pytest.raises(wm.InputError, match="needs coarse_hz"):
        cal.predict(test)
    beyond = np.full(5, frequency[-1] + 3 * cal.fsr_hz_)
    with pytest.raises(wm.InputError, match="outside the calibrated band"):
        cal.predict(test, coarse_hz=beyond, errors="raise")
    # by default such readings get NaN and OUTSIDE_SPAN, and cost no other reading
    mixed = np.where(np.arange(5) % 2 == 0, beyond, frequency[:5])
    read = cal.readout(test, coarse_hz=mixed)
    assert np.isnan(read.frequency_hz[::2]).all() and np.isfinite(read.frequency_hz[1::2]).all()
    np.testing.assert_array_equal(
        read.frequency_hz[1::2], cal.predict(test[1::2], coarse_hz=frequency[1:5:2])
    )
    assert np.all(read.flags[::2] == wm.ReadingFlag.OUTSIDE_SPAN)
    assert np.all(cal.flags(test, coarse_hz=beyond) & wm.ReadingFlag.OUTSIDE_SPAN)
    just_beyond = frequency[-1] + 0.4 * cal.fsr_hz_
    outside = device.powers(np.full(5, just_beyond), POWER_W, NOISE_W, rng=4)
    assert np.all(cal.flags(outside, coarse_hz=just_beyond) & wm.ReadingFlag.OUTSIDE_SPAN)
    inside = cal.flags(test, coarse_hz=frequency[:5])
    assert not np.any(inside & wm.ReadingFlag.OUTSIDE_SPAN)


def test_save_load_round_trip_keeps_every_reading(tmp_path):
    device = dispersive()
    frequency = band_hz(device)
    cal = fitted(device, frequency, phase_order=2, map_order=1)
    path = tmp_path / "band.wmcal.json"
    cal.save(path)
    loaded = wm.load_calibration(path)
    assert type(loaded) is wm.WidebandCalibrator
    test, truth = held_out(device, frequency[0], frequency[-1], count=200)
    for name in ("predict", "frequency_std_hz", "flags"):
        assert (
            getattr(loaded, name)(test, coarse_hz=truth).tobytes()
            == getattr(cal, name)(test, coarse_hz=truth).tobytes()
        )
    np.testing.assert_array_equal(loaded.map_coefficients_, cal.map_coefficients_)
    assert loaded.diagnostics_["wideband"] == cal.diagnostics_["wideband"]


def test_plain_calibrator_over_a_dispersive_band_warns_and_names_this_calibrator():
    device = dispersive()
    frequency = band_hz(device)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.warns(wm.CalibrationWarning) as caught:
        wm.Calibrator().fit(readings, frequency)
    notes = [note.message for note in caught if note.message.cause == "dispersion"]
    assert notes and "WidebandCalibrator" in notes[0].remedy


@pytest.mark.parametrize(
    ("setting", "value"),
    [
        ("phase_order", 0),
        ("phase_order", 5),
        ("map_order", -1),
        ("map_order", 2.0),
        ("retrieval", "x"),
    ],
)
def test_settings_are_checked_by_name(setting, value):
    device = dispersive()
    frequency = band_hz(device, fsr_count=2, per_fsr=50)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.raises(wm.InputError, match=setting):
        wm.WidebandCalibrator(**{setting: value}).fit(readings, frequency)


@pytest.mark.slow
def test_monitored_power_with_offsets_is_fitted_affine():
    device = dataclasses.replace(dispersive(), dark_offset_w=np.array([2e-6, -1e-6, 3e-6]))
    frequency = band_hz(device, fsr_count=8, per_fsr=400)
    power = POWER_W * (1 + 0.1 * np.sin(np.linspace(0, 7, frequency.size)))
    readings = device.powers(frequency, power, NOISE_W, rng=2)
    with pytest.warns(wm.CalibrationWarning, match="offsets"):
        cal = wm.WidebandCalibrator().fit(
            readings, frequency, power_monitor_w=device.monitor(power)
        )
    column = 3 * (cal.map_order_ + 1)
    std = np.sqrt(np.diag(cal.parameter_covariance_)[: 3 * (column + 1)]).reshape(3, -1)[:, -1]
    assert np.all(np.abs(cal.offset_w_ - device.dark_offset_w) < 5 * std)


@pytest.mark.slow
def test_a_phase_order_too_low_warns_with_the_remedy_of_this_calibrator():
    device = dispersive()
    frequency = band_hz(device)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.warns(wm.CalibrationWarning) as caught:
        wm.WidebandCalibrator(phase_order=1, map_order=0).fit(readings, frequency)
    notes = [note.message for note in caught if note.message.cause == "dispersion"]
    assert notes and "higher phase_order (this fit has 1)" in notes[0].remedy
    assert str(notes[0]).endswith(notes[0].remedy)


def test_three_separated_fsrs_are_followed_and_read_between():
    """Calibrated on three FSRs four apart: the fit follows the fringes across the gaps
    (a map varying with frequency must not let the phase wander while it grows), and the
    FSRs between are read at the bound with honest uncertainties."""
    device = wm.Interferometer.table1(3, seed=8).with_spectral("sin", seed=3)
    frequency = band_hz(device, fsr_count=12, per_fsr=300, every=4)[: 3 * 300]
    cal = fitted(device, frequency)
    assert abs(cal.fsr_hz_ / device.true_fsr_hz - 1) < 0.01
    assert cal.map_order_ <= 1  # three FSRs tell the phase from a map of order 1 at most
    test, truth = held_out(device, frequency[0], frequency[-1])
    gap = (np.floor((truth - frequency[0]) / device.true_fsr_hz) % 4) != 0
    test, truth = test[gap], truth[gap]
    error = cal.predict(test, coarse_hz=truth) - truth
    bound = rms(cal.crlb_hz(test, coarse_hz=truth, frequency_hz=truth))
    stated = cal.frequency_std_hz(test, coarse_hz=truth)
    band = rms_band(truth.size)
    assert bound * (1 - band) <= rms(error) <= rms(stated) * (1 + band)
    assert abs(np.std(error / stated) - 1) < band


def test_a_map_order_the_fsrs_cannot_tell_from_the_phase_is_refused():
    device = dispersive()
    frequency = band_hz(device, fsr_count=4, per_fsr=200)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.raises(wm.InputError, match=r"map_order 3 needs readings in at least 5 FSR"):
        wm.WidebandCalibrator(map_order=3).fit(readings, frequency)


@pytest.mark.slow
def test_orders_are_raised_while_every_reading_rejects_the_smaller_model():
    """Fixed to a constant map, the phase order is raised by the sweep's F test; the test
    record says which models were tried and taken, and the fit leaves nothing to warn."""
    device = dispersive()
    frequency = band_hz(device)
    cal = fitted(device, frequency, map_order=0)
    record = cal.diagnostics_["wideband"]["orders"]
    assert (cal.phase_order_, cal.map_order_) == (2, 0)
    taken = [test for test in record["sweep_tests"] if test["taken"]]
    assert all(test["p_value"] < 1e-6 for test in taken)
    untaken = [test for test in record["sweep_tests"] if not test["taken"]]
    assert untaken and all(test["p_value"] >= 1e-6 for test in untaken)
    assert all(test["map_order"] == 0 for test in record["sweep_tests"])


@pytest.mark.slow
def test_a_fit_that_loses_the_fringes_is_refused(monkeypatch):
    """The FSR at the middle of the band must stay in the bracket searched: a growth that
    lost the fringes is an error, not a calibration."""
    import wavemeter.calibration.methods.wideband as module

    grow = module.fit_band
    monkeypatch.setattr(module, "fit_band", lambda *a, **k: grow(*a, **k) * 0.6)
    device = dispersive()
    frequency = band_hz(device, fsr_count=8, per_fsr=200)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.raises(wm.InputError, match="outside the bracket searched") as raised:
        wm.WidebandCalibrator(phase_order=2, map_order=0).fit(readings, frequency)
    assert raised.value.parameter == "fsr_hz"


@pytest.mark.slow
def test_a_plain_calibrator_over_a_band_of_changing_couplers_names_the_wide_band():
    device = dataclasses.replace(
        wm.Interferometer.table1(3, seed=6).with_spectral("sin", seed=2), dispersion_s2=0.0
    )
    frequency = band_hz(device, fsr_count=40, per_fsr=200)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    with pytest.warns(wm.CalibrationWarning) as caught:
        wm.Calibrator().fit(readings, frequency)
    assert any("WidebandCalibrator" in note.message.remedy for note in caught)
