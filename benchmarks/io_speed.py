"""Speed of reading and writing data files: prints a markdown table (median of runs).

Target (issue 3): a 2,000,000-row, 4-column CSV (frequency and three ports) loads in
under 3 s. Reading goes through :func:`wavemeter.io.read_table` (column discovery, unit
conversion, row checks included) with pyarrow's CSV parser when it is installed and
numpy's C ``loadtxt`` otherwise; both are timed. Writing is the ``measure`` output
(frequency, wavelength, phase) in every format.

Usage: ``python benchmarks/io_speed.py [--rows 2000000] [--runs 3]``
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
from _montecarlo import median_time_s

from wavemeter.io import read_table, write_table


def _sweep_columns(rows: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(1)
    columns = {"frequency_hz": 193.4e12 + rng.uniform(-25e9, 25e9, rows)}
    for port in range(1, 4):
        columns[f"p{port}_w"] = rng.uniform(1e-5, 1e-3, rows)
    return columns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=2_000_000)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    has_arrow = importlib.util.find_spec("pyarrow") is not None
    results = []
    with tempfile.TemporaryDirectory() as folder:
        csv_path = Path(folder) / "sweep.csv"
        columns = _sweep_columns(args.rows)
        write_table(csv_path, columns)
        size_mb = csv_path.stat().st_size / 1e6
        label = f"read CSV {args.rows:,} x 4 ({size_mb:.0f} MB)"
        if has_arrow:
            seconds, _ = median_time_s(lambda: read_table(csv_path), args.runs)
            results.append((label, "pyarrow.csv", seconds))
        with mock.patch("wavemeter.io.text._pyarrow", return_value=None):
            seconds, _ = median_time_s(lambda: read_table(csv_path), args.runs)
        results.append((label, "numpy.loadtxt", seconds))
        output = {
            "frequency_hz": columns["frequency_hz"],
            "wavelength_nm": 299792458.0 / columns["frequency_hz"] * 1e9,
            "phase_rad": np.linspace(-np.pi, np.pi, args.rows),
        }
        formats = ["csv", "hdf5", "npz"] + (["parquet"] if has_arrow else [])
        for file_format in formats:
            target = Path(folder) / f"out.{file_format}"
            seconds, _ = median_time_s(
                lambda target=target, file_format=file_format: write_table(
                    target, output, file_format
                ),
                args.runs,
            )
            results.append((f"write {args.rows:,} x 3", file_format, seconds))
    print(f"| task | parser / format | median of {args.runs} (s) |")
    print("| --- | --- | ---: |")
    for task, how, seconds in results:
        print(f"| {task} | {how} | {seconds:.2f} |")


if __name__ == "__main__":
    main()
