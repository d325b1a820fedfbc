"""The main job, run as a user runs it, and the command line's error convention."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.cli import main


@pytest.mark.slow
def test_demo_writes_its_files_and_beats_conventional(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "learned" in printed and "conventional" in printed and "CRLB" in printed
    summary = json.loads((out / "results.json").read_text())
    learned = summary["methods"]["learned"]["rms_hz"] / summary["crlb_rms_hz"]
    conventional = summary["methods"]["conventional"]["rms_hz"] / summary["crlb_rms_hz"]
    # 20000 test samples: the ratio is known to ~0.5 %; the estimator's excess is < 8 %
    assert 0.98 < learned < 1.08
    assert conventional > 10 * learned
    cal = wm.load_calibration(out / "learned.wmcal.json")
    sweep = np.loadtxt(out / "sweep.csv", delimiter=",", skiprows=1)
    header = (out / "sweep.csv").read_text().splitlines()[0]
    assert header == "frequency_hz,p1_w,p2_w,p3_w"
    assert sweep.shape == (2001, 4)
    error = wm.frequency_error_hz(cal.predict(sweep[:, 1:]), sweep[:, 0], cal.fsr_hz_)
    assert np.sqrt(np.mean(error**2)) == np.float64(cal.calibration_rms_hz_)


@pytest.mark.slow
def test_installed_script_runs_and_reports_user_errors(tmp_path):
    script = Path(sys.executable).with_name("wavemeter")
    env = {**os.environ, "COLUMNS": "120"}
    done = subprocess.run(
        [str(script), "demo", "--quiet", "--out", str(tmp_path / "d")],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    done = subprocess.run(
        [str(script), "demo", "--out", str(blocked)], capture_output=True, text=True, check=False
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and str(blocked) in lines[0]


def test_unknown_command_is_a_usage_error(capsys):
    assert main(["frobnicate"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "frobnicate" in err[0]


@pytest.mark.slow
def test_quickstart_example_runs_and_retrieves_frequencies():
    example = Path(__file__).resolve().parents[1] / "examples" / "quickstart.py"
    done = subprocess.run(
        [sys.executable, str(example)], capture_output=True, text=True, check=True
    )
    errors_mhz = [float(line.split("error")[1].split()[0]) for line in done.stdout.splitlines()[1:]]
    # three readings at 0.5 mW: CRLB ~ 20 MHz each; allow 5 standard deviations
    assert len(errors_mhz) == 3 and max(abs(e) for e in errors_mhz) < 100
