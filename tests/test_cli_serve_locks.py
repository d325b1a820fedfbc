"""`wavemeter serve`'s lock and reference options: bad values are one ``error:`` line and
exit code 2, before anything is served."""

from __future__ import annotations

import pytest

from .helpers import run_cli

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

LOCAL = "--publish tcp://127.0.0.1:0 --control tcp://127.0.0.1:0 --http off"


@pytest.mark.parametrize(
    "options, message",
    [
        ("--simulate --chip-ramp 2K", "--chip-ramp '2K': expected KELVIN/DURATION"),
        ("--simulate --chip-ramp 2K/0s", "the duration must be > 0"),
        ("--simulate --chip-ramp 2K/fast", "--chip-ramp duration 'fast'"),
        ("--simulate --reference 193.414THz", "expected N=FREQUENCY"),
        ("--simulate --reference 1=193.414THz", "channels 0 .. 0 (--channels)"),
        ("--simulate --channels 2 --reference 1=fast", "--reference 'fast'"),
        ("--simulate --channels 2 --reference 1=194THz", "inside the calibration's span"),
        ("--simulate --output 0", "expected N=NAME"),
        ("--simulate --output 0=dac:device", "option 'device' is not KEY=VALUE"),
        ("--simulate --output 0=nope", "no output plug-in 'nope'"),
        ("--simulate --output 0=nope --output 0=nope", "no output plug-in 'nope'"),
    ],
)
def test_bad_lock_options_are_one_error_line(capsys, options, message):
    code, out, err = run_cli(capsys, f"serve {options} {LOCAL}")
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err


def test_a_chip_ramp_needs_the_simulated_meter(capsys, tmp_path):
    calibration = tmp_path / "chip.wmcal.json"
    calibration.write_text("{}")
    code, _, err = run_cli(capsys, f"serve {calibration} --chip-ramp 2K/60s {LOCAL}")
    assert code == 2 and "--chip-ramp warms the simulated chip" in err
