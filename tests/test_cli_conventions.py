"""One convention across the command line: units, option names, flag hints, printable
text, progress.

Physical quantities take a unit (bare numbers are SI, a bare frequency below 1 MHz is a
missing unit), option names say the quantity (old names still work, hidden), errors from
the library name the option that sets the parameter at fault, nothing from a file reaches
the terminal as a control sequence, and long work reports progress.
"""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.cli import main
from wavemeter.exceptions import InputError
from wavemeter.progress import busy, chunked, progress_bar, progress_line

from .helpers import one_error, simulated_files
from .helpers import run_cli as run


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    return simulated_files(tmp_path_factory.mktemp("conventions"), test_rows=200)


# ---------------------------------------------------------------------------- units
def _simulated(capsys, tmp_path, options: str) -> bytes:
    out = tmp_path / f"s{len(list(tmp_path.iterdir()))}.csv"
    code, _, err = run(capsys, f"simulate -o {out} --samples 30 --quiet {options}")
    assert code == 0, err
    return out.read_bytes()


@pytest.mark.parametrize(
    ("reference", "equivalents"),
    [
        ("--power 1e-3", ["--power 1mW", "--power '1 mW'", "--power 0dBm", "--power-w 1e-3"]),
        ("--noise 5e-7", ["--noise 5e-7W", "--noise '0.5 uW'", "--noise 500nW", "--noise-w 5e-7"]),
        ("--fsr 5e10", ["--fsr 50GHz", "--fsr '50 GHz'", "--fsr 50000MHz", "--fsr 0.05THz"]),
    ],
)
def test_quantities_take_units_and_bare_numbers_are_si(capsys, tmp_path, reference, equivalents):
    expected = _simulated(capsys, tmp_path, reference)
    for options in equivalents:
        assert _simulated(capsys, tmp_path, options) == expected, options


def test_dbm_noise_and_power_convert(capsys, tmp_path):
    # -30 dBm is exactly 1 uW: the same file as --power 1uW
    assert _simulated(capsys, tmp_path, "--power -30dBm") == _simulated(
        capsys, tmp_path, "--power 1uW"
    )


@pytest.mark.parametrize("value", ["50", "5000", "999999", "0.05"])
@pytest.mark.parametrize("command", ["calibrate {sweep} -o {out}", "simulate -o {out}"])
def test_bare_small_fsr_is_a_missing_unit_refused_fast(files, tmp_path, capsys, value, command):
    out = tmp_path / "c.wmcal.json"
    started = time.perf_counter()
    code, _, err = run(capsys, command.format(sweep=files["sweep"], out=out) + f" --fsr {value}")
    assert time.perf_counter() - started < 2.0
    err = one_error(code, err)
    assert f"{value} is a bare number, so in Hz" in err
    assert "is not an FSR an optical interferometer has" in err
    assert f"did you mean {value}GHz?" in err and not out.exists()


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--power 0", "'--power': 0: must be > 0"),
        ("--power 1V", "V is a relative detector scale, not a power"),
        ("--noise -1uW", "must be >= 0"),
        ("--power 1mA", "unknown power unit 'mA'"),
        ("--fsr -50GHz", "must be > 0"),
        ("--fsr 50nm", "unknown frequency unit 'nm'"),
        ("--fsr 1e400", "not a finite number"),
    ],
)
def test_bad_quantities(tmp_path, capsys, options, expected):
    out = tmp_path / "s.csv"
    err = one_error(*run(capsys, f"simulate -o {out} {options}")[::2])
    assert expected in err and not out.exists()


@pytest.mark.slow
def test_coarse_frequency_takes_a_frequency_or_a_wavelength(tmp_path, capsys):
    sweep, cal = tmp_path / "wide.csv", tmp_path / "set.wmcal.json"
    run(capsys, f"simulate -o {sweep} --span-fsr 3 --samples 1500 --test 300 --quiet")
    assert run(capsys, f"calibrate {sweep} -o {cal} --per-fsr --quiet")[0] == 0
    test = tmp_path / "wide-test.csv"
    centre_hz = wm.load_calibration(cal).windows_[1].center_hz_
    outputs = []
    for index, value in enumerate(
        [f"{centre_hz!r}", f"'{centre_hz / 1e12!r} THz'", f"{299792458 / centre_hz * 1e9!r}nm"]
    ):
        for option in ("--coarse-frequency", "--coarse-hz"):
            out = tmp_path / f"f{index}{option}.csv"
            code, _, err = run(capsys, f"measure {cal} {test} -o {out} {option} {value}")
            assert code == 0, err
            outputs.append(np.loadtxt(out, delimiter=",", skiprows=1))
    for other in outputs[1:]:
        np.testing.assert_allclose(other, outputs[0], rtol=1e-12)
    err = one_error(*run(capsys, f"measure {cal} {test} -o x.csv --coarse-frequency 193.4")[::2])
    assert "193.4 is a bare number, so in Hz" in err and "did you mean 193.4THz?" in err
    err = one_error(*run(capsys, f"measure {cal} {test} -o x.csv --coarse-frequency 1550")[::2])
    assert "did you mean 1550nm?" in err
    err = one_error(*run(capsys, f"measure {cal} {test} -o x.csv --coarse-frequency 5GHz")[::2])
    assert "not an optical frequency" in err


def test_option_names_say_the_quantity_and_old_names_are_hidden(capsys):
    printed = " ".join(run(capsys, "simulate --help")[1].split())
    for shown in ("--power POWER", "--noise POWER", "--write-axis-unit", "--write-power-unit"):
        assert shown in printed
    for hidden in ("--power-w", "--noise-w", "--x-unit", "--power-unit"):
        assert f"{hidden} " not in printed and f"{hidden}," not in printed
    assert printed.count("a bare number is in") >= 3  # power, noise, FSR
    printed = " ".join(run(capsys, "measure --help")[1].split())
    assert "--coarse-frequency" in printed and "--coarse-hz" not in printed
    assert "a bare number is in Hz" in printed
    assert "a bare number is in Hz" in " ".join(run(capsys, "calibrate --help")[1].split())


def test_old_option_names_still_work(tmp_path, capsys):
    out = tmp_path / "lab.csv"
    options = "--x-unit nm --power-unit dBm --noise-w 2e-8 --power-w 1e-3 --samples 10"
    code, _, err = run(capsys, f"simulate -o {out} {options} --quiet")
    assert code == 0, err
    assert out.read_text().startswith("wavelength_nm,p1_dBm,p2_dBm,p3_dBm\n")
    new = tmp_path / "lab2.csv"
    options = "--write-axis-unit nm --write-power-unit dBm --noise 2e-8W --power 1mW --samples 10"
    assert run(capsys, f"simulate -o {new} {options} --quiet")[0] == 0
    assert new.read_bytes() == out.read_bytes()


# ---------------------------------------------------------------------------- flag hints
def _raising(error):
    def fit(*args, **kwargs):
        raise error

    return fit


@pytest.mark.parametrize(
    ("error", "hint"),
    [
        (InputError("the design FSR is far from the sweep's", parameter="fsr_hz"), "(use --fsr)"),
        (
            InputError("widen fsr_tolerance or correct fsr_hz"),
            "(fsr_tolerance: --fsr-tolerance, fsr_hz: --fsr)",
        ),
        (InputError("no such port", parameter="ports"), "(use --ports)"),
        (InputError("something else", parameter="not_an_option"), "something else"),
    ],
)
def test_library_errors_get_the_option_of_their_parameter(
    files, tmp_path, capsys, monkeypatch, error, hint
):
    import wavemeter.jobs

    monkeypatch.setattr(wavemeter.jobs, "calibrate_file", _raising(error))
    out = tmp_path / "c.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {files['sweep']} -o {out}")[::2])
    assert err.rstrip().endswith(hint)


def test_hints_follow_the_running_command(tmp_path, capsys, monkeypatch):
    from wavemeter.simulation import Scenario

    monkeypatch.setattr(Scenario, "tables", _raising(InputError("bad", parameter="x_unit")))
    err = one_error(*run(capsys, f"simulate -o {tmp_path / 's.csv'} --samples 10")[::2])
    assert err.rstrip().endswith("bad (use --write-axis-unit)")


@pytest.mark.parametrize(
    "options", ["--fsr 30GHz --fsr-tolerance 0.1", "--fsr 45GHz --fsr-tolerance 0.05"]
)
def test_a_design_fsr_off_the_sweep_names_the_fsr_option(files, tmp_path, capsys, options):
    out = tmp_path / "c.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {files['sweep']} -o {out} {options}")[::2])
    assert "fsr_hz: --fsr" in err or "use --fsr" in err
    assert not out.exists()


# ---------------------------------------------------------------------------- printable text
def test_no_control_characters_reach_the_terminal(files, tmp_path, capsys):
    lines = files["sweep"].read_text().splitlines()
    evil_port = "p3\x1b]0;pwned\x07_w"
    evil = tmp_path / "evil.csv"
    evil.write_text("\n".join([lines[0].replace("p3_w", evil_port), *lines[1:]]) + "\n")
    out = tmp_path / "c.wmcal.json"
    ports = ["--ports", f"p1_w,p2_w,{evil_port}"]
    code = main(["calibrate", str(evil), "-o", str(out), "--x", "nope", *ports])
    err = one_error(code, capsys.readouterr().err)
    assert "no column 'nope'" in err and "\x1b" not in err and "\x07" not in err
    assert main(["calibrate", str(evil), "-o", str(out), *ports]) == 0
    printed = capsys.readouterr()
    assert "ports p1_w, p2_w, p3?]0;pwned?_w" in printed.out
    assert "\x1b" not in printed.out + printed.err and "\x07" not in printed.out + printed.err
    missing = tmp_path / "gone\x1b[2J.csv"
    code = main(["measure", str(files["cal"]), str(missing), "-o", str(tmp_path / "f.csv")])
    err = one_error(code, capsys.readouterr().err)
    assert "\x1b" not in err and "gone?[2J.csv" in err


# ---------------------------------------------------------------------------- progress
class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class FakeClock:
    def __init__(self, step_s: float):
        self.now, self.step_s = 0.0, step_s

    def __call__(self) -> float:
        self.now += self.step_s
        return self.now


def test_progress_line_has_percentage_count_rate_and_eta():
    line = progress_line("measuring data.csv", 450000, 1000000, 450000 / 2.1e5, "rows")
    assert line == "measuring data.csv: 45 % (450000/1000000 rows, 2.1e5 rows/s, ETA 3 s)"
    assert progress_line("x", 0, 10, 0.0, "rows") == "x: 0 % (0/10 rows)"
    assert progress_line("x", 100, 1000, 1.0, "windows").endswith("100 windows/s, ETA 9 s)")


def test_plain_progress_lines_every_interval_off_a_terminal():
    stream = io.StringIO()
    clock = FakeClock(1.0)  # every call: one second later
    slices = list(
        chunked(1000, "measuring d.csv", chunk_rows=100, stream=stream, interval_s=3, clock=clock)
    )
    assert len(slices) == 10
    assert stream.getvalue().splitlines() == [
        "measuring d.csv: 30 % (300/1000 rows, 100 rows/s, ETA 7 s)",
        "measuring d.csv: 60 % (600/1000 rows, 100 rows/s, ETA 4 s)",
        "measuring d.csv: 90 % (900/1000 rows, 100 rows/s, ETA 1 s)",
    ]


def test_no_progress_for_short_work_or_when_quiet():
    stream = io.StringIO()
    list(chunked(1000, "quick", chunk_rows=10, stream=stream))  # 5 s default interval
    with busy("quick", stream=stream):
        pass
    quiet = io.StringIO()
    list(chunked(10, "x", chunk_rows=1, stream=quiet, quiet=True, interval_s=0, clock=FakeClock(1)))
    with busy("x", stream=quiet, quiet=True, interval_s=0.01):
        time.sleep(0.05)
    assert stream.getvalue() == "" and quiet.getvalue() == ""


def test_busy_off_a_terminal_reports_elapsed_time():
    stream = io.StringIO()
    with busy("calibrating on s.csv", stream=stream, interval_s=0.02):
        time.sleep(0.15)
    lines = stream.getvalue().splitlines()
    assert len(lines) >= 2 and all(line == "calibrating on s.csv: 0 s elapsed" for line in lines)


def test_terminal_bar_shows_percentage_count_and_rate():
    stream = FakeTerminal()
    with progress_bar("measuring d.csv", 10, stream=stream) as advance:
        for _ in range(10):
            advance(1)
    drawn = stream.getvalue()
    assert "measuring d.csv" in drawn and "100%" in drawn and "10/10" in drawn
    assert "rows/s" in drawn


def test_an_aliasing_design_fsr_is_refused_fast_with_the_sweeps_own(files, tmp_path, capsys):
    """``--fsr 5e6`` (5 MHz; issue 15: it used to 'succeed' with an aliased calibration)."""
    out = tmp_path / "c.wmcal.json"
    started = time.perf_counter()
    code, _, err = run(capsys, f"calibrate {files['sweep']} -o {out} --fsr 5e6")
    assert time.perf_counter() - started < 2.0  # a hang guard: no delay grid is built
    err = one_error(code, err)
    assert "is not resolved by the sweep" in err and not out.exists()
    suggested = float(re.search(r"set fsr_hz to about (\S+) Hz", err).group(1))
    true_fsr_hz = wm.Interferometer.table1(3, seed=1).true_fsr_hz  # the sweep's device
    assert suggested == pytest.approx(true_fsr_hz, rel=1e-3)


@pytest.mark.slow
def test_python_dash_m_wavemeter_is_the_command_with_its_exit_code(tmp_path):
    missing = tmp_path / "missing.wmcal.json"
    done = subprocess.run(
        [sys.executable, "-m", "wavemeter", "info", str(missing)], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert done.stderr.startswith("error: ") and str(missing) in done.stderr
    assert "Traceback" not in done.stderr
