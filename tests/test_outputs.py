"""Outputs never destroy data: inputs, devices, existing files, signals, stdin and stdout.

Every command that writes checks its outputs before any work (not an input, also through
links; a regular file or ``-``; an existing file only with ``--force``), writes atomically,
and cleans up its temporary file on SIGTERM and SIGHUP as on Ctrl-C. ``-`` reads a data
file from stdin and writes the output table to stdout with nothing else there.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.atomic import atomic_path
from wavemeter.cli import main
from wavemeter.exceptions import InputError
from wavemeter.report.demo import DEMO_FILES, DEMO_SETUP

from .helpers import one_error, simulated_files
from .helpers import run_cli as run

SCRIPT = Path(sys.executable).with_name("wavemeter")


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    return simulated_files(tmp_path_factory.mktemp("outputs"), test_rows=300)


# ---------------------------------------------------------------------------- inputs are safe
@pytest.mark.parametrize("link", ["same", "symlink", "hardlink"])
def test_output_that_is_an_input_is_refused_and_the_input_kept(files, tmp_path, capsys, link):
    data = tmp_path / "data.csv"
    data.write_bytes(files["test"].read_bytes())
    sweep = tmp_path / "sweep.csv"
    sweep.write_bytes(files["sweep"].read_bytes())
    targets = {"same": (data, sweep)}
    if link == "symlink":
        (tmp_path / "d.csv").symlink_to(data)
        (tmp_path / "s.csv").symlink_to(sweep)
        targets[link] = (tmp_path / "d.csv", tmp_path / "s.csv")
    if link == "hardlink":
        os.link(data, tmp_path / "d.csv")
        os.link(sweep, tmp_path / "s.json")
        targets[link] = (tmp_path / "d.csv", tmp_path / "s.json")
    data_out, sweep_out = targets[link]
    before = data.read_bytes(), sweep.read_bytes()
    for command, target in (
        (f"measure {files['cal']} {data} -o {data_out} --force", data),
        (f"calibrate {sweep} -o {sweep_out} --force", sweep),
    ):
        err = one_error(*run(capsys, command)[::2])
        assert f"it is the input file {target}" in err
    assert (data.read_bytes(), sweep.read_bytes()) == before
    err = one_error(*run(capsys, f"measure {files['cal']} {data} -o {files['cal']} --force")[::2])
    assert "it is the input file" in err and wm.load_calibration(files["cal"]).n_ports_ == 3


@pytest.mark.parametrize("target", ["/dev/null", "folder", "fifo"])
def test_output_that_is_not_a_regular_file_is_refused(files, tmp_path, capsys, target):
    path = {"/dev/null": Path("/dev/null"), "folder": tmp_path, "fifo": tmp_path / "pipe"}[target]
    if target == "fifo":
        os.mkfifo(path)
    code, _, err = run(capsys, f"measure {files['cal']} {files['test']} -o {path} --force")
    err = one_error(code, err)
    assert str(path) in err
    assert Path("/dev/null").is_char_device()  # not turned into a regular file


def test_empty_output_name_is_a_clear_error(files, tmp_path, capsys):
    code, _, err = run(capsys, f"measure {files['cal']} {files['test']} -o ''")
    assert "output file name is empty" in one_error(code, err) and "Errno" not in err
    code, _, err = run(capsys, "simulate -o '' --samples 10")
    assert "output file name is empty" in one_error(code, err)


# ---------------------------------------------------------------------------- --force
@pytest.mark.parametrize("command", ["simulate", "calibrate", "measure"])
def test_existing_output_needs_force(files, tmp_path, capsys, command):
    out = tmp_path / ("out.wmcal.json" if command == "calibrate" else "out.csv")
    out.write_text("precious\n")
    line = {
        "simulate": f"simulate -o {out} --samples 20",
        "calibrate": f"calibrate {files['sweep']} -o {out}",
        "measure": f"measure {files['cal']} {files['test']} -o {out}",
    }[command]
    err = one_error(*run(capsys, line)[::2])
    assert f"{out} already exists" in err and err.rstrip().endswith("(use --force)")
    assert out.read_text() == "precious\n"
    code, _, err = run(capsys, f"{line} --force --quiet")
    assert code == 0, err
    assert out.read_text() != "precious\n"
    assert not list(tmp_path.glob(".*.tmp"))


def test_simulate_checks_every_target_before_writing_any(tmp_path, capsys):
    sweep, test = tmp_path / "s.csv", tmp_path / "s-test.csv"
    test.write_text("precious\n")
    err = one_error(*run(capsys, f"simulate -o {sweep} --test 10 --samples 20")[::2])
    assert f"{test} already exists" in err
    assert not sweep.exists() and test.read_text() == "precious\n"
    err = one_error(*run(capsys, f"simulate -o {sweep} --test 10 --test-out {sweep}")[::2])
    assert "give two different files" in err and not sweep.exists()
    err = one_error(*run(capsys, "simulate -o - --test 10")[::2])
    assert "--test-out" in err


def test_unknown_output_extensions_are_refused(files, tmp_path, capsys):
    for command, out in (
        (f"calibrate {files['sweep']} -o {{out}}", tmp_path / "cal.yaml"),
        ("simulate -o {out} --samples 20", tmp_path / "q.xlsx"),
        (f"measure {files['cal']} {files['test']} -o {{out}}", tmp_path / "f.xlsx"),
    ):
        err = one_error(*run(capsys, command.format(out=out))[::2])
        assert str(out) in err and not out.exists()


# ---------------------------------------------------------------------------- demo
def test_demo_replaces_only_its_own_files(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(DEMO_SETUP, "training_samples", 300)
    monkeypatch.setitem(DEMO_SETUP, "test_samples", 500)
    out = tmp_path / "demo"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    first = {name: (out / name).read_bytes() for name in DEMO_FILES}
    (out / "sweep.csv").write_text("stale\n")
    assert main(["demo", "--out", str(out), "--quiet", "--seed", "2"]) == 0  # again: no --force
    assert (out / "notes.txt").read_text() == "mine\n"
    assert sorted(path.name for path in out.iterdir()) == sorted([*DEMO_FILES, "notes.txt"])
    assert (out / "sweep.csv").read_bytes() != first["sweep.csv"]
    capsys.readouterr()
    (out / "results.json").unlink()
    (out / "results.json").mkdir()  # a demo file name that is not a regular file
    (out / "sweep.csv").write_text("kept\n")
    err = one_error(*run(capsys, f"demo --out {out}")[::2])
    assert str(out / "results.json") in err and "not a regular file" in err
    assert (out / "sweep.csv").read_text() == "kept\n"  # refused before any work


def test_demo_help_says_what_it_replaces(capsys):
    printed = run(capsys, "demo --help")[1]
    assert "replaces" in printed and "results.json" in printed


# ---------------------------------------------------------------------------- atomic_path
@pytest.mark.parametrize(
    "error", [ValueError("writer failed"), KeyboardInterrupt(), SystemExit(143)]
)
def test_atomic_path_leaves_nothing_on_any_exception(tmp_path, error):
    target = tmp_path / "out.csv"
    target.write_text("old\n")
    with pytest.raises(type(error)):
        with atomic_path(target) as temporary:
            assert temporary.parent == tmp_path and temporary.name.startswith(".out.csv.")
            temporary.write_text("partial")
            raise error
    assert sorted(path.name for path in tmp_path.iterdir()) == ["out.csv"]
    assert target.read_text() == "old\n"


def test_atomic_path_writes_with_the_usual_mode(tmp_path):
    old_umask = os.umask(0o027)
    try:
        with atomic_path(tmp_path / "out.csv") as temporary:
            temporary.write_text("new\n")
    finally:
        os.umask(old_umask)
    assert (tmp_path / "out.csv").read_text() == "new\n"
    assert (tmp_path / "out.csv").stat().st_mode & 0o777 == 0o640
    assert [path.name for path in tmp_path.iterdir()] == ["out.csv"]
    with pytest.raises(InputError, match="output file name is empty"):
        with atomic_path(""):
            pass
    with pytest.raises(InputError, match="is a folder"):
        with atomic_path(tmp_path):
            pass


# ---------------------------------------------------------------------------- signals
@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "exit_code"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)]
)
def test_signal_during_a_write_removes_the_temporary_file(tmp_path, signum, exit_code):
    out = tmp_path / "big.csv"
    process = subprocess.Popen(
        [str(SCRIPT), "simulate", "-o", str(out), "--samples", "1000000", "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    while sum(path.stat().st_size for path in tmp_path.glob(".big.csv.*.tmp")) < 1 << 20:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.005)
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == exit_code, err
    assert list(tmp_path.iterdir()) == []  # neither the temporary file nor a partial output
    assert b"Traceback" not in err


def test_main_restores_the_signal_handlers(capsys):
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)
    assert main(["--help"]) == 0
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)) == before


# ---------------------------------------------------------------------------- stdin, stdout
@pytest.mark.slow
def test_stdin_to_stdout_is_the_same_table_as_files(files, tmp_path):
    out = tmp_path / "f.csv"
    keep = ["--keep", "true_frequency_hz"]
    assert main(["measure", str(files["cal"]), str(files["test"]), "-o", str(out), *keep]) == 0
    done = subprocess.run(
        [str(SCRIPT), "measure", str(files["cal"]), "-", "-o", "-", *keep],
        input=files["test"].read_bytes(),
        capture_output=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == out.read_bytes()  # nothing else on stdout
    assert done.stderr.decode().startswith("wrote stdout (300 rows)")


@pytest.mark.slow
def test_stdin_sweep_and_calibration_to_stdout(files, tmp_path):
    done = subprocess.run(
        [str(SCRIPT), "calibrate", "-", "-o", "-"],
        input=files["sweep"].read_bytes(),
        capture_output=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    cal = tmp_path / "c.wmcal.json"
    cal.write_bytes(done.stdout)
    reference = wm.load_calibration(files["cal"])
    assert wm.load_calibration(cal).fsr_hz_ == reference.fsr_hz_
    assert done.stderr.decode().startswith("calibrated <stdin>: 400 rows")


def test_stdin_errors_name_stdin(files, capsys, monkeypatch, tmp_path):
    import io

    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"time_s,p1,p2\n0,1,2\n")))
    out = tmp_path / "f.csv"
    err = one_error(*run(capsys, f"measure {files['cal']} - -o {out}")[::2])
    assert err.startswith("error: <stdin>: ") and "/tmp" not in err and not out.exists()
    err = one_error(*run(capsys, f"measure - {files['test']} -o {out}")[::2])
    assert "calibration is read from its file" in err


def test_pipe_input_is_read_once(files, tmp_path, capsys):
    fifo, out = tmp_path / "pipe.csv", tmp_path / "f.csv"
    os.mkfifo(fifo)

    def feed():
        with open(fifo, "wb") as pipe:
            pipe.write(files["test"].read_bytes())

    writer = threading.Thread(target=feed)
    writer.start()
    code, _, err = run(capsys, f"measure {files['cal']} {fifo} -o {out}")
    writer.join(timeout=30)
    assert code == 0, err
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (300, 5) and np.isfinite(data).all()


def test_bare_wavemeter_prints_help_and_succeeds(capsys):
    code, printed, err = run(capsys, "")
    assert code == 0 and err == ""
    assert (
        printed.startswith("Usage: wavemeter") and "Commands" in printed and "calibrate" in printed
    )
