"""`wavemeter noise` end to end: a simulated laser read by a simulated Table 1 meter.

The report holds the figures and the numbers, --json prints the library's analysis of the
same series, the rate comes from --rate or a uniform time column, a drift over more than
one FSR is unwrapped, and every bad input is one ``error:`` line, exit code 2, no report.
"""

from __future__ import annotations

import html
import io
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.analysis.noise import frequency_noise
from wavemeter.cli import main
from wavemeter.exceptions import recorded_calibration_warnings
from wavemeter.simulation import laser_frequency_hz

from .helpers import NOISE_W, POWER_W, one_error
from .helpers import run_cli as run

RATE_HZ = 10e6
ROWS = 1 << 14
#: white FM of the laser (Hz^2/Hz), about 15x the meter's floor 2 sigma^2 / rate with
#: sigma ~ 10 MHz per reading at Table 1 noise: linewidth pi h0 ~ 0.94 GHz
WHITE_FM_HZ2_PER_HZ = 3e8


@pytest.fixture(scope="module")
def meter(tmp_path_factory):
    """A Table 1 device, its learned calibration and its file."""
    folder = tmp_path_factory.mktemp("noise")
    device = wm.Interferometer.table1(ports=3, seed=1)
    sweep = device.sweep_hz(400)
    calibration = wm.Calibrator(fsr_hz=50e9).fit(
        device.powers(sweep, POWER_W, NOISE_W, rng=1), sweep
    )
    path = folder / "chip.wmcal.json"
    calibration.save(path)
    return {"device": device, "calibration": wm.load_calibration(path), "cal": path, "dir": folder}


def write_readings(path: Path, powers: np.ndarray, time_s=None) -> Path:
    """A CSV of port readings (W), with a ``time_s`` column first when given."""
    columns, header = [powers], "p1_w,p2_w,p3_w"
    if time_s is not None:
        columns.insert(0, np.asarray(time_s)[:, None])
        header = "time_s," + header
    np.savetxt(path, np.hstack(columns), delimiter=",", header=header, comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def laser(meter):
    """A white-FM laser at the device centre read at RATE_HZ: readings file with time
    stamps, and its powers."""
    device = meter["device"]
    frequency = laser_frequency_hz(
        ROWS, RATE_HZ, center_hz=device.center_hz, white_fm_hz2_per_hz=WHITE_FM_HZ2_PER_HZ, rng=5
    )
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=6)
    path = write_readings(meter["dir"] / "laser.csv", powers, np.arange(ROWS) / RATE_HZ)
    return {"path": path, "powers": powers}


def ok(capsys, command: str) -> str:
    code, printed, err = run(capsys, command)
    assert code == 0, err
    return printed


def library_analysis(calibration, powers):
    """What a user gets from the library on the same readings: predict, the RMS of the
    per-reading standard deviations, frequency_noise."""
    series = calibration.predict(powers)
    meter_std = np.sqrt(np.mean(calibration.frequency_std_hz(powers) ** 2))
    with recorded_calibration_warnings():  # the command prints them; the result keeps them
        return frequency_noise(series, RATE_HZ, meter_std_hz=meter_std, fsr_hz=calibration.fsr_hz_)


@pytest.mark.slow
def test_report_and_json_hold_the_librarys_numbers(meter, laser, tmp_path, capsys):
    out = tmp_path / "noise.html"
    printed = ok(capsys, f"noise {meter['cal']} {laser['path']} --rate 10MHz -o {out} --json")
    numbers = json.loads(printed)  # stdout is the JSON alone
    assert numbers["format"] == "wavemeter-noise" and numbers["version"] == 1
    expected = library_analysis(meter["calibration"], laser["powers"])
    for name in ("lorentzian_linewidth_hz", "white_fm_hz2_per_hz", "drift_hz_per_s"):
        # the same readings measured in chunks: equal to the rounding of the retrieval
        assert numbers[name] == pytest.approx(getattr(expected, name), rel=1e-6), name
    assert numbers["rate_hz"] == RATE_HZ and numbers["n_readings"] == ROWS
    assert not numbers["linewidth_is_upper_limit"]  # the laser is ~15x the meter's floor
    width, std = numbers["lorentzian_linewidth_hz"], numbers["lorentzian_linewidth_std_hz"]
    assert abs(width - np.pi * WHITE_FM_HZ2_PER_HZ) < 3 * std  # within its stated uncertainty
    assert numbers["warnings"] == list(expected.warnings)
    # the PSD crosses the beta line at pi^2 h0 / (8 ln2) ~ 530 MHz, far above the 5 MHz
    # Nyquist frequency: the beta linewidth can only be a lower limit
    assert numbers["beta_linewidth_is_lower_limit"]
    page = out.read_text(encoding="utf-8")
    for figure in ("frequency", "psd", "allan"):
        assert (
            f'id="figure-{figure}"><img alt="{figure} figure" src="data:image/png;base64,' in page
        )
    shown = re.search(r"Lorentzian linewidth π h₀ \(FWHM\)</td><td>([\d.]+) ± ([\d.]+) MHz", page)
    assert float(shown.group(1)) == pytest.approx(width / 1e6, abs=float(shown.group(2)) / 100)
    assert float(shown.group(2)) == pytest.approx(std / 1e6, rel=0.01)
    beta = re.search(r"β-line linewidth \(FWHM\), T_obs [\d.]+ s</td><td>&gt; ([\d.]+) MHz", page)
    assert float(beta.group(1)) == pytest.approx(numbers["beta_linewidth_hz"] / 1e6, rel=5e-3)
    assert html.escape(str(laser["path"])) in page and "Allan deviations" in page
    assert html.escape(numbers["warnings"][0]) in page


@pytest.mark.slow
def test_json_alone_writes_nothing_and_the_summary_is_printed_without_it(
    meter, laser, tmp_path, capsys
):
    before = set(tmp_path.iterdir())
    numbers = json.loads(ok(capsys, f"noise {meter['cal']} {laser['path']} --rate 10MHz --json"))
    assert set(tmp_path.iterdir()) == before and "taus_s" in numbers
    out = tmp_path / "noise.html"
    printed = ok(capsys, f"noise {meter['cal']} {laser['path']} --rate 10MHz -o {out}")
    assert "Lorentzian linewidth" in printed and f"wrote {out}" in printed
    assert "flagged" in printed and out.exists()
    assert (
        ok(capsys, f"noise {meter['cal']} {laser['path']} --rate 10MHz -o {out} --force --quiet")
        == ""
    )


@pytest.mark.slow
def test_the_rate_from_the_time_column(meter, laser, capsys):
    command = f"noise {meter['cal']} {laser['path']} --json --time-column time_s"
    numbers = json.loads(ok(capsys, command))
    assert numbers["rate_hz"] == pytest.approx(RATE_HZ, rel=1e-9)
    both = json.loads(ok(capsys, command + " --rate 10MHz"))
    assert both["lorentzian_linewidth_hz"] == pytest.approx(numbers["lorentzian_linewidth_hz"])
    err = one_error(*run(capsys, command + " --rate 20MHz")[::2])
    assert "disagrees with the time column 'time_s'" in err and "(use --rate)" in err


@pytest.mark.slow
def test_a_drift_over_more_than_one_fsr_is_unwrapped(meter, tmp_path, capsys):
    device, calibration = meter["device"], meter["calibration"]
    drift_hz_per_s = 1.5 * device.true_fsr_hz * RATE_HZ / ROWS  # 1.5 FSR over the record
    frequency = laser_frequency_hz(
        ROWS,
        RATE_HZ,
        center_hz=device.center_hz,
        white_fm_hz2_per_hz=1e6,
        drift_hz_per_s=drift_hz_per_s,
        rng=7,
    )
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=8)
    assert np.ptp(calibration.predict(powers)) < calibration.fsr_hz_  # read modulo the FSR
    path = write_readings(tmp_path / "drift.csv", powers)
    numbers = json.loads(ok(capsys, f"noise {meter['cal']} {path} --rate 10MHz --json"))
    # the calibrated FSR scales every frequency step by fsr_cal / fsr_true
    scale_error = abs(calibration.fsr_hz_ / device.true_fsr_hz - 1) * drift_hz_per_s
    tolerance = 3 * numbers["drift_std_hz_per_s"] + scale_error
    assert abs(numbers["drift_hz_per_s"] - drift_hz_per_s) < tolerance
    assert tolerance < 0.01 * drift_hz_per_s  # the test can tell a wrong unwrap


def test_progress_on_a_terminal_and_not_when_quiet(meter, laser, monkeypatch):
    class FakeTerminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    for quiet, drawn in ((False, True), (True, False)):
        terminal = FakeTerminal()
        monkeypatch.setattr(sys, "stderr", terminal)
        options = ["--rate", "10MHz", "--json"] + (["--quiet"] if quiet else [])
        assert main(["noise", str(meter["cal"]), str(laser["path"]), *options]) == 0
        assert ("measuring" in terminal.getvalue()) is drawn


# ---------------------------------------------------------------------------- bad input
@pytest.fixture(scope="module")
def short(meter, laser):
    """The first 60 readings of the laser."""
    lines = laser["path"].read_text().splitlines()
    path = meter["dir"] / "short.csv"
    path.write_text("\n".join(lines[:61]) + "\n")
    return path


def _refused(capsys, command: str, out: Path) -> str:
    err = one_error(*run(capsys, command)[::2])
    assert not out.exists() and "Traceback" not in err
    return err


def test_fewer_than_100_readings(meter, short, tmp_path, capsys):
    out = tmp_path / "noise.html"
    err = _refused(capsys, f"noise {meter['cal']} {short} --rate 10MHz -o {out}", out)
    assert str(short) in err and "100" in err


def test_no_rate(meter, laser, tmp_path, capsys):
    out = tmp_path / "noise.html"
    err = _refused(capsys, f"noise {meter['cal']} {laser['path']} -o {out}", out)
    assert "no sampling rate" in err and "--rate" in err and "--time-column" in err


def test_nothing_to_write_or_a_page_to_stdout(meter, laser, capsys):
    command = f"noise {meter['cal']} {laser['path']} --rate 10MHz"
    err = one_error(*run(capsys, command)[::2])
    assert "-o FILE" in err and "--json" in err
    code, printed, err = run(capsys, command + " -o -")
    assert "not written to stdout" in one_error(code, err) and printed == ""


@pytest.mark.slow
@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (lambda t: t.__setitem__(500, t[500] + 1e-9), "not uniformly sampled"),
        (lambda t: t.__setitem__(slice(500, None), t[500:] + 1e-6), "gap in time column"),
    ],
)
def test_non_uniform_time_and_gaps(meter, laser, tmp_path, capsys, change, expected):
    time_s = np.arange(ROWS) / RATE_HZ
    change(time_s)
    path = write_readings(tmp_path / "t.csv", laser["powers"], time_s)
    out = tmp_path / "noise.html"
    err = _refused(capsys, f"noise {meter['cal']} {path} --time-column time_s -o {out}", out)
    assert expected in err and "line 502" in err


def test_everything_invalid(meter, laser, tmp_path, capsys):
    path = write_readings(tmp_path / "dark.csv", laser["powers"] * 1e-3)  # laser off
    out = tmp_path / "noise.html"
    err = _refused(capsys, f"noise {meter['cal']} {path} --rate 10MHz -o {out}", out)
    assert "no usable reading" in err and "INVALID" in err


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--rate abc", "'--rate'"),
        ("--rate 10MHz --observation-time 1min", "unknown time unit"),
        ("--rate 10MHz --observation-time -1ms", "must be a finite time > 0"),
        ("--rate 0Hz", "rate_hz must be a finite number > 0, got 0.0 (use --rate)"),
        ("--time-column clock", "no column 'clock' (given as the time column)"),
    ],
)
def test_bad_options(meter, laser, tmp_path, capsys, options, expected):
    out = tmp_path / "noise.html"
    err = _refused(capsys, f"noise {meter['cal']} {laser['path']} {options} -o {out}", out)
    assert expected in err


def test_an_existing_report_needs_force(meter, laser, tmp_path, capsys):
    out = tmp_path / "noise.html"
    out.write_text("keep me")
    err = one_error(
        *run(capsys, f"noise {meter['cal']} {laser['path']} --rate 10MHz -o {out}")[::2]
    )
    assert "--force" in err and out.read_text() == "keep me"
