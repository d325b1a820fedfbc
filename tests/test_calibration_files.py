"""Calibration files as untrusted input: every number checked, reading bounded, and `info`.

Each bad file gives one FileFormatError that names the file and the field (issue 16,
items 4 and 5); none loads into a calibrator that predicts garbage.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import MAX_DEPTH, MAX_INTEGER_DIGITS, SCHEMA_VERSION

from .helpers import NOISE_W, POWER_W
from .helpers import run_cli as run

#: a hang guard for reading a device or a crafted document (each takes well under a second)
HANG_GUARD_S = 5.0


@pytest.fixture(scope="module")
def sweep():
    device = wm.Interferometer.table1(3, seed=9)
    frequency = device.sweep_hz(501)
    return device, frequency, device.powers(frequency, POWER_W, NOISE_W, rng=9)


@pytest.fixture(scope="module")
def documents(sweep, tmp_path_factory):
    """Saved documents of a learned, a conventional and an ellipse calibration."""
    _, frequency, readings = sweep
    folder = tmp_path_factory.mktemp("files")
    result = {}
    for name, cal in (
        ("learned", wm.Calibrator(50e9)),
        ("conventional", wm.ConventionalCalibrator(50e9)),
        ("ellipse", wm.EllipseCalibrator(50e9)),
    ):
        cal.fit(readings, frequency).save(folder / f"{name}.json")
        result[name] = json.loads((folder / f"{name}.json").read_text())
    return result


def write(path: Path, document) -> Path:
    path.write_text(json.dumps(document))  # NaN and Infinity literals allowed, as a file may
    return path


def _rank_two(document):
    document["state"]["map"] = [[row[0], row[1], row[0]] for row in document["state"]["map"]]


@pytest.mark.parametrize(
    ("name", "mutate", "match"),
    [
        (
            "conventional",
            lambda d: d["state"].update(phase_origin_rad=math.nan),
            "field 'phase_origin_rad' must be a finite number",
        ),
        (
            "conventional",
            lambda d: d["state"].update(phase_origin_rad=7.0),
            r"'phase_origin_rad' \(the phase origin\) must be >= -3.142 rad and <= 3.142 rad",
        ),
        (
            "learned",
            lambda d: d["state"].update(map=[[0.0] * 3] * 3),
            r"field 'map' \(the map\) must give the map's largest singular value between 1e-18",
        ),
        ("learned", _rank_two, "map must have full rank 3"),
        (
            "learned",
            lambda d: d["state"].update(map=[["1", "2", "3"]] * 3),
            "field 'map' must hold numbers only",
        ),
        (
            "learned",
            lambda d: d["state"].update(noise_std_w=math.nan),
            "field 'noise_std_w' must be a finite number",
        ),
        (
            "learned",
            lambda d: d["state"].update(noise_std_w=-1e-7),
            r"'noise_std_w' \(a detector noise standard deviation\) must be > \d.\d+e-22 W",
        ),
        ("learned", lambda d: d.update(center_hz=2.0), "'center_hz' must be an optical frequency"),
        ("learned", lambda d: d.update(fsr_hz=-5e10), "'fsr_hz' must be >= 1000 Hz"),
        ("learned", lambda d: d.update(fsr_hz=math.inf), "'fsr_hz' must be a finite number"),
        ("learned", lambda d: d["span_hz"].reverse(), r"'span_hz' must be \[low, high\]"),
        (
            "learned",
            lambda d: d["state"].update(delay_s=d["state"]["delay_s"] * 1.01),
            r"field 'delay_s' \(the delay\) must be >= \d\.\d+e-11 s and <= .* times the "
            r"delay 1 / fsr_hz",
        ),
        ("learned", lambda d: d.update(metadata=[1, 2]), "'metadata' must be an object"),
        ("learned", lambda d: d.update(diagnostics="fine"), "'diagnostics' must be an object"),
        ("learned", lambda d: d.update(port_names=["a", 2, "c"]), "'port_names' must list 3"),
        ("learned", lambda d: d.update(n_samples=2), "'n_samples' must be an integer >= 4"),
        ("learned", lambda d: d.update(n_ports=True), "'n_ports' must be an integer >= 3"),
        ("learned", lambda d: d.update(created_utc=[]), "'created_utc' must be a string"),
        (
            "learned",
            lambda d: d["params"].update(fsr_tolerance=5),
            r"parameters do not fit method 'learned': fsr_tolerance must be in \(0, 1.0\)",
        ),
        ("ellipse", lambda d: d["params"].update(ports=[0, 7]), r"ports \[0, 7\] must index"),
        (
            "ellipse",
            lambda d: d["state"].pop("ellipse"),
            "field .ellipse. must be an object, got null",
        ),
    ],
)
def test_bad_numbers_are_refused_naming_the_field(documents, tmp_path, name, mutate, match):
    document = json.loads(json.dumps(documents[name]))
    mutate(document)
    path = write(tmp_path / "bad.wmcal.json", document)
    with pytest.raises(wm.FileFormatError, match=match) as info:
        wm.load_calibration(path)
    assert str(info.value).startswith(f"{path}: ")


def test_a_refused_field_is_quoted_as_the_file_holds_it(documents, tmp_path):
    """One formatter (``wavemeter.exceptions.shown``) quotes values everywhere; a field of a
    file is quoted as the file holds it (JSON, every digit, cut to 80 characters with
    ``...``), so that a search of the file finds it, where a message of the library shows
    numbers to 6 digits."""
    document = json.loads(json.dumps(documents["learned"]))
    digits = 1.2345678912345e-07
    document["state"]["map"][0][1] = "dark"
    path = write(tmp_path / "bad.wmcal.json", document)
    with pytest.raises(wm.FileFormatError) as info:
        wm.load_calibration(path)
    quoted = str(info.value).split("got ", 1)[1]
    assert quoted.endswith("...") and len(quoted) == 80
    assert quoted[:-3] in path.read_text()  # the file's own text, cut
    document = json.loads(json.dumps(documents["learned"]))
    document["state"]["noise_std_w"] = [digits, None]
    path = write(tmp_path / "list.wmcal.json", document)
    with pytest.raises(wm.FileFormatError, match=r"got \[1\.2345678912345e-07, null\]$"):
        wm.load_calibration(path)
    assert "1.2345678912345e-07" in path.read_text()


def test_files_without_the_new_fields_still_load(documents, sweep, tmp_path):
    """No diagnostics, no delay standard error: what 0.1 wrote (tests/data/v0.1 has more)."""
    document = json.loads(json.dumps(documents["learned"]))
    document.pop("diagnostics")
    document["state"].pop("delay_std_s")
    cal = wm.load_calibration(write(tmp_path / "old.wmcal.json", document))
    assert cal.diagnostics_ == {} and cal.delay_std_s_ is None
    assert cal.summary()["fsr_hz"].stderr is None
    assert np.all(np.isfinite(cal.predict(sweep[2])))


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 100_000])
def test_deep_nesting_is_refused_quickly(tmp_path, depth):
    path = tmp_path / "deep.json"
    path.write_text("[" * depth + "]" * depth)
    start = time.perf_counter()
    with pytest.raises(wm.FileFormatError, match=f"JSON nested more than {MAX_DEPTH} deep"):
        wm.load_calibration(path)
    assert time.perf_counter() - start < HANG_GUARD_S


def test_brackets_inside_strings_do_not_count(documents, tmp_path):
    document = json.loads(json.dumps(documents["learned"]))
    document["metadata"] = {"note": "[" * 1000 + '"{' * 10}
    wm.load_calibration(write(tmp_path / "ok.wmcal.json", document))


@pytest.mark.parametrize("digits", [MAX_INTEGER_DIGITS + 1, 5000, 1_000_000])
def test_huge_integers_are_refused(documents, tmp_path, digits):
    text = json.dumps(documents["learned"]).replace(
        '"n_samples": 501', '"n_samples": ' + "9" * digits
    )
    path = tmp_path / "huge.wmcal.json"
    path.write_text(text)
    with pytest.raises(wm.FileFormatError, match=f"an integer of {digits} digits"):
        wm.load_calibration(path)


def test_reading_a_device_is_bounded():
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    start = time.perf_counter()
    with pytest.raises(wm.FileFormatError, match="larger than 64 MiB"):
        wm.load_calibration("/dev/zero")
    assert time.perf_counter() - start < HANG_GUARD_S


def test_nan_in_the_ml_retrieval_cannot_come_from_a_valid_file(documents, sweep, tmp_path):
    """A loaded map is finite and full rank, so every retrieval of real readings is finite."""
    document = json.loads(json.dumps(documents["learned"]))
    document["params"]["retrieval"] = "ml"
    document["state"]["map"][0] = [5.0, -3.0, 1.0]  # absurd but full rank
    cal = wm.load_calibration(write(tmp_path / "ml.wmcal.json", document))
    assert np.all(np.isfinite(cal.predict(sweep[2])))


# ---------------------------------------------------------------------------- wavemeter info


def test_info_strips_escape_sequences_from_the_file(sweep, tmp_path, capsys):
    _, frequency, readings = sweep
    path = tmp_path / "esc.wmcal.json"
    cal = wm.Calibrator(50e9).fit(readings, frequency, port_names=["p1\x1b[2J", "p2", "p3"])
    wm.save_calibration(cal, path, {"operator": "\x1b]0;owned\x07"})
    code, out, _ = run(capsys, f"info {path}")
    assert code == 0 and "\x1b" not in out and "\x07" not in out
    assert "p1?[2J, p2, p3" in out and "?]0;owned?" in out


def test_info_shows_every_setting_and_the_metadata(sweep, tmp_path, capsys):
    device, _, _ = sweep
    frequency = device.sweep_hz(2002, span_fsr=2.0)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=4)
    window = wm.Calibrator(retrieval="ml")
    cal = wm.CalibrationSet(50e9, fsr_tolerance=0.15, window=window).fit(readings, frequency)
    metadata = {
        "sweep_file": "lab.csv",
        "rows": 2002,
        "x_column": "wavelength_nm",
        "x_unit": "nm",
        "port_columns": ["P1_dBm", "P2_dBm", "P3_dBm"],
        "port_units": ["dBm", "dBm", "dBm"],
        "monitor_column": "monitor_mW",
        "temperature_column": "temp_C",
        "temperature_k_range": [293.15, 294.05],
        "dropped_rows": 3,
    }
    path = tmp_path / "set.wmcal.json"
    wm.save_calibration(cal, path, metadata)
    code, out, err = run(capsys, f"info {path}")
    assert code == 0, err
    for expected in (
        f"wavemeter {wm.__version__} calibration (schema {SCHEMA_VERSION})",
        "method           learned per FSR",
        "fsr_tolerance 0.15; window learned (",
        "retrieval ml)",
        "FSR              ",
        " +- ",
        "windows          centre THz",
        "sweep            lab.csv (2002 rows, axis wavelength_nm in nm, ports in dBm)",
        "port columns     P1_dBm, P2_dBm, P3_dBm",
        "monitor column   monitor_mW",
        "temperature      293.15 to 294.05 K (column temp_C)",
        "dropped rows     3",
        "warnings         none",
    ):
        assert expected in out, expected


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("scan.csv", b"wavelength_nm,p1_mW,p2_mW,p3_mW\n1550.1,0.1,0.2,0.3\n"),
        ("scan", b"# lab file\nfrequency_hz;P1;P2;P3\n1.934e14;0.1;0.2;0.3\n"),
        ("scan", b"\x89HDF\r\n\x1a\n" + bytes(64)),
    ],
    ids=["csv-extension", "text-table", "hdf5-signature"],
)
def test_info_recognises_a_data_file(tmp_path, capsys, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    code, out, err = run(capsys, f"info {path}")
    assert code == 2 and out == ""
    assert err == (
        f"error: {path} is a data file, not a calibration file; calibrate it with "
        f"`wavemeter calibrate {path} -o cal.wmcal.json`\n"
    )


def test_info_on_a_bad_metadata_field_is_one_error_line(documents, tmp_path, capsys):
    document = json.loads(json.dumps(documents["learned"]))
    document["metadata"] = "not an object"
    path = write(tmp_path / "meta.wmcal.json", document)
    code, _, err = run(capsys, f"info {path}")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(f"error: {path}: field 'metadata' must be an object")
