"""The thermal calibration on the command line: simulate, calibrate, measure, reanchor, info.

The simulated chip is the ``simulate --seed 1 --platform sin`` device (Table 1, 3 ports,
fringes moving 2.6 GHz/K, delay rate 1.35e-5 /K), swept at 292, 293.5 and 295 K (steps of
1.5 K resolve bias rates up to pi / 1.5 K = 2.1 rad/K, beyond the 1.9 rad/K a chip may
have, so the fit does not warn). Test readings lie inside the calibrated temperatures,
with 1 mK sensor noise on the temperature written (the calibrator's default
``temperature_std_k``), so that ``(estimate - truth) / frequency_std_hz`` has unit standard
deviation; its RMS over M readings has a relative standard error ``1 / sqrt(2 M)`` (2.2 %
for M = 1000), and the bounds below are 7 such errors wide. Fitted rates are checked
against the device's within ``MAX_Z`` of their own standard errors.
"""

from __future__ import annotations

import csv
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import read_calibration_file
from wavemeter.cli import main
from wavemeter.io import write_table

from .helpers import NOISE_W, POWER_W, one_error, run_cli

SEED = 1
SWEEP_TEMPERATURES_K = (292.0, 293.5, 295.0)
SWEEP_SAMPLES = 400
TEST_READINGS = 1000
LINE_READINGS = 50
SENSOR_STD_K = 1e-3
#: |estimate - truth| / standard error beyond which a correct estimator is refuted
MAX_Z = 5.0
#: RMS of (estimate - truth) / frequency_std_hz: 1 within 7 Monte-Carlo standard errors
Z_RMS_BOUNDS = (1 - 7 / np.sqrt(2 * TEST_READINGS), 1 + 7 / np.sqrt(2 * TEST_READINGS))
#: test frequencies stay this fraction of an FSR from the centre: no alias at the edges
HALF_SPAN_FSR = 0.45
BIAS_SHIFT_RAD = 0.3


def ok(capsys, command: str) -> str:
    code, out, err = run_cli(capsys, command)
    assert code == 0, err
    return out


@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    """The device ``simulate --seed 1 --platform sin`` records."""
    return wm.Interferometer.table1(3, seed=SEED).with_thermal("sin")


def sweep_name(temperature_k: float) -> str:
    return f"s{temperature_k:g}.csv"


def strip_temperature(source: Path, target: Path) -> Path:
    """A copy of a simulated file without its temperature column."""
    columns = read_output(source)
    write_table(target, {name: v for name, v in columns.items() if name != "temperature_k"})
    return target


def write_readings(path: Path, device, frequency_hz, temperature_k, seed: int, **extra) -> Path:
    """Readings of ``device`` at ``frequency_hz`` and chip temperatures ``temperature_k``,
    with the temperature written in degrees Celsius as 'Temp (C)' after 1 mK sensor noise."""
    rng = np.random.default_rng(seed)
    powers = device.powers(frequency_hz, POWER_W, NOISE_W, rng, temperature_k=temperature_k)
    sensed_k = temperature_k + SENSOR_STD_K * rng.standard_normal(np.shape(temperature_k))
    columns = {f"p{k + 1}_w": powers[:, k] for k in range(device.ports)}
    write_table(path, {**extra, **columns, "Temp (C)": sensed_k - 273.15}, "csv")
    return path


def random_frequencies(device, samples: int, rng) -> np.ndarray:
    """Test frequencies (Hz) uniform over the central part of the FSR."""
    half = HALF_SPAN_FSR * device.true_fsr_hz
    return device.center_hz + rng.uniform(-half, half, samples)


@pytest.fixture(scope="module")
def files(tmp_path_factory, device) -> dict[str, Path]:
    """Three simulated sweeps (with and without temperature columns), their thermal
    calibration, and test readings inside the calibrated temperatures."""
    folder = tmp_path_factory.mktemp("thermal")
    sweeps = []
    for temperature in SWEEP_TEMPERATURES_K:
        path = folder / sweep_name(temperature)
        command = (
            f"simulate -o {path} --seed {SEED} --samples {SWEEP_SAMPLES} --platform sin "
            f"--temperature-k {temperature:g} --quiet"
        )
        assert main(shlex.split(command)) == 0
        sweeps.append(path)
    bare = [strip_temperature(path, path.with_name(f"bare-{path.name}")) for path in sweeps]
    cal = folder / "thermal.wmcal.json"
    command = f"calibrate --method thermal {' '.join(map(str, sweeps))} -o {cal} --quiet"
    assert main(shlex.split(command)) == 0
    rng = np.random.default_rng(7)
    truth = random_frequencies(device, TEST_READINGS, rng)
    low, high = SWEEP_TEMPERATURES_K[0], SWEEP_TEMPERATURES_K[-1]
    temperature = rng.uniform(low, high, TEST_READINGS)
    test = write_readings(
        folder / "test.csv", device, truth, temperature, 8, true_frequency_hz=truth
    )
    return {"sweeps": sweeps, "bare": bare, "cal": cal, "test": test, "folder": folder}


def read_output(path: Path) -> dict[str, np.ndarray]:
    """The columns of a CSV file by their names as written."""
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    values = np.array(rows[1:], dtype=float)
    return {name: values[:, k] for k, name in enumerate(rows[0])}


# ---------------------------------------------------------------------------- calibrate, info
@pytest.mark.slow
def test_simulated_sweeps_carry_their_temperature(files):
    for path, temperature in zip(files["sweeps"], SWEEP_TEMPERATURES_K, strict=True):
        columns = read_output(path)
        assert np.all(columns["temperature_k"] == temperature)
        assert columns["frequency_hz"].size == SWEEP_SAMPLES


def test_info_shows_the_rates_the_device_has(files, device, capsys):
    out = ok(capsys, f"info {files['cal']}")
    rate, rate_std = map(float, re.search(r"bias phase rate\s+(\S+) \+- (\S+) rad/K", out).groups())
    delay_rate, delay_rate_std = map(
        float, re.search(r"delay rate\s+(\S+) \+- (\S+) 1/K", out).groups()
    )
    assert abs(rate - device.thermal_phase_rad_per_k) < MAX_Z * rate_std
    assert abs(delay_rate - device.thermal_delay_per_k) < MAX_Z * delay_rate_std
    reference = float(re.search(r"reference temperature\s+(\S+) K", out).group(1))
    assert reference == pytest.approx(np.mean(SWEEP_TEMPERATURES_K))
    assert "calibrated temperatures 292 to 295 K" in out
    assert re.search(r"bias rate unambiguous within \+-2\.09 rad/K", out)  # pi / 1.5 K
    assert "(column temperature_k)" in out
    assert f"{3 * SWEEP_SAMPLES} = 400 + 400 + 400 rows" in out
    calibration = read_calibration_file(files["cal"]).calibrator
    fsr = calibration.summary()["fsr_hz"]
    assert abs(fsr.value - device.true_fsr_hz_at(reference)) < MAX_Z * fsr.stderr


def test_temperature_given_per_file_is_the_same_calibration(files, tmp_path, capsys):
    """--temperature-k once per file (K or C) gives the fit of the temperature columns."""
    cal = tmp_path / "given.wmcal.json"
    values = "--temperature-k 292 --temperature-k 20.35C --temperature-k 295K"
    out = ok(
        capsys, f"calibrate --method thermal {' '.join(map(str, files['bare']))} -o {cal} {values}"
    )
    assert "temperature 292 to 295 K (--temperature-k)" in out
    given = read_calibration_file(cal).calibrator
    columns = read_calibration_file(files["cal"]).calibrator
    std = columns.summary()["thermal_phase_rad_per_k"].stderr
    assert abs(given.thermal_phase_rad_per_k_ - columns.thermal_phase_rad_per_k_) < 1e-6 * std
    assert "given per file: 292, 293.5, 295 K" in ok(capsys, f"info {cal}")


# ---------------------------------------------------------------------------- measure
def test_measure_uses_the_temperature_column_and_reaches_the_noise_limit(files, tmp_path, capsys):
    out_path = tmp_path / "f.csv"
    ok(capsys, f"measure {files['cal']} {files['test']} -o {out_path} --keep true_frequency_hz")
    out = read_output(out_path)
    test = read_output(files["test"])
    assert np.array_equal(out["temperature_k"], test["Temp (C)"] + 273.15)
    z = (out["frequency_hz"] - out["true_frequency_hz"]) / out["frequency_std_hz"]
    assert Z_RMS_BOUNDS[0] < np.sqrt(np.mean(z**2)) < Z_RMS_BOUNDS[1]
    assert not np.any(out["flags"].astype(int) & wm.ReadingFlag.TEMPERATURE_RANGE)


def test_readings_far_outside_the_calibrated_temperatures_are_flagged(
    files, device, tmp_path, capsys
):
    rng = np.random.default_rng(11)
    truth = random_frequencies(device, 20, rng)
    temperature = np.r_[np.full(10, 299.0), np.full(10, 293.0)]
    readings = write_readings(tmp_path / "r.csv", device, truth, temperature, 12)
    out_path = tmp_path / "f.csv"
    printed = ok(capsys, f"measure {files['cal']} {readings} -o {out_path}")
    flagged = (read_output(out_path)["flags"].astype(int) & 16) != 0
    assert flagged.tolist() == [True] * 10 + [False] * 10
    assert "TEMPERATURE_RANGE 10" in printed


def test_one_temperature_for_the_whole_file(files, device, tmp_path, capsys):
    rng = np.random.default_rng(13)
    truth = random_frequencies(device, TEST_READINGS, rng)
    powers = device.powers(truth, POWER_W, NOISE_W, rng, temperature_k=294.0)
    readings = tmp_path / "r.csv"
    write_table(readings, {f"p{k + 1}_w": powers[:, k] for k in range(3)})
    out_path = tmp_path / "f.csv"
    ok(capsys, f"measure {files['cal']} {readings} -o {out_path} --temperature-k 20.85C")
    out = read_output(out_path)
    assert np.allclose(out["temperature_k"], 294.0, rtol=0, atol=1e-9)
    # the sensor noise in frequency_std_hz (1 mK x 2.6 GHz/K) is absent from these readings
    z = (out["frequency_hz"] - truth) / out["frequency_std_hz"]
    assert np.sqrt(np.mean(z**2)) < Z_RMS_BOUNDS[1]


def test_measure_without_a_temperature_says_how_to_give_it(files, tmp_path, capsys):
    out_path = tmp_path / "f.csv"
    err = one_error(
        *run_cli(capsys, f"measure {files['cal']} {files['bare'][0]} -o {out_path}")[::2]
    )
    assert "is a thermal calibration" in err
    assert "--temperature COL" in err and "--temperature-k T" in err
    assert not out_path.exists()


def test_a_plain_calibration_refuses_a_temperature(files, tmp_path, capsys):
    plain = tmp_path / "plain.wmcal.json"
    ok(capsys, f"calibrate {files['sweeps'][1]} -o {plain} --quiet")
    out_path = tmp_path / "f.csv"
    for option in ("--temperature-k 294", "--temperature 'Temp (C)'"):
        command = f"measure {plain} {files['test']} -o {out_path} {option}"
        err = one_error(*run_cli(capsys, command)[::2])
        assert "learned calibration, which does not use it" in err
        assert not out_path.exists()


# ---------------------------------------------------------------------------- reanchor
def test_reanchor_on_one_line_brings_a_shifted_chip_back(files, device, tmp_path, capsys):
    """The chip's bias moves by 0.3 rad (2.4 GHz); 50 readings of one line at 294 K move
    the calibration back: the test error is again at its stated uncertainty."""
    import dataclasses

    shifted = dataclasses.replace(device, bias_phase_rad=device.bias_phase_rad + BIAS_SHIFT_RAD)
    line_hz = device.center_hz + 0.1 * device.true_fsr_hz
    lines = write_readings(
        tmp_path / "line.csv",
        shifted,
        np.full(LINE_READINGS, line_hz),
        np.full(LINE_READINGS, 294.0),
        21,
    )
    new = tmp_path / "new.wmcal.json"
    printed = ok(capsys, f"reanchor {files['cal']} {lines} --frequency {line_hz}Hz -o {new}")
    shift, shift_std = map(
        float, re.search(r"phase shift ([-+]\S+) rad \(std (\S+) rad\)", printed).groups()
    )
    assert abs(abs(shift) - BIAS_SHIFT_RAD) < MAX_Z * shift_std
    rng = np.random.default_rng(22)
    truth = random_frequencies(device, TEST_READINGS, rng)
    temperature = rng.uniform(SWEEP_TEMPERATURES_K[0], SWEEP_TEMPERATURES_K[-1], TEST_READINGS)
    readings = write_readings(tmp_path / "r.csv", shifted, truth, temperature, 23)
    for cal, anchored in ((files["cal"], False), (new, True)):
        out_path = tmp_path / f"f-{anchored}.csv"
        ok(capsys, f"measure {cal} {readings} -o {out_path}")
        out = read_output(out_path)
        z_rms = np.sqrt(np.mean(((out["frequency_hz"] - truth) / out["frequency_std_hz"]) ** 2))
        if anchored:
            assert Z_RMS_BOUNDS[0] < z_rms < Z_RMS_BOUNDS[1]
        else:  # off by 0.3 rad: about 2.4 GHz against a 10 MHz uncertainty
            assert z_rms > 100


def test_reanchor_of_a_thermal_calibration_needs_the_temperature(files, device, tmp_path, capsys):
    new = tmp_path / "new.wmcal.json"
    command = f"reanchor {files['cal']} {files['bare'][1]} --frequency 193.4THz -o {new}"
    err = one_error(*run_cli(capsys, command)[::2])
    assert "is a thermal calibration" in err and "--temperature-k T" in err
    assert not new.exists()


def test_evaluate_reads_the_temperature_column_and_compares_with_the_bound(files, capsys):
    code, out, err = run_cli(capsys, f"evaluate {files['cal']} {files['test']} --json")
    assert code == 0, err
    report = json.loads(out)
    thermal = report["methods"]["thermal"]
    # the bound is the Cramer-Rao one of the readings, without the sensor's share; the
    # 1 mK sensor adds 2.6 MHz in quadrature to ~10 MHz: at most 4 %, and the RMS of
    # TEST_READINGS errors is known to 4 / sqrt(2 M)
    tolerance = 4 / np.sqrt(2 * TEST_READINGS)
    assert 1 - tolerance <= thermal["rms_mod_fsr_over_crlb"] <= 1.04 * (1 + tolerance) + 0.05


def test_evaluate_without_a_temperature_column_is_one_error(files, tmp_path, capsys):
    columns = read_output(files["test"])
    bare_test = tmp_path / "bare-test.csv"
    write_table(bare_test, {name: v for name, v in columns.items() if name != "Temp (C)"})
    err = one_error(*run_cli(capsys, f"evaluate {files['cal']} {bare_test}")[::2])
    assert "the thermal calibration needs the chip temperature of each reading" in err
    assert "--temperature COL" in err


# ---------------------------------------------------------------------------- report
@pytest.mark.slow
def test_the_report_shows_the_rates_and_the_error_against_temperature(files, tmp_path, capsys):
    """On the three sweeps in one file: the plain learned comparison, blind to the
    temperature, drifts in phase; the page says so and the command prints no warning."""
    texts = [path.read_text().splitlines() for path in files["sweeps"]]
    sweep = tmp_path / "all.csv"
    sweep.write_text("\n".join(texts[0] + texts[1][1:] + texts[2][1:]) + "\n")
    page = tmp_path / "report.html"
    command = f"report {files['cal']} {sweep} {files['test']} -o {page} --quiet"
    code, _, err = run_cli(capsys, command)
    assert code == 0 and err == ""
    assert (tmp_path / "report-temperature.png").stat().st_size > 0
    text = page.read_text()
    assert "<td>bias phase rate</td>" in text
    assert "calibrated temperatures 292 to 295 K (clusters at 292, 293.5, 295 K;" in text
    assert "[phase_drift]" in text


@pytest.mark.slow
def test_the_report_shows_a_thermal_calibration_alone_when_plain_cannot_fit(tmp_path, capsys):
    """Sweeps 10 K apart move the fringes by 26 GHz: the plain learned comparison finds no
    delay and is refused; the report shows the thermal calibration and says why."""
    paths = []
    for temperature in (290, 295, 300):
        path = tmp_path / f"w{temperature}.csv"
        command = (
            f"simulate -o {path} --seed {SEED} --samples {SWEEP_SAMPLES} --platform sin "
            f"--temperature-k {temperature} --quiet"
        )
        assert main(shlex.split(command)) == 0
        paths.append(path)
    cal = tmp_path / "wide.wmcal.json"
    joined = " ".join(map(str, paths))
    assert main(shlex.split(f"calibrate --method thermal {joined} -o {cal} --quiet")) == 0
    texts = [path.read_text().splitlines() for path in paths]
    sweep = tmp_path / "all.csv"
    sweep.write_text("\n".join(texts[0] + texts[1][1:] + texts[2][1:]) + "\n")
    page = tmp_path / "report.html"
    code, _, err = run_cli(capsys, f"report {cal} {sweep} -o {page} --quiet")
    assert code == 0, err
    text = page.read_text()
    assert "could not be fitted on the same sweep" in text and "side minimum" in text


# ---------------------------------------------------------------------------- bad input
def rewrite_temperature(source: Path, target: Path, header: str, values) -> Path:
    """A copy of a simulated sweep with its temperature column renamed and rewritten."""
    lines = source.read_text().splitlines()
    cells = [line.rsplit(",", 1)[0] for line in lines]
    body = [f"{cell},{value}" for cell, value in zip(cells[1:], values, strict=True)]
    target.write_text("\n".join([f"{cells[0]},{header}", *body]) + "\n")
    return target


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("no column", "has no temperature column"),
        ("all equal", "spread the calibration temperatures"),
        ("not a number", "'warm' is not a number"),
        ("unknown unit", "unknown temperature unit 'F'"),
        ("count mismatch", "temperature_k is given 2 time(s) for 3 sweep file(s)"),
        ("bad value", "'--temperature-k': 20F: unknown temperature unit 'F'"),
        ("learned with several", "method 'learned' takes one sweep file, got 3"),
        ("other ports", "the sweeps of one calibration need the same ports"),
        ("per fsr", "method 'thermal' also needs temperature_k"),
    ],
)
def test_bad_temperatures_are_one_error_and_no_file(files, tmp_path, capsys, case, expected):
    sweeps = list(map(str, files["sweeps"]))
    bare = list(map(str, files["bare"]))
    first = files["sweeps"][0]
    options = "--method thermal"
    if case == "no column":
        sweeps = bare
    elif case == "all equal":
        sweeps = [str(files["sweeps"][1]), str(files["sweeps"][1])]
    elif case == "not a number":
        values = ["20"] * (SWEEP_SAMPLES - 1) + ["warm"]
        sweeps[0] = str(rewrite_temperature(first, tmp_path / "t.csv", "Temp (C)", values))
    elif case == "unknown unit":
        values = ["68"] * SWEEP_SAMPLES
        sweeps[0] = str(rewrite_temperature(first, tmp_path / "t.csv", "Temp (F)", values))
    elif case == "count mismatch":
        sweeps, options = bare, "--method thermal --temperature-k 292 --temperature-k 293"
    elif case == "bad value":
        sweeps, options = bare[:1], "--method thermal --temperature-k 20F"
    elif case == "learned with several":
        options = "--method learned"
    elif case == "other ports":
        text = files["sweeps"][2].read_text().replace("p3_w", "p4_w", 1)
        (tmp_path / "p4.csv").write_text(text)
        sweeps[2] = str(tmp_path / "p4.csv")
    elif case == "per fsr":
        options = "--method thermal --per-fsr"
    out = tmp_path / "c.wmcal.json"
    command = f"calibrate {' '.join(sweeps)} -o {out} {options}"
    err = one_error(*run_cli(capsys, command)[::2])
    assert expected in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--temperature-k 290", "--temperature-k needs a thermal device"),
        ("--platform sin --temperature-k 290 --ramp-k 290:291", "give one of them"),
        ("--platform sin --ramp-k 290", "is not a ramp"),
    ],
)
def test_simulate_refuses_temperatures_it_cannot_honour(tmp_path, capsys, options, expected):
    out = tmp_path / "s.csv"
    err = one_error(*run_cli(capsys, f"simulate -o {out} --samples 10 {options}")[::2])
    assert expected in err
    assert not out.exists()


def test_a_ramp_during_repeated_sweeps_is_one_thermal_calibration(device, tmp_path, capsys):
    """Five one-FSR sweeps while the chip warms by 4 K: temperature and frequency do not
    change together, and the fit finds the device's bias rate without cluster aliasing."""
    sweep, cal = tmp_path / "ramp.csv", tmp_path / "ramp.wmcal.json"
    ok(
        capsys,
        f"simulate -o {sweep} --platform sin --ramp-k 292:296 --repeat 5 --samples 200 --quiet",
    )
    columns = read_output(sweep)
    assert columns["temperature_k"][0] == 292.0 and columns["temperature_k"][-1] == 296.0
    assert columns["frequency_hz"].size == 1000
    out = ok(capsys, f"calibrate --method thermal {sweep} -o {cal}")
    assert "continuous temperatures: no alias" in out
    summary = read_calibration_file(cal).calibrator.summary()
    rate = summary["thermal_phase_rad_per_k"]
    assert abs(rate.value - device.thermal_phase_rad_per_k) < MAX_Z * rate.stderr
