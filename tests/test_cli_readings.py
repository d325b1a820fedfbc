"""What ``measure`` reads (``wavemeter.cli._readings``): in chunks of ``CHUNK_ROWS`` rows, each
row's flags are the calibration's own, rows skipped as invalid get the INVALID bit and
nothing else, and the summary line counts every flag.

The chunks are made small by setting the module's ``CHUNK_ROWS``, hence the file named
after the module.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.contract.flags import ReadingFlag
from wavemeter.cli import _readings as readings_module
from wavemeter.cli import main
from wavemeter.io import ColumnRequest, read_table, write_table

from .helpers import NOISE_W, POWER_W
from .helpers import run_cli as run

SAMPLES = 400
TEST_ROWS = 300


def write_readings(path: Path, readings: np.ndarray, frequency_hz=None) -> Path:
    """Port readings (W) as ``p1_w, p2_w, ..`` with a ``frequency_hz`` column if given."""
    columns = {} if frequency_hz is None else {"frequency_hz": frequency_hz}
    columns |= {f"p{k + 1}_w": readings[:, k] for k in range(readings.shape[1])}
    write_table(path, columns)
    return path


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> dict[str, Path]:
    """A 3-port Table 1 sweep over one FSR, test readings, and the calibration."""
    folder = tmp_path_factory.mktemp("clean")
    device = wm.Interferometer.table1(3, seed=4)
    rng = np.random.default_rng(4)
    frequency = device.sweep_hz(SAMPLES)
    sweep = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    half = device.true_fsr_hz / 2
    truth = device.center_hz + rng.uniform(-half, half, TEST_ROWS)
    files = {
        "sweep": write_readings(folder / "sweep.csv", sweep, frequency),
        "test": write_readings(
            folder / "test.csv", device.powers(truth, POWER_W, NOISE_W, rng=rng)
        ),
        "cal": folder / "chip.wmcal.json",
    }
    assert main(["calibrate", str(files["sweep"]), "-o", str(files["cal"]), "--quiet"]) == 0
    return files


def test_flags_follow_their_rows_through_chunks_and_dropped_rows(
    clean, tmp_path, capsys, monkeypatch
):
    """A NaN row skipped with --drop-invalid gets INVALID and nothing else; readings at 3
    and 1/3 of the source power get POWER_RANGE (outside the calibrated total power by
    more than a factor 2); every other row has the calibration's own flags, measured in
    chunks of 7 rows."""
    monkeypatch.setattr(readings_module, "CHUNK_ROWS", 7)  # the chunks measure reads
    readings = read_table(clean["test"], ColumnRequest(), need_x=False).powers_w[:40]
    readings[[5, 6]] *= 3.0
    readings[20] /= 3.0
    readings[11, 2] = np.nan
    data, out = write_readings(tmp_path / "d.csv", readings), tmp_path / "f.csv"
    code, printed, err = run(capsys, f"measure {clean['cal']} {data} -o {out} --drop-invalid")
    assert code == 0, err
    header, result = read_csv(out)
    flags = result[:, header.index("flags")].astype(int)
    assert flags[11] == ReadingFlag.INVALID
    assert np.isnan(result[11, : header.index("flags")]).all()
    assert all(flags[row] & ReadingFlag.POWER_RANGE for row in (5, 6, 20))
    valid = np.delete(np.arange(40), 11)
    expected = wm.load_calibration(clean["cal"]).flags(readings[valid])
    np.testing.assert_array_equal(flags[valid], expected)
    counts = {bit.name: int(np.count_nonzero(flags & bit)) for bit in ReadingFlag}
    assert counts["INVALID"] == 1 and counts["POWER_RANGE"] >= 3
    assert f"flagged {np.count_nonzero(flags)} of 40 readings: " in printed
    for name, count in counts.items():
        assert (f"{name} {count}" in printed) == (count > 0), printed
