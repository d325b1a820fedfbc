"""OFF_MODEL against the calibration's own distances once the fit finds a model error.

A calibration whose sweep sits on its cone within the detector noise keeps the
detector-noise test (p = 1e-6); one whose sweep's distances show a model error compares a
reading with those distances (the noise's distribution scaled to their median), so its own
readings, and readings like them, are not flagged while readings that leave the model by
more than the sweep's scatter are. The data sets and faults are the benchmark's
(``benchmarks/offmodel.py``): simulated Table 1 devices, clean or with 5 % detector
compression, and the measured MiniPTI fibre coupler labelled with its published phase.
"""

from __future__ import annotations

import importlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm

from .helpers import NOISE_W, POWER_W

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
MEASURED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
OLD_FILES = Path(__file__).parent / "data" / "offmodel-0.7.1"
OFF_MODEL = int(wm.ReadingFlag.OFF_MODEL)
#: the p-value of the detector-noise test and of the sign test that finds a model error
P_VALUE = 1e-6


@pytest.fixture(scope="module")
def bench():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("offmodel")


@pytest.fixture(scope="module")
def measured(bench):
    if not MEASURED.is_dir():
        pytest.skip(f"measured data not found: {MEASURED}")
    return bench.measured_case(MEASURED)


@pytest.fixture(scope="module")
def simulated(bench):
    """Per (ports, model error): a calibration and 3000 fresh readings of its device."""
    return {
        (ports, error): bench.simulated_case(ports, seed=0, model_error=error, test=3000)
        for ports in (3, 4)
        for error in (False, True)
    }


def off_model_share(calibration, readings) -> float:
    return float(np.mean(calibration.flags(readings) & OFF_MODEL > 0))


def without_record(calibration, folder: Path):
    """The calibration saved and loaded without its ``off_model`` record: a 0.7 file."""
    path = folder / "old.wmcal.json"
    calibration.save(path)
    document = json.loads(path.read_text())
    del document["state"]["off_model"]
    path.write_text(json.dumps(document))
    return wm.load_calibration(path)


# ---------------------------------------------------------------------------- good readings
def test_measured_fibre_coupler_flags_almost_none_of_its_own_readings(measured, tmp_path):
    """The issue's case: 79 % of the calibration's own readings were OFF_MODEL."""
    calibration = measured.calibration
    assert off_model_share(calibration, measured.good) <= 0.01
    assert off_model_share(without_record(calibration, tmp_path), measured.good) > 0.5
    note = str(calibration.summary())
    assert "OFF_MODEL beyond cone distance" in note and "a model error" in note


@pytest.mark.slow
@pytest.mark.parametrize("ports", [3, 4])
def test_fresh_readings_of_a_device_with_a_model_error_are_not_flagged(simulated, ports):
    """Readings of the compressing device, like its sweep's, stay under the threshold; the
    detector-noise test flagged 40-70 % of them."""
    case = simulated[(ports, True)]
    assert off_model_share(case.calibration, case.good) <= 0.01
    assert "a model error" in str(case.calibration.summary())


@pytest.mark.parametrize("ports", [3, 4])
def test_a_clean_calibration_keeps_the_detector_noise_test(simulated, bench, tmp_path, ports):
    """No model error found: the flags are those of a file without the record, bit for
    bit, on good and faulty readings alike."""
    case = simulated[(ports, False)]
    assert "no model error" in str(case.calibration.summary())
    old = without_record(case.calibration, tmp_path)
    rng = np.random.default_rng(3)
    rows = np.vstack(
        [case.good] + [bench.inject(kind, case, rng).readings for kind in bench.FAULTS]
    )
    np.testing.assert_array_equal(case.calibration.flags(rows), old.flags(rows))


# ---------------------------------------------------------------------------- faults
@pytest.mark.parametrize("kind", ["glitch", "two-tone", "saturated"])
@pytest.mark.parametrize(
    "data", ["clean 3", "clean 4", "model error 3", "model error 4", "measured"]
)
def test_a_fault_that_leaves_the_model_is_caught(bench, simulated, request, kind, data):
    """Of the faulty readings, OFF_MODEL catches at least 90 % as many as a distance test
    can see at its threshold: those whose fault takes the reading's own point on the cone
    beyond it. (The rest differ by the reading's own scatter, within the threshold, which
    pushes some faults out and pulls others in.) What no distance test sees, a one-port
    fault at the two phases per fringe where it lies along a 3-port cone or a second line
    in phase with the first, the benchmark counts apart."""
    if data == "measured":
        case = request.getfixturevalue("measured")
    else:
        label, ports = data.rsplit(" ", 1)
        case = simulated[(int(ports), label == "model error")]
    calibration = case.calibration
    faulty = bench.inject(kind, case, np.random.default_rng(11))
    visible = calibration.flags(faulty.on_cone[faulty.affected]) & OFF_MODEL > 0
    caught = calibration.flags(faulty.readings[faulty.affected]) & OFF_MODEL > 0
    assert np.count_nonzero(visible) >= 100  # enough to tell the shares apart
    assert np.count_nonzero(caught) >= 0.9 * np.count_nonzero(visible)


def test_a_calibration_with_a_model_error_still_sees_gross_faults(simulated, bench):
    """A glitch of 100 scatters and a port stuck at twice its calibrated maximum leave the
    compressing device's model far beyond its scatter: at least 90 % caught (the rest lie
    along the cone)."""
    case = simulated[(3, True)]
    calibration, good = case.calibration, case.good
    rng = np.random.default_rng(5)
    rows = np.arange(good.shape[0])
    port = rng.integers(0, 3, good.shape[0])
    glitched, stuck = good.copy(), good.copy()
    glitched[rows, port] += rng.choice([-1, 1], rows.size) * 100 * bench.scatter(calibration)[port]
    stuck[rows, port] = 2 * good.max(axis=0)[port]
    for faulty in (glitched, stuck):
        assert off_model_share(calibration, faulty) >= 0.9


# ---------------------------------------------------------------------------- the basis
def threshold_amount(calibration, reading, direction) -> float:
    """How far along ``direction`` (W) ``reading`` moves before it is OFF_MODEL: the
    threshold as a physical step, by bisection on ``flags``."""

    def off_model(amount: float) -> bool:
        return bool(calibration.flags(reading + amount * direction)[0] & OFF_MODEL)

    low, high = 0.0, 1.0
    assert not off_model(low) and off_model(high)
    for _ in range(50):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if off_model(middle) else (middle, high)
    return high


def fitted(calibrator, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return calibrator.fit(*args)


def outlying_sweeps(device, model_error: bool, bench):
    """A sweep (1 FSR, 2001 readings), the same with 1 % of it glitched by 30 noise standard
    deviations (a few times the compressing device's scatter), and the compression's
    reference (W)."""
    rng = np.random.default_rng(1)
    sweep_hz = device.sweep_hz(2001)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=rng)
    largest = float(sweep.max())
    if model_error:
        sweep = bench.compressed(sweep, largest)
    spoilt = sweep.copy()
    rows = rng.choice(sweep_hz.size, sweep_hz.size // 100, replace=False)
    spoilt[rows, rng.integers(0, 3, rows.size)] += 30 * NOISE_W
    return sweep_hz, sweep, spoilt, largest


@pytest.mark.slow
def test_a_few_outliers_in_the_sweep_do_not_move_the_threshold(bench):
    """With a model error, the threshold (as the step along a fixed direction that takes a
    reading off the model) moves by less than 10 % with 1 % of the sweep outlying."""
    device = wm.Interferometer.table1(ports=3, seed=7)
    sweep_hz, sweep, spoilt, largest = outlying_sweeps(device, True, bench)
    plain = fitted(wm.Calibrator(fsr_hz=50e9), sweep, sweep_hz)
    with_outliers = fitted(wm.Calibrator(fsr_hz=50e9), spoilt, sweep_hz)
    assert plain.off_model_basis_.model_error and with_outliers.off_model_basis_.model_error
    reading = device.powers(device.center_hz + 0.2 * device.true_fsr_hz, POWER_W, 0.0)[0]
    direction = np.array([1.0, -0.3, 0.1]) * POWER_W
    steps = [
        threshold_amount(cal, bench.compressed(reading, largest), direction)
        for cal in (plain, with_outliers)
    ]
    assert steps[1] == pytest.approx(steps[0], rel=0.1)


def test_outliers_in_a_clean_sweep_are_no_model_error(bench):
    """1 % of a clean sweep outlying: the median distance does not take them for a model
    error; the detector-noise test stays (the noise estimate itself grows with them)."""
    device = wm.Interferometer.table1(ports=3, seed=7)
    sweep_hz, _, spoilt, _ = outlying_sweeps(device, False, bench)
    basis = fitted(wm.Calibrator(fsr_hz=50e9), spoilt, sweep_hz).off_model_basis_
    assert not basis.model_error and basis.scale == 1.0


def test_the_summary_states_the_threshold_and_its_basis(simulated):
    case = simulated[(3, True)]
    basis = case.calibration.off_model_basis_
    text = str(case.calibration.summary())
    assert f"{basis.scale:.4g}x the detector noise's" in text
    assert f"{basis.beyond} of {basis.readings} sweep readings beyond it" in text
    as_dict = case.calibration.summary().as_dict()
    assert any("OFF_MODEL" in note for note in as_dict["notes"])


# ---------------------------------------------------------------------------- files
@pytest.mark.parametrize("name", ["learned", "wideband"])
def test_a_file_without_the_record_gives_the_flags_it_gave(name):
    """Files written by 0.7.1 (commit 03d2f4d, ``make_files.py``) of a compressing device:
    the detector-noise test, bit for bit, though it flags most good readings."""
    expected = json.loads((OLD_FILES / "expected.json").read_text())[name]
    calibration = wm.load_calibration(OLD_FILES / f"{name}.wmcal.json")
    assert calibration.off_model_basis_ is None
    readings = np.array(expected["readings_w"])
    inputs = {"coarse_hz": np.array(expected["coarse_hz"])} if calibration.requires else {}
    np.testing.assert_array_equal(calibration.flags(readings, **inputs), expected["flags"])
    streamed = [record.flags for record in calibration.stream(readings, **inputs)]
    np.testing.assert_array_equal(streamed, expected["flags"])
    assert "a file without the sweep's distances" in str(calibration.summary())


def test_the_record_round_trips_through_a_file(simulated, tmp_path):
    case = simulated[(3, True)]
    path = tmp_path / "cal.wmcal.json"
    case.calibration.save(path)
    loaded = wm.load_calibration(path)
    assert loaded.off_model_basis_ == case.calibration.off_model_basis_
    np.testing.assert_array_equal(loaded.flags(case.good), case.calibration.flags(case.good))


@pytest.mark.parametrize(
    ("field", "value"),
    [("scale", 0.5), ("readings", 0), ("above", 5000), ("median", "big"), ("beyond", 1.5)],
)
def test_a_bad_record_is_refused_with_its_field(simulated, tmp_path, field, value):
    path = tmp_path / "cal.wmcal.json"
    simulated[(3, True)].calibration.save(path)
    document = json.loads(path.read_text())
    document["state"]["off_model"][field] = value
    path.write_text(json.dumps(document))
    with pytest.raises(wm.FileFormatError, match=f"off_model.{field}"):
        wm.load_calibration(path)


# ---------------------------------------------------------------------------- stream
def test_the_stream_flags_what_flags_gives_about_the_scaled_threshold(simulated):
    """Readings moved off the compressing device's cone by amounts about its scaled
    threshold (found by bisection): the stream's screen gives way to the exact test there,
    and both flag the same readings."""
    case = simulated[(3, True)]
    calibration = case.calibration
    clean = case.good[0]
    direction = np.array([1.0, -0.3, 0.1]) * POWER_W

    high = threshold_amount(calibration, clean, direction)
    amounts = high * np.array([0.5, 0.9, 0.999, 1.0 - 1e-9, 1.0, 1.001, 1.1])
    rows = np.vstack([clean + amounts[:, None] * direction, case.good[:200]])
    flags = calibration.flags(rows)
    np.testing.assert_array_equal([record.flags for record in calibration.stream(rows)], flags)
    assert [bool(bit) for bit in flags[:7] & OFF_MODEL] == [False] * 4 + [True] * 3


@pytest.mark.slow
def test_a_wideband_calibration_with_a_model_error_reads_its_readings_unflagged(bench):
    device = wm.Interferometer.table1(ports=3, seed=2)
    rng = np.random.default_rng(4)
    sweep_hz = device.sweep_hz(6001, span_fsr=6.0)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=rng)
    largest = float(sweep.max())
    calibration = fitted(
        wm.WidebandCalibrator(fsr_hz=50e9), bench.compressed(sweep, largest), sweep_hz
    )
    assert calibration.off_model_basis_.model_error
    truth = rng.uniform(sweep_hz.min(), sweep_hz.max(), 2000)
    good = bench.compressed(device.powers(truth, POWER_W, NOISE_W, rng=rng), largest)
    coarse = truth + rng.normal(0.0, 1e9, truth.size)
    flags = calibration.flags(good, coarse_hz=coarse)
    assert np.mean(flags & OFF_MODEL > 0) <= 0.01
    streamed = [record.flags for record in calibration.stream(good[:100], coarse_hz=coarse[:100])]
    np.testing.assert_array_equal(streamed, flags[:100])


# ---------------------------------------------------------------------------- false alarms
@pytest.mark.slow
def test_clean_sweeps_find_no_model_error_and_keep_the_stated_false_alarm_rate():
    """100 clean Table 1 calibrations (3 ports, 2001 readings) and 5000 fresh readings of
    each: no sweep shows a model error (each would at 1e-6), and OFF_MODEL flags fresh
    readings at the detector-noise test's rate: 5e5 readings at p = 1e-6 expect 0.5 flags,
    more than 4 has a probability below 2e-4."""
    found, flagged, readings = 0, 0, 0
    for seed in range(100):
        device = wm.Interferometer.table1(ports=3, seed=seed)
        rng = np.random.default_rng(seed)
        sweep_hz = device.sweep_hz(2001)
        calibration = fitted(
            wm.Calibrator(fsr_hz=50e9), device.powers(sweep_hz, POWER_W, NOISE_W, rng=rng), sweep_hz
        )
        found += calibration.off_model_basis_.model_error
        half = device.true_fsr_hz / 2
        truth = device.center_hz + rng.uniform(-half, half, 5000)
        flags = calibration.flags(device.powers(truth, POWER_W, NOISE_W, rng=rng))
        flagged += int(np.count_nonzero(flags & OFF_MODEL))
        readings += truth.size
    assert found == 0
    assert flagged <= stats.poisson.ppf(1 - 2e-4, P_VALUE * readings)
