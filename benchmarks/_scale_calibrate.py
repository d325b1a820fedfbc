"""The calibrate part of ``benchmarks/scale.py``: ``wavemeter calibrate`` on large sweep files.

A Table 1 3x3 device (seed 7) swept evenly over 4 FSRs of 50 GHz (noise 5e-7 W at 1 mW),
sweep files of ``rows`` rows (``frequency_hz``, ``p1_w..p3_w``, written in chunks by
:func:`wavemeter.io.table_writer`) in CSV and Parquet. Each file is calibrated by the
command line in a child process (``python -m wavemeter calibrate FILE -o OUT --quiet``),
which reads it in chunks (the learned method) and diagnoses at most
``Calibrator.diagnostic_samples`` readings; its wall time and peak resident memory are
recorded as for ``measure`` (:func:`_scale_measure.child_wall_and_peak`), beside the time
pyarrow alone takes to read the file. The memory target (issue 13, as for ``measure``): a
1e7-row file takes no more than 1.2x the peak memory of a 1e5-row file plus the chunk
(``wavemeter.io.streaming.CHUNK_ROWS`` rows of a frequency and three readings).
"""

from __future__ import annotations

import sys
from pathlib import Path

import _scale_measure
import numpy as np
from _scale_measure import FORMATS, MeasureRun, arrow_read_s, child_wall_and_peak

import wavemeter as wm
from wavemeter.io import table_writer
from wavemeter.io.streaming import CHUNK_ROWS

SEED = 7
FSR_HZ = 50e9
START_HZ = 193.3e12
SPAN_FSR = 4
POWER_W = 1e-3
NOISE_W = 5e-7
#: bytes of one sweep row held per chunk: its frequency and three readings
ROW_BYTES = 8 * (1 + 3)


def sweep_file(folder: Path, rows: int, suffix: str) -> Path:
    """A sweep file of ``rows`` rows, evenly over 4 FSRs, written a chunk at a time."""
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    rng = np.random.default_rng(rows)
    step = SPAN_FSR * FSR_HZ / (rows - 1)
    path = folder / f"sweep_{rows}{suffix}"
    with table_writer(path) as write:
        for start in range(0, rows, _scale_measure.WRITE_CHUNK_ROWS):
            count = min(_scale_measure.WRITE_CHUNK_ROWS, rows - start)
            frequency = START_HZ + step * np.arange(start, start + count)
            powers = device.powers(frequency, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
            write({"frequency_hz": frequency, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}})
    return path


def run_calibrate(sweep: Path, out: Path) -> tuple[float, int]:
    """Wall time (s) and peak resident memory (bytes) of one ``wavemeter calibrate`` child."""
    command = [sys.executable, "-m", "wavemeter", "calibrate", str(sweep), "-o", str(out)]
    return child_wall_and_peak(command + ["--fsr", f"{FSR_HZ:g}", "--quiet", "--force"])


def calibrate_runs(folder: Path, sizes, progress) -> list[MeasureRun]:
    """Calibrate from a sweep file of each size in each format; files deleted once done."""
    runs = []
    for name, suffix in FORMATS.items():
        for rows in sizes:
            progress(f"calibrate: writing {rows:.0e} rows of {name}")
            sweep = sweep_file(folder, rows, suffix)
            progress(f"calibrate: {rows:.0e} rows of {name}")
            out = folder / "chip.wmcal.json"
            wall, peak = run_calibrate(sweep, out)
            runs.append(
                MeasureRun(name, rows, sweep.stat().st_size, wall, peak, arrow_read_s(sweep))
            )
            sweep.unlink()
            out.unlink()
    return runs


def chunk_bytes() -> int:
    """Memory of one chunk of the sweep read."""
    return CHUNK_ROWS * ROW_BYTES
