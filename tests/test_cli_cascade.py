"""The cascade on the command line: simulate, calibrate, measure, info, report, evaluate.

The device is the issue's C-band cascade as ``simulate --cascade`` draws it by default
(Table 1 stages of 5 THz / 500 GHz / 50 GHz design FSR, 3 ports each, seed 1, silicon-nitride
spectral slopes) swept over the C band (191-195.4 THz) with ``SWEEP_READINGS`` readings, and
calibrated with ``calibrate --method cascade`` and its defaults. Frequencies read back are
judged by the calibration's own ``frequency_std_hz``: ``(estimate - truth) / std`` has unit
standard deviation, and the RMS of ``M`` such values a relative standard error
``1 / sqrt(2 M)``; the bounds below are ``MAX_Z`` such errors wide.
"""

from __future__ import annotations

import csv
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm
from wavemeter.calibration.files.document import read_calibration_file
from wavemeter.cli import main
from wavemeter.io import write_table
from wavemeter.report.html import report_paths

from .helpers import NOISE_W, POWER_W, one_error, run_cli

FSRS_HZ = (5e12, 500e9, 50e9)
BAND_HZ = (191.0e12, 195.4e12)
SEED = 1
PORTS = 3
SWEEP_READINGS = 2000
TEST_READINGS = 2000
#: the port columns simulate writes: stage, then port
COLUMNS = [f"p{stage}{port}_w" for stage in (1, 2, 3) for port in (1, 2, 3)]
#: standard errors an estimate may stray from what it estimates but for a refutation
MAX_Z = 5.0
#: detector noise of the noisy readings, in units of the calibration sweep's
NOISY_FACTOR = 4.0
#: detector noise of a sweep too noisy for the 5 THz -> 500 GHz hand-over (20x Table 1:
#: a margin of about 3.5 standard deviations where a rate of 1e-6 needs 4.9), and of one it
#: allows (10x: about 7)
REFUSED_NOISE_W = 20 * NOISE_W
ACCEPTED_NOISE_W = 10 * NOISE_W


def ok(capsys, command: str) -> tuple[str, str]:
    code, out, err = run_cli(capsys, command)
    assert code == 0, err
    return out, err


def read_columns(path: Path) -> dict[str, np.ndarray]:
    """The columns of a CSV file by their names as written."""
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    values = np.array(rows[1:], dtype=float)
    return {name: values[:, k] for k, name in enumerate(rows[0])}


def powers_of(columns: dict[str, np.ndarray], names=COLUMNS) -> np.ndarray:
    return np.column_stack([columns[name] for name in names])


def rms_bounds(count: int, extra_relative_std: float = 0.0) -> tuple[float, float]:
    """Where the RMS of ``count`` unit-variance Gaussian values lies but for a refutation,
    when their scale is itself known to ``extra_relative_std``."""
    spread = MAX_Z * np.hypot(1.0 / np.sqrt(2 * count), extra_relative_std)
    return 1.0 - spread, 1.0 + spread


def noise_scale_relative_std(readings: int, free: int) -> float:
    """Relative standard error of a noise scale ``sqrt(median(d) / m)`` estimated from
    ``readings`` cone distances ``d ~ chi2(free)`` (the median's large-sample error
    ``1 / (2 f(m) sqrt(N))``, halved by the square root)."""
    median = stats.chi2.median(free)
    density = stats.chi2.pdf(median, free)
    return 0.5 / (2.0 * density * np.sqrt(readings) * median)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict:
    """The default cascade's sweep with test readings, and its calibration by defaults."""
    folder = tmp_path_factory.mktemp("cascade")
    sweep, cal = folder / "cband.csv", folder / "cband.wmcal.json"
    simulate = (
        f"simulate -o {sweep} --cascade 5THz,500GHz,50GHz --spectral sin --seed {SEED} "
        f"--samples {SWEEP_READINGS} --test {TEST_READINGS} --quiet"
    )
    assert main(shlex.split(simulate)) == 0
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --method cascade --quiet")) == 0
    return {
        "folder": folder,
        "sweep": sweep,
        "test": folder / "cband-test.csv",
        "cal": cal,
        "calibration": read_calibration_file(cal).calibrator,
    }


# ---------------------------------------------------------------------------- simulate
@pytest.mark.slow
def test_simulate_writes_the_cascade_the_python_api_draws(files):
    """The files hold the readings of CascadeInterferometer.table1 with the seed, centred in
    the band: the sweep evenly over the band, ends included, then the test readings at
    frequencies uniform over it, the noise from the seed's generator in that order."""
    device = wm.CascadeInterferometer.table1(
        FSRS_HZ, ports=PORTS, seed=SEED, center_hz=sum(BAND_HZ) / 2, spectral="sin"
    )
    rng = np.random.default_rng(SEED)
    truth = rng.uniform(*BAND_HZ, TEST_READINGS)
    sweep_hz = np.linspace(*BAND_HZ, SWEEP_READINGS)
    sweep = read_columns(files["sweep"])
    test = read_columns(files["test"])
    assert list(sweep) == ["frequency_hz", *COLUMNS]
    assert list(test) == ["true_frequency_hz", *COLUMNS]
    np.testing.assert_array_equal(sweep["frequency_hz"], sweep_hz)
    np.testing.assert_array_equal(test["true_frequency_hz"], truth)
    expected = device.powers(sweep_hz, POWER_W, NOISE_W, rng=rng)
    np.testing.assert_array_equal(powers_of(sweep), expected)
    np.testing.assert_array_equal(powers_of(test), device.powers(truth, POWER_W, NOISE_W, rng=rng))


def test_simulate_says_which_columns_are_which_stage(tmp_path, capsys):
    out, _ = ok(
        capsys,
        f"simulate -o {tmp_path / 's.csv'} --cascade 1.5THz,150GHz,15GHz --band "
        "192.9THz:193.9THz --ports 4 --samples 20",
    )
    assert "columns p11-p14, p21-p24, p31-p34" in out
    device = wm.CascadeInterferometer.table1(
        (1.5e12, 150e9, 15e9), ports=4, seed=SEED, center_hz=193.4e12, spectral=None
    )
    assert (
        "true FSRs "
        + ", ".join(
            f"{value / 1e12:.6g} THz" if value >= 1e12 else f"{value / 1e9:.6g} GHz"
            for value in device.true_fsrs_hz
        )
        in out
    )


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ("--cascade 5THz,500GHz,50GHz --span-fsr 3", ["--span-fsr", "--band"]),
        ("--cascade 5THz,500GHz,50GHz --fsr 50GHz", ["--fsr", "--cascade"]),
        ("--cascade 5THz,500GHz,50GHz --platform sin", ["--platform"]),
        ("--band 191THz:195.4THz", ["--band", "--cascade", "--span-fsr"]),
        ("--cascade 50GHz,500GHz,5THz", ["decreasing FSR", "coarsest first"]),
        ("--cascade 5THz", ["two or more stages"]),
        ("--cascade 1THz,100GHz,10GHz", ["does not exceed the band", "--band"]),
        ("--cascade 5THz,500GHz,50GHz --band 191THz", ["LOW:HIGH"]),
    ],
)
def test_simulate_refuses_what_a_cascade_is_not(tmp_path, capsys, options, named):
    out = tmp_path / "s.csv"
    code, _, err = run_cli(capsys, f"simulate -o {out} --samples 20 {options}")
    line = one_error(code, err)
    assert all(part in line for part in named), line
    assert not out.exists()


# ---------------------------------------------------------------------------- calibrate
@pytest.mark.slow
def test_calibrate_defaults_to_the_issue_cascade_and_prints_stages_and_margins(
    files, tmp_path, capsys
):
    calibration = files["calibration"]
    assert calibration.method == "cascade"
    assert tuple(calibration.get_params()["fsr_hz"]) == FSRS_HZ
    assert calibration.stage_ports_ == ((0, 1, 2), (3, 4, 5), (6, 7, 8))
    assert calibration.port_names_ == COLUMNS
    cal = tmp_path / "again.wmcal.json"
    out, _ = ok(capsys, f"calibrate {files['sweep']} -o {cal} --method cascade")
    stages, handovers = calibration.summary().tables
    for line in stages.text_lines() + handovers.text_lines():
        assert line in out.splitlines()
    records = calibration.diagnostics_["cascade"]["stages"]
    assert [row[1] for row in stages.rows] == [", ".join(r["ports"]) for r in records]
    for row, record in zip(handovers.rows, calibration.handovers_, strict=True):
        wanted = [record[key] for key in ("ratio", "largest_usable_ratio", "margin_std")]
        assert list(row[1:4]) == wanted


@pytest.mark.slow
def test_stage_ports_give_each_stage_its_columns_by_position(files, tmp_path, capsys):
    """Read with the stages' columns in reverse order and --stage-ports pointing at them,
    every stage is fitted on the same data as by default: the same calibration."""
    ports = ",".join(COLUMNS[6:] + COLUMNS[3:6] + COLUMNS[:3])
    cal = tmp_path / "reordered.wmcal.json"
    ok(
        capsys,
        f"calibrate {files['sweep']} -o {cal} --method cascade --ports {ports} "
        "--stage-ports 7-9/4-6/1,2,3 --quiet",
    )
    reordered = read_calibration_file(cal).calibrator
    assert reordered.stage_ports_ == ((6, 7, 8), (3, 4, 5), (0, 1, 2))
    default = files["calibration"]
    np.testing.assert_array_equal(reordered.stage_fsrs_hz_, default.stage_fsrs_hz_)
    test = read_columns(files["test"])
    order = [COLUMNS.index(name) for name in ports.split(",")]
    np.testing.assert_allclose(
        reordered.predict(powers_of(test)[:, order]),
        default.predict(powers_of(test)),
        rtol=1e-12,
    )


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ("--method cascade --fsr 50GHz", ["two or more", "coarsest first"]),
        ("--method cascade --fsr 50GHz,500GHz,5THz", ["must decrease", "coarsest first"]),
        ("--method cascade --fsr 5THz,500GHz,50", ["50 is a bare number", "50GHz"]),
        ("--fsr 5THz,500GHz,50GHz", ["method 'learned'", "got 3", "(cascade)", "--fsr"]),
        ("--method wideband --fsr 500GHz,50GHz", ["method 'wideband'", "(cascade)", "--fsr"]),
        ("--method cascade --stage-ports 1-3/3-5/6-9", ["column(s) 3", "more than one stage"]),
        (
            "--method cascade --fsr 5THz,500GHz --stage-ports 1-3/4-6",
            ["column(s) 7, 8, 9", "p31_w, p32_w, p33_w", "--ports"],
        ),
        ("--method cascade --stage-ports 1-3/4-6/7-10", ["column(s) 10", "9 port columns"]),
        ("--method cascade --stage-ports 1-4/5-9", ["2 stage(s)", "has by default 3 FSRs"]),
        ("--method cascade --stage-ports 1-2/3-6/7-9", ["stage(s) 1 fewer than 3"]),
        ("--method cascade --stage-ports 0-2/3-5/6-8", ["position from 1"]),
        ("--stage-ports 1-3/4-6/7-9", ["--stage-ports", "'learned' has no", "of cascade"]),
        ("--method wideband --max-order-error 1e-3", ["--max-order-error", "of cascade"]),
        ("--method cascade --per-fsr", ["--per-fsr", "method 'cascade'"]),
        ("--method cascade --phase-order 2", ["--phase-order", "'cascade' has no"]),
    ],
)
def test_bad_cascade_options_are_refused_with_one_line(files, tmp_path, capsys, options, named):
    out = tmp_path / "cal.wmcal.json"
    code, _, err = run_cli(capsys, f"calibrate {files['sweep']} -o {out} {options}")
    line = one_error(code, err)
    assert all(part in line for part in named), line
    assert not out.exists()


@pytest.mark.slow
def test_a_hand_over_the_noise_does_not_allow_is_refused_at_fit_time(tmp_path, capsys):
    """At 20x the Table-1 noise the 5 THz stage's spread is a third of the 500 GHz stage's
    half FSR: refused, naming both stages and the largest usable ratio. Where detector noise
    dominates the stages' uncertainties, that ratio goes as 1/noise: half the one the sweep
    at 10x (accepted) gives, each from its sweep's noise estimate (to 1/sqrt(2 N (n - 2))
    relative), MAX_Z of their combined error apart."""

    def sweep_at(noise_w: float) -> Path:
        path = tmp_path / f"noise{noise_w:g}.csv"
        simulate = (
            f"simulate -o {path} --cascade 5THz,500GHz,50GHz --spectral sin --seed {SEED} "
            f"--samples {SWEEP_READINGS} --noise {noise_w} --quiet"
        )
        assert main(shlex.split(simulate)) == 0
        return path

    accepted = tmp_path / "accepted.wmcal.json"
    calibrate = "calibrate {} -o {} --method cascade --quiet"
    ok(capsys, calibrate.format(sweep_at(ACCEPTED_NOISE_W), accepted))
    reference = read_calibration_file(accepted).calibrator.handovers_[0]
    out = tmp_path / "refused.wmcal.json"
    code, _, err = run_cli(capsys, calibrate.format(sweep_at(REFUSED_NOISE_W), out))
    line = one_error(code, err)
    assert "stage 1 (5 THz) cannot pick the fringe order of stage 2 (500 GHz)" in line
    found = re.search(r"largest usable FSR ratio is (\S+) and these stages have (\S+):", line)
    usable, ratio = float(found[1]), float(found[2])
    assert usable < ratio
    expected = reference["largest_usable_ratio"] * ACCEPTED_NOISE_W / REFUSED_NOISE_W
    tolerance = MAX_Z * np.sqrt(2.0 / (2 * SWEEP_READINGS * (PORTS - 2)))
    assert abs(usable / expected - 1.0) < tolerance
    assert "(use --fsr, max_order_error: --max-order-error)" in line
    assert not out.exists()


# ---------------------------------------------------------------------------- measure
def test_measure_writes_what_the_python_api_reads(files, tmp_path, capsys):
    out_path = tmp_path / "f.csv"
    printed, _ = ok(capsys, f"measure {files['cal']} {files['test']} -o {out_path}")
    out = read_columns(out_path)
    assert list(out) == [
        "frequency_hz",
        "wavelength_nm",
        "phase_rad",
        "frequency_std_hz",
        "order_error_probability",
        "flags",
    ]
    test = read_columns(files["test"])
    calibration = wm.load_calibration(files["cal"])
    found = calibration.read(powers_of(test))
    np.testing.assert_allclose(out["frequency_hz"], found.frequency_hz[-1], rtol=1e-9)
    np.testing.assert_allclose(out["frequency_std_hz"], found.std_hz[-1], rtol=1e-9)
    np.testing.assert_array_equal(
        out["order_error_probability"], calibration.order_error_probability(powers_of(test))
    )
    np.testing.assert_array_equal(out["flags"].astype(int), found.flags)
    # absolute, no coarse input: every reading at its stated uncertainty, none a whole
    # FSR off, none flagged
    z = (out["frequency_hz"] - test["true_frequency_hz"]) / out["frequency_std_hz"]
    low, high = rms_bounds(TEST_READINGS)
    assert low < np.sqrt(np.mean(z**2)) < high
    assert np.max(np.abs(z)) < 6.0
    assert not np.any(out["flags"])
    assert f"flagged 0 of {TEST_READINGS} readings" in printed


def test_measure_warns_when_the_readings_are_noisier_and_follows_their_noise(
    files, tmp_path, capsys
):
    """Readings at 4x the sweep's noise: one warning line names each stage's factor, 4
    within the error of the median-based estimate (3 ports: one free cone distance per
    reading), and the uncertainties written are those of the readings' noise."""
    device = wm.CascadeInterferometer.table1(
        FSRS_HZ, ports=PORTS, seed=SEED, center_hz=sum(BAND_HZ) / 2, spectral="sin"
    )
    truth = np.random.default_rng(7).uniform(*BAND_HZ, TEST_READINGS)
    powers = device.powers(truth, POWER_W, NOISY_FACTOR * NOISE_W, rng=8)
    readings = tmp_path / "noisy.csv"
    write_table(
        readings, {"true_hz": truth, **{name: powers[:, k] for k, name in enumerate(COLUMNS)}}
    )
    out_path = tmp_path / "f.csv"
    _, err = ok(capsys, f"measure {files['cal']} {readings} -o {out_path} --keep true_hz")
    lines = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(lines) == 1 and lines[0].startswith("warning: [reading_noise] "), err
    factors = re.findall(r"(\S+)x in stage (\d) \(", lines[0])
    assert [int(stage) for _, stage in factors] == [1, 2, 3]
    scale_error = np.hypot(
        noise_scale_relative_std(TEST_READINGS, PORTS - 2),
        1.0 / np.sqrt(2 * SWEEP_READINGS * (PORTS - 2)),  # the calibrated noise's own
    )
    for factor, _ in factors:
        assert abs(float(factor) / NOISY_FACTOR - 1.0) < MAX_Z * scale_error
    assert "frequency_std_hz and order_error_probability follow the readings' noise" in lines[0]
    out = read_columns(out_path)
    z = (out["frequency_hz"] - out["true_hz"]) / out["frequency_std_hz"]
    low, high = rms_bounds(TEST_READINGS, scale_error)
    assert low < np.sqrt(np.mean(z**2)) < high


@pytest.mark.parametrize("option", ["--coarse-frequency 193THz", "--coarse true_frequency_hz"])
def test_measure_refuses_a_coarse_input_a_cascade_has_no_use_for(files, tmp_path, capsys, option):
    out_path = tmp_path / "f.csv"
    code, _, err = run_cli(capsys, f"measure {files['cal']} {files['test']} -o {out_path} {option}")
    line = one_error(code, err)
    assert "cascade calibration" in line and "no use for a coarse frequency" in line
    assert option.split()[0] in line
    assert not out_path.exists()


# ---------------------------------------------------------------------------- info
def test_info_shows_stages_hand_overs_and_the_edge_margin(files, capsys):
    calibration = files["calibration"]
    printed, _ = ok(capsys, f"info {files['cal']}")
    record = calibration.diagnostics_["cascade"]
    stages, handovers = calibration.summary().tables
    for line in stages.text_lines() + handovers.text_lines():
        assert line in printed.splitlines()
    for row, stage in zip(stages.rows, record["stages"], strict=True):
        assert (row[4], row[5]) == (stage["phase_order"], stage["map_order"])
        assert row[6] == stage["median_std_hz"] / 1e6
    for row, handover in zip(handovers.rows, record["handovers"], strict=True):
        assert float(row[5]) == float(f"{handover['predicted_rate']:.3g}")
        assert row[7] == handover["wrong_on_sweep"]
    found = re.search(r"^edge margin \(std\)\s+(\S+)", printed, re.M)
    assert float(found[1]) == float(f"{record['edge_margin_std']:.6g}")


# ---------------------------------------------------------------------------- report
@pytest.mark.slow
def test_report_has_the_cascade_section(files, tmp_path, capsys):
    page = tmp_path / "report.html"
    ok(capsys, f"report {files['cal']} {files['sweep']} {files['test']} -o {page} --quiet")
    text = page.read_text(encoding="utf-8")
    calibration = files["calibration"]
    assert "<h3>stages</h3>" in text and "<h3>hand-overs</h3>" in text
    assert text.count("<td>stage 1 to 2</td>") == 1 and text.count("<td>stage 2 to 3</td>") == 1
    assert "<td>p31_w, p32_w, p33_w</td>" in text
    test = read_columns(files["test"])
    error = calibration.predict(powers_of(test)) - test["true_frequency_hz"]
    wrong = int(np.count_nonzero(np.abs(error) >= 0.5 * calibration.fsr_hz_))
    assert f"<p>{wrong} of {TEST_READINGS} readings off" in text
    # absolute errors: the table's RMS is the cascade's own, at its uncertainty
    rms = float(re.search(r"<td>cascade</td><td>([0-9.]+)</td>", text)[1]) * 1e6
    std = calibration.frequency_std_hz(powers_of(test))
    low, high = rms_bounds(TEST_READINGS)
    assert low < rms / np.sqrt(np.mean(std**2)) < high
    assert all(path.exists() for path in report_paths(page, calibration))


# ---------------------------------------------------------------------------- evaluate
@pytest.mark.slow
def test_evaluate_reads_absolute_frequency_and_counts_wrong_orders(files, capsys):
    report = json.loads(ok(capsys, f"evaluate {files['cal']} {files['test']} --json")[0])
    assert report["coarse_from"] is None
    stats_ = report["methods"]["cascade"]
    assert stats_["gross_error_fraction"] == 0 and stats_["outside_span_fraction"] == 0
    calibration = files["calibration"]
    test = read_columns(files["test"])
    std = calibration.frequency_std_hz(powers_of(test))
    low, high = rms_bounds(TEST_READINGS)
    assert low < stats_["rms_abs_hz"] / np.sqrt(np.mean(std**2)) < high
    orders = report["order_errors"]["cascade"]
    assert orders["wrong_orders"] == 0 and orders["flagged_order_ambiguous"] == 0
    assert orders["expected_wrong_orders"] == pytest.approx(
        float(np.sum(calibration.order_error_probability(powers_of(test)))), abs=1e-300
    )
    printed, _ = ok(capsys, f"evaluate {files['cal']} {files['test']}")
    assert re.search(r"^cascade\s+\d+\.\d+", printed, re.M)
    assert f"fringe orders of cascade: 0 of {TEST_READINGS} readings off" in printed


@pytest.mark.parametrize(
    ("option", "named"),
    [("--sweep {sweep}", "--sweep"), ("--coarse true_frequency_hz", "--coarse")],
)
def test_evaluate_refuses_what_a_cascade_has_no_use_for(files, capsys, option, named):
    code, _, err = run_cli(
        capsys, f"evaluate {files['cal']} {files['test']} " + option.format(sweep=files["sweep"])
    )
    line = one_error(code, err)
    assert named in line and "cascade calibration" in line
