"""One reading never costs the others on the command line, and --strict refuses instead.

Issue 29, item 1: a per-FSR calibration measured on readings whose coarse values partly lie
outside its windows writes every row (NaN and ``OUTSIDE_SPAN`` for those), and
``measure --strict`` (``errors="raise"`` in the library) refuses the file with exit code 3,
writing nothing and naming the readings by their file lines. Item 8: a coarse frequency
given to a calibration that reads within its FSR is refused the same way everywhere.
"""

from __future__ import annotations

import csv
import io
import shlex

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.cli import main
from wavemeter.jobs import ReadingsRefused, measure_file


def _run(capsys, command: str) -> tuple[int, str, str]:
    code = main(shlex.split(command))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A per-FSR set over 3 FSRs, a learned calibration, and test readings over 4 FSRs."""
    folder = tmp_path_factory.mktemp("status")
    for command in (
        f"simulate -o {folder / 'set.csv'} --seed 4 --span-fsr 3 --samples 1200 --quiet",
        f"simulate -o {folder / 'wide.csv'} --seed 4 --span-fsr 4 --samples 400 --test 400 --quiet",
        f"calibrate {folder / 'set.csv'} --per-fsr -o {folder / 'set.wmcal.json'} --quiet",
        f"calibrate {folder / 'wide.csv'} -o {folder / 'chip.wmcal.json'} --quiet",
    ):
        assert main(shlex.split(command)) == 0, command
    with open(folder / "wide-test.csv", newline="") as handle:
        truth = np.array([float(row["true_frequency_hz"]) for row in csv.DictReader(handle)])
    low, high = wm.load_calibration(folder / "set.wmcal.json").covered_hz()
    outside = (truth < low) | (truth > high)
    assert 0 < np.count_nonzero(outside) < truth.size  # some readings only
    return {"folder": folder, "outside": outside}


def test_measure_writes_every_row_and_flags_the_ones_it_cannot_read(files, capsys):
    folder = files["folder"]
    out = folder / "every.csv"
    code, _, err = _run(
        capsys,
        f"measure {folder / 'set.wmcal.json'} {folder / 'wide-test.csv'} -o {out} "
        "--coarse true_frequency_hz",
    )
    assert code == 0, err
    with open(out, newline="") as handle:
        rows = list(csv.DictReader(handle))
    outside = files["outside"]
    assert len(rows) == outside.size
    frequency = np.array([float(row["frequency_hz"]) for row in rows])
    flags = np.array([int(row["flags"]) for row in rows])
    assert np.isnan(frequency[outside]).all()
    assert (flags[outside] & wm.ReadingFlag.OUTSIDE_SPAN).all()
    assert np.isfinite(frequency[~outside]).all()  # the others read as usual


def test_strict_refuses_the_file_naming_its_lines_and_writes_nothing(files, capsys):
    folder = files["folder"]
    out = folder / "strict.csv"
    code, _, err = _run(
        capsys,
        f"measure {folder / 'set.wmcal.json'} {folder / 'wide-test.csv'} -o {out} "
        "--coarse true_frequency_hz --strict",
    )
    assert code == 3
    assert not out.exists()
    (line,) = err.strip().splitlines()
    assert line.startswith("error: ") and "nothing was written" in line
    count = int(np.count_nonzero(files["outside"]))
    assert f"{count} of {files['outside'].size} readings cannot be read" in line
    first = int(np.flatnonzero(files["outside"])[0])
    assert f"line {first + 2} (OUTSIDE_SPAN)" in line  # the header is line 1


def test_the_library_job_raises_with_errors_raise_and_writes_nothing(files):
    folder = files["folder"]
    calibration = wm.load_calibration(folder / "set.wmcal.json")
    out = folder / "library.csv"
    request = wm.io.ColumnRequest(coarse="true_frequency_hz")
    with pytest.raises(ReadingsRefused) as caught:
        measure_file(calibration, folder / "wide-test.csv", out, request=request, errors="raise")
    assert caught.value.unread == int(np.count_nonzero(files["outside"]))
    assert not out.exists()
    summary = measure_file(calibration, folder / "wide-test.csv", out, request=request)
    assert summary.flag_counts["OUTSIDE_SPAN"] == caught.value.unread


@pytest.mark.parametrize(
    "command",
    [
        "measure {cal} {test} -o {out} --coarse true_frequency_hz",
        "measure {cal} {test} -o {out} --coarse-frequency 193.4THz",
        "evaluate {cal} {test} --coarse true_frequency_hz",
        "stream {cal} --coarse-frequency 193.4THz",
    ],
    ids=["measure --coarse", "measure --coarse-frequency", "evaluate --coarse", "stream"],
)
def test_a_coarse_frequency_is_refused_by_a_calibration_that_reads_within_its_fsr(
    files, capsys, command, monkeypatch
):
    folder = files["folder"]
    out = folder / "refused.csv"
    text = (folder / "wide-test.csv").read_text()
    monkeypatch.setattr("sys.stdin", io.StringIO(text))  # for stream
    code, _, err = _run(
        capsys,
        command.format(cal=folder / "chip.wmcal.json", test=folder / "wide-test.csv", out=out),
    )
    assert code == 2 and not out.exists()
    (line,) = err.strip().splitlines()
    assert "is a learned calibration, which reads within its FSR and does not use it" in line
    assert "--coarse" in line  # the option to leave out, named by the command line
