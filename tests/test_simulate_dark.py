"""``wavemeter simulate --dark N``: readings with the source off, for ``calibrate --dark``.

The dark file holds what ``Scenario(dark=N).dark_table()`` gives, value for value: the
detectors' dark offset plus their noise (the mean within 5 standard errors of the offset,
the spread within a chi-square bound of the noise), the sweep's port columns and no axis;
the other files are the same with and without it, and ``calibrate --dark`` on it removes
the offset the sweep carries.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from wavemeter.simulation import Scenario

from .helpers import assert_file_holds, one_error, run_cli

OFFSET_W = (2e-6, -1e-6, 5e-7)
NOISE_W = 5e-7
ROWS = 4000


def test_dark_readings_are_offset_plus_noise():
    scenario = Scenario(dark=ROWS, dark_offset_w=OFFSET_W, noise_w=NOISE_W, seed=3)
    dark = scenario.dark_table()
    assert list(dark) == ["p1_w", "p2_w", "p3_w"]
    values = np.column_stack(list(dark.values()))
    assert values.shape == (ROWS, 3)
    # the source is off: the mean is the offset, within 5 standard errors of the noise
    np.testing.assert_allclose(values.mean(axis=0), OFFSET_W, atol=5 * NOISE_W / np.sqrt(ROWS))
    # and the spread is the detector noise (two-sided chi-square bound at p = 1e-6 each)
    low, high = stats.chi2.ppf([1e-6, 1 - 1e-6], ROWS - 1) / (ROWS - 1)
    variance_ratio = values.var(axis=0, ddof=1) / NOISE_W**2
    assert np.all((variance_ratio > low) & (variance_ratio < high)), variance_ratio


def test_no_dark_readings_unless_asked_and_the_other_tables_unchanged():
    plain = Scenario(test=20, laser=10, seed=2)
    with_dark = Scenario(test=20, laser=10, seed=2, dark=50)
    assert plain.dark_table() is None
    for table, other in zip(plain.tables(), with_dark.tables(), strict=True):
        assert table.keys() == other.keys()
        for name in table:
            np.testing.assert_array_equal(table[name], other[name])
    for name, values in plain.laser_table().items():
        np.testing.assert_array_equal(values, with_dark.laser_table()[name])


def test_dark_readings_of_a_thermal_device_with_a_monitor_have_the_sweeps_columns():
    dark = Scenario(dark=10, platform="sin", power_drift=0.05, seed=1).dark_table()
    assert list(dark) == ["p1_w", "p2_w", "p3_w", "monitor_w", "temperature_k"]
    assert np.all(dark["monitor_w"] == 0)  # the monitor sees the source: off


def test_the_command_writes_the_dark_file_and_calibrate_removes_the_offset(tmp_path, capsys):
    sweep, dark = tmp_path / "s.csv", tmp_path / "s-dark.csv"
    offsets = ",".join(f"{value:g}" for value in OFFSET_W)
    code, printed, err = run_cli(
        capsys, f"simulate -o {sweep} --dark-offset {offsets} --dark {ROWS} --seed 4"
    )
    assert code == 0, err
    assert f"wrote {dark} ({ROWS} rows: p1_w, p2_w, p3_w)" in printed
    assert_file_holds(dark, Scenario(dark=ROWS, dark_offset_w=OFFSET_W, seed=4).dark_table())
    calibration = tmp_path / "c.wmcal.json"
    code, _, err = run_cli(capsys, f"calibrate {sweep} -o {calibration} --dark {dark} --quiet")
    assert code == 0, err
    # the dark offsets the calibration subtracts: the file's means, the offsets within noise
    dark_w = json.loads(calibration.read_text())["reading_model"]["dark_w"]
    np.testing.assert_allclose(dark_w, OFFSET_W, atol=5 * NOISE_W / np.sqrt(ROWS))


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--dark 10 -o -", "with -o - (stdout) and --dark, name the dark file with --dark-out"),
        ("--dark 10 --test 10 --dark-out {test}", "--dark-out {test} is the test file too"),
    ],
)
def test_the_dark_file_is_a_file_of_its_own(tmp_path, capsys, options, expected):
    out, test = tmp_path / "s.csv", tmp_path / "s-test.csv"
    options = options.format(out=out, test=test)
    command = f"simulate --samples 20 {options}" + ("" if "-o -" in options else f" -o {out}")
    line = one_error(*run_cli(capsys, command)[::2])
    assert expected.format(out=out, test=test) in line
    assert not out.exists() and not test.exists()
