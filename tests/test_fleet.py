"""Fleets (issue 13 item 5): ``jobs.calibrate_file``, ``wavemeter.fleet.calibrate_fleet``
and ``wavemeter fleet calibrate``.

Five tiny Table 1 devices (300 readings each, CSV), one of them a broken file: the broken
one is a row with its error, the others are calibrated exactly as a direct fit of the same
readings; serial and dask runs (an in-process LocalCluster) give identical summaries; a
second run resumes without touching a file; an interrupt leaves every file complete.
"""

from __future__ import annotations

import base64
import csv
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import InputError
from wavemeter.fleet import SUMMARY_COLUMNS, calibrate_fleet, die_position
from wavemeter.io import read_table, write_table
from wavemeter.jobs import calibrate_device, calibrate_file
from wavemeter.jobs.calibrate import DIFFERING_FIELDS

from .helpers import NOISE_W, POWER_W, one_error, run_cli

SAMPLES = 300
PORTS = 3
#: the devices, in file-name order; the broken one is a truncated CSV
DEVICES = ("die_x01_y02", "die_x02_y02", "die_x03_y01", "die_x03_y02", "die_x04_y01")
BROKEN = "die_x03_y01"
#: in-sample RMS over the Cramer-Rao RMS, and the noise estimate over the true noise, each
#: within 5 standard errors of a mean square of N (x 3 ports for the noise) Gaussian terms
RATIO_TOLERANCE = 5 / math.sqrt(2 * SAMPLES)
NOISE_TOLERANCE = 5 / math.sqrt(2 * SAMPLES * PORTS)


def _write_device(folder: Path, name: str, seed: int) -> Path:
    device = wm.Interferometer.table1(PORTS, seed=seed)
    frequency = device.sweep_hz(SAMPLES)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=seed)
    path = folder / f"{name}.csv"
    ports = {f"p{k + 1}_w": powers[:, k] for k in range(PORTS)}
    write_table(path, {"frequency_hz": frequency, **ports})
    return path


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory) -> list[Path]:
    folder = tmp_path_factory.mktemp("wafer")
    paths = [_write_device(folder, name, seed) for seed, name in enumerate(DEVICES)]
    broken = paths[DEVICES.index(BROKEN)]
    text = broken.read_text()
    broken.write_text(text[: len(text) // 2].rsplit(",", 1)[0] + ",abc\n")
    return paths


@pytest.fixture(scope="module")
def serial(sweeps, tmp_path_factory):
    """A serial run (no dask) into a fresh folder."""
    out = tmp_path_factory.mktemp("serial") / "out"
    return calibrate_fleet(sweeps, out, workers=0)


@pytest.fixture(scope="module")
def client():
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as running,
    ):
        yield running


def _leftovers(folder: Path) -> list[str]:
    """Temporary files of atomic writes left in ``folder``."""
    return sorted(path.name for path in folder.iterdir() if path.name.endswith(".tmp"))


def _calibration_document(path: Path) -> dict:
    document = json.loads(path.read_text())
    del document["created_utc"]
    return document


# ---------------------------------------------------------------------------- one device
def test_calibrate_file_is_the_direct_fit_and_saves_it(sweeps, tmp_path):
    path = sweeps[0]
    out = tmp_path / "chip.wmcal.json"
    result = calibrate_file(path, out)
    table = read_table(path)
    direct = wm.Calibrator(fsr_hz=50e9).fit(table.powers_w, table.x_hz, None, ["p1", "p2", "p3"])
    assert result.ok and result.device == DEVICES[0] and result.samples == SAMPLES
    assert result.fsr_hz == direct.fsr_hz_
    assert result.calibration_rms_hz == direct.calibration_rms_hz_
    assert result.noise_std_w == direct.noise_std_w_
    crlb = np.sqrt(np.mean(direct.crlb_hz(table.powers_w) ** 2))
    assert result.crlb_rms_hz == pytest.approx(crlb, rel=1e-12)
    assert abs(result.crlb_ratio - 1) < RATIO_TOLERANCE
    assert abs(result.noise_std_w / NOISE_W - 1) < NOISE_TOLERANCE
    saved = wm.load_calibration(out)
    assert saved.fsr_hz_ == direct.fsr_hz_
    np.testing.assert_array_equal(saved.predict(table.powers_w), direct.predict(table.powers_w))


def test_calibrate_device_turns_bad_input_into_an_error_row(sweeps, tmp_path):
    broken = calibrate_device(sweeps[DEVICES.index(BROKEN)])
    assert not broken.ok and broken.device == BROKEN and str(sweeps[2]) in broken.error
    assert math.isnan(broken.fsr_hz) and broken.calibration is None
    thermal = calibrate_device(sweeps[0], method="thermal")
    assert not thermal.ok and "no temperature column" in thermal.error
    missing = calibrate_device(tmp_path / "gone.csv")
    assert missing.status == "error" and "gone.csv" in missing.error
    with pytest.raises(InputError) as info:
        calibrate_file(sweeps[0], method="conventional", retrieval="ml")
    assert info.value.parameter == "retrieval"
    with pytest.raises(InputError) as info:
        calibrate_file(sweeps[0], method="no_such_method")
    assert info.value.parameter == "method"


# ---------------------------------------------------------------------------- the fleet
@pytest.mark.slow
def test_broken_device_is_recorded_and_the_others_are_calibrated(serial, sweeps):
    assert [row.device for row in serial.rows] == list(DEVICES)
    assert (serial.calibrated, serial.failed, serial.resumed) == (4, 1, 0)
    for row, path in zip(serial.rows, sweeps, strict=True):
        output = serial.out_dir / f"{row.device}.wmcal.json"
        if row.device == BROKEN:
            assert row.status == "error" and str(path) in row.error
            assert not output.exists()
            continue
        assert row.status == "ok" and not row.error
        assert abs(row.crlb_ratio - 1) < RATIO_TOLERANCE
        assert abs(row.noise_std_w / NOISE_W - 1) < NOISE_TOLERANCE
        assert wm.load_calibration(output).fsr_hz_ == row.fsr_hz
    assert _leftovers(serial.out_dir) == []


def test_summary_parquet_holds_what_summary_csv_holds(serial):
    pq = pytest.importorskip("pyarrow.parquet")
    with open(serial.summary_csv, newline="") as handle:
        rows = list(csv.reader(handle))
    assert tuple(rows[0]) == SUMMARY_COLUMNS
    table = pq.read_table(serial.summary_parquet).to_pydict()
    assert tuple(table) == SUMMARY_COLUMNS
    for index, name in enumerate(SUMMARY_COLUMNS):
        written = [row[index] for row in rows[1:]]
        stored = table[name]
        if isinstance(stored[0], float):
            np.testing.assert_array_equal(np.array(written, dtype=float), stored)
        elif isinstance(stored[0], int):
            assert [int(value) for value in written] == stored
        else:
            assert written == stored
    device = table["device"].index(BROKEN)
    assert table["status"][device] == "error" and BROKEN in table["error"][device]
    assert (table["die_x"][device], table["die_y"][device]) == (3.0, 1.0)


def test_page_has_the_histograms_the_wafer_map_and_the_failure(serial):
    page = serial.page.read_text()
    for name in ("fsr", "noise", "rms", "crlb_ratio", "wafer"):
        found = re.search(
            rf'id="figure-{name}"><img [^>]*src="data:image/png;base64,([^"]+)"', page
        )
        assert found, name
        assert base64.b64decode(found.group(1)).startswith(b"\x89PNG")
    assert "Failed devices (1)" in page and BROKEN in page


@pytest.mark.slow
def test_dask_and_serial_give_identical_results(serial, sweeps, client, tmp_path):
    result = calibrate_fleet(sweeps, tmp_path / "out", client=client)
    assert result.summary_csv.read_bytes() == serial.summary_csv.read_bytes()
    for row in result.rows:
        if row.ok:
            name = f"{row.device}.wmcal.json"
            assert _calibration_document(result.out_dir / name) == _calibration_document(
                serial.out_dir / name
            )


@pytest.mark.slow
def test_second_run_resumes_and_force_recalibrates(serial, sweeps, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(serial.out_dir, out)
    files = sorted(out.glob("*.wmcal.json"))
    before = {path.name: (path.stat().st_ino, path.stat().st_mtime_ns) for path in files}
    again = calibrate_fleet(sweeps, out, workers=0)
    assert (again.calibrated, again.failed, again.resumed) == (4, 1, 4)
    after = {path.name: (path.stat().st_ino, path.stat().st_mtime_ns) for path in files}
    assert after == before
    for first, second in zip(serial.rows, again.rows, strict=True):
        assert second.resumed == first.ok
        if first.ok:  # the same numbers, read back from the saved file
            assert second.fsr_hz == first.fsr_hz
            assert second.crlb_ratio == first.crlb_ratio
            assert second.noise_std_w == first.noise_std_w
            assert second.warnings == first.warnings
    forced = calibrate_fleet(sweeps, out, workers=0, force=True)
    assert (forced.calibrated, forced.resumed) == (4, 0)
    assert all(path.stat().st_ino != before[path.name][0] for path in files)


def test_saved_calibrations_of_other_options_are_left_alone(serial, sweeps, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(serial.out_dir, out)
    first = out / f"{DEVICES[0]}.wmcal.json"
    text = first.read_text()
    result = calibrate_fleet(sweeps, out, workers=0, fsr_hz=49e9)
    assert result.calibrated == 0
    assert "other options: fsr_hz 50000000000.0 (now 49000000000.0)" in result.rows[0].error
    assert first.read_text() == text


@pytest.mark.slow
@pytest.mark.parametrize("runner", ["serial", "dask"])
def test_interrupt_leaves_only_complete_files(runner, sweeps, tmp_path, monkeypatch, request):
    """The third calibration is interrupted half-way through its write: it is not there,
    no temporary file is left, the two written before load, and no summary is written."""
    options = {"client": request.getfixturevalue("client")} if runner == "dask" else {"workers": 0}
    write_text = Path.write_text
    writes = []

    def interrupted(self, text, *args, **kwargs):
        if self.name.endswith(".tmp") and ".wmcal.json" in self.name:
            writes.append(self.name)
            if len(writes) == 3:
                write_text(self, text[: len(text) // 2], *args, **kwargs)
                raise KeyboardInterrupt
        return write_text(self, text, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", interrupted)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        calibrate_fleet(sweeps, out, **options)
    monkeypatch.undo()
    assert _leftovers(out) == []
    written = sorted(out.glob("*.wmcal.json"))
    assert len(written) == 2
    for path in written:
        assert wm.load_calibration(path).n_samples_ == SAMPLES
    assert sorted(path.name for path in out.iterdir()) == [path.name for path in written]
    resumed = calibrate_fleet(sweeps, out, workers=0)
    assert (resumed.calibrated, resumed.resumed) == (4, 2)


@pytest.mark.parametrize(
    ("name", "position"),
    [
        ("die_x03_y12", (3, 12)),
        ("X-2Y5", (-2, 5)),
        ("w1_x3-y4_r2", (3, 4)),
        ("chip7", None),
        ("max3y4", None),
        ("die_x3_y4567a", (3, 4567)),
        ("x3_y", None),
    ],
)
def test_die_position_from_the_name(name, position):
    assert die_position(name) == position


def test_refused_before_any_work(sweeps, tmp_path):
    twin = tmp_path / "other" / sweeps[0].name
    twin.parent.mkdir()
    shutil.copy(sweeps[0], twin)
    out = tmp_path / "out"
    with pytest.raises(InputError, match=re.escape(str(twin))) as info:
        calibrate_fleet([sweeps[0], twin], out, workers=0)
    assert str(sweeps[0]) in str(info.value)
    with pytest.raises(InputError, match="sequence of sweep files"):
        calibrate_fleet(str(sweeps[0]), out, workers=0)
    with pytest.raises(InputError, match="without workers or scheduler"):
        calibrate_fleet(sweeps, out, client=object(), workers=2)
    with pytest.raises(InputError, match="workers must be"):
        calibrate_fleet(sweeps, out, workers=-1)
    with pytest.raises(InputError) as info:
        calibrate_fleet(sweeps, out, workers=0, method="conventional", fsr_tolerance=0.1)
    assert info.value.parameter == "fsr_tolerance"
    afile = tmp_path / "afile"
    afile.write_text("")
    with pytest.raises(InputError, match="is a file"):
        calibrate_fleet(sweeps, afile, workers=0)
    assert not out.exists()


def test_a_scheduler_that_is_not_there_is_an_input_error(sweeps, tmp_path):
    pytest.importorskip("distributed")
    with pytest.raises(InputError, match="cannot connect to the dask scheduler at x") as info:
        calibrate_fleet(sweeps, tmp_path / "out", scheduler="x")
    assert info.value.parameter == "scheduler"


# ---------------------------------------------------------------------------- command line
@pytest.mark.slow
def test_cli_calibrates_resumes_and_reports(sweeps, tmp_path, capsys):
    folder = sweeps[0].parent
    out = tmp_path / "out"
    code, printed, err = run_cli(capsys, f"fleet calibrate {folder} -o {out} --workers 0")
    assert code == 0, err
    assert f"calibrated 4 of 5 devices into {out} (1 failed)" in printed
    assert f"{out / 'summary.csv'}" in printed and f"{out / 'fleet.html'}" in printed
    assert (
        err.startswith("warning: 1 of 5 devices failed (first: die_x03_y01: ")
        and err.count("\n") == 1
    )
    code, printed, err = run_cli(capsys, f"fleet calibrate '{folder}/*.csv' -o {out} --workers 0")
    assert code == 0 and "0 calibrated now, 4 kept from an earlier run, 1 failed" in printed
    code, printed, err = run_cli(
        capsys, f"fleet calibrate {folder} -o {out} --workers 0 --force --quiet"
    )
    assert code == 0 and printed == "" and err.startswith("warning: 1 of 5")


@pytest.mark.slow
def test_cli_exit_codes(sweeps, tmp_path, capsys, monkeypatch):
    broken = sweeps[DEVICES.index(BROKEN)]
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, f"fleet calibrate {broken} -o {out} --workers 0")
    assert "no device calibrated: 1 of 1 devices failed" in one_error(code, err)
    code, _, err = run_cli(
        capsys, f"fleet calibrate {sweeps[0]} -o {out} --workers 2 --scheduler x"
    )
    assert "--scheduler" in one_error(code, err)
    code, _, err = run_cli(
        capsys, f"fleet calibrate {sweeps[0]} -o {out} --method conventional --retrieval ml"
    )
    assert "--retrieval" in one_error(code, err)
    code, _, err = run_cli(capsys, f"fleet calibrate '{tmp_path}/none*.csv' -o {out}")
    assert "names no data file" in one_error(code, err)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("wavemeter.fleet.run.calibrate_device", interrupted)
    fresh = tmp_path / "fresh"
    code, _, err = run_cli(capsys, f"fleet calibrate {sweeps[0]} -o {fresh} --workers 0")
    assert code == 130 and "interrupted" in err
    assert list(fresh.iterdir()) == []


# ---------------------------------------------------------------------------- one pipeline
@pytest.mark.slow
@pytest.mark.parametrize(
    "options",
    [
        "",  # the learned method, read in chunks
        "--method conventional --port-phases-deg 0,120,240",  # read whole
        "--retrieval ml --fsr-tolerance 0.1 --fsr 52GHz",
        "--method thermal --temperature-std-k 0.002",  # refused alike: no temperature column
    ],
)
def test_calibrate_and_fleet_calibrate_write_the_same_file(
    sweeps, tmp_path, capsys, monkeypatch, options
):
    """The two commands run one job: their files differ only in DIFFERING_FIELDS (the
    sweep named relative to the working folder here, by its path in the fleet's folder)."""
    folder = sweeps[0].parent
    monkeypatch.chdir(folder)
    single = tmp_path / "single.wmcal.json"
    code, _, single_err = run_cli(capsys, f"calibrate {sweeps[0].name} -o {single} {options}")
    out = tmp_path / "fleet"
    command = f"fleet calibrate {folder} -o {out} --workers 0 --quiet {options}"
    fleet_code, _, fleet_err = run_cli(capsys, command)
    fleet_file = out / f"{DEVICES[0]}.wmcal.json"
    if "thermal" in options:  # the same refusal: an error line, a failed row
        assert "no temperature column" in one_error(code, single_err)
        assert "no temperature column" in fleet_err and not fleet_file.exists()
        return
    assert code == 0 and fleet_code == 0, single_err + fleet_err
    documents = [json.loads(path.read_text()) for path in (single, fleet_file)]
    assert DIFFERING_FIELDS == ("created_utc", "metadata.sweep_file")
    assert documents[0]["metadata"]["sweep_file"] == sweeps[0].name
    assert documents[1]["metadata"]["sweep_file"] == str(sweeps[0])
    for document in documents:
        del document["created_utc"], document["metadata"]["sweep_file"]
    assert documents[0] == documents[1]
    record = documents[0]["metadata"]["calibrate_options"]
    assert record["settings"] == documents[0]["params"]  # every setting, defaults too
