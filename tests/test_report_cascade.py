"""The report of a cascade calibration: absolute errors, its stages and hand-overs, and the
wrong fringe orders of the evaluation readings against those predicted.

A small cascade keeps the module fast: 1 THz / 100 GHz / 10 GHz stages over a 0.8 THz band,
Table-1 impairments and the silicon-nitride spectral slopes, calibrated at the Table-1
noise and evaluated at ``NOISY_FACTOR`` times it, where the hand-overs pick wrong orders for
a few % of the readings (as the calibrator's own tests find).
"""

from __future__ import annotations

import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods.cascade_report import order_errors
from wavemeter.exceptions import InputError
from wavemeter.model.errors import error_summary_hz
from wavemeter.report.content import comparison_calibration, retrieved_frequency_hz
from wavemeter.report.html import report_paths, write_report

from .helpers import NOISE_W, POWER_W

FSRS_HZ = (1e12, 100e9, 10e9)
BAND_HZ = 0.8e12
SWEEP_READINGS = 3000
TEST_READINGS = 4000
SEED = 4
#: detector noise of the evaluation readings over the calibration's: wrong orders happen
NOISY_FACTOR = 30.0
#: the calibrator's standard deviations are honest to about 3 %, which moves a rate at a
#: margin of z ~ 2.6 standard deviations by z^2 times that (test_cascade's reasoning)
RATE_TOLERANCE = 0.2
MAX_Z = 5.0


@pytest.fixture(scope="module")
def fitted():
    """The cascade, its calibration on one sweep over the band, and noisy test readings."""
    device = wm.CascadeInterferometer.table1(FSRS_HZ, ports=3, seed=SEED, spectral="sin")
    low = device.center_hz - BAND_HZ / 2
    sweep_hz = low + BAND_HZ * np.arange(SWEEP_READINGS) / (SWEEP_READINGS - 1)
    sweep = SimpleNamespace(
        powers_w=device.powers(sweep_hz, POWER_W, NOISE_W, rng=11), frequency_hz=sweep_hz
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        calibration = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(sweep.powers_w, sweep_hz)
    truth = low + BAND_HZ * np.random.default_rng(12).random(TEST_READINGS)
    test = SimpleNamespace(
        powers_w=device.powers(truth, POWER_W, NOISY_FACTOR * NOISE_W, rng=13),
        frequency_hz=truth,
    )
    return calibration, sweep, test


def wrong_orders(calibration, test) -> np.ndarray:
    """Readings a whole fringe order off (by half the finest stage's FSR or more)."""
    error = calibration.predict(test.powers_w) - test.frequency_hz
    return np.abs(error) >= 0.5 * calibration.fsr_hz_at(test.frequency_hz)


@pytest.mark.slow
def test_a_cascade_is_retrieved_absolute_so_wrong_orders_show(fitted):
    calibration, _, test = fitted
    retrieved = retrieved_frequency_hz(calibration, test.powers_w, test.frequency_hz)
    np.testing.assert_array_equal(retrieved, calibration.predict(test.powers_w))
    # the wrong orders are there to be shown, not folded back into one FSR
    wrong = wrong_orders(calibration, test)
    assert np.count_nonzero(wrong) > 0
    assert np.all(np.abs(retrieved - test.frequency_hz)[wrong] >= 0.5 * calibration.fsr_hz_)


def test_order_errors_count_seen_predicted_and_flagged(fitted):
    calibration, _, test = fitted
    counts = order_errors(calibration, test.powers_w, test.frequency_hz)
    wrong = wrong_orders(calibration, test)
    found = calibration.read(test.powers_w)
    flagged = (found.flags & wm.ReadingFlag.ORDER_AMBIGUOUS) != 0
    assert counts == {
        "readings": TEST_READINGS,
        "wrong_orders": int(np.count_nonzero(wrong)),
        "expected_wrong_orders": pytest.approx(float(np.sum(found.order_error_probability))),
        "flagged_order_ambiguous": int(np.count_nonzero(flagged)),
        "wrong_orders_flagged": int(np.count_nonzero(wrong & flagged)),
    }
    # what the report sets side by side agrees: Poisson and the rates' own tolerance
    expected = counts["expected_wrong_orders"]
    allowed = MAX_Z * np.sqrt(expected) + RATE_TOLERANCE * expected
    assert abs(counts["wrong_orders"] - expected) < allowed


def test_a_cascade_has_no_comparison_method(fitted):
    calibration, sweep, _ = fitted
    with pytest.raises(InputError, match="cascade calibration has no other method"):
        comparison_calibration(calibration, sweep.powers_w, sweep.frequency_hz)


@pytest.mark.slow
def test_the_page_shows_stages_hand_overs_and_the_wrong_orders(fitted, tmp_path):
    calibration, sweep, test = fitted
    page = tmp_path / "report.html"
    written = write_report(calibration, sweep, test, page)
    assert written == report_paths(page, calibration)
    text = page.read_text(encoding="utf-8")
    assert "<h3>stages</h3>" in text and "<h3>hand-overs</h3>" in text
    for record in calibration.diagnostics_["cascade"]["stages"]:
        assert f"<td>{', '.join(record['ports'])}</td>" in text
    assert [f"stage {k} to {k + 1}" for k in (1, 2)] == re.findall(
        r"<td>(stage \d to \d)</td>", text
    )
    wrong = int(np.count_nonzero(wrong_orders(calibration, test)))
    assert "<h2>wrong fringe orders</h2>" in text
    assert f"<p>{wrong} of {TEST_READINGS} readings off" in text
    # the errors table holds the absolute errors, wrong orders and all
    error = calibration.predict(test.powers_w) - test.frequency_hz
    rms_mhz = error_summary_hz(error)["rms_hz"] / 1e6
    shown = float(re.search(r"<td>cascade</td><td>([0-9.e+]+)</td>", text)[1])
    assert shown == pytest.approx(rms_mhz, rel=5e-3)  # three significant digits
    assert "design FSRs, coarsest first (GHz)</td><td>1000, 100, 10</td>" in text
