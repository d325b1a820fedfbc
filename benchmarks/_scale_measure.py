"""The measure part of ``benchmarks/scale.py``: ``wavemeter measure`` on large files.

A Table 1 3x3 device (seed 7) calibrated from 20 000 readings over 4 FSRs; readings files
of ``rows`` rows (three port columns ``p1_w..p3_w``, written in chunks by
:func:`wavemeter.io.table_writer`) in CSV and Parquet. Each file is measured by the command
line in a child process (``python -m wavemeter measure CAL FILE -o OUT --quiet``); its wall
time and its peak resident memory (``ru_maxrss`` of that child alone, from ``os.wait4`` in a
small launcher process) are recorded, beside the time pyarrow alone takes to read the same
file into memory (``pyarrow.csv.read_csv`` / ``pyarrow.parquet.read_table``, in this
process). The memory
target (issue 13): a 1e7-row file takes no more than 1.2x the peak memory of a 1e5-row file
plus the chunk (``wavemeter.jobs.MEASURE_CHUNK_ROWS`` rows of readings and results).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import wavemeter as wm
from wavemeter.io import table_writer
from wavemeter.jobs import MEASURE_CHUNK_ROWS

#: the device and its calibration sweep
SEED = 7
FSR_HZ = 50e9
SWEEP_SAMPLES = 20_000
START_HZ = 193.3e12
POWER_W = 1e-3
NOISE_W = 5e-7
#: rows generated and written at a time
WRITE_CHUNK_ROWS = 1_000_000
#: bytes of one measured row held per chunk: three readings in, five float64 columns out
ROW_BYTES = 8 * (3 + 5)
#: the memory target: 1e7 rows within this factor of 1e5 rows' peak, plus the chunk
MEMORY_FACTOR = 1.2
FORMATS = {"CSV": ".csv", "Parquet": ".parquet"}


@dataclass(frozen=True)
class MeasureRun:
    """One run of a command on a file (``wavemeter measure``, or ``calibrate``).

    Attributes
    ----------
    file_format : str
        ``"CSV"`` or ``"Parquet"``.
    rows : int
    file_bytes : int
        Size of the readings file.
    wall_s : float
        Wall time of the child process, start to exit (s).
    peak_rss_bytes : int
        Its peak resident memory.
    arrow_read_s : float
        pyarrow alone reading the same file into memory (s).
    """

    file_format: str
    rows: int
    file_bytes: int
    wall_s: float
    peak_rss_bytes: int
    arrow_read_s: float

    @property
    def rows_per_s(self) -> float:
        return self.rows / self.wall_s


def calibration_file(folder: Path) -> Path:
    """Calibrate the device from its sweep; the calibration file."""
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    frequency = np.linspace(START_HZ, START_HZ + 4 * FSR_HZ, SWEEP_SAMPLES)
    sweep = device.powers(frequency, power_w=POWER_W, noise_w=NOISE_W, rng=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        calibration = wm.Calibrator(fsr_hz=FSR_HZ).fit(sweep, frequency)
    path = folder / "chip.wmcal.json"
    calibration.save(path)
    return path


def readings_file(folder: Path, rows: int, suffix: str) -> Path:
    """A readings file of ``rows`` rows of the device at uniform random frequencies."""
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    rng = np.random.default_rng(rows)
    path = folder / f"readings_{rows}{suffix}"
    with table_writer(path) as write:
        for start in range(0, rows, WRITE_CHUNK_ROWS):
            count = min(WRITE_CHUNK_ROWS, rows - start)
            frequency = rng.uniform(START_HZ, START_HZ + 4 * FSR_HZ, count)
            powers = device.powers(frequency, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
            write({f"p{port + 1}_w": powers[:, port] for port in range(3)})
    return path


#: runs a command as its child and prints its wall time, peak memory, exit code and stderr:
#: measured from this small process, the child's peak is its own (a child forked straight
#: from the benchmark would count the benchmark's memory, which exec does not reset)
_LAUNCHER = """
import json, os, subprocess, sys, time
start = time.perf_counter()
child = subprocess.Popen(sys.argv[1:], stderr=subprocess.PIPE)
message = child.stderr.read().decode()
_, status, usage = os.wait4(child.pid, 0)
wall = time.perf_counter() - start
print(json.dumps([wall, usage.ru_maxrss, os.waitstatus_to_exitcode(status), message]))
"""


def child_wall_and_peak(command: list[str]) -> tuple[float, int]:
    """Wall time (s) and peak resident memory (bytes) of ``command`` run as a child.

    Raises RuntimeError with the command's stderr when it fails.
    """
    launched = subprocess.run(
        [sys.executable, "-c", _LAUNCHER, *command], capture_output=True, text=True, check=True
    )
    wall, peak_kb, code, message = json.loads(launched.stdout)
    if code != 0:
        raise RuntimeError(f"{command[2:4]} failed ({code}): {message}")
    return wall, peak_kb * 1024  # Linux reports kilobytes


def run_measure(calibration: Path, readings: Path, out: Path) -> tuple[float, int]:
    """Wall time (s) and peak resident memory (bytes) of one ``wavemeter measure`` child."""
    command = [sys.executable, "-m", "wavemeter", "measure", str(calibration), str(readings)]
    return child_wall_and_peak(command + ["-o", str(out), "--quiet", "--force"])


def arrow_read_s(path: Path) -> float:
    """Time pyarrow alone takes to read the whole file into memory (s)."""
    import pyarrow.csv
    import pyarrow.parquet

    start = time.perf_counter()
    if path.suffix == ".csv":
        pyarrow.csv.read_csv(path)
    else:
        pyarrow.parquet.read_table(path)
    return time.perf_counter() - start


def measure_runs(folder: Path, sizes, progress) -> list[MeasureRun]:
    """Measure a file of each size in each format; files are deleted once measured."""
    calibration = calibration_file(folder)
    runs = []
    for name, suffix in FORMATS.items():
        for rows in sizes:
            progress(f"measure: writing {rows:.0e} rows of {name}")
            readings = readings_file(folder, rows, suffix)
            progress(f"measure: {rows:.0e} rows of {name}")
            wall, peak = run_measure(calibration, readings, folder / f"out{suffix}")
            arrow = arrow_read_s(readings)
            runs.append(MeasureRun(name, rows, readings.stat().st_size, wall, peak, arrow))
            readings.unlink()
            (folder / f"out{suffix}").unlink()
    return runs


def chunk_bytes() -> int:
    """Memory of one measured chunk: its readings and its results."""
    return MEASURE_CHUNK_ROWS * ROW_BYTES


def memory_target(runs: list[MeasureRun], chunk: int | None = None) -> list[tuple[str, str, bool]]:
    """Per format: the largest file's peak against 1.2x the smallest's plus the chunk
    (``chunk`` bytes; default a measured chunk, :func:`chunk_bytes`)."""
    chunk = chunk_bytes() if chunk is None else chunk
    verdicts = []
    for name in FORMATS:
        mine = sorted((run for run in runs if run.file_format == name), key=lambda r: r.rows)
        smallest, largest = mine[0], mine[-1]
        allowed = MEMORY_FACTOR * smallest.peak_rss_bytes + chunk
        cell = (
            f"{largest.rows:.0e} rows: {largest.peak_rss_bytes / 2**20:.0f} MiB <= "
            f"{MEMORY_FACTOR:g} x {smallest.peak_rss_bytes / 2**20:.0f} MiB "
            f"({smallest.rows:.0e} rows) + {chunk / 2**20:.0f} MiB = "
            f"{allowed / 2**20:.0f} MiB"
        )
        verdicts.append((name, cell, largest.peak_rss_bytes <= allowed))
    return verdicts
