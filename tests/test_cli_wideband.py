"""The wide-band calibration on the command line: calibrate, measure, info, evaluate, report.

The device is the Table 1 3-port chip (seed 3) with a group-delay dispersion of 1e-26 s^2,
swept over 12 FSRs (300 readings each) with the Table 1 noise: a linear phase leaves a
phase error of several mrad there, so the fit takes a phase order of 2. Frequencies read
back are judged by the calibration's own ``frequency_std_hz``: ``(estimate - truth) / std``
has unit standard deviation, and its RMS over ``M`` readings has a relative standard error
``1 / sqrt(2 M)``; the bounds below are ``Z_BOUND`` such errors wide. Fitted coefficients
are checked against the device within ``MAX_Z`` of their own standard errors.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import read_calibration_file
from wavemeter.calibration.models.wideband_orders import MAX_MAP_ORDER, MAX_PHASE_ORDER
from wavemeter.cli import main
from wavemeter.io import write_table
from wavemeter.report.html import report_paths

from .helpers import NOISE_W, POWER_W, one_error, run_cli

FSR_COUNT = 12
PER_FSR = 300
TEST_READINGS = 1000
LINE_READINGS = 400
AMBIGUOUS_READINGS = 100
#: |estimate - truth| / standard error beyond which a correct estimator is refuted
MAX_Z = 5.0
#: Monte-Carlo standard errors an RMS of unit-variance values may stray from 1
Z_BOUND = 7.0
#: the coarse values of the test readings lie within this share of an FSR of the truth
COARSE_SPREAD_FSR = 0.2
#: readings this far from the one coarse value (share of an FSR) are read right but flagged
AMBIGUOUS_FSR = (0.3, 0.45)
#: the one coarse value of the line readings: this many FSRs above the middle of the band
LINE_OFFSET_FSR = 2.3


def rms_bounds(count: int) -> tuple[float, float]:
    """Where the RMS of ``count`` unit-variance Gaussian values lies but for a refutation."""
    spread = Z_BOUND / np.sqrt(2 * count)
    return 1.0 - spread, 1.0 + spread


def ok(capsys, command: str) -> str:
    code, out, err = run_cli(capsys, command)
    assert code == 0, err
    return out


def read_columns(path: Path) -> dict[str, np.ndarray]:
    """The columns of a CSV file by their names as written."""
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    values = np.array(rows[1:], dtype=float)
    return {name: values[:, k] for k, name in enumerate(rows[0])}


def write_readings(path: Path, device, truth_hz, seed: int, **extra) -> Path:
    """Readings of ``device`` at ``truth_hz`` (Hz) with the Table 1 noise, and ``extra``
    columns before the ports."""
    powers = device.powers(truth_hz, POWER_W, NOISE_W, rng=seed)
    write_table(path, {**extra, **{f"p{k + 1}_w": powers[:, k] for k in range(device.ports)}})
    return path


@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return dataclasses.replace(wm.Interferometer.table1(3, seed=3), dispersion_s2=1e-26)


@pytest.fixture(scope="module")
def files(tmp_path_factory, device) -> dict:
    """The band sweep, its wide-band calibration (orders chosen), test readings with a
    coarse column, and line readings about one coarse value."""
    folder = tmp_path_factory.mktemp("wideband")
    fsr = device.true_fsr_hz
    index = np.arange(FSR_COUNT * PER_FSR)
    sweep_hz = device.center_hz + (index / PER_FSR - FSR_COUNT / 2) * fsr
    sweep = write_readings(folder / "band.csv", device, sweep_hz, 1, frequency_hz=sweep_hz)
    cal = folder / "band.wmcal.json"
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --method wideband --quiet")) == 0
    rng = np.random.default_rng(5)
    truth = rng.uniform(sweep_hz[0], sweep_hz[-1], TEST_READINGS)
    set_point = truth + rng.uniform(-COARSE_SPREAD_FSR, COARSE_SPREAD_FSR, truth.size) * fsr
    test = write_readings(
        folder / "test.csv", device, truth, 6, frequency_hz=truth, set_point_hz=set_point
    )
    line_hz = device.center_hz + LINE_OFFSET_FSR * fsr
    near = line_hz + rng.uniform(-COARSE_SPREAD_FSR, COARSE_SPREAD_FSR, LINE_READINGS) * fsr
    sign = rng.choice([-1.0, 1.0], AMBIGUOUS_READINGS)
    far = line_hz + sign * rng.uniform(*AMBIGUOUS_FSR, AMBIGUOUS_READINGS) * fsr
    line_truth = np.r_[near, far]
    line = write_readings(folder / "line.csv", device, line_truth, 7, true_hz=line_truth)
    return {
        "folder": folder,
        "sweep": sweep,
        "cal": cal,
        "test": test,
        "line": line,
        "line_hz": line_hz,
        "calibration": read_calibration_file(cal).calibrator,
    }


# ---------------------------------------------------------------------------- calibrate
@pytest.mark.slow
def test_the_band_gets_the_dispersion_the_device_has(files, device):
    calibration = files["calibration"]
    assert calibration.method == "wideband"
    assert calibration.phase_order_ >= 2
    record = calibration.diagnostics_["wideband"]
    std = record["phase_coefficients_std_s"]
    assert abs(calibration.phase_coefficients_[1] - device.dispersion_s2) < MAX_Z * std[1]
    assert abs(calibration.delay_s_ - device.delay_s) < MAX_Z * std[0]


@pytest.mark.parametrize(
    ("options", "named", "allowed"),
    [
        ("--method wideband --phase-order 0", "--phase-order", f"from 1 to {MAX_PHASE_ORDER}"),
        ("--method wideband --phase-order 9", "--phase-order", f"from 1 to {MAX_PHASE_ORDER}"),
        ("--method wideband --phase-order x", "--phase-order", f"from 1 to {MAX_PHASE_ORDER}"),
        ("--method wideband --map-order 9", "--map-order", f"from 0 to {MAX_MAP_ORDER}"),
        ("--method wideband --map-order -1", "--map-order", f"from 0 to {MAX_MAP_ORDER}"),
        ("--method wideband --map-order 1.5", "--map-order", f"from 0 to {MAX_MAP_ORDER}"),
        ("--phase-order 2", "--phase-order", "of wideband"),
        ("--method thermal --map-order 1", "--map-order", "of wideband"),
        ("--method wideband --per-fsr", "--per-fsr", "method 'wideband' also needs"),
    ],
)
def test_bad_order_options_are_refused_before_any_work(
    files, tmp_path, capsys, options, named, allowed
):
    out_path = tmp_path / "cal.wmcal.json"
    code, _, err = run_cli(capsys, f"calibrate {files['sweep']} -o {out_path} {options}")
    line = one_error(code, err)
    assert named in line and allowed in line
    assert not out_path.exists()


def test_given_orders_are_kept_and_info_says_so(files, tmp_path, capsys):
    cal = tmp_path / "given.wmcal.json"
    ok(
        capsys,
        f"calibrate {files['sweep']} -o {cal} --method wideband --phase-order 2 --map-order 1",
    )
    calibration = read_calibration_file(cal).calibrator
    assert (calibration.phase_order_, calibration.map_order_) == (2, 1)
    printed = ok(capsys, f"info {cal}")
    assert re.search(r"^phase order P\s+2$", printed, re.M)
    assert re.search(r"^map order J\s+1$", printed, re.M)
    assert "both orders given" in printed
    assert "held-out RMS" not in printed  # nothing was cross-validated


@pytest.mark.slow
def test_a_linear_phase_on_a_dispersive_band_warns_and_strict_refuses(files, tmp_path, capsys):
    """Forced to the paper's model, the fit leaves the dispersion in its residual: a
    warning line, and with --strict exit code 3 and no file."""
    cal = tmp_path / "linear.wmcal.json"
    options = "--method wideband --phase-order 1 --map-order 0"
    code, _, err = run_cli(capsys, f"calibrate {files['sweep']} -o {cal} {options} --quiet")
    assert code == 0, err
    # the remedy is this fit's own phase order, and its option
    assert re.search(
        r"^warning: \[dispersion\] .*higher phase_order \(this fit has 1\).*"
        r"\(options: --phase-order\)$",
        err,
        re.M,
    )
    assert cal.exists()
    strict = tmp_path / "strict.wmcal.json"
    code, _, err = run_cli(capsys, f"calibrate {files['sweep']} -o {strict} {options} --strict")
    assert code == 3 and err.startswith("error: [dispersion]"), err
    assert not strict.exists()


# ---------------------------------------------------------------------------- measure
def test_measure_with_a_coarse_column_reads_at_the_stated_uncertainty(files, tmp_path, capsys):
    out_path = tmp_path / "f.csv"
    ok(
        capsys,
        f"measure {files['cal']} {files['test']} -o {out_path} --coarse set_point_hz",
    )
    out = read_columns(out_path)
    z = (out["frequency_hz"] - read_columns(files["test"])["frequency_hz"]) / out[
        "frequency_std_hz"
    ]
    low, high = rms_bounds(TEST_READINGS)
    assert low < np.sqrt(np.mean(z**2)) < high
    flags = out["flags"].astype(int)
    assert not np.any(flags & (wm.ReadingFlag.ORDER_AMBIGUOUS | wm.ReadingFlag.OUTSIDE_SPAN))


def test_measure_with_one_coarse_frequency_flags_far_readings(files, tmp_path, capsys):
    """One coarse value for the file: readings within half an FSR of it are read right;
    those more than ORDER_MARGIN_FSR from it carry ORDER_AMBIGUOUS."""
    out_path = tmp_path / "f.csv"
    coarse = f"{files['line_hz'] / 1e12:.9f}THz"
    printed = ok(
        capsys,
        f"measure {files['cal']} {files['line']} -o {out_path} --coarse-hz {coarse} --keep true_hz",
    )
    out = read_columns(out_path)
    z = (out["frequency_hz"] - out["true_hz"]) / out["frequency_std_hz"]
    low, high = rms_bounds(z.size)
    assert low < np.sqrt(np.mean(z**2)) < high
    ambiguous = (out["flags"].astype(int) & wm.ReadingFlag.ORDER_AMBIGUOUS) != 0
    assert ambiguous.tolist() == [False] * LINE_READINGS + [True] * AMBIGUOUS_READINGS
    assert f"ORDER_AMBIGUOUS {AMBIGUOUS_READINGS}" in printed


def test_measure_without_a_coarse_frequency_says_what_to_pass(files, tmp_path, capsys):
    out_path = tmp_path / "f.csv"
    code, _, err = run_cli(capsys, f"measure {files['cal']} {files['line']} -o {out_path}")
    line = one_error(code, err)
    assert "wideband calibration" in line and "fringe order" in line
    assert "--coarse COL" in line and "--coarse-frequency" in line
    assert not out_path.exists()


# ---------------------------------------------------------------------------- info
def test_info_shows_orders_coefficients_and_the_cross_validation_curve(files, device, capsys):
    calibration = files["calibration"]
    record = calibration.diagnostics_["wideband"]
    printed = ok(capsys, f"info {files['cal']}")
    found = [
        int(re.search(rf"^{label}\s+(\d+)$", printed, re.M)[1])
        for label in ("phase order P", "map order J", "fitted parameters")
    ]
    assert found == [calibration.phase_order_, calibration.map_order_, calibration.n_parameters_]
    value, error = map(
        float, re.search(r"^group-delay dispersion\s+(\S+) \+- (\S+) s\^2$", printed, re.M).groups()
    )
    assert abs(value - device.dispersion_s2) < MAX_Z * error
    (table,) = calibration.summary().tables
    for line in table.text_lines():
        assert line in printed.splitlines()
    rows = table.rows
    candidates = record["orders"]["candidates"]
    assert len(rows) == len(candidates) >= 2
    chosen = [row for row in rows if row[4]]
    assert [row[:2] for row in chosen] == [(calibration.phase_order_, calibration.map_order_)]
    # the paper's linear phase predicts held-out FSRs of a dispersive band worse
    linear = next(row for row in rows if row[:2] == (1, 0))
    assert linear[3] > chosen[0][3]
    windows = len(record["residual_phase"])
    low, high = map(
        float,
        re.search(
            rf"residual phase RMS per FSR window (\S+) to (\S+) mrad over {windows} windows",
            printed,
        ).groups(),
    )
    # every window noise-limited: their RMS over PER_FSR readings agree within the spread
    bound_low, bound_high = rms_bounds(PER_FSR)
    assert high / low < bound_high / bound_low


# ---------------------------------------------------------------------------- evaluate
def test_evaluate_reports_the_error_at_the_stated_uncertainty(files, capsys):
    report = json.loads(
        ok(capsys, f"evaluate {files['cal']} {files['test']} --coarse set_point_hz --json")
    )
    assert report["coarse_from"] == "coarse_hz"
    stats = report["methods"]["wideband"]
    assert stats["outside_span_fraction"] == 0 and stats["gross_error_fraction"] == 0
    test = read_columns(files["test"])
    powers = np.column_stack([test[f"p{k}_w"] for k in (1, 2, 3)])
    std = files["calibration"].frequency_std_hz(powers, coarse_hz=test["set_point_hz"])
    low, high = rms_bounds(TEST_READINGS)
    assert low < stats["rms_abs_hz"] / np.sqrt(np.mean(std**2)) < high
    printed = ok(capsys, f"evaluate {files['cal']} {files['test']}")
    assert re.search(r"^wideband\s+\d+\.\d+", printed, re.M)
    assert "coarse frequency of each reading (wideband calibrations): the true frequency" in printed


def test_evaluate_adjacent_needs_a_set(files, capsys):
    code, _, err = run_cli(capsys, f"evaluate {files['cal']} {files['test']} --adjacent")
    line = one_error(code, err)
    assert "--adjacent" in line and "wideband calibration" in line and "--per-fsr" in line


# ---------------------------------------------------------------------------- report
@pytest.mark.slow
def test_report_has_the_wide_band_section_and_figures(files, tmp_path, capsys):
    page = tmp_path / "report.html"
    ok(capsys, f"report {files['cal']} {files['sweep']} {files['test']} -o {page}")
    text = page.read_text(encoding="utf-8")
    assert "<h3>orders scored</h3>" in text and "residual phase RMS per FSR window" in text
    for figure in ("cross_validation", "residual_phase"):
        assert f'id="figure-{figure}"' in text
    candidates = files["calibration"].diagnostics_["wideband"]["orders"]["candidates"]
    assert text.count("<td>chosen</td>") == sum(candidate["chosen"] for candidate in candidates)
    assert "<td>learned per FSR</td>" in text  # compared with a set fitted per FSR
    assert all(path.exists() for path in report_paths(page, files["calibration"]))


@pytest.mark.slow
def test_report_lists_the_comparisons_warnings_on_the_page_only(tmp_path, capsys):
    """On a sweep of 15.6 FSRs the per-FSR set's outer windows cover part of an FSR and
    warn: that is about the comparison, not the user's calibration, so it goes to the page,
    not to stderr."""
    device = dataclasses.replace(
        wm.Interferometer.table1(3, seed=2).with_spectral("sin", seed=2), dispersion_s2=1e-26
    )
    frequency = device.center_hz + (np.arange(int(15.6 * 300)) / 300 - 8) * device.true_fsr_hz
    sweep = write_readings(tmp_path / "band.csv", device, frequency, 1, frequency_hz=frequency)
    with pytest.warns(wm.CalibrationWarning) as caught:  # the comparison does warn
        wm.CalibrationSet().fit(device.powers(frequency, POWER_W, NOISE_W, rng=1), frequency)
    cal, page = tmp_path / "band.wmcal.json", tmp_path / "report.html"
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --method wideband --quiet")) == 0
    code, _, err = run_cli(capsys, f"report {cal} {sweep} -o {page} --quiet")
    assert code == 0 and "warning:" not in err, err
    text = page.read_text(encoding="utf-8")
    assert "fitted on the same sweep) warned:" in text
    assert f"[{caught[0].message.cause}]" in text
