"""Calibrators of another package through every command (issue 27 item 2).

The toy plug-in package ``tests/plugins/wavemeter_toy`` is installed as a user installs one
(``pip install --no-deps --no-build-isolation --target``, offline), and every command runs
as a subprocess of the real command line with it on ``PYTHONPATH``: ``toy_fixed_delay``
(the documented minimal interface: the learned map at the design FSR, no delay search)
and ``toy_ml`` (``wm.Calibrator`` under a tag of its own, the cone maximum-likelihood
retrieval by default). At the device's true FSR the fixed-delay fit is the learned fit
without the search, so its error on the test readings is the learned calibration's: both
are about the Cramer-Rao bound times sqrt(1 + 3/N).
"""

from __future__ import annotations

import csv
import json
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.jobs.calibrate import DIFFERING_FIELDS
from wavemeter.simulation import Scenario

# about 15 subprocesses of a few seconds each on a loaded 2-core machine
pytestmark = pytest.mark.slow

PLUGIN = Path(__file__).parent / "plugins" / "wavemeter_toy"
SEED = 3
SAMPLES = 2001
TEST_READINGS = 2000
#: the toy's RMS error over the learned calibration's on the same test readings: the same
#: fit at the true FSR, so equal but for the learned FSR's error (the brief's 1.2)
RMS_RATIO = 1.2
TIMEOUT_S = 600


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The toy package installed into a folder of its own, as a user would, offline."""
    root = tmp_path_factory.mktemp("plugin")
    source = root / "wavemeter_toy"
    shutil.copytree(PLUGIN, source)  # pip builds in the source tree: not in the repository
    target = root / "site"
    command = [sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation"]
    command += ["--no-index", "--quiet", "--disable-pip-version-check"]
    done = subprocess.run(
        [*command, "--target", str(target), str(source)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return target


def wavemeter(site: Path, folder: Path, command: str, *args, stdin: str | None = None):
    """``python -m wavemeter COMMAND ARGS`` in ``folder`` with the plug-in installed."""
    env = {**os.environ, "PYTHONPATH": str(site), "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "wavemeter", *shlex.split(command), *map(str, args)],
        cwd=folder,
        env=env,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )


def ok(site: Path, folder: Path, command: str, *args, stdin: str | None = None) -> str:
    done = wavemeter(site, folder, command, *args, stdin=stdin)
    assert done.returncode == 0, done.stderr
    return done.stdout


def text_columns(path: Path) -> dict[str, list[str]]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return {name: [row[k] for row in rows[1:]] for k, name in enumerate(rows[0])}


def columns(path: Path) -> dict[str, np.ndarray]:
    return {name: np.array(values, dtype=float) for name, values in text_columns(path).items()}


@pytest.fixture(scope="module")
def files(site, tmp_path_factory) -> dict:
    """A simulated sweep and test file, calibrated with the learned method and both toys."""
    folder = tmp_path_factory.mktemp("toy")
    simulate = f"simulate -o sweep.csv --seed {SEED} --samples {SAMPLES} --test {TEST_READINGS}"
    ok(site, folder, simulate, "--quiet")
    true_fsr_hz = Scenario(seed=SEED).device.true_fsr_hz
    calibrations = {
        "learned": "--method learned",
        "toy_fixed_delay": f"--method toy_fixed_delay --fsr {true_fsr_hz!r}Hz",
        "toy_ml": "--method toy_ml",
    }
    printed = {
        name: ok(site, folder, f"calibrate sweep.csv -o {name}.wmcal.json {options}")
        for name, options in calibrations.items()
    }
    return {"folder": folder, "fsr_hz": true_fsr_hz, "printed": printed, "options": calibrations}


def test_the_plugins_are_methods_of_the_command_line(site, files):
    folder = files["folder"]
    shown = " ".join(ok(site, folder, "calibrate --help").split())
    assert "|toy_fixed_delay|toy_ml]" in shown
    done = wavemeter(site, folder, "calibrate sweep.csv -o x.wmcal.json --method toy")
    assert done.returncode == 2 and "toy_fixed_delay, toy_ml" in done.stderr
    # a setting the toy does not have is refused, naming the methods that have it
    done = wavemeter(
        site,
        folder,
        "calibrate sweep.csv -o x.wmcal.json --method toy_fixed_delay --fsr-tolerance 0.1",
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "method 'toy_fixed_delay' has no setting fsr_tolerance" in done.stderr
    assert "toy_ml" in done.stderr and "--fsr-tolerance" in done.stderr
    assert not (folder / "x.wmcal.json").exists()


def test_calibrate_info_and_the_library_load_the_plugin(site, files):
    folder = files["folder"]
    assert "method           toy_fixed_delay" in files["printed"]["toy_fixed_delay"]
    info = ok(site, folder, "info toy_fixed_delay.wmcal.json")
    assert "toy_fixed_delay" in info and "FSR              " in info
    script = (
        "import json, wavemeter as wm\n"
        "from wavemeter.io import read_table\n"
        "test = read_table('sweep-test.csv')\n"
        "out = {}\n"
        "for name in ('toy_fixed_delay', 'toy_ml'):\n"
        "    cal = wm.load_calibration(name + '.wmcal.json')\n"
        "    error = wm.frequency_error_hz(cal.predict(test.powers_w), test.x_hz, cal.fsr_hz_)\n"
        "    out[name] = [type(cal).__name__, cal.method, cal.fsr_hz_,\n"
        "                 float(abs(error).max() / cal.calibration_rms_hz_)]\n"
        "print(json.dumps(out))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    done = subprocess.run(
        [sys.executable, "-c", script],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    loaded = json.loads(done.stdout)
    name, method, fsr_hz, worst = loaded["toy_fixed_delay"]
    assert (name, method, fsr_hz) == ("FixedDelayCalibrator", "toy_fixed_delay", files["fsr_hz"])
    assert loaded["toy_ml"][:2] == ["MlCalibrator", "toy_ml"]
    # Gaussian errors of about the calibration's RMS: 2000 readings stay within 5 of it
    assert worst < 5 and loaded["toy_ml"][3] < 5


def _measured_rms_hz(site, folder: Path, name: str, fsr_hz: float) -> tuple[float, dict]:
    """Measure the test file with a calibration: the RMS error modulo the FSR (Hz) and
    the columns written."""
    out = f"{name}-f.csv"
    ok(
        site,
        folder,
        f"measure {name}.wmcal.json sweep-test.csv -o {out} --quiet",
        "--keep",
        "true_frequency_hz",
    )
    written = columns(folder / out)
    error = wm.frequency_error_hz(written["frequency_hz"], written["true_frequency_hz"], fsr_hz)
    return float(np.sqrt(np.mean(error**2))), written


def test_measure_stream_and_evaluate_give_the_learned_precision(site, files):
    folder = files["folder"]
    learned = wm.load_calibration(folder / "learned.wmcal.json")
    rms = {}
    for name, fsr_hz in (("learned", learned.fsr_hz_), ("toy_fixed_delay", files["fsr_hz"])):
        rms[name], written = _measured_rms_hz(site, folder, name, fsr_hz)
        assert np.all(written["flags"] == 0)  # clean readings: nothing to report
    assert 1 / RMS_RATIO < rms["toy_fixed_delay"] / rms["learned"] < RMS_RATIO
    # the same readings streamed on stdin: the same frequencies, flags 0
    lines = (folder / "sweep-test.csv").read_text().splitlines()[:51]
    header = lines[0].split(",")
    ports = [header.index(name) for name in ("p1_w", "p2_w", "p3_w")]
    text = "\n".join(",".join(line.split(",")[k] for k in ports) for line in lines) + "\n"
    streamed = ok(site, folder, "stream toy_fixed_delay.wmcal.json", stdin=text).splitlines()
    assert streamed[0] == "frequency_hz,wavelength_nm,frequency_std_hz,flags"
    values = np.array([row.split(",") for row in streamed[1:]], dtype=float)
    measured = columns(folder / "toy_fixed_delay-f.csv")
    np.testing.assert_array_equal(values[:, 0], measured["frequency_hz"][:50])
    assert np.all(values[:, 3] == 0) and np.all(np.isnan(values[:, 2]))  # it gives no std
    evaluate = "evaluate toy_fixed_delay.wmcal.json sweep-test.csv --compare learned.wmcal.json"
    report = json.loads(ok(site, folder, evaluate, "--json"))
    methods = report["methods"]
    assert methods["toy_fixed_delay"]["rms_mod_fsr_hz"] == pytest.approx(
        rms["toy_fixed_delay"], rel=1e-9
    )
    assert methods["learned (learned.wmcal.json)"]["rms_mod_fsr_hz"] == pytest.approx(
        rms["learned"], rel=1e-9
    )


def _report(site, folder: Path, name: str) -> tuple:
    page = folder / f"{name}-report.html"
    command = f"report {name}.wmcal.json sweep.csv sweep-test.csv -o {page.name} --quiet"
    done = wavemeter(site, folder, command)
    return done, page


def test_report_of_a_subclass_of_the_learned_calibrator(site, files):
    folder = files["folder"]
    done, page = _report(site, folder, "toy_ml")
    assert done.returncode == 0, done.stderr
    text = page.read_text()
    names = {path.stem.rsplit("-", 1)[1] for path in folder.glob("toy_ml-report-*.png")}
    assert names >= {"fringes", "object_space", "retrieved", "residual", "histogram"}
    assert all(f'alt="{name} figure"' in text for name in names) and "toy_ml" in text


def test_report_of_the_minimal_interface(site, files):
    folder = files["folder"]
    done, page = _report(site, folder, "toy_fixed_delay")
    assert done.returncode == 0, done.stderr
    assert page.exists() and sorted(folder.glob("toy_fixed_delay-report-*.png"))


def test_reanchor_is_refused_without_the_capability_and_works_with_it(site, files):
    folder = files["folder"]
    reanchor = "reanchor {}.wmcal.json sweep-test.csv --x true_frequency_hz -o {}"
    refused = wavemeter(site, folder, reanchor.format("toy_fixed_delay", "re-toy.wmcal.json"))
    assert refused.returncode == 2 and refused.stdout == ""
    assert refused.stderr.count("\n") == 1 and refused.stderr.startswith("error: ")
    assert "cannot be re-anchored" in refused.stderr and "toy_ml" in refused.stderr
    assert not (folder / "re-toy.wmcal.json").exists()
    printed = ok(site, folder, reanchor.format("toy_ml", "re-ml.wmcal.json"))
    assert "re-anchored toy_ml.wmcal.json" in printed
    assert json.loads((folder / "re-ml.wmcal.json").read_text())["method"] == "toy_ml"


def test_fleet_calibrate_writes_what_calibrate_writes(site, files):
    folder = files["folder"]
    options = files["options"]["toy_fixed_delay"]
    ok(site, folder, f"fleet calibrate sweep.csv -o fleet --workers 0 --quiet {options}")
    summary = text_columns(folder / "fleet" / "summary.csv")
    assert summary["status"] == ["ok"] and summary["device"] == ["sweep"]
    fleet = json.loads((folder / "fleet" / "sweep.wmcal.json").read_text())
    single = json.loads((folder / "toy_fixed_delay.wmcal.json").read_text())
    assert DIFFERING_FIELDS == ("created_utc", "metadata.sweep_file")
    for document in (fleet, single):
        del document["created_utc"]
    assert fleet == single  # the sweep named alike by both commands here
