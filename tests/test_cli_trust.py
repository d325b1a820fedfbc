"""Calibrations and readings the command line says whether to trust (issue 9, items 2, 6, 8).

Calibration warnings print as ``warning: [cause] message`` lines, also with ``--quiet``;
``calibrate --strict`` refuses them (exit code 3, nothing written). Dark readings
(``--dark FILE`` averaged per port, ``--dark-w``) are subtracted in fit and predict: a
calibration with dark ``d`` gives bit for bit what a calibration of ``sweep - d`` gives on
``readings - d``. ``measure`` writes the calibration's own ``flags`` and
``frequency_std_hz`` for every row (rows skipped as invalid get the INVALID bit); in chunks,
in ``test_cli_readings.py``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import read_calibration_file
from wavemeter.cli import main
from wavemeter.io import ColumnRequest, read_table, write_table

from .helpers import NOISE_W, POWER_W, one_error
from .helpers import run_cli as run

SAMPLES = 400
TEST_ROWS = 300
#: a dead port: a detector offset and its noise, no fringe
DEAD_PORT_W = 1e-6
WARNING_LINE = re.compile(r"^warning: \[[a-z_]+\] \S.*$")
STRICT_LINE = re.compile(r"^error: \[[a-z_]+\] \S.* \(--strict: no calibration written\)$")


def write_readings(path: Path, readings: np.ndarray, frequency_hz=None) -> Path:
    """Port readings (W) as ``p1_w, p2_w, ..`` with a ``frequency_hz`` column if given."""
    columns = {} if frequency_hz is None else {"frequency_hz": frequency_hz}
    columns |= {f"p{k + 1}_w": readings[:, k] for k in range(readings.shape[1])}
    write_table(path, columns)
    return path


def device_data(ports: int, seed: int, *, dead_port: int | None = None):
    """Sweep (frequency, readings) over one FSR and test readings of a Table 1 device, with
    one port replaced by dark noise if ``dead_port`` is given."""
    device = wm.Interferometer.table1(ports, seed=seed)
    rng = np.random.default_rng(seed)
    frequency = device.sweep_hz(SAMPLES)
    sweep = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    half = device.true_fsr_hz / 2
    truth = device.center_hz + rng.uniform(-half, half, TEST_ROWS)
    test = device.powers(truth, POWER_W, NOISE_W, rng=rng)
    if dead_port is not None:
        sweep[:, dead_port] = DEAD_PORT_W + NOISE_W * rng.standard_normal(SAMPLES)
    return frequency, sweep, truth, test


@pytest.fixture(scope="module")
def dead(tmp_path_factory) -> Path:
    """A 4-port sweep whose third port is dead: the fit warns (cause dead_port)."""
    frequency, sweep, _, _ = device_data(4, seed=3, dead_port=2)
    return write_readings(tmp_path_factory.mktemp("dead") / "dead.csv", sweep, frequency)


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> dict[str, Path]:
    """A clean 3-port sweep, test readings with their truth, and the calibration."""
    folder = tmp_path_factory.mktemp("clean")
    frequency, sweep, truth, test = device_data(3, seed=4)
    files = {
        "sweep": write_readings(folder / "sweep.csv", sweep, frequency),
        "test": write_readings(folder / "test.csv", test),
        "cal": folder / "chip.wmcal.json",
    }
    assert main(["calibrate", str(files["sweep"]), "-o", str(files["cal"]), "--quiet"]) == 0
    return files


def lines(text: str, prefix: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(prefix)]


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


# ---------------------------------------------------------------------------- warnings
def test_warnings_are_one_line_each_with_their_cause_also_when_quiet(dead, tmp_path, capsys):
    cal = tmp_path / "cal.wmcal.json"
    code, out, err = run(capsys, f"calibrate {dead} -o {cal}")
    assert code == 0, err
    warned = lines(err, "warning: ")
    assert warned and all(WARNING_LINE.match(line) for line in warned), err
    assert any(line.startswith("warning: [dead_port] port(s) p3_w ") for line in warned)
    # not Python's default display ("...py:123: CalibrationWarning: ...")
    assert "CalibrationWarning" not in err and ".py:" not in err
    # the summary names the causes of the warnings, as the file keeps them
    causes = [note["cause"] for note in wm.load_calibration(cal).diagnostics_["warnings"]]
    assert [line.split("]")[0][len("warning: [") :] for line in warned] == causes
    assert all(re.search(rf"^warning +{cause}: ", out, re.M) for cause in causes), out
    # --quiet hides the summary, not the warnings; a second fit in the same process warns again
    code, out, quiet_err = run(capsys, f"calibrate {dead} -o {cal} --force --quiet")
    assert code == 0 and out == "" and lines(quiet_err, "warning: ") == warned


def test_every_command_that_fits_prints_warnings_the_same_way(dead, tmp_path, capsys):
    cal = tmp_path / "cal.wmcal.json"
    run(capsys, f"calibrate {dead} -o {cal} --quiet")
    # evaluate fits the conventional method on the sweep for comparison: it warns too
    code, _, err = run(capsys, f"evaluate {cal} {dead} --sweep {dead}")
    assert code == 0, err
    warned = lines(err, "warning: ")
    assert any(line.startswith("warning: [dead_port] ") for line in warned), err
    assert all(WARNING_LINE.match(line) for line in warned) and ".py:" not in err


@pytest.mark.parametrize("to_stdout", [False, True], ids=["file", "stdout"])
def test_strict_refuses_warnings_with_exit_code_3_and_writes_nothing(
    dead, tmp_path, capsys, to_stdout
):
    cal = tmp_path / "cal.wmcal.json"
    code, _, err = run(capsys, f"calibrate {dead} -o {cal} --quiet")
    warned = lines(err, "warning: ")
    strict = tmp_path / "strict.wmcal.json"
    target = "-" if to_stdout else strict
    code, out, err = run(capsys, f"calibrate {dead} -o {target} --strict --quiet")
    assert code == 3, err
    refused = lines(err, "error: ")
    # --quiet leaves the errors, and nothing else (no progress lines on a slow machine)
    assert err.count("\n") == len(refused) == len(warned), err
    assert all(STRICT_LINE.match(line) for line in refused), err
    assert [line[len("error: ") :].rsplit(" (--strict", 1)[0] for line in refused] == [
        line[len("warning: ") :] for line in warned
    ]
    assert out == "" and not strict.exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["cal.wmcal.json"]


def test_strict_passes_a_clean_sweep(clean, tmp_path, capsys):
    cal = tmp_path / "strict.wmcal.json"
    code, _, err = run(capsys, f"calibrate {clean['sweep']} -o {cal} --strict --quiet")
    assert code == 0 and err == "" and cal.is_file()


# ---------------------------------------------------------------------------- dark readings
@pytest.fixture(scope="module")
def offsets(tmp_path_factory) -> dict:
    """A 3-port sweep and readings with per-port detector offsets added, and the same
    with the offsets taken off, written by numpy (float64 CSV round trip is exact)."""
    folder = tmp_path_factory.mktemp("dark")
    frequency, sweep, _, test = device_data(3, seed=5)
    dark_w = np.array([2e-6, -1e-6, 5e-7])
    rng = np.random.default_rng(55)
    # dark readings about zero on average: many rows sum to <= 0 and must still count
    dark_rows = dark_w - dark_w.mean() + 2 * NOISE_W * rng.standard_normal((200, 3))
    return {
        "dark_w": dark_w,
        "dark_rows": dark_rows,
        "sweep": write_readings(folder / "sweep.csv", sweep + dark_w, frequency),
        "test": write_readings(folder / "test.csv", test + dark_w),
        "dark_file": write_readings(folder / "dark.csv", dark_rows),
        "clean_sweep": write_readings(folder / "clean.csv", sweep + dark_w - dark_w, frequency),
        "clean_test": write_readings(folder / "clean-test.csv", test + dark_w - dark_w),
    }


def measured(capsys, cal: Path, data: Path, out: Path) -> np.ndarray:
    code, _, err = run(capsys, f"measure {cal} {data} -o {out} --quiet")
    assert code == 0, err
    header, values = read_csv(out)
    return values[:, header.index("frequency_hz")]


def test_dark_w_is_subtracted_in_fit_and_predict(offsets, tmp_path, capsys):
    dark = ",".join(f"{value:.17g}" for value in offsets["dark_w"])
    cal, reference = tmp_path / "dark.wmcal.json", tmp_path / "ref.wmcal.json"
    code, _, err = run(capsys, f"calibrate {offsets['sweep']} -o {cal} --dark-w {dark} --quiet")
    assert code == 0, err
    assert run(capsys, f"calibrate {offsets['clean_sweep']} -o {reference} --quiet")[0] == 0
    loaded = wm.load_calibration(cal)
    np.testing.assert_array_equal(loaded.dark_w_, offsets["dark_w"])
    with_dark = measured(capsys, cal, offsets["test"], tmp_path / "a.csv")
    without = measured(capsys, reference, offsets["clean_test"], tmp_path / "b.csv")
    np.testing.assert_array_equal(with_dark, without)
    # and it changes the result: the offsets are not what the readings carry
    plain = tmp_path / "plain.wmcal.json"
    assert run(capsys, f"calibrate {offsets['sweep']} -o {plain} --quiet")[0] == 0
    assert wm.load_calibration(plain).dark_w_ is None
    assert not np.array_equal(measured(capsys, plain, offsets["test"], tmp_path / "c.csv"), without)


def test_dark_w_takes_units(offsets, tmp_path, capsys):
    cal = tmp_path / "dark.wmcal.json"
    code, _, err = run(capsys, f"calibrate {offsets['sweep']} -o {cal} --dark-w 2uW,-1uW,500nW")
    assert code == 0, err
    np.testing.assert_allclose(wm.load_calibration(cal).dark_w_, offsets["dark_w"], rtol=1e-15)


def test_dark_file_is_averaged_per_port_rows_without_light_included(offsets, tmp_path, capsys):
    assert np.mean(offsets["dark_rows"].sum(axis=1) <= 0) > 0.2  # the case this is about
    cal = tmp_path / "dark.wmcal.json"
    command = f"calibrate {offsets['sweep']} -o {cal} --dark {offsets['dark_file']} --quiet"
    code, _, err = run(capsys, command)
    assert code == 0, err
    loaded = wm.load_calibration(cal)
    # the mean of 200 rows, summed in another order: equal to a few ulp of the offsets
    np.testing.assert_allclose(loaded.dark_w_, offsets["dark_rows"].mean(axis=0), atol=1e-20)
    metadata = read_calibration_file(cal).metadata
    assert metadata["dark_file"] == str(offsets["dark_file"])


def test_dark_file_with_a_nan_needs_drop_invalid(offsets, tmp_path, capsys):
    rows = offsets["dark_rows"].copy()
    rows[7, 1] = np.nan
    dark = write_readings(tmp_path / "dark.csv", rows)
    cal = tmp_path / "dark.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {offsets['sweep']} -o {cal} --dark {dark}")[::2])
    assert "1 invalid row(s): line 9 (p2_w is NaN" in err and "--drop-invalid" in err
    assert not cal.exists()
    command = f"calibrate {offsets['sweep']} -o {cal} --dark {dark} --drop-invalid"
    code, _, err = run(capsys, command)
    assert code == 0 and "skipped 1 invalid row(s)" in err, err
    kept = np.delete(rows, 7, axis=0).mean(axis=0)
    np.testing.assert_allclose(wm.load_calibration(cal).dark_w_, kept, atol=1e-20)


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--dark-w 1uW,2uW", "dark_w gives 2 value(s) but"),
        ("--dark-w 1uW,2uW,3uW,4uW", "dark_w gives 4 value(s) but"),
        ("--dark-w -30dBm,0,0", "dBm names only positive powers"),
        ("--dark-w 1uW,,2uW", "is not a number"),
        ("--dark-w 1e-6 --dark {dark_file}", "give a file or values, not both"),
        ("--dark {four_ports}", "has ports p1_w, p2_w, p3_w, p4_w but"),
    ],
)
def test_wrong_dark_readings_are_one_error(offsets, tmp_path, capsys, options, expected):
    four_ports = write_readings(tmp_path / "four.csv", np.full((5, 4), 1e-6))
    options = options.format(dark_file=offsets["dark_file"], four_ports=four_ports)
    cal = tmp_path / "cal.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {offsets['sweep']} -o {cal} {options}")[::2])
    assert expected in err
    if "gives" in expected or "has ports" in expected:
        assert "has 3 ports (p1_w, p2_w, p3_w)" in err  # the ports expected
    assert not cal.exists()


# ---------------------------------------------------------------------------- measure
def test_measure_writes_flags_and_uncertainty_by_default(clean, tmp_path, capsys):
    out = tmp_path / "f.csv"
    code, printed, err = run(capsys, f"measure {clean['cal']} {clean['test']} -o {out}")
    assert code == 0, err
    header, data = read_csv(out)
    assert header == ["frequency_hz", "wavelength_nm", "phase_rad", "frequency_std_hz", "flags"]
    calibration = wm.load_calibration(clean["cal"])
    readings = read_table(clean["test"], ColumnRequest(), need_x=False).powers_w
    np.testing.assert_array_equal(data[:, 3], calibration.frequency_std_hz(readings))
    flags = calibration.flags(readings)
    np.testing.assert_array_equal(data[:, 4], flags)
    flagged = int(np.count_nonzero(flags))
    assert re.search(rf"^flagged {flagged} of {TEST_ROWS} readings", printed, re.M), printed
    # without the standard deviation: the same table less that column
    less = tmp_path / "g.csv"
    code, _, err = run(capsys, f"measure {clean['cal']} {clean['test']} -o {less} --no-uncertainty")
    assert code == 0, err
    header_less, data_less = read_csv(less)
    assert header_less == ["frequency_hz", "wavelength_nm", "phase_rad", "flags"]
    np.testing.assert_array_equal(data_less, np.delete(data, 3, axis=1))


def test_flag_cells_are_integers(clean, tmp_path, capsys):
    out = tmp_path / "f.csv"
    assert run(capsys, f"measure {clean['cal']} {clean['test']} -o {out} --quiet")[0] == 0
    cells = [line.rsplit(",", 1)[1] for line in out.read_text().splitlines()[1:]]
    assert all(re.fullmatch(r"\d+", cell) for cell in cells), cells[:3]


def test_conventional_calibration_writes_flags_without_uncertainty(clean, tmp_path, capsys):
    cal, out = tmp_path / "conv.wmcal.json", tmp_path / "f.csv"
    command = f"calibrate {clean['sweep']} -o {cal} --method conventional --quiet"
    assert run(capsys, command)[0] == 0
    assert run(capsys, f"measure {cal} {clean['test']} -o {out} --quiet")[0] == 0
    assert read_csv(out)[0] == ["frequency_hz", "wavelength_nm", "phase_rad", "flags"]


# ---------------------------------------------------------------------------- info
def test_info_shows_the_diagnostics_and_warning_causes(dead, tmp_path, capsys):
    cal = tmp_path / "cal.wmcal.json"
    assert run(capsys, f"calibrate {dead} -o {cal} --quiet")[0] == 0
    code, printed, err = run(capsys, f"info {cal}")
    assert code == 0, err
    assert re.search(r"^warning +dead_port: port\(s\) p3_w ", printed, re.M), printed
    assert re.search(r"^port p3_w +dead: ", printed, re.M), printed
    assert re.search(r"^noise estimate +\d", printed, re.M), printed


def test_info_shows_the_fit_diagnostics(clean, capsys):
    """The residual statistics of ``diagnostics_["fit"]`` (from the fit report, summary.py):
    per-port residual against noise and autocorrelation, and the map's condition number."""
    code, printed, err = run(capsys, f"info {clean['cal']}")
    assert code == 0, err
    for label in ("autocorrelation", "condition number"):
        assert label in printed.lower(), printed
