"""Calibrators made absolute by a reference cell in their fit (issue 32, round two).

Small sweeps: a 1 THz stretch of the simulated ``hcn-like`` band (11 lines, the band's
origin gap inside, so their pattern identifies them), 8000 readings of a Table 1 device
without spectral slopes (a learned calibrator reads it over many FSRs), the laser at its
specification. The issue's criteria: the corrected calibration's absolute error within
1.2x its stated budget where the plain one inherits the laser's error; no axis at all
calibrates as well; a pattern that cannot be identified uniquely is refused with the
reason. Errors of a single-FSR calibrator are taken modulo its FSR (it reads frequency
modulo the FSR; the coarse value picks the fringe).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import ReferenceCell, laser_sweep

BAND_HZ = (193.9e12, 194.9e12)
TEST_BAND_HZ = (194.0e12, 194.8e12)
SAMPLES = 8000
POWER_W, NOISE_W = 1e-3, 5e-7


def wrapped(error_hz, fsr_hz):
    return (error_hz + fsr_hz / 2) % fsr_hz - fsr_hz / 2


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def recording(preset="tls-spec", seed=1, band=BAND_HZ, samples=SAMPLES):
    """A sweep of a device with the cell beside it, and test readings of known frequency."""
    rng = np.random.default_rng([32, seed])
    cell = ReferenceCell.simulated(rng=rng.spawn(1)[0])
    sweep = laser_sweep(band, samples, preset, rng=rng.spawn(1)[0])
    device = wm.Interferometer.table1(3, seed=seed)
    powers = device.powers(sweep.true_hz, POWER_W, NOISE_W, rng=rng.spawn(1)[0])
    channel = cell.transmission(sweep.true_hz, rng=rng.spawn(1)[0])
    test_hz = rng.uniform(*TEST_BAND_HZ, 2000)
    test = device.powers(test_hz, POWER_W, NOISE_W, rng=rng.spawn(1)[0])
    keywords = {
        "reference_transmission": channel,
        "reference_lines": cell.lines,
        "reference_pressure_pa": cell.nominal_pressure_pa,
        "reference_pressure_std_pa": cell.pressure_std_pa,
    }
    return sweep, powers, keywords, test, test_hz


def quiet(calibrator, *args, **keywords):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return calibrator.fit(*args, **keywords)


@pytest.fixture(scope="module")
def spec():
    sweep, powers, cell, test, test_hz = recording()
    plain = quiet(wm.Calibrator(50e9), powers, sweep.recorded_hz)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)  # no warning on a good fit
        corrected = wm.Calibrator(50e9).fit(powers, sweep.recorded_hz, **cell)
        selfcal = wm.Calibrator(50e9).fit(powers, None, band_hz=BAND_HZ, **cell)
    return sweep, powers, cell, test, test_hz, plain, corrected, selfcal


def absolute(calibration, test, test_hz):
    error = wrapped(calibration.predict(test) - test_hz, calibration.fsr_hz_)
    std = calibration.frequency_std_hz(test, absolute=True)
    return error, std


def test_corrected_within_its_budget_where_the_plain_one_inherits_the_laser(spec):
    sweep, _, _, test, test_hz, plain, corrected, _ = spec
    inside = (sweep.true_hz >= TEST_BAND_HZ[0]) & (sweep.true_hz <= TEST_BAND_HZ[1])
    laser_rms = rms(sweep.axis_error_hz[inside])
    plain_error = wrapped(plain.predict(test) - test_hz, plain.fsr_hz_)
    assert rms(plain_error) >= 0.5 * laser_rms > 100e6  # the laser's error, hundreds of MHz
    error, std = absolute(corrected, test, test_hz)
    assert rms(error) <= 1.2 * rms(std)
    assert rms(std) < 0.1 * rms(plain_error)
    # the absolute uncertainty is the own one and the axis budget, in quadrature
    own = corrected.frequency_std_hz(test)
    axis = corrected.uncertainty_budget_.axis_std_hz(corrected.predict(test))
    assert np.allclose(std, np.hypot(own, axis), rtol=1e-12)
    assert np.all(std > own)


def test_no_axis_at_all_calibrates_as_well(spec):
    *_, test, test_hz, _, corrected, selfcal = spec
    error, std = absolute(selfcal, test, test_hz)
    assert rms(error) <= 1.2 * rms(std)
    assert selfcal.axis_correction_.mode == "self-calibrated"
    assert selfcal.axis_correction_.shift_hz is None
    assert corrected.axis_correction_.mode == "corrected"
    # same lines, same budget terms in both
    assert selfcal.axis_correction_.labels == corrected.axis_correction_.labels
    assert set(selfcal.uncertainty_budget_.terms_hz) == set(corrected.uncertainty_budget_.terms_hz)


def test_the_record_says_which_lines_and_how(spec):
    sweep, *_, corrected, _ = spec
    record = corrected.axis_correction_
    assert record.identification == "pattern"  # no axis error was stated
    assert len(record.labels) == 11
    # fitted centres on the corrected axis lie within their budget of the table's
    assert rms(record.line_fitted_hz - record.line_target_hz) < 3 * 5e6
    # the correction undoes the laser's error: corrected less recorded = truth less recorded
    by_truth = np.argsort(sweep.true_hz)
    true_hz, shift_hz = sweep.true_hz[by_truth], -sweep.axis_error_hz[by_truth]
    truth_shift = np.interp(record.frequency_hz, true_hz, shift_hz)
    assert rms(record.shift_hz - truth_shift) < 3 * rms(record.shift_std_hz) + 5e6
    budget = corrected.uncertainty_budget_
    assert budget.descriptions.keys() == budget.terms_hz.keys()
    assert all(len(text) > 20 for text in budget.descriptions.values())


def test_stated_axis_error_identifies_by_the_nearest_line():
    sweep, powers, cell, *_ = recording(seed=2)
    calibration = quiet(wm.Calibrator(50e9), powers, sweep.recorded_hz, axis_error_hz=1.5e9, **cell)
    assert calibration.axis_correction_.identification == "nearest"


def test_a_file_keeps_the_budget_and_predicts_the_same(spec, tmp_path):
    *_, test, test_hz, _, corrected, _ = spec
    corrected.save(tmp_path / "abs.wmcal.json")
    document = json.loads((tmp_path / "abs.wmcal.json").read_text())
    assert document["schema_version"] == 2 and set(document["absolute"]) == {
        "axis_correction",
        "uncertainty_budget",
    }
    loaded = wm.load_calibration(tmp_path / "abs.wmcal.json")
    assert np.array_equal(loaded.predict(test), corrected.predict(test))
    assert np.array_equal(
        loaded.frequency_std_hz(test, absolute=True),
        corrected.frequency_std_hz(test, absolute=True),
    )
    assert loaded.axis_correction_.labels == corrected.axis_correction_.labels
    text = str(loaded.summary())
    assert "absolute uncertainty budget" in text and "pressure_shift" in text
    names = [figure.name for figure in loaded.report_figures()]
    assert names == ["reference_cell", "axis_correction", "uncertainty_budget"]


def test_a_damaged_budget_in_a_file_is_refused_naming_the_field(spec, tmp_path):
    *_, corrected, _ = spec
    corrected.save(tmp_path / "abs.wmcal.json")
    document = json.loads((tmp_path / "abs.wmcal.json").read_text())
    document["absolute"]["uncertainty_budget"]["terms_hz"]["line_table"][3] = -1.0
    (tmp_path / "bad.json").write_text(json.dumps(document))
    with pytest.raises(wm.FileFormatError, match="line_table"):
        wm.load_calibration(tmp_path / "bad.json")


def test_a_plain_fit_has_no_budget_and_its_file_no_field(spec, tmp_path):
    *_, test, test_hz, plain, corrected, _ = spec
    assert plain.uncertainty_budget_ is None and plain.axis_correction_ is None
    plain.save(tmp_path / "plain.wmcal.json")
    assert "absolute" not in json.loads((tmp_path / "plain.wmcal.json").read_text())
    with pytest.raises(wm.InputError, match="without a reference cell"):
        plain.frequency_std_hz(test, absolute=True)
    assert plain.report_figures() == ()


def test_refitting_without_the_cell_forgets_the_budget():
    sweep, powers, cell, *_ = recording(seed=3, samples=4000)
    calibration = quiet(wm.Calibrator(50e9), powers, sweep.recorded_hz, **cell)
    assert calibration.uncertainty_budget_ is not None
    quiet(calibration, powers, sweep.true_hz)
    assert calibration.uncertainty_budget_ is None and calibration.axis_correction_ is None


def test_a_pattern_that_cannot_be_identified_is_refused_with_the_reason():
    # a stretch of the R branch far from the band's origin, no axis: the cubic map fits
    # the assignment shifted by a line as well (nothing fixes the lines' place)
    band = (195.0e12, 195.9e12)
    _, powers, cell, *_ = recording(band=band, samples=6000)
    with pytest.raises(wm.InputError, match="cannot be identified uniquely") as caught:
        quiet(wm.Calibrator(50e9), powers, None, band_hz=(191.0e12, 197.0e12), **cell)
    assert caught.value.parameter == "reference_lines"
    assert "sweep across one, or give a recorded axis" in str(caught.value)


def test_the_cell_keywords_are_checked_by_name():
    sweep, powers, cell, *_ = recording(seed=4, samples=400)
    calibrator = wm.Calibrator(50e9)
    cases = [
        ({"band_hz": BAND_HZ}, "band_hz"),
        ({"reference_transmission": cell["reference_transmission"]}, "reference_lines"),
        (
            {**cell, "reference_transmission": cell["reference_transmission"][:-1]},
            "reference_transmission",
        ),
        ({**cell, "reference_lines": "hcn.csv"}, "reference_lines"),
        ({**cell, "band_hz": (195e12, 194e12)}, "band_hz"),
        ({**cell, "axis_error_hz": -1.0}, "axis_error_hz"),
    ]
    for keywords, parameter in cases:
        with pytest.raises(wm.InputError) as caught:
            calibrator.fit(powers, sweep.recorded_hz, **keywords)
        assert caught.value.parameter == parameter, keywords
    bad = cell["reference_transmission"].copy()
    bad[7] = np.nan
    with pytest.raises(wm.InputError, match="reading 7"):
        calibrator.fit(powers, sweep.recorded_hz, **{**cell, "reference_transmission": bad})
    with pytest.raises(wm.InputError, match="frequency_hz is None") as caught:
        calibrator.fit(powers, None)
    assert caught.value.parameter == "frequency_hz"
    with pytest.raises(wm.InputError, match="needs band_hz") as caught:
        calibrator.fit(powers, None, **cell)
    assert caught.value.parameter == "band_hz"


def test_a_calibrator_without_the_capability_refuses_a_cell():
    assert "reference_cell" not in wm.ReferenceFreeCalibrator().capabilities
    from wavemeter.calibration import registered

    offering = {tag for tag, cls in registered().items() if "reference_cell" in cls().capabilities}
    assert {"learned", "thermal", "wideband", "cascade", "calibration_set"} <= offering


def test_the_wideband_calibrator_on_the_corrected_axis():
    sweep, powers, cell, test, test_hz = recording(seed=5)
    calibration = quiet(wm.WidebandCalibrator(50e9), powers, sweep.recorded_hz, **cell)
    error = calibration.predict(test, coarse_hz=test_hz) - test_hz
    std = calibration.frequency_std_hz(test, coarse_hz=test_hz, absolute=True)
    assert rms(error) <= 1.2 * rms(std)


def test_the_calibration_set_on_the_corrected_axis():
    sweep, powers, cell, test, test_hz = recording(seed=6)
    calibration = quiet(wm.CalibrationSet(50e9), powers, sweep.recorded_hz, **cell)
    error = calibration.predict(test, coarse_hz=test_hz) - test_hz
    std = calibration.frequency_std_hz(test, coarse_hz=test_hz, absolute=True)
    assert rms(error) <= 1.2 * rms(std)
    assert calibration.windows_[0].uncertainty_budget_ is None  # the set holds the budget


def test_the_thermal_calibrator_on_the_corrected_axis():
    sweep, powers, cell, test, test_hz = recording(seed=7)
    # two interleaved sweeps 0.1 K apart (the thermal fit needs a spread; this device
    # does not drift, so its rates come out near zero)
    temperature = 293.15 + 0.05 * (-1.0) ** np.arange(sweep.true_hz.size)
    calibration = quiet(
        wm.ThermalCalibrator(50e9), powers, sweep.recorded_hz, temperature_k=temperature, **cell
    )
    error = wrapped(calibration.predict(test, temperature_k=293.15) - test_hz, calibration.fsr_hz_)
    std = calibration.frequency_std_hz(test, temperature_k=293.15, absolute=True)
    assert rms(error) <= 1.2 * rms(std)


def test_the_corrected_axis_own_smooth_error_is_not_a_misfit():
    # these draws leave the corrected axis a smooth error (the meter's phase noise through
    # the smoothing) that the misfit test used to name dispersion and set aside as within
    # twice the axis budget: that phase along the rows is now the axis's, not tested
    # (``tests/test_reference_cell_misfit.py``), so nothing is warned or set aside
    cell = ReferenceCell.simulated(rng=1)
    sweep = laser_sweep(BAND_HZ, SAMPLES, "tls-spec", rng=2)
    device = wm.Interferometer.table1(3, seed=1)
    powers = device.powers(sweep.true_hz, POWER_W, NOISE_W, rng=3)
    keywords = {
        "reference_transmission": cell.transmission(sweep.true_hz, rng=4),
        "reference_lines": cell.lines,
        "reference_pressure_pa": cell.nominal_pressure_pa,
        "reference_pressure_std_pa": cell.pressure_std_pa,
    }
    with warnings.catch_warnings(record=True) as plain_warnings:
        warnings.simplefilter("always", wm.CalibrationWarning)
        wm.Calibrator(50e9).fit(powers, sweep.true_hz)
    assert not plain_warnings  # on the true axis the device fits without a misfit
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        calibration = wm.Calibrator(50e9).fit(powers, sweep.recorded_hz, **keywords)
    record = calibration.diagnostics_["reference_cell"]
    assert record["explained_by_axis"] == []
    assert calibration.diagnostics_["fit"]["p_values"]["phase_scatter"] > 0.01
