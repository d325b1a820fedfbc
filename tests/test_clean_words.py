"""Clean words (issue 29, item 10): what the package prints reads as words and numbers.

A catalogue of the errors and warnings the command line and the library give (faulty
sweeps of every kind the simulator makes, bad options, bad files, wrong units) is run and
everything it prints is scanned: no Python repr (``np.float64(...)``, ``array(...)``,
``{'key': ...}``, ``None``), no traceback, no temporary file name, no hint given twice, no
raw key of the package's files; every refusal is one ``error:`` line with exit code 2. The
single rules behind it (a noise level not significant is an upper limit, the fleet says
what it calibrated now, a read-only folder is named, not the temporary file) have their
own tests here.
"""

from __future__ import annotations

import html
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import shown

from .helpers import one_error, run_cli, simulated_files

#: what no output may hold: Python reprs, tracebacks, temporary files, doubled hints, raw
#: keys of the calibration file and the diagnostics
FORBIDDEN = {
    "numpy repr": re.compile(r"\bnp\.\w+\(|\barray\(|\bdtype="),
    "dict repr": re.compile(r"\{'\w+':"),
    "None": re.compile(r"\bNone\b"),
    "traceback": re.compile(r"Traceback \(most recent call last\)"),
    "temporary file": re.compile(r"\.tmp\b"),
    "doubled hint": re.compile(r"\((--?[\w-]+)\)\s*\(\1\b|\((\w+)\) \(\2:"),
    "raw key": re.compile(
        r"\b(phase_coefficient_\d\w*|stage_\d_fsr_hz|reanchor_file|dropped_rows|"
        r"crlb_rms_hz|calibrate_options|noise_method|second_difference|cost_w2)\b"
    ),
}


def _unclean(text: str) -> list[str]:
    return [
        f"{name}: {match.group(0)!r} in ...{text[max(match.start() - 60, 0) : match.end() + 40]}..."
        for name, pattern in FORBIDDEN.items()
        for match in pattern.finditer(text)
    ]


def _page_text(path: Path) -> str:
    """An HTML page's words: scripts and styles dropped, tags removed."""
    page = path.read_text(encoding="utf-8")
    page = re.sub(r"<(script|style)\b.*?</\1>", "", page, flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", " ", page))


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    return simulated_files(tmp_path_factory.mktemp("words"), test_rows=300)


#: faulty sweeps the simulator makes (options beside ``--samples``), each a calibration
#: warning of its own cause
FAULTS = {
    "power_drift": "--power-drift 0.05",
    "detector_offset": "--dark-offset 20uW,0,0 --power-fluctuation 0.2",
    "phase_drift": "--thermal-drift 2 --platform sin",
    "dispersion": "--dispersion 1e-26 --span-fsr 8",
    "partial_span": "--span-fsr 0.6",
    "unequal_noise": "--port-noise 5e-7,5e-7,5e-6",
}


@pytest.mark.slow
@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_every_warning_of_a_faulty_sweep_reads_clean(fault, tmp_path, capsys):
    sweep, cal = tmp_path / "sweep.csv", tmp_path / "chip.wmcal.json"
    code, out, err = run_cli(
        capsys, f"simulate -o {sweep} --samples 3000 --seed 3 --test 300 {FAULTS[fault]}"
    )
    assert code == 0, err
    code, out, err = run_cli(capsys, f"calibrate {sweep} -o {cal} --fsr 50GHz")
    assert code == 0, err
    assert "warning" in err + out, f"the {fault} sweep calibrated without a warning"
    printed = [out, err]
    code, out, err = run_cli(capsys, f"info {cal}")
    printed += [out, err]
    test = tmp_path / "sweep-test.csv"
    code, out, err = run_cli(capsys, f"evaluate {cal} {test} --sweep {sweep}")
    printed += [out, err]
    code, out, err = run_cli(capsys, f"measure {cal} {test} -o {tmp_path / 'f.csv'}")
    printed += [out, err]
    assert _unclean("\n".join(printed)) == []


@pytest.mark.slow
def test_the_report_reads_clean(files, tmp_path, capsys):
    page = tmp_path / "report.html"
    code, _, err = run_cli(
        capsys, f"report {files['cal']} {files['sweep']} {files['test']} -o {page} --quiet"
    )
    assert code == 0, err
    text = _page_text(page)
    assert "Diagnostics of the calibration" in text
    assert _unclean(text) == []


def _broken_calibration(files, folder: Path) -> Path:
    """The learned calibration with a detector noise no meter has (issue 29: 5e-307 W)."""
    document = json.loads(files["cal"].read_text(encoding="utf-8"))
    noise = document["state"]["port_noise_std_w"]
    document["state"]["port_noise_std_w"] = [5e-307, *noise[1:]]
    path = folder / "broken.wmcal.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


#: refused commands: each prints one clean ``error:`` line (``{sweep}``, ``{test}``,
#: ``{cal}``, ``{broken}``, ``{out}`` are filled in)
REFUSED = {
    "missing file": "calibrate {out}/missing.csv -o {out}/c.wmcal.json",
    "FSR out of range": "calibrate {sweep} -o {out}/c.wmcal.json --fsr 50",
    "coarse to learned": "measure {cal} {test} -o {out}/f.csv --coarse-frequency 1THz",
    "ports chosen wrongly": "measure {cal} {test} -o {out}/f.csv --ports p1_w,p2_w",
    "broken calibration file": "measure {broken} {test} -o {out}/f.csv",
    "method setting of another method": "calibrate {sweep} -o {out}/c.wmcal.json --phase-order 2",
    "unknown method": "calibrate {sweep} -o {out}/c.wmcal.json --method nonsense",
    "band of no width": "design --band 195THz:195THz --finest-fsr 50GHz",
    "info of a data file": "info {sweep}",
    "reanchor without frequency": "reanchor {cal} {test} -o {out}/r.wmcal.json",
    "noise without a rate": "noise {cal} {test} -o {out}/n.html",
    "output folder missing": "measure {cal} {test} -o {out}/nowhere/f.csv",
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_every_refusal_is_one_clean_error_line(case, files, tmp_path, capsys):
    names = {
        "sweep": files["sweep"],
        "test": files["test"],
        "cal": files["cal"],
        "broken": _broken_calibration(files, tmp_path),
        "out": tmp_path,
    }
    code, out, err = run_cli(capsys, REFUSED[case].format(**names))
    line = one_error(code, err)
    assert out == ""
    assert _unclean(line) == []
    assert not any(path.suffix == ".tmp" for path in tmp_path.iterdir())


def test_library_messages_show_numbers_as_numbers():
    device = wm.Interferometer.table1(ports=3, seed=7)
    f_hz = device.sweep_hz(200)
    powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    messages = []
    for call in (
        lambda: wm.design_cascade((np.float64(195e12), np.float64(191e12)), 50e9),
        lambda: wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz / 1e12),  # an axis in THz
        lambda: wm.Calibrator(fsr_hz=np.float64(-5e10)).fit(powers, f_hz),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                call()
            except wm.WavemeterError as error:
                messages.append(str(error))
    assert len(messages) == 3, messages
    assert _unclean("\n".join(messages)) == []
    assert "THz" in messages[1]  # the unit is named, not an FSR in 0.05 Hz


def test_shown_gives_numbers_as_people_write_them():
    assert shown(np.float64(0.0515011)) == "0.0515011"
    assert shown(np.int64(3)) == "3"
    assert shown(np.array([1.0, np.nan])) == "(1, nan)"
    assert shown("nm") == "'nm'"
    assert shown(None) == "nothing"
    assert shown(list(range(10))) == "(0, 1, 2, 3, 4, 5, 6, 7, ...)"


def test_shown_quotes_a_files_field_as_the_file_holds_it():
    """The same formatter, for a value read from a file: JSON with every digit, so that the
    message quotes what a search of the file finds; cut to 80 characters with ``...``."""
    assert shown(np.float64(0.051501123456789), as_in_file=True) == "0.051501123456789"
    assert shown([1.0, None, float("nan")], as_in_file=True) == "[1.0, null, NaN]"
    assert shown({"a": [1, 2]}, as_in_file=True) == '{"a": [1, 2]}'
    assert shown(None, as_in_file=True) == "null" and shown(True, as_in_file=True) == "true"
    assert shown("nm", as_in_file=True) == "'nm'"
    assert shown(np.arange(3.0), as_in_file=True) == "[0.0, 1.0, 2.0]"
    long = shown(list(range(100)), as_in_file=True)
    assert len(long) == 80 and long.endswith("...") and long.startswith("[0, 1, 2")


def test_a_read_only_folder_is_named_not_the_temporary_file(tmp_path, monkeypatch):
    from wavemeter.atomic import atomic_path

    real_open = __import__("os").open

    def refusing_open(path, flags, *args):
        if str(path).endswith(".tmp"):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, flags, *args)

    monkeypatch.setattr("os.open", refusing_open)
    target = tmp_path / "out.csv"
    with pytest.raises(wm.InputError) as caught, atomic_path(target):
        pass
    message = str(caught.value)
    assert message.startswith(f"cannot write {target}: folder {tmp_path} takes no new file")
    assert ".tmp" not in message and "permission denied" in message


@pytest.mark.slow
def test_a_noise_level_not_significant_is_an_upper_limit(tmp_path, capsys):
    """A laser without random-walk FM: its fitted h_-2 scatters about zero and may come out
    negative; the report gives an upper limit, never a negative level."""
    sweep, cal = tmp_path / "sweep.csv", tmp_path / "chip.wmcal.json"
    code, _, err = run_cli(
        capsys,
        f"simulate -o {sweep} --samples 2000 --seed 2 --laser 16384 --laser-rate 10MHz "
        "--white-fm 1e4 --random-walk-fm 0 --quiet",
    )
    assert code == 0, err
    assert run_cli(capsys, f"calibrate {sweep} -o {cal} --quiet")[0] == 0
    page = tmp_path / "noise.html"
    laser = tmp_path / "sweep-laser.csv"
    code, _, err = run_cli(capsys, f"noise {cal} {laser} -o {page} --rate 10MHz --quiet")
    assert code == 0, err
    text = " ".join(_page_text(page).split())
    level = re.search(r"random-walk FM h₋₂ (\S+)", text)
    assert level is not None, text[:2000]
    assert level.group(1) == "<", level.group(0)  # no random-walk FM: not significant
    assert _unclean(text) == []


@pytest.mark.slow
def test_the_fleet_says_what_it_calibrated_now(tmp_path, capsys):
    folder = tmp_path / "wafer"
    folder.mkdir()
    for seed in (1, 2):
        code, _, err = run_cli(
            capsys, f"simulate -o {folder / f'chip{seed}.csv'} --samples 400 --seed {seed} --quiet"
        )
        assert code == 0, err
    out = tmp_path / "cal"
    code, printed, err = run_cli(capsys, f"fleet calibrate {folder} -o {out} --workers 0")
    assert code == 0, err
    assert f"calibrated 2 of 2 devices into {out} (0 failed)" in printed
    code, printed, err = run_cli(capsys, f"fleet calibrate {folder} -o {out} --workers 0")
    assert code == 0, err
    assert "0 calibrated now, 2 kept from an earlier run, 0 failed" in printed
    assert "resumed" not in printed


def test_the_scan_sees_what_it_forbids():
    seen = _unclean(
        "got np.float64(3.5); offset (W): None; {'retrieval': 'ml'}; /a/.out.csv.1f.tmp; "
        "name them (ports) (ports: --ports); phase_coefficient_2_s2"
    )
    assert sorted(line.split(":")[0] for line in seen) == sorted(
        ["numpy repr", "None", "dict repr", "temporary file", "doubled hint", "raw key"]
    )
