"""Readings measured as one frequency series for a noise analysis (wavemeter.jobs.noise).

The series is the calibration's frequency of each reading in file order, whatever the
chunking; untrustworthy readings are NaN and counted by reason; a single interferometer's
readings are unwrapped across its FSR; the rate comes from a time column only when that
column is uniform, and every bad case is an InputError naming the row.
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.contract.flags import ReadingFlag
from wavemeter.exceptions import CalibrationWarning, InputError
from wavemeter.jobs.noise import EXCLUDED_FLAGS, measure_series, reads_modulo_fsr
from wavemeter.jobs.noise_clock import time_unit_s
from wavemeter.jobs.noise_unwrap import AMBIGUOUS_STEP_CAUSE

from .helpers import NOISE_W, POWER_W

RATE_HZ = 1e4
ROWS = 3000


@pytest.fixture(scope="module")
def meter():
    """A Table 1 device and its learned calibration on a one-FSR sweep."""
    device = wm.Interferometer.table1(ports=3, seed=1)
    sweep = device.sweep_hz(400)
    powers = device.powers(sweep, POWER_W, NOISE_W, rng=1)
    return device, wm.Calibrator(fsr_hz=50e9).fit(powers, sweep)


def write_readings(path: Path, powers: np.ndarray, time_s=None, time_name="time_s") -> Path:
    """A CSV of port readings (W), with a time column first when given."""
    columns, header = [powers], "p1_w,p2_w,p3_w"
    if time_s is not None:
        columns.insert(0, np.asarray(time_s)[:, None])
        header = f"{time_name},{header}"
    np.savetxt(path, np.hstack(columns), delimiter=",", header=header, comments="", fmt="%.17g")
    return path


def laser_hz(device, rows: int, rng, drift_fsr: float = 0.0, white_hz: float = 20e6):
    """A laser about the device centre: white frequency noise (Hz std) and a linear drift
    over ``drift_fsr`` true FSRs, centred."""
    ramp = drift_fsr * device.true_fsr_hz * (np.arange(rows) / (rows - 1) - 0.5)
    return device.center_hz + ramp + rng.normal(0.0, white_hz, rows)


def test_series_is_the_calibrations_frequency_in_file_order_whatever_the_chunks(
    meter, tmp_path, rng
):
    device, calibration = meter
    frequency = laser_hz(device, ROWS, rng)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    path = write_readings(tmp_path / "r.csv", powers)
    whole = measure_series(calibration, path, rate_hz=RATE_HZ)
    progress = ProgressRecord()
    chunked = measure_series(calibration, path, rate_hz=RATE_HZ, chunk_rows=257, progress=progress)
    expected = calibration.predict(powers)
    # the same retrieval row by row: equal to a few float64 ulps at 193 THz (0.03 Hz each)
    np.testing.assert_allclose(whole.frequency_hz, expected, rtol=0, atol=0.2)
    np.testing.assert_allclose(chunked.frequency_hz, whole.frequency_hz, rtol=0, atol=0.2)
    std = calibration.frequency_std_hz(powers)
    assert whole.meter_std_hz == pytest.approx(np.sqrt(np.mean(std**2)), rel=1e-12)
    assert chunked.meter_std_hz == pytest.approx(whole.meter_std_hz, rel=1e-12)
    assert whole.rows == ROWS and whole.excluded == 0 and whole.rate_hz == RATE_HZ
    assert whole.unwrapped and whole.fsr_hz == calibration.fsr_hz_
    assert whole.time_column is None and whole.ambiguous_steps == 0
    # progress in rows of the text file (counted before reading), once per chunk, to its end
    assert (progress.total, progress.unit) == (ROWS, "rows")
    assert len(progress.steps) == -(-ROWS // 257) and progress.steps[-1] == progress.total


class ProgressRecord:
    """A progress display that records its total, unit and position after each advance."""

    def __init__(self):
        self.total, self.unit, self.steps = None, None, []

    @contextlib.contextmanager
    def __call__(self, description, total, unit):
        self.total, self.unit = total, unit
        yield lambda steps: self.steps.append((self.steps[-1] if self.steps else 0) + steps)


def test_untrustworthy_readings_are_excluded_and_counted_by_reason(meter, tmp_path, rng):
    device, calibration = meter
    frequency = laser_hz(device, ROWS, rng)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    powers[10, 1] = np.nan  # the reader refuses it: INVALID
    powers[20] = 0.0  # no light: INVALID
    powers[30] += np.array([1, -1, 1]) * 50 * NOISE_W  # 50 sigma off the cone: OFF_MODEL
    powers[40] *= 1.2  # a brighter reading: POWER_RANGE (no dark readings: 1.05x), kept
    path = write_readings(tmp_path / "r.csv", powers)
    series = measure_series(calibration, path, rate_hz=RATE_HZ)
    flags = calibration.flags(powers)
    assert flags[30] & ReadingFlag.OFF_MODEL and flags[40] & ReadingFlag.POWER_RANGE
    assert not flags[40] & EXCLUDED_FLAGS
    excluded = np.flatnonzero(np.isnan(series.frequency_hz))
    expected = np.flatnonzero((flags & EXCLUDED_FLAGS) != 0)
    np.testing.assert_array_equal(excluded, expected)
    assert {10, 20, 30} <= set(excluded) and 40 not in excluded
    assert series.excluded == expected.size
    assert series.excluded_counts["INVALID"] == 2
    assert series.excluded_counts["OFF_MODEL"] == np.count_nonzero(flags & ReadingFlag.OFF_MODEL)
    assert series.flag_counts["POWER_RANGE"] >= 1
    assert series.flagged == np.count_nonzero(flags)
    # the power-invariant retrieval reads the brighter reading right
    assert abs(series.frequency_hz[40] - frequency[40]) < 6 * series.meter_std_hz
    kept = ~np.isnan(series.frequency_hz)
    std = calibration.frequency_std_hz(powers[kept])
    assert series.meter_std_hz == pytest.approx(np.sqrt(np.mean(std**2)), rel=1e-12)
    assert "line 12" in series.invalid_examples[0]  # header is line 1: row 10 is line 12


@pytest.mark.slow
def test_a_drift_over_two_fsrs_is_unwrapped_chunk_by_chunk(meter, tmp_path, rng):
    device, calibration = meter
    frequency = laser_hz(device, ROWS, rng, drift_fsr=2.2)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    path = write_readings(tmp_path / "r.csv", powers)
    wrapped = calibration.predict(powers)
    assert np.ptp(wrapped) < calibration.fsr_hz_  # the calibration reads modulo its FSR
    for chunk_rows in (ROWS, 100, 1):
        series = measure_series(calibration, path, rate_hz=RATE_HZ, chunk_rows=chunk_rows)
        error = series.frequency_hz - frequency
        # no whole FSR left anywhere: the error is the meter's noise (4000 draws stay
        # within 5 sigma) plus the calibrated FSR's tiny scale error over 2.2 FSRs
        scale_hz = abs(calibration.fsr_hz_ / device.true_fsr_hz - 1) * 2.2 * device.true_fsr_hz
        assert np.max(np.abs(error - np.mean(error))) < 5 * series.meter_std_hz + scale_hz
        assert series.ambiguous_steps == 0
    # the calibrated scale's uncertainty goes with the series (a drift's std needs it)
    # (stated as the FSR's standard error over the FSR: 1/delay, so the same to rounding)
    relative = calibration.delay_std_s_ / calibration.delay_s_
    assert relative > 0
    assert series.scale_rel_std == pytest.approx(relative, rel=1e-12)


def test_a_step_of_a_third_fsr_warns_that_the_unwrap_is_ambiguous(meter, tmp_path, rng):
    device, calibration = meter
    frequency = laser_hz(device, ROWS, rng)
    frequency[1500:] += device.true_fsr_hz / 3  # a mode hop between rows 1499 and 1500
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    path = write_readings(tmp_path / "r.csv", powers)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        series = measure_series(calibration, path, rate_hz=RATE_HZ, chunk_rows=700)
    found = [w.message for w in caught if isinstance(w.message, CalibrationWarning)]
    assert [w.cause for w in found] == [AMBIGUOUS_STEP_CAUSE]
    assert series.ambiguous_steps == 1 and series.warnings == tuple(found)
    assert "before line 1502" in str(found[0]) and "quarter of the FSR" in found[0].remedy


def test_which_calibrations_read_modulo_their_fsr():
    class Stub:
        def __init__(self, absolute: bool, requires: frozenset):
            self.absolute_frequency, self.requires = absolute, requires

    single, coarse = Stub(False, frozenset()), Stub(False, frozenset({"coarse_hz"}))
    assert reads_modulo_fsr(single, None, None)
    assert not reads_modulo_fsr(Stub(True, frozenset()), None, None)  # a cascade
    assert reads_modulo_fsr(coarse, None, 193.4e12)  # one coarse value for all readings
    assert not reads_modulo_fsr(coarse, "set_point_THz", None)  # a coarse value per reading


# ---------------------------------------------------------------------------- time column
@pytest.fixture
def uniform(meter, tmp_path, rng):
    """Readings of a quiet laser and their uniform time stamps (s)."""
    device, calibration = meter
    powers = device.powers(laser_hz(device, 400, rng), POWER_W, NOISE_W, rng=rng)
    return calibration, powers, 5.0 + np.arange(400) / RATE_HZ


@pytest.mark.parametrize(
    ("name", "scale"), [("time_s", 1.0), ("t_ms", 1e3), ("Time (us)", 1e6), ("timestamp", 1.0)]
)
def test_the_rate_comes_from_a_uniform_time_column_in_its_unit(uniform, tmp_path, name, scale):
    calibration, powers, time_s = uniform
    path = write_readings(tmp_path / "r.csv", powers, time_s * scale, name)
    series = measure_series(calibration, path, time_column=name, chunk_rows=64)
    assert series.rate_hz == pytest.approx(RATE_HZ, rel=1e-9) and series.time_column == name
    # a rate that agrees within 1e-3 is accepted; the time column's is used
    again = measure_series(calibration, path, time_column=name, rate_hz=RATE_HZ * (1 + 5e-4))
    assert again.rate_hz == pytest.approx(RATE_HZ, rel=1e-9)


def _error(calibration, path, **options) -> InputError:
    with pytest.raises(InputError) as caught:
        measure_series(calibration, path, **options)
    return caught.value


@pytest.mark.parametrize("chunk_rows", [1000, 100, 37])  # 37: row 100's step spans chunks
def test_bad_time_stamps_are_refused_naming_the_row(uniform, tmp_path, chunk_rows):
    calibration, powers, time_s = uniform
    options = {"time_column": "time_s", "chunk_rows": chunk_rows}
    jittered = time_s.copy()
    jittered[100] += 0.01 / RATE_HZ  # 1 % of a step
    error = _error(calibration, write_readings(tmp_path / "j.csv", powers, jittered), **options)
    assert "not uniformly sampled" in str(error) and "before line 102" in str(error)
    assert "resample" in str(error) and error.parameter == "time_column"
    gap = np.delete(time_s, 100)  # one reading missing: a step of two
    error = _error(calibration, write_readings(tmp_path / "g.csv", powers[:-1], gap), **options)
    assert "gap in time column 'time_s' between line 101 and line 102" in str(error)
    assert "split the record" in str(error) and "2 times the median step" in str(error)
    backwards = time_s.copy()
    backwards[[100, 101]] = backwards[[101, 100]]
    error = _error(calibration, write_readings(tmp_path / "b.csv", powers, backwards), **options)
    assert "does not increase at line 103" in str(error) and "sort the file" in str(error)


def test_missing_or_text_time_stamps_are_refused(uniform, tmp_path):
    calibration, powers, time_s = uniform
    missing = time_s.copy()
    missing[50] = np.nan
    path = write_readings(tmp_path / "m.csv", powers, missing)
    error = _error(calibration, path, time_column="time_s")
    assert "has no time at line 52" in str(error)
    lines = write_readings(tmp_path / "t.csv", powers, time_s).read_text().splitlines()
    text = tmp_path / "text.csv"
    text.write_text(
        "\n".join(
            [lines[0]]
            + [f"12:00:{k:02d}," + line.split(",", 1)[1] for k, line in enumerate(lines[1:])]
        )
        + "\n"
    )
    assert "holds text" in str(_error(calibration, text, time_column="time_s"))
    assert "no column 'clock'" in str(_error(calibration, path, time_column="clock"))


def test_a_rate_that_disagrees_with_the_time_column_is_refused(uniform, tmp_path):
    calibration, powers, time_s = uniform
    path = write_readings(tmp_path / "r.csv", powers, time_s)
    error = _error(calibration, path, time_column="time_s", rate_hz=2 * RATE_HZ)
    assert "disagrees with the time column 'time_s'" in str(error)
    assert error.parameter == "rate_hz"


@pytest.mark.parametrize("rate", [0.0, -1.0, np.nan, np.inf, True, "10MHz"])
def test_a_rate_must_be_a_positive_number(uniform, tmp_path, rate):
    calibration, powers, _ = uniform
    path = write_readings(tmp_path / "r.csv", powers)
    assert _error(calibration, path, rate_hz=rate).parameter == "rate_hz"


def test_no_rate_and_no_time_column_is_refused_before_reading(meter, tmp_path):
    _, calibration = meter
    error = _error(calibration, tmp_path / "does-not-exist.csv")
    assert "no sampling rate" in str(error) and error.parameter == "rate_hz"


def test_readings_all_excluded_are_refused(uniform, tmp_path):
    calibration, powers, _ = uniform
    path = write_readings(tmp_path / "dark.csv", powers * 1e-3)  # the laser off: no light
    error = _error(calibration, path, rate_hz=RATE_HZ)
    assert "no usable reading: all 400 readings are excluded (INVALID 400)" in str(error)


def test_time_units_from_column_names():
    assert time_unit_s("time_s") == 1.0 and time_unit_s("t_ms") == 1e-3
    assert time_unit_s("Time (µs)") == 1e-6 and time_unit_s("t [ns]") == 1e-9
    assert time_unit_s("elapsed_time") == 1.0  # a suffix that is no unit: seconds
    with pytest.raises(InputError, match="unknown time unit 'min'"):
        time_unit_s("Time (min)")
