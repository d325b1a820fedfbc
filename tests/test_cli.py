"""The command line end to end: simulate, calibrate, measure, evaluate, report, info.

Round trips through ``main([...])`` and through the installed ``wavemeter`` script, a
lab-like file (wavelength in nm, ports in dBm) checked against the Cramer-Rao bound of the
true device, and every bad input: exit code 2, one ``error:`` line naming the file, column
or value, and no output file.
"""

from __future__ import annotations

import io
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.cli import cli, main
from wavemeter.io import ColumnRequest, read_table
from wavemeter.model.cone import delay_phase_rad
from wavemeter.progress import chunked

from .helpers import run_cli as run

SCRIPT = Path(sys.executable).with_name("wavemeter")
MINIPTI_CSV = Path(__file__).parents[2] / "shared/data/minipti-fiber-3x3/Decimation_Comercial.csv"
SEED = 1
C = 299792458.0


def ok(capsys, command: str) -> str:
    """Run a command that must succeed; its stdout."""
    code, printed, err = run(capsys, command)
    assert code == 0, err
    return printed


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """A simulated sweep with a test file, and its learned calibration."""
    folder = tmp_path_factory.mktemp("cli")
    sweep, cal = folder / "sweep.csv", folder / "chip.wmcal.json"
    assert main(shlex.split(f"simulate -o {sweep} --seed {SEED} --test 4000 --quiet")) == 0
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --quiet")) == 0
    return {"sweep": sweep, "test": folder / "sweep-test.csv", "cal": cal}


def test_simulate_calibrate_measure_round_trip(files, tmp_path, capsys):
    out = tmp_path / "frequencies.csv"
    keep = "--keep true_frequency_hz,p2_w"
    assert "4000 rows" in ok(capsys, f"measure {files['cal']} {files['test']} -o {out} {keep}")
    header, data = read_csv(out)
    assert header == [
        "frequency_hz",
        "wavelength_nm",
        "phase_rad",
        "frequency_std_hz",
        "flags",
        "true_frequency_hz",
        "p2_w",
    ]
    _, test = read_csv(files["test"])
    calibration = wm.load_calibration(files["cal"])
    np.testing.assert_array_equal(data[:, 0], calibration.predict(test[:, 1:]))
    np.testing.assert_array_equal(data[:, 2], calibration.phase(test[:, 1:]))
    np.testing.assert_allclose(data[:, 1], C / data[:, 0] * 1e9, rtol=1e-16)
    np.testing.assert_array_equal(data[:, 3], calibration.frequency_std_hz(test[:, 1:]))
    np.testing.assert_array_equal(data[:, 4], calibration.flags(test[:, 1:]))
    np.testing.assert_array_equal(data[:, 5:], test[:, [0, 2]])  # kept columns, in row order


@pytest.mark.parametrize("file_format", ["parquet", "hdf5", "npz"])
def test_measure_writes_every_format(files, tmp_path, capsys, file_format):
    if file_format == "parquet":
        pytest.importorskip("pyarrow")
    out = tmp_path / "frequencies.out"
    options = f"--format {file_format} --keep p1_w,p2_w,p3_w"
    ok(capsys, f"measure {files['cal']} {files['test']} -o {out} {options}")
    table = read_table(out, ColumnRequest(x="frequency_hz"))  # read back with our reader
    assert table.port_names == ("p1_w", "p2_w", "p3_w") and table.n_rows == 4000
    predicted = wm.load_calibration(files["cal"]).predict(table.powers_w)
    np.testing.assert_array_equal(table.x_hz, predicted)


def test_info_and_help(files, capsys):
    printed = ok(capsys, f"info {files['cal']}")
    for expected in (
        "method           learned",
        "ports            3: p1_w, p2_w, p3_w",
        "sweep.csv",
    ):
        assert expected in printed
    for command in cli.commands:
        assert "Example:" in ok(capsys, f"{command} --help"), command


def test_evaluate_reports_both_methods_against_the_crlb(files, capsys):
    report = json.loads(
        ok(capsys, f"evaluate {files['cal']} {files['test']} --sweep {files['sweep']} --json")
    )
    learned = report["methods"]["learned"]
    conventional = report["methods"]["conventional (fitted on sweep.csv)"]
    assert report["samples"] == 4000 and report["truth_column"] == "true_frequency_hz"
    # 4000 test readings: the RMS is known to ~1.1 %, the noise estimate to ~1 %
    assert 0.95 < learned["rms_abs_over_crlb"] < 1.08
    assert conventional["rms_abs_hz"] > 10 * learned["rms_abs_hz"]
    assert report["noise_std_w"] == pytest.approx(5e-7, rel=0.05)
    printed = ok(capsys, f"evaluate {files['cal']} {files['test']}")
    assert "RMS/CRLB" in printed and "learned" in printed


def test_lab_like_file_in_nm_and_dbm_meets_the_crlb_of_the_true_device(tmp_path, capsys):
    """A power-meter style sweep (vacuum wavelength in nm, ports in dBm, low noise) goes
    from file to frequency; the errors against the truth match the physical limit."""
    noise_w, power_w = 1e-8, 1e-3
    sweep, cal, out = tmp_path / "lab.csv", tmp_path / "lab.wmcal.json", tmp_path / "f.csv"
    test = tmp_path / "lab-test.csv"
    lab = f"--write-axis-unit nm --write-power-unit dBm --noise {noise_w}W --test 5000"
    ok(capsys, f"simulate -o {sweep} --seed {SEED} {lab}")
    assert test.read_text().startswith("true_wavelength_nm,p1_dBm,p2_dBm,p3_dBm\n")
    ok(capsys, f"calibrate {sweep} -o {cal} --fsr '50 GHz'")
    ok(capsys, f"measure {cal} {test} -o {out} --keep true_wavelength_nm")
    header, data = read_csv(out)
    truth_hz = C / (data[:, header.index("true_wavelength_nm")] * 1e-9)
    device = wm.Interferometer.table1(3, seed=SEED)
    error = wm.frequency_error_hz(data[:, 0], truth_hz, device.true_fsr_hz)
    phase = delay_phase_rad(truth_hz, device.center_hz, device.delay_s)
    bound = wm.crlb_frequency_std(device.true_map(), phase, power_w, noise_w, device.true_fsr_hz)
    ratio = np.sqrt(np.mean(error**2)) / np.sqrt(np.mean(bound**2))
    assert 0.95 < ratio < 1.08  # 5000 readings: +-1 %; 2001 calibration readings: +0.1 %
    report = json.loads(ok(capsys, f"evaluate {cal} {test} --sweep {sweep} --json"))
    assert report["truth_unit"] == "nm"
    assert 0.95 < report["methods"]["learned"]["rms_abs_over_crlb"] < 1.08
    assert report["methods"]["conventional (fitted on lab.csv)"]["rms_abs_over_crlb"] > 100


def test_power_monitor_column_is_used(tmp_path, capsys):
    sweep, cal = tmp_path / "s.csv", tmp_path / "c.json"
    ok(capsys, f"simulate -o {sweep} --write-power-unit mW --power-fluctuation 0.05 --quiet")
    assert "monitor monitor_mW" in ok(capsys, f"calibrate {sweep} -o {cal}")
    document = json.loads(cal.read_text())
    assert document["metadata"]["monitor_column"] == "monitor_mW"
    assert document["calibration_rms_hz"] < 15e6  # 5 % power noise is divided out


@pytest.mark.slow
def test_per_fsr_set_needs_a_coarse_frequency_and_reproduces_fig9(tmp_path, capsys):
    sweep, cal, out = tmp_path / "wide.csv", tmp_path / "set.json", tmp_path / "f.csv"
    test = tmp_path / "wide-test.csv"
    ok(capsys, f"simulate -o {sweep} --span-fsr 3 --samples 3000 --test 3000 --quiet")
    assert "learned per FSR" in ok(capsys, f"calibrate {sweep} -o {cal} --per-fsr")
    code, _, err = run(capsys, f"measure {cal} {test} -o {out}")
    assert code == 2 and "learned per FSR calibration (3 windows" in err and "--coarse" in err
    assert not out.exists()
    truth = "true_frequency_hz"
    ok(capsys, f"measure {cal} {test} -o {out} --coarse {truth} --keep {truth}")
    header, data = read_csv(out)
    error = data[:, 0] - data[:, header.index(truth)]
    assert np.sqrt(np.mean(error**2)) < 12e6  # absolute frequency
    adjacent = json.loads(ok(capsys, f"evaluate {cal} {test} --adjacent --json"))["adjacent"]
    assert adjacent["windows_evaluated"] == 3
    assert adjacent["adjacent"]["rms_hz"] < 1.2 * adjacent["own"]["rms_hz"]
    assert adjacent["conventional_adjacent"]["rms_hz"] > 10 * adjacent["adjacent"]["rms_hz"]


@pytest.mark.slow
def test_report_writes_html_and_figures(files, tmp_path, capsys):
    out = tmp_path / "report.html"
    ok(capsys, f"report {files['cal']} {files['sweep']} {files['test']} -o {out}")
    assert out.read_text().lstrip().lower().startswith("<!doctype html")
    assert len(list(tmp_path.glob("report-*.png"))) >= 4


def test_drop_invalid_writes_nan_rows_in_place(files, tmp_path, capsys):
    lines = files["test"].read_text().splitlines()[:6]
    lines[2] = lines[2].rsplit(",", 1)[0] + ",nan"
    lines[4] = lines[4].rsplit(",", 1)[0] + ",9.91e37"
    data, out = tmp_path / "d.csv", tmp_path / "f.csv"
    data.write_text("\n".join(lines) + "\n")
    code, _, err = run(capsys, f"measure {files['cal']} {data} -o {out} --drop-invalid")
    assert code == 0 and "skipped 2 invalid row(s), first: line 3" in err
    header, result = read_csv(out)
    assert result.shape == (5, 5) and header[4] == "flags"
    values = result[:, :4]
    assert np.isnan(values[[1, 3]]).all() and np.isfinite(values[[0, 2, 4]]).all()
    assert result[:, 4].tolist() == [0, wm.ReadingFlag.INVALID, 0, wm.ReadingFlag.INVALID, 0]


@pytest.mark.slow
def test_installed_script_round_trip_and_error(tmp_path):
    env = {**os.environ, "COLUMNS": "120"}

    def script(command: str):
        arguments = [str(SCRIPT), *shlex.split(command)]
        return subprocess.run(arguments, capture_output=True, text=True, env=env, check=False)

    sweep, cal, out = tmp_path / "s.csv", tmp_path / "c.json", tmp_path / "f.csv"
    assert script(f"simulate -o {sweep} --samples 500 --quiet").returncode == 0
    done = script(f"calibrate {sweep} -o {cal} --quiet")
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")
    done = script(f"measure {cal} {sweep} -o {out}")
    assert done.returncode == 0 and done.stderr == ""  # stderr is not a terminal: no bar
    assert len(out.read_text().splitlines()) == 501
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,p1,p2\n0,1,2\n1,2,3\n")  # two ports
    done = script(f"measure {cal} {bad} -o {tmp_path / 'g.csv'}")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and done.stderr.startswith(f"error: {bad}:")
    assert not (tmp_path / "g.csv").exists()


# ---------------------------------------------------------------------------- bad input
def _sweep_lines(files, rows: int = 12) -> list[str]:
    return files["sweep"].read_text().splitlines()[: rows + 1]


def _with_cell(lines: list[str], line: int, column: int, value: str) -> list[str]:
    """``lines`` with one cell replaced (``line`` counted from 1, as in the file)."""
    edited = list(lines)
    cells = edited[line - 1].split(",")
    cells[column] = value
    edited[line - 1] = ",".join(cells)
    return edited


BAD_SWEEPS = {
    # name: (edit of the first 13 lines of a sweep, expected text in the error)
    "nan": (lambda lines: _with_cell(lines, 4, 2, "nan"), "line 4 (p2_w is NaN"),
    "empty row": (lambda lines: lines[:3] + [",,,"] + lines[4:], "line 4 (p1_w is NaN"),
    "sentinel": (
        lambda lines: _with_cell(lines, 6, 1, "9.91E+37"),
        "line 6 (p1_w is a power-meter 'no reading' code 9.91e+37)",
    ),
    "no light": (
        lambda lines: [lines[0], "1.934e14,0,0,-1e-9", *lines[2:]],
        "line 2 (port powers sum to <= 0",
    ),
    "duplicate": (
        lambda lines: [lines[0].replace("p3_w", "p2_w"), *lines[1:]],
        "duplicate column name 'p2_w'",
    ),
    "unknown unit": (
        lambda lines: [lines[0].replace("_w", "_mA"), *lines[1:]],
        "column 'p1_mA': unknown power unit 'mA'",
    ),
    "few samples": (lambda lines: lines[:4], "need at least 4 samples"),
    "short span": (lambda lines: lines, "the sweep spans"),
    "non-numeric": (
        lambda lines: _with_cell(lines, 8, 3, "high"),
        "line 8, column 'p3_w': 'high' is not a number",
    ),
    "empty file": (lambda lines: [], "the file is empty"),
    "dbm as watts": (
        lambda lines: [lines[0]] + ["1.934e14,-3,-4,-5"] * 8,
        "are these dBm?",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_SWEEPS))
def test_bad_sweep_files(files, tmp_path, capsys, case):
    edit, expected = BAD_SWEEPS[case]
    sweep, out = tmp_path / "bad.csv", tmp_path / "cal.json"
    lines = edit(_sweep_lines(files))
    sweep.write_text("\n".join(lines) + "\n" if lines else "")
    code, printed, err = run(capsys, f"calibrate {sweep} -o {out}")
    assert code == 2 and printed == ""
    assert err.count("\n") == 1 and err.startswith(f"error: {sweep}: ")
    assert expected in err
    assert not out.exists()


def test_nm_values_labelled_thz(files, tmp_path, capsys):
    header, data = read_csv(files["sweep"])
    data[:, 0] = C / data[:, 0] * 1e9
    sweep, out = tmp_path / "nm.csv", tmp_path / "c.json"
    np.savetxt(sweep, data, delimiter=",", header="freq_THz," + ",".join(header[1:]), comments="")
    code, _, err = run(capsys, f"calibrate {sweep} -o {out}")
    assert code == 2 and err.startswith(f"error: {sweep}: column 'freq_THz': values 1549")
    assert "labelled THz look like nm; give the axis unit nm (use --x-unit)" in err
    assert not out.exists()
    ok(capsys, f"calibrate {sweep} -o {out} --x-unit nm")


def test_delay_minimum_on_the_bracket_edge(files, tmp_path, capsys):
    out = tmp_path / "c.json"
    bracket = "--fsr 45GHz --fsr-tolerance 0.05"
    code, _, err = run(capsys, f"calibrate {files['sweep']} -o {out} {bracket}")
    assert code == 2 and err.startswith(f"error: {files['sweep']}: ")
    assert "edge of the FSR bracket" in err and not out.exists()
    assert err.rstrip().endswith("(fsr_hz: --fsr, fsr_tolerance: --fsr-tolerance)")


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--fsr fast", "Invalid value for '--fsr': value 'fast' is not a number"),
        ("--fsr '50 nm'", "unknown frequency unit 'nm'"),
        ("--method magic", "Invalid value for '--method'"),
        ("--x nope", "no column 'nope'"),
        ("--ports p1_w,p2_w", "found 2 port column(s) (p1_w, p2_w); need at least 3"),
        ("--power-unit furlongs", "unknown power unit 'furlongs'"),
        ("--monitor p1_w,p2_w", "no column 'p1_w,p2_w'"),
    ],
)
def test_bad_options(files, tmp_path, capsys, options, expected):
    out = tmp_path / "c.json"
    code, _, err = run(capsys, f"calibrate {files['sweep']} -o {out} {options}")
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and expected in err
    assert options.split()[0] in err  # the option at fault is named
    assert not out.exists()


def test_calibration_used_on_other_ports(files, tmp_path, capsys):
    four, renamed, out = tmp_path / "four.csv", tmp_path / "renamed.csv", tmp_path / "f.csv"
    ok(capsys, f"simulate -o {four} --ports 4 --samples 50 --quiet")
    lines = _sweep_lines(files)
    renamed.write_text("\n".join([lines[0].replace("p", "ch"), *lines[1:]]) + "\n")
    code, _, err = run(capsys, f"measure {files['cal']} {four} -o {out}")
    expected = f"{four} has 4 ports (p1_w, p2_w, p3_w, p4_w) but {files['cal']} was calibrated on 3"
    assert code == 2 and expected in err
    code, _, err = run(capsys, f"measure {files['cal']} {renamed} -o {out}")
    assert code == 2 and "has ports ch1_w, ch2_w, ch3_w but" in err and "p1_w, p2_w, p3_w" in err
    assert not out.exists()
    ok(capsys, f"measure {files['cal']} {renamed} -o {out} --ports ch1_w,ch2_w,ch3_w")


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        ("", "not valid JSON"),
        ('{"format": "wavemeter.calibration", "schema_version": 1', "not valid JSON"),
        ('{"format": "something.else"}', "not a wavemeter calibration file"),
        (None, "calibration file not found"),
    ],
)
def test_corrupt_truncated_foreign_or_missing_calibration(
    files, tmp_path, capsys, content, expected
):
    cal, out = tmp_path / "cal.json", tmp_path / "f.csv"
    if content is not None:
        cal.write_text(content)
    for command in (
        f"measure {cal} {files['test']} -o {out}",
        f"info {cal}",
        f"evaluate {cal} {files['test']}",
    ):
        code, _, err = run(capsys, command)
        assert code == 2 and err.startswith(f"error: {cal}: ") and expected in err
    assert not out.exists()


def test_adjacent_needs_a_calibration_set(files, capsys):
    code, _, err = run(capsys, f"evaluate {files['cal']} {files['test']} --adjacent")
    assert code == 2 and "--adjacent needs a per-FSR calibration set" in err


@pytest.mark.skipif(not MINIPTI_CSV.exists(), reason="shared MiniPTI data not present")
def test_test_file_without_truth(files, capsys):
    code, _, err = run(capsys, f"evaluate {files['cal']} '{MINIPTI_CSV}'")
    assert code == 2 and "no frequency or wavelength column" in err


# ---------------------------------------------------------------------------- progress
class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize(
    ("stream", "quiet", "drawn"),
    [(FakeTerminal(), False, True), (FakeTerminal(), True, False), (io.StringIO(), False, False)],
)
def test_progress_bar_only_on_a_terminal_and_not_when_quiet(stream, quiet, drawn):
    slices = list(chunked(10, "working", quiet=quiet, chunk_rows=3, stream=stream))
    assert slices == [slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 10)]
    assert bool(stream.getvalue()) is drawn


def test_ml_retrieval_and_per_reading_uncertainty(files, tmp_path, capsys):
    """calibrate --retrieval ml and measure --uncertainty: errors / std have unit RMS."""
    cal, out = tmp_path / "ml.wmcal.json", tmp_path / "f.csv"
    ok(capsys, f"calibrate {files['sweep']} -o {cal} --retrieval ml --quiet")
    assert wm.load_calibration(cal).retrieval == "ml"
    ok(capsys, f"measure {cal} {files['test']} -o {out} --uncertainty --keep true_frequency_hz")
    header, data = read_csv(out)
    assert header == [
        "frequency_hz",
        "wavelength_nm",
        "phase_rad",
        "frequency_std_hz",
        "flags",
        "true_frequency_hz",
    ]
    fsr = wm.load_calibration(cal).fsr_hz_
    normalised = wm.frequency_error_hz(data[:, 0], data[:, 5], fsr) / data[:, 3]
    # 4000 readings: the RMS of unit-variance errors is known to ~1.1 %; allow 4 of them
    assert np.sqrt(np.mean(normalised**2)) == pytest.approx(1.0, abs=0.045)


def test_uncertainty_and_ml_need_the_learned_method(files, tmp_path, capsys):
    conventional = tmp_path / "conv.wmcal.json"
    code, _, err = run(
        capsys, f"calibrate {files['sweep']} -o {conventional} --method conventional --retrieval ml"
    )
    assert code == 2 and "method 'conventional' has no setting retrieval" in err
    assert "it is a setting of learned," in err and "(retrieval: --retrieval)" in err
    assert not conventional.exists()
    ok(capsys, f"calibrate {files['sweep']} -o {conventional} --method conventional --quiet")
    out = tmp_path / "f.csv"
    code, _, err = run(capsys, f"measure {conventional} {files['test']} -o {out} --uncertainty")
    assert code == 2 and err.startswith("error:") and "is a conventional calibration" in err
    assert "gives no standard deviation" in err and "(uncertainty: --uncertainty)" in err
    assert not out.exists()


@pytest.mark.slow
def test_uncertainty_of_a_calibration_set_has_unit_z_spread(tmp_path, capsys):
    """measure --uncertainty works for a per-FSR set (issue 15): errors over the stated
    standard deviation spread as N(0, 1), within the statistics of 2000 readings."""
    sweep, cal, out = tmp_path / "wide.csv", tmp_path / "set.wmcal.json", tmp_path / "m.csv"
    ok(capsys, f"simulate -o {sweep} --span-fsr 3 --samples 6000 --test 2000 --quiet")
    ok(capsys, f"calibrate {sweep} -o {cal} --per-fsr --quiet")
    test = tmp_path / "wide-test.csv"
    ok(capsys, f"measure {cal} {test} -o {out} --coarse true_frequency_hz --uncertainty --quiet")
    header, data = read_csv(out)
    truth = np.loadtxt(test, delimiter=",", skiprows=1, usecols=0)
    z = (data[:, header.index("frequency_hz")] - truth) / data[:, header.index("frequency_std_hz")]
    # rms of 2000 unit normals: 1 +- 4 / sqrt(2 * 2000); calibration adds sqrt(1 + 3/2000)
    assert abs(np.sqrt(np.mean(z**2)) - 1) < 4 / np.sqrt(2 * 2000) + 0.01
