"""Live readout (issue 13 item 4): ``BaseCalibrator.stream``, ``jobs.stream_lines``,
``jobs.follow_lines`` and ``wavemeter stream`` over real pipes.

The numbers of a stream are those of ``predict``, ``frequency_std_hz`` and ``flags`` on the
same readings, to float64 rounding (1e-12 relative: a reading read alone, in one pass, may
round differently in the last bits from the same reading in a batch; tests/test_stream_fast_path.py
tests that pass case by case). Lines are read as files
are: the readings of a line are compared with those ``read_table`` gives for the same text
in a file. Over a pipe, every output line is read back before the next reading is written:
a command that did not flush each line would block the test (each wait is bounded by
``TIMEOUT_S``).
"""

from __future__ import annotations

import io
import itertools
import os
import select
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.contract.streaming import INVALID_READING_CAUSE
from wavemeter.io import read_table
from wavemeter.jobs import follow_lines, stream_lines
from wavemeter.jobs.stream import MAX_LINE_WARNINGS
from wavemeter.units import SPEED_OF_LIGHT_M_S

from .helpers import NOISE_W, POWER_W, one_error, run_cli, thermal_sweep

SCRIPT = Path(sys.executable).with_name("wavemeter")
INVALID = int(wm.ReadingFlag.INVALID)
#: numerical precision of a reading read alone against the same reading in a batch
RTOL = 1e-12
#: the longest wait for one line from a child process (s): a bound, not a measurement
TIMEOUT_S = 30.0
HEADER_MW = "time_s,P1_mW,P2_mW,P3_mW"
#: the children's environment: Python's own buffering of a pipe (block-buffered stdout), so
#: only the command's flushing can bring a line out before the input ends
CHILD_ENV = {name: value for name, value in os.environ.items() if name != "PYTHONUNBUFFERED"}


# ---------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return wm.Interferometer.table1(3, seed=7)


@pytest.fixture(scope="module")
def calibration(device) -> wm.Calibrator:
    sweep_hz = device.sweep_hz(400)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1)
    return wm.Calibrator(fsr_hz=50e9).fit(sweep, sweep_hz)


@pytest.fixture(scope="module")
def cal_path(calibration, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("stream") / "chip.wmcal.json"
    calibration.save(path)
    return path


@pytest.fixture(scope="module")
def readings(device) -> np.ndarray:
    """Readings (W) inside the calibrated FSR, the last three made to raise flags: 3x the
    power (POWER_RANGE), a port 20 % off (OFF_MODEL), a reading too dark (INVALID)."""
    rng = np.random.default_rng(3)
    frequency = device.center_hz + rng.uniform(-0.45, 0.45, 40) * device.true_fsr_hz
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    bright = 3.0 * powers[0]
    off_model = powers[1] * np.array([1.2, 1.0, 1.0])
    dark = 1e-4 * powers[2]
    return np.vstack([powers, bright, off_model, dark])


def _text(value) -> str:
    return repr(float(value))


def mw_lines(powers_w: np.ndarray) -> list[str]:
    """Data lines under ``HEADER_MW``: a time stamp, then the powers in mW."""
    return [
        ",".join([str(k), *(_text(value * 1e3) for value in row)]) for k, row in enumerate(powers_w)
    ]


def parsed(text: str) -> tuple[list[str], np.ndarray]:
    """The header and the values (rows, columns) of an output."""
    header, *rows = text.splitlines()
    values = np.array([[float(cell) for cell in row.split(",")] for row in rows])
    return header.split(","), values.reshape(len(rows), -1)


def calibration_warnings(caught) -> list[wm.CalibrationWarning]:
    return [w.message for w in caught if isinstance(w.message, wm.CalibrationWarning)]


# ---------------------------------------------------------------------------- library: stream
def test_a_stream_gives_what_predict_frequency_std_and_flags_give(calibration, readings):
    records = list(calibration.stream(readings[:-1]))
    rows = readings[:-1]
    assert len(records) == rows.shape[0]
    np.testing.assert_allclose(
        [r.frequency_hz for r in records], calibration.predict(rows), rtol=RTOL, atol=0
    )
    np.testing.assert_allclose(
        [r.frequency_std_hz for r in records],
        calibration.frequency_std_hz(rows),
        rtol=RTOL,
        atol=0,
    )
    flags = np.array([r.flags for r in records])
    np.testing.assert_array_equal(flags, calibration.flags(rows))
    assert flags[-2] & wm.ReadingFlag.POWER_RANGE and flags[-1] & wm.ReadingFlag.OFF_MODEL
    assert all(r.order_error_probability is None for r in records)


def test_a_stream_reads_an_endless_iterator_one_row_per_record(calibration, readings):
    pulled = []

    def endless():
        for count, row in enumerate(itertools.cycle(readings[:5]), start=1):
            pulled.append(count)
            yield row

    records = calibration.stream(endless())
    assert pulled == []  # nothing is read before a record is asked for
    for count in range(1, 8):
        record = next(records)
        assert len(pulled) == count
        assert record.frequency_hz == pytest.approx(
            calibration.predict(readings[(count - 1) % 5])[0], rel=RTOL
        )


def test_rows_that_cannot_be_read_are_invalid_with_one_warning(calibration, readings):
    good, dark = readings[0], readings[-1]
    rows = [good, good[:2], [np.nan, 1e-3, 1e-3], ["a", "b", "c"], np.zeros(3), dark, good]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = list(calibration.stream(rows))
    noted = calibration_warnings(caught)
    assert [w.cause for w in noted] == [INVALID_READING_CAUSE]
    assert "reading 1 " in str(noted[0]) and "shape (2,)" in str(noted[0])
    expected = calibration.predict(good)[0]
    assert records[0].frequency_hz == records[-1].frequency_hz == pytest.approx(expected, rel=RTOL)
    for record in records[1:5]:
        assert np.isnan(record.frequency_hz) and np.isnan(record.frequency_std_hz)
    assert records[1].flags == records[2].flags == records[3].flags == INVALID
    # a reading of the right length keeps the other bits flags gives it (no light: POWER_RANGE)
    assert records[4].flags == calibration.flags(np.zeros(3))[0] != INVALID
    # too little light to trust, enough to read: predict reads it, flags says INVALID
    assert records[5].frequency_hz == pytest.approx(calibration.predict(dark)[0], rel=RTOL)
    assert records[5].flags == calibration.flags(dark)[0]
    assert records[5].flags & INVALID


@pytest.mark.parametrize("make", [wm.ConventionalCalibrator, wm.CalibrationSet])
def test_every_calibrator_streams_its_own_numbers(device, readings, make):
    """A calibration without an uncertainty gives NaN; one that needs a coarse frequency
    takes it per row, in step with the rows."""
    sweep_hz = device.sweep_hz(400)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cal = make().fit(sweep, sweep_hz)
    rows = readings[:10]
    inputs = {"coarse_hz": cal.predict(rows, coarse_hz=cal.center_hz_)} if cal.requires else {}
    streamed = {name: iter(values) for name, values in inputs.items()}
    records = list(cal.stream(rows, **streamed))
    found = [r.frequency_hz for r in records]
    np.testing.assert_allclose(found, cal.predict(rows, **inputs), rtol=RTOL, atol=0)
    np.testing.assert_array_equal([r.flags for r in records], cal.flags(rows, **inputs))
    stds = [r.frequency_std_hz for r in records]
    if "frequency_std" in cal.capabilities:
        np.testing.assert_allclose(stds, cal.frequency_std_hz(rows, **inputs), rtol=RTOL)
    else:
        assert np.all(np.isnan(stds))


def test_a_missing_required_input_is_refused_before_any_row(device):
    powers, frequency, temperature = thermal_sweep(device.with_thermal("sin"), 100, NOISE_W, 1)
    thermal = wm.ThermalCalibrator().fit(powers, frequency, temperature_k=temperature)

    def untouchable():
        raise AssertionError("a row was read")
        yield

    with pytest.raises(wm.InputError, match="temperature_k"):
        thermal.stream(untouchable())
    with pytest.raises(wm.InputError, match="temperature_k contains NaN"):
        thermal.stream(untouchable(), temperature_k=float("nan"))
    with pytest.raises(wm.InputError, match="temperature_k must be None, a number or an"):
        thermal.stream(untouchable(), temperature_k=object())
    short = thermal.stream(powers[:3], temperature_k=iter(temperature[:2]))
    assert len([next(short), next(short)]) == 2
    with pytest.raises(wm.InputError, match="temperature_k ended at reading 2"):
        next(short)
    # in step with the rows: each reading at its own temperature
    records = list(thermal.stream(powers[::50], temperature_k=iter(temperature[::50])))
    np.testing.assert_allclose(
        [r.frequency_hz for r in records],
        thermal.predict(powers[::50], temperature_k=temperature[::50]),
        rtol=RTOL,
        atol=0,
    )


@pytest.mark.slow
def test_a_cascade_streams_its_order_error_probability():
    fsrs_hz = (1e12, 100e9, 10e9)
    cascade = wm.CascadeInterferometer.table1(fsrs_hz, ports=3, seed=4, spectral="sin")
    low = cascade.center_hz - 0.4e12
    sweep_hz = low + 0.8e12 * np.arange(3000) / 2999
    sweep = cascade.powers(sweep_hz, POWER_W, NOISE_W, rng=11)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cal = wm.CascadeCalibrator(fsr_hz=fsrs_hz).fit(sweep, sweep_hz)
    rows = cascade.powers(low + 0.8e12 * np.random.default_rng(5).random(12), POWER_W, NOISE_W, 6)
    rows[0, 4] = np.nan
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        records = list(cal.stream(rows))
    assert len(calibration_warnings(caught)) == 1
    assert np.isnan(records[0].order_error_probability) and records[0].flags == INVALID
    good = rows[1:]
    for name, expected in (
        ("frequency_hz", cal.predict(good)),
        ("frequency_std_hz", cal.frequency_std_hz(good)),
        ("order_error_probability", cal.order_error_probability(good)),
    ):
        found = [getattr(record, name) for record in records[1:]]
        np.testing.assert_allclose(found, expected, rtol=RTOL, atol=0, err_msg=name)
    np.testing.assert_array_equal([r.flags for r in records[1:]], cal.flags(good))


# ---------------------------------------------------------------------------- library: lines
@pytest.mark.parametrize("delimiter", [",", "\t"])
def test_lines_are_read_as_files_are(calibration, readings, tmp_path, delimiter):
    lines = [HEADER_MW, *mw_lines(readings)]
    text = "\n".join(line.replace(",", delimiter) for line in lines) + "\n"
    (tmp_path / "same.csv").write_text(text)
    powers_w = read_table(tmp_path / "same.csv", need_x=False, allow_invalid=True).powers_w
    out = io.StringIO()
    summary = stream_lines(calibration, io.StringIO(text), out)
    header, values = parsed(out.getvalue())
    assert header == ["frequency_hz", "wavelength_nm", "frequency_std_hz", "flags"]
    good = slice(0, -1)  # the last reading is too dark: flagged, still read
    np.testing.assert_allclose(
        values[good, 0], calibration.predict(powers_w[good]), rtol=RTOL, atol=0
    )
    np.testing.assert_array_equal(values[:, 1], SPEED_OF_LIGHT_M_S / values[:, 0] * 1e9)
    np.testing.assert_allclose(
        values[good, 2], calibration.frequency_std_hz(powers_w[good]), rtol=RTOL, atol=0
    )
    np.testing.assert_array_equal(values[:, 3], calibration.flags(powers_w))
    assert (summary.rows, summary.invalid_rows) == (readings.shape[0], 0)
    assert summary.flagged == np.count_nonzero(calibration.flags(powers_w))


def test_lines_that_hold_no_valid_reading_are_invalid_and_named(calibration, readings):
    good = mw_lines(readings[:2])
    lines = [
        "# logged by the test",
        HEADER_MW,  # line 2
        good[0],
        "",  # blank: skipped
        "7,0.1,0.2",  # line 5: a cell missing
        "8,0.1,abc,0.3",  # line 6: text
        "9,nan,0.2,0.3",  # line 7: NaN
        "10,9.91e37,0.2,0.3",  # line 8: a power meter's 'no reading' code
        "# a comment",
        good[1] + ",",  # line 10: a trailing delimiter is allowed
    ]
    out = io.StringIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = stream_lines(calibration, lines, out, name="log.csv")
    _, values = parsed(out.getvalue())
    assert values.shape == (6, 4)
    assert np.all(np.isnan(values[1:5, :3])) and np.all(values[1:5, 3] == INVALID)
    np.testing.assert_allclose(
        values[[0, 5], 0], calibration.predict(readings[:2]), rtol=1e-9, atol=0
    )
    texts = [str(w) for w in calibration_warnings(caught)]
    assert [text.split(":")[0] for text in texts] == [f"log.csv line {n}" for n in (5, 6, 7, 8)]
    assert "3 cells, the header has 4" in texts[0] and "'abc' is not a number" in texts[1]
    assert (summary.rows, summary.invalid_rows) == (6, 4)
    assert summary.flag_counts["INVALID"] == 4


def test_only_the_first_invalid_lines_are_warned_about(calibration):
    out = io.StringIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = stream_lines(calibration, [HEADER_MW, *["1,2"] * 15], out)
    noted = calibration_warnings(caught)
    assert len(noted) == MAX_LINE_WARNINGS and "further invalid lines" in str(noted[-1])
    assert summary.invalid_rows == 15 and out.getvalue().count("\n") == 16


def test_a_header_with_other_ports_is_refused_before_any_output(calibration):
    out = io.StringIO()
    with pytest.raises(wm.InputError) as refused:
        stream_lines(calibration, ["a,p1,p2,p3,p4", "1,1,1,1,1"], out, name="<stdin>")
    message = str(refused.value)
    assert message.startswith("<stdin> has 4 ports (p1, p2, p3, p4)")
    assert "but the calibration reads 3 (" in message
    assert out.getvalue() == ""
    with pytest.raises(wm.InputError, match="no header line"):
        stream_lines(calibration, ["", "# nothing"], out)


# ---------------------------------------------------------------------------- follow_lines
def test_follow_gives_appended_lines_and_holds_a_partial_one(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("a,b\n1,2\n")
    stop = threading.Event()
    lines = follow_lines(path, poll_s=0.01, stop=stop)
    assert [next(lines), next(lines)] == ["a,b\n", "1,2\n"]
    with open(path, "a") as handle:
        handle.write("3,")  # a line still being written
        handle.flush()

        def finish():
            time.sleep(0.2)
            handle.write("4\n5,")
            handle.flush()

        writer = threading.Thread(target=finish)
        writer.start()
        started = time.monotonic()
        assert next(lines) == "3,4\n"  # held until its newline arrived
        assert time.monotonic() - started >= 0.15
        writer.join()
    stop.set()
    assert list(lines) == []  # '5,' never got its newline
    with pytest.raises(wm.InputError, match="file not found"):
        follow_lines(tmp_path / "missing.csv")


# ---------------------------------------------------------------------------- command line
def _line(child, timeout: float = TIMEOUT_S) -> str:
    """One line of a child's stdout (unbuffered), waiting at most ``timeout``."""
    text = b""
    deadline = time.monotonic() + timeout
    while not text.endswith(b"\n"):
        ready, _, _ = select.select([child.stdout], [], [], max(deadline - time.monotonic(), 0))
        assert ready, f"no output line within {timeout} s; got {text!r}"
        byte = child.stdout.read(1)
        assert byte, f"output ended: {text!r} {child.stderr.read()!r}"
        text += byte
    return text.decode()


def _stream_child(*arguments) -> subprocess.Popen:
    return subprocess.Popen(
        [str(SCRIPT), "stream", *map(str, arguments)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        bufsize=0,
        env=CHILD_ENV,
    )


@pytest.mark.slow
def test_the_command_answers_each_line_before_the_next_is_written(cal_path, calibration, readings):
    child = _stream_child(cal_path)
    try:
        child.stdin.write(f"{HEADER_MW}\n".encode())
        assert _line(child) == "frequency_hz,wavelength_nm,frequency_std_hz,flags\n"
        answers = []
        for line in mw_lines(readings[:12]):
            child.stdin.write(f"{line}\n".encode())
            answers.append(_line(child))  # the answer comes while the input stays open
        child.stdin.close()
        assert child.wait(timeout=TIMEOUT_S) == 0
        err = child.stderr.read().decode()
    finally:
        child.kill()
        child.wait()
    _, values = parsed("header\n" + "".join(answers))
    np.testing.assert_allclose(values[:, 0], calibration.predict(readings[:12]), rtol=1e-9)
    assert child.stdout.read() == b""
    assert err.startswith("end of input: streamed 12 readings from <stdin>, 0 invalid")


@pytest.mark.slow
def test_ctrl_c_exits_130_with_the_lines_written_intact(cal_path, readings):
    child = _stream_child(cal_path)
    try:
        child.stdin.write(("\n".join([HEADER_MW, *mw_lines(readings[:3])]) + "\n").encode())
        lines = [_line(child) for _ in range(4)]
        child.send_signal(signal.SIGINT)
        assert child.wait(timeout=TIMEOUT_S) == 130
        err = child.stderr.read().decode()
        rest = child.stdout.read()
    finally:
        child.kill()
        child.wait()
    assert all(len(line.split(",")) == 4 for line in lines) and rest == b""
    assert "Traceback" not in err
    assert err.strip().endswith(
        "stopped by Ctrl-C: streamed 3 readings from <stdin>, 0 invalid; flagged 0 of 3 readings"
    )


@pytest.mark.slow
def test_follow_reads_a_file_as_it_grows(cal_path, calibration, readings, tmp_path):
    path = tmp_path / "log.csv"
    lines = mw_lines(readings[:4])
    path.write_text("\n".join([HEADER_MW, *lines[:2]]) + "\n")
    child = _stream_child(cal_path, "--follow", path)
    try:
        answers = [_line(child) for _ in range(3)]
        with open(path, "a") as handle:
            handle.write("\n".join(lines[2:]) + "\n")
        answers += [_line(child) for _ in range(2)]
        child.send_signal(signal.SIGINT)
        assert child.wait(timeout=TIMEOUT_S) == 130
        err = child.stderr.read().decode()
    finally:
        child.kill()
        child.wait()
    _, values = parsed("".join(answers))
    np.testing.assert_allclose(values[:, 0], calibration.predict(readings[:4]), rtol=1e-9)
    assert "Traceback" not in err and f"streamed 4 readings from {path}" in err


@pytest.mark.slow
def test_a_reader_that_goes_away_ends_the_command_quietly(cal_path, readings, tmp_path):
    path = tmp_path / "many.csv"
    path.write_text("\n".join([HEADER_MW, *mw_lines(np.resize(readings, (3000, 3)))]) + "\n")
    with open(path, "rb") as source:
        child = subprocess.Popen(
            [str(SCRIPT), "stream", str(cal_path)],
            stdin=source,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            bufsize=0,
            env=CHILD_ENV,
        )
    try:
        assert _line(child).startswith("frequency_hz")
        child.stdout.close()  # as `| head -1` does
        assert child.wait(timeout=TIMEOUT_S) == 0
        err = child.stderr.read()
    finally:
        child.kill()
        child.wait()
    assert err == b""


@pytest.fixture()
def stdin(monkeypatch):
    """Give ``wavemeter stream`` run in this process these bytes on standard input."""

    def give(text: str) -> None:
        monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(text.encode())))

    return give


def test_thermal_readings_carry_their_temperature_column(capsys, stdin, tmp_path):
    device = wm.Interferometer.table1(3, seed=7).with_thermal("sin")
    powers, frequency, temperature = thermal_sweep(device, 200, NOISE_W, 1)
    thermal = wm.ThermalCalibrator().fit(powers, frequency, temperature_k=temperature)
    path = tmp_path / "thermal.wmcal.json"
    thermal.save(path)
    rows, kelvin = powers[::40], temperature[::40]
    lines = [
        ",".join([*(_text(v) for v in row), _text(t - 273.15)])
        for row, t in zip(rows, kelvin, strict=True)
    ]
    stdin("\n".join(["p1_w,p2_w,p3_w,Temp (C)", *lines]) + "\n")
    code, out, err = run_cli(capsys, f"stream {path} --quiet")
    assert code == 0 and err == ""
    _, values = parsed(out)
    expected = thermal.predict(rows, temperature_k=kelvin)
    # the temperature went through text in degrees Celsius and back: ~1e-13 K of rounding,
    # times the fringe's ~3 GHz/K, is ~1e-3 Hz
    np.testing.assert_allclose(values[:, 0], expected, rtol=0, atol=1.0)
    np.testing.assert_array_equal(values[:, 3], thermal.flags(rows, temperature_k=kelvin))
    stdin("p1_w,p2_w,p3_w\n1,1,1\n")
    err = one_error(*run_cli(capsys, f"stream {path}")[::2])
    assert "needs the chip temperature of each reading" in err and "--temperature" in err


def test_bad_calibration_or_header_is_one_error_line(capsys, stdin, cal_path, tmp_path):
    stdin("a,P1_mW,P2_mW\n1,2,3\n")
    code, out, err = run_cli(capsys, f"stream {cal_path}")
    assert out == ""
    assert "found 2 port column(s) (P1_mW, P2_mW)" in one_error(code, err)
    stdin("Q1_mW,Q2_mW,Q3_mW\n1,2,3\n")
    code, out, err = run_cli(capsys, f"stream {cal_path}")
    assert "--ports" in one_error(code, err) and out == ""
    stdin("p1_w,p2_w,p3_w\n1,2,3\n")
    code, _, err = run_cli(capsys, f"stream {tmp_path / 'missing.json'}")
    assert "missing.json" in one_error(code, err)
    stdin("")
    code, _, err = run_cli(capsys, f"stream {cal_path}")
    assert "no header line" in one_error(code, err)
