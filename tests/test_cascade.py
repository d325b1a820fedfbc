"""The cascade calibrator: absolute frequency from stages of decreasing FSR, with the
probability of a wrong fringe order (issue 12).

A small cascade keeps the module fast: 1 THz / 100 GHz / 10 GHz stages over a 0.8 THz band
(80 FSRs of the finest stage), Table-1 impairments and the silicon-nitride spectral slopes.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm
from wavemeter.calibration.methods import cascade as cascade_module
from wavemeter.calibration.methods.cascade_chain import DISAGREEMENT_STD
from wavemeter.calibration.methods.cascade_handover import HANDOVER_CAUSE
from wavemeter.calibration.methods.cascade_reading import noise_scale
from wavemeter.model import handover_error_probability, wrap_error_probability

from ._fringe import true_fringe_coefficients_s
from .helpers import NOISE_W, POWER_W

FSRS_HZ = (1e12, 100e9, 10e9)
BAND_HZ = 0.8e12
SWEEP_READINGS = 6000
SEED = 4


def band_hz(device, readings: int, rng=None) -> np.ndarray:
    """Frequencies (Hz) over the band: evenly spaced, or uniform with ``rng``."""
    low = device.center_hz - BAND_HZ / 2
    if rng is None:
        return low + BAND_HZ * np.arange(readings) / (readings - 1)
    return low + BAND_HZ * rng.random(readings)


@functools.cache
def device(spectral: str | None = "sin") -> wm.CascadeInterferometer:
    return wm.CascadeInterferometer.table1(FSRS_HZ, ports=3, seed=SEED, spectral=spectral)


@functools.cache
def calibrated(noise_w: float = NOISE_W, spectral: str | None = "sin"):
    """A cascade calibrated on one sweep over the band (no warning other than the
    coarsest stage's white-noise check may be raised), and its sweep."""
    cascade = device(spectral)
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    sweep = cascade.powers(sweep_hz, POWER_W, noise_w, rng=11)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cal = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(sweep, sweep_hz)
    return cal, sweep, sweep_hz


@pytest.mark.slow
def test_noiseless_orders_are_exact_across_the_band():
    cal, _, _ = calibrated(0.0, None)
    cascade = device(None)
    truth = band_hz(cascade, 4001, np.random.default_rng(5))
    readings = cascade.powers(truth, POWER_W)
    found = cal.read(readings)
    # float64 rounding of a 193 THz frequency through three stages, nothing more
    assert np.max(np.abs(found.frequency_hz[-1] - truth)) < 1.0
    assert np.max(found.order_error_probability) < 1e-12
    assert not np.any(found.flags & wm.ReadingFlag.ORDER_AMBIGUOUS)


@pytest.mark.slow
def test_each_stage_hands_the_next_the_order_its_predict_would_pick():
    """The class agrees with its stages read one after another, the coarse value of each
    the frequency of the one before (the band's middle for the first)."""
    cal, _, _ = calibrated()
    truth = band_hz(device(), 500, np.random.default_rng(6))
    readings = device().powers(truth, POWER_W, NOISE_W, rng=7)
    coarse = np.full(truth.size, cal.center_hz_)
    stds = []
    for stage, block in zip(cal.stages_, cal.stage_ports_, strict=True):
        rows = readings[:, list(block)]
        stds.append(stage.frequency_std_hz(rows, coarse_hz=coarse))
        coarse = stage.predict(rows, coarse_hz=coarse)
        stds[-1] = (coarse, stds[-1])
    found = cal.read(readings)
    np.testing.assert_allclose(found.frequency_hz[-1], coarse, rtol=1e-15, atol=0)
    np.testing.assert_allclose(cal.predict(readings), coarse, rtol=1e-15, atol=0)
    np.testing.assert_allclose(cal.frequency_std_hz(readings), stds[-1][1], rtol=1e-12)
    for index in (1, 2):
        (before, std_before), (after, std_after) = stds[index - 1], stds[index]
        expected = handover_error_probability(
            before - after, cal.stages_[index].fsr_hz_at(after), np.hypot(std_before, std_after)
        )
        np.testing.assert_allclose(found.error_probability[index], expected, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(
        cal.order_error_probability(readings), found.order_error_probability, rtol=1e-15
    )
    np.testing.assert_array_equal(cal.flags(readings), found.flags)


@pytest.mark.slow
def test_uncertainty_is_honest_and_noise_limited():
    cal, _, _ = calibrated()
    truth = band_hz(device(), 20_000, np.random.default_rng(8))
    readings = device().powers(truth, POWER_W, NOISE_W, rng=9)
    found = cal.read(readings)
    error = found.frequency_hz[-1] - truth
    z = error / found.std_hz[-1]
    # 20000 z-scores: the spread of a unit normal's std is 1/sqrt(2 N) = 0.005
    assert abs(np.std(z) - 1.0) < 0.03
    assert np.all(found.noise_scale == 1.0)
    assert not np.any(found.flags)
    # no wrong order: every error within a few standard deviations
    assert np.max(np.abs(z)) < 6.0


@pytest.mark.slow
def test_wrong_orders_seen_match_those_predicted_at_high_noise():
    """At 30x the calibration's noise the hand-overs and the coarsest stage's ends pick
    wrong orders for several % of the readings: the count seen agrees with the sum of the
    predicted probabilities within Poisson statistics plus the model's own tolerance (the
    standard deviations are held to 3 % below; at a margin of ``z ~ 2.6`` a rate moves by
    ``z^2`` times that, 20 %), and the flag holds them."""
    cal, _, _ = calibrated()
    truth = band_hz(device(), 20_000, np.random.default_rng(10))
    readings = device().powers(truth, POWER_W, 30 * NOISE_W, rng=11)
    found = cal.read(readings)
    # the readings' own noise, found from them
    assert np.all(np.abs(found.noise_scale / 30 - 1) < 0.05)
    wrong = np.abs(found.frequency_hz[-1] - truth) > 0.5 * cal.fsr_hz_at(truth)
    predicted = float(found.order_error_probability.sum())
    assert 20 <= predicted
    seen = np.count_nonzero(wrong)
    assert abs(seen / predicted - 1) < 4 / math.sqrt(predicted) + 2.6**2 * 0.03
    flagged = (found.flags & wm.ReadingFlag.ORDER_AMBIGUOUS) != 0
    assert np.count_nonzero(wrong & flagged) >= 0.9 * np.count_nonzero(wrong)
    # among the right orders the finest stage's uncertainty holds at that noise
    z = (found.frequency_hz[-1] - truth)[~wrong] / found.std_hz[-1][~wrong]
    assert abs(np.std(z) - 1.0) < 0.05


@pytest.mark.slow
def test_the_readings_noise_scales_batches_not_single_readings_or_glitches():
    rng = np.random.default_rng(12)
    quiet = rng.chisquare(1, 10_000)
    noise_median = float(stats.chi2.median(1))
    median = float(np.median(rng.chisquare(1, 10_000)))  # as a sweep would find it
    assert noise_scale(quiet, median, noise_median) == 1.0
    assert noise_scale(9.0 * quiet, median, noise_median) == pytest.approx(3.0, rel=0.05)
    assert noise_scale(np.array([400.0]), median, noise_median) == 1.0
    glitched = quiet.copy()
    glitched[:20] = 1e6
    assert noise_scale(glitched, median, noise_median) == 1.0
    # a model that missed a constant 2 on the sweep: the noise scales the rest only
    missed = 2.0
    swept = float(np.median(quiet + missed))
    assert noise_scale(9.0 * quiet + missed, swept, noise_median) == pytest.approx(3.0, rel=0.05)
    cal, _, _ = calibrated()
    truth = band_hz(device(), 3, np.random.default_rng(13))
    readings = device().powers(truth, POWER_W, NOISE_W, rng=14)
    readings[0, :3] = readings[1, :3]  # stage 1 reads another frequency, on its cone
    found = cal.read(readings)
    assert np.all(found.noise_scale == 1.0)
    assert found.flags[0] & wm.ReadingFlag.OFF_MODEL
    assert np.max(found.disagreement_std[:, 0]) > DISAGREEMENT_STD


def test_wrap_probability_of_the_coarsest_stage_is_its_posterior():
    """The coarsest stage's edge term equals the posterior weighed in its phase."""
    cal, _, _ = calibrated()
    truth = band_hz(device(), 200, np.random.default_rng(15))
    readings = device().powers(truth, POWER_W, 40 * NOISE_W, rng=16)
    found = cal.read(readings)
    model = cal.stages_[0].band_model_
    frequency = found.frequency_hz[0]
    expected = wrap_error_probability(
        model.phase_rad(frequency),
        found.std_hz[0] * model.phase_slope_rad_per_hz(frequency),
        tuple(model.phase_rad(np.asarray(cal.span_hz_))),
        2 * np.pi,
    )
    np.testing.assert_allclose(found.error_probability[0], expected, rtol=1e-12)


def test_fit_records_stages_and_handovers():
    cal, _, sweep_hz = calibrated()
    assert len(cal.stages_) == 3 and cal.stage_ports_ == ((0, 1, 2), (3, 4, 5), (6, 7, 8))
    # the finer stages span many FSRs: their fringe delays are the chips' (the coarsest
    # stage's sub-FSR band cannot tell a map that turns with frequency from phase
    # curvature, so its linear phase coefficient is not the delay; its frequencies are
    # checked below)
    for stage, chip in zip(cal.stages_[1:], device().stages[1:], strict=True):
        truth = true_fringe_coefficients_s(chip, stage.center_hz_, stage.half_span_hz_, 1)
        assert abs(stage.fsr_hz_ - 1.0 / truth[0]) < 5 * stage._fsr_std_hz()
    assert cal.fsr_hz_ == cal.stage_fsrs_hz_[-1]
    assert [record["to_stage"] for record in cal.handovers_] == [2, 3]
    for record in cal.handovers_:
        assert record["wrong_on_sweep"] == 0
        # ratio 10 at 0.4 % phase noise: margins of tens of standard deviations
        assert record["margin_std"] > 20 and record["largest_usable_ratio"] > record["ratio"]
        assert record["predicted_rate"] < 1e-20
    assert cal.edge_margin_std_ > 5
    record = cal.diagnostics_["cascade"]
    assert [stage["stage"] for stage in record["stages"]] == [1, 2, 3]
    # the stages' z-scores on the sweep: honest to the sweep's statistics
    for stage in record["stages"]:
        assert abs(stage["z_std"] - 1.0) < 0.15
    assert cal.calibration_rms_hz_ < 2 * record["stages"][-1]["median_std_hz"]
    assert cal.span_hz_ == (sweep_hz.min(), sweep_hz.max())
    assert len(cal.summary().windows) == 3


def test_save_and_load_keep_every_reading_output(tmp_path):
    cal, _, _ = calibrated()
    path = tmp_path / "cascade.wmcal.json"
    cal.save(path)
    loaded = wm.load_calibration(path)
    truth = band_hz(device(), 300, np.random.default_rng(17))
    readings = device().powers(truth, POWER_W, 20 * NOISE_W, rng=18)
    mine, theirs = cal.read(readings), loaded.read(readings)
    for name in ("frequency_hz", "std_hz", "error_probability", "flags", "noise_scale"):
        assert getattr(mine, name).tobytes() == getattr(theirs, name).tobytes(), name
    assert loaded.handovers_ == cal.handovers_
    assert loaded.stage_ports_ == cal.stage_ports_
    assert loaded.edge_margin_std_ == cal.edge_margin_std_


@pytest.mark.slow
def test_stage_ports_pick_the_columns_of_each_stage():
    cal, sweep, sweep_hz = calibrated()
    order = [6, 7, 8, 0, 1, 2, 3, 4, 5]  # stage 2's columns first, then 3's, then 1's
    shuffled = sweep[:, order]
    ports = ((3, 4, 5), (6, 7, 8), (0, 1, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        other = wm.CascadeCalibrator(fsr_hz=FSRS_HZ, stage_ports=ports).fit(shuffled, sweep_hz)
    truth = band_hz(device(), 100, np.random.default_rng(19))
    readings = device().powers(truth, POWER_W, NOISE_W, rng=20)
    np.testing.assert_array_equal(other.predict(readings[:, order]), cal.predict(readings))


@pytest.mark.parametrize(
    ("stage_ports", "match"),
    [
        (((0, 1, 2), (3, 4, 5)), "for each of the 3 stages"),
        (((0, 1), (2, 3, 4), (5, 6, 7, 8)), "3 or more column"),
        (((0, 1, 2), (2, 3, 4), (5, 6, 7)), "one stage only"),
        (
            ((0, 1, 2), (3, 4, 5), (6, 7, 9)),
            r"columns \[8\] belong to no stage.*\[9\] do not exist",
        ),
        (((0, 1, 2), (3, 4, 5), (6, 7, -1)), "zero-based"),
        ("012", "for each of the 3 stages"),
    ],
)
def test_bad_stage_ports_are_named(stage_ports, match):
    _, sweep, sweep_hz = calibrated()
    with pytest.raises(wm.InputError, match=match) as caught:
        wm.CascadeCalibrator(fsr_hz=FSRS_HZ, stage_ports=stage_ports).fit(sweep, sweep_hz)
    assert caught.value.parameter == "stage_ports"


def test_columns_that_do_not_split_into_stages_are_refused():
    _, sweep, sweep_hz = calibrated()
    with pytest.raises(wm.InputError, match="do not split into 3 stages") as caught:
        wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(sweep[:, :8], sweep_hz)
    assert caught.value.parameter == "stage_ports"


@pytest.mark.parametrize(
    ("fsr_hz", "match"),
    [
        ((50e9,), "two or more stages"),
        (50e9, "two or more stages"),
        ((500e9, 5e12), "decrease"),
        ((5e12, -1.0), "fsr_hz must be"),
    ],
)
def test_bad_design_fsrs_are_named(fsr_hz, match):
    _, sweep, sweep_hz = calibrated()
    with pytest.raises(wm.InputError, match=match) as caught:
        wm.CascadeCalibrator(fsr_hz=fsr_hz).fit(sweep, sweep_hz)
    assert caught.value.parameter == "fsr_hz"


@pytest.mark.slow
def test_a_ratio_too_large_for_the_noise_is_refused_with_the_largest_usable_one():
    """Two stages 100x apart at 20x the noise: the coarse stage's noise is comparable to
    the fine stage's half FSR, so the fit refuses and says which stages, why, and the
    largest ratio this noise allows (the phase noise ``s`` of the coarse stage allows
    about ``pi / (4.9 s)`` for a rate of 1e-6)."""
    fsrs = (1e12, 10e9)
    cascade = wm.CascadeInterferometer.table1(fsrs, ports=3, seed=SEED)
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    sweep = cascade.powers(sweep_hz, POWER_W, 20 * NOISE_W, rng=21)
    with pytest.raises(wm.InputError) as caught:
        wm.CascadeCalibrator(fsr_hz=fsrs).fit(sweep, sweep_hz)
    message = str(caught.value)
    assert caught.value.parameter == "fsr_hz"
    assert "stage 1 (1 THz) cannot pick the fringe order of stage 2 (10 GHz)" in message
    usable = float(message.split("largest usable FSR ratio is ")[1].split(" ")[0])
    # the ideal 3-port stage at half the power and 20x the noise: s = sqrt(6) 1e-5 / 5e-4;
    # Table 1's spread of couplers and responsivities (10 % each) moves a stage's phase
    # noise by some tens of percent either way
    ideal_phase_std = math.sqrt(6) * 20 * NOISE_W / (POWER_W / 2)
    required = math.sqrt(2) * 4.8916  # erfc(z / sqrt 2) = 1e-6
    assert 1 / 1.5 < usable / (math.pi / (required * ideal_phase_std)) < 1.5
    assert "add a stage between them" in message


@pytest.mark.slow
def test_a_coarsest_stage_narrower_than_the_band_is_refused():
    fsrs = (0.5e12, 50e9)
    cascade = wm.CascadeInterferometer.table1(fsrs, ports=3, seed=SEED)
    sweep_hz = band_hz(cascade, 3000)
    sweep = cascade.powers(sweep_hz, POWER_W, NOISE_W, rng=22)
    with pytest.raises(wm.InputError, match="does not exceed the band swept") as caught:
        wm.CascadeCalibrator(fsr_hz=fsrs).fit(sweep, sweep_hz)
    assert caught.value.parameter == "fsr_hz"


@pytest.mark.slow
def test_stage_warnings_are_named_and_a_bad_handover_on_the_sweep_warns():
    cascade = device()
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    sweep = cascade.powers(sweep_hz, POWER_W, NOISE_W, rng=11)
    # a mode hop: 30 readings of the sweep taken 1.5 finest FSRs off their recorded frequency
    hopped = sweep.copy()
    rows = np.arange(1000, 1030)
    hopped[rows] = cascade.powers(sweep_hz[rows] + 1.5 * FSRS_HZ[2], POWER_W, NOISE_W, rng=23)
    with pytest.warns(wm.CalibrationWarning) as record:
        wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(hopped, sweep_hz)
    messages = [str(entry.message) for entry in record]
    assert all(message.startswith("stage ") for message in messages)
    causes = [entry.message.cause for entry in record]
    assert HANDOVER_CAUSE in causes


def test_score_counts_a_wrong_order_as_the_whole_fsr_it_is():
    cal, _, _ = calibrated()
    truth = band_hz(device(), 50, np.random.default_rng(24))
    readings = device().powers(truth, POWER_W, NOISE_W, rng=25)
    shifted = truth + cal.fsr_hz_  # every reading claimed one finest FSR away
    error = cal.predict(readings) - shifted
    assert cal.score(readings, shifted) == pytest.approx(-np.sqrt(np.mean(error**2)), rel=1e-12)
    assert -cal.score(readings, shifted) > 0.9 * cal.fsr_hz_


def jittered(cascade, frequency_hz: np.ndarray, seed: int) -> np.ndarray:
    """Readings whose coarsest stage saw frequencies 1 GHz RMS off the recorded ones (a
    phase scatter of ~6 mrad at 1 THz, ~10x its noise, that no stage model has)."""
    readings = cascade.powers(frequency_hz, POWER_W, NOISE_W, rng=seed)
    jitter_hz = np.random.default_rng(seed + 100).normal(0.0, 1e9, frequency_hz.size)
    moved = cascade.powers(frequency_hz + jitter_hz, POWER_W, NOISE_W, rng=seed + 200)
    readings[:, :3] = moved[:, :3]
    return readings


@pytest.mark.slow
def test_a_clean_cascade_with_spectral_slopes_warns_nothing():
    """Over less than one of its FSRs the coarsest stage follows its couplers' and
    detectors' slopes with a map slope (issue 29: it used to warn ``other_misfit`` on clean
    data): no warning, and no error beyond its uncertainty."""
    cascade = device()
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        cal = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(
            cascade.powers(sweep_hz, POWER_W, NOISE_W, rng=11), sweep_hz
        )
    assert cal.stages_[0].map_order_ == 1
    assert np.all(cal.model_error_hz_ == 0)


@pytest.mark.slow
def test_a_misfit_of_the_coarsest_stage_says_what_it_means_in_a_cascade():
    """A misfit the coarsest stage cannot fit (its readings jittered in frequency): the
    warning says that it costs hand-over margin, which the fit reports."""
    cascade = device()
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    sweep = jittered(cascade, sweep_hz, 11)
    with pytest.warns(wm.CalibrationWarning) as record:
        cal = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(sweep, sweep_hz)
    coarsest = [entry.message for entry in record if str(entry.message).startswith("stage 1 ")]
    assert coarsest
    for note in coarsest:
        margin = f"{cal.handovers_[0]['margin_std']:.3g} standard deviations"
        assert "costs hand-over margin" in str(note) and margin in note.remedy


@pytest.mark.slow
def test_a_stage_whose_model_misses_the_chip_widens_its_uncertainty_by_what_the_sweep_showed():
    """The coarsest stage's readings jittered in frequency: its sweep errors exceed its std,
    the excess is kept, and the z-scores of new readings of that stage are of unit spread; the
    other stages, and a clean cascade over the C band (whose coarsest stage follows its
    spectral slopes), show nothing significant."""
    cascade = device()
    sweep_hz = band_hz(cascade, SWEEP_READINGS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cal = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(jittered(cascade, sweep_hz, 11), sweep_hz)
    assert cal.model_error_hz_[0] > 0 and np.all(cal.model_error_hz_[1:] == 0)
    plain, _, _ = calibrated(spectral=None)
    assert np.all(plain.model_error_hz_ == 0)
    c_band = wm.CascadeInterferometer.table1(seed=1, center_hz=193.2e12)
    c_band_hz = np.linspace(191.0e12, 195.4e12, 8000)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        clean = wm.CascadeCalibrator().fit(
            c_band.powers(c_band_hz, POWER_W, NOISE_W, rng=26), c_band_hz
        )
    assert np.all(clean.model_error_hz_ == 0)
    truth = band_hz(cascade, 20_000, np.random.default_rng(27))
    found = cal.read(jittered(cascade, truth, 28))
    z = (found.frequency_hz[0] - truth) / found.std_hz[0]
    # 20000 readings: 1/sqrt(2 N) = 0.005; the excess is estimated on 6000 sweep readings
    # whose errors are correlated along the band, so allow a few percent
    assert abs(np.std(z) - 1.0) < 0.05


def test_stages_of_unequal_sizes_are_settings_a_file_keeps():
    """``stage_ports`` of 4 + 3 + 3 columns is a ragged setting: written as nested lists and
    read back as the tuples the constructor was given."""
    ports = ((0, 1, 2, 3), (4, 5, 6), (7, 8, 9))
    calibrator = wm.CascadeCalibrator(stage_ports=ports)
    written = calibrator.get_params_for_file()
    assert written["stage_ports"] == [[0, 1, 2, 3], [4, 5, 6], [7, 8, 9]]
    read = cascade_module.CascadeCalibrator._params_from_file(written)  # what a load calls
    assert read["stage_ports"] == ports
    assert wm.CascadeCalibrator(**read).get_params() == calibrator.get_params()
