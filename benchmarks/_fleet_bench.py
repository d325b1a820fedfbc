"""The fleet part of ``benchmarks/scale.py``: many devices, serial against a LocalCluster.

Issue 13: 1000 simulated devices x 2000 samples, calibrated in this process one after the
other (``workers=0``) and on a ``distributed.LocalCluster`` of 2 worker processes (one
thread each), wall time of each and whether the results are identical. Each device is a
Table 1 3x3 device of its own seed, swept over one true FSR with Table 1 noise, written as a
CSV file ``die_xXX_yYY.csv`` (32 dies a row) in a temporary folder once, before any clock
runs. Both runs are :func:`wavemeter.fleet.calibrate_fleet` as the command line calls it:
reading every file, fitting, writing every calibration, the summary (CSV, Parquet) and
``fleet.html``. The cluster's run includes starting and closing it; the start alone is
timed beside it. Identical: ``summary.csv`` byte for byte, and every calibration file's
content but its time of writing.

Run: ``python benchmarks/_fleet_bench.py [--devices N] [--samples S] [--workers W]``.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import wavemeter as wm
from wavemeter.fleet import calibrate_fleet
from wavemeter.io import write_table

#: issue 13's fleet
DEVICES = 1000
SAMPLES = 2000
WORKERS = 2
PORTS = 3
POWER_W = 1e-3
NOISE_W = 5e-7
#: dies in a row of the simulated wafer
DIES_PER_ROW = 32


def write_devices(folder: Path, devices: int, samples: int) -> list[Path]:
    """One sweep file per simulated device in ``folder``; their paths, in name order."""
    paths = []
    for seed in range(devices):
        device = wm.Interferometer.table1(PORTS, seed=seed)
        frequency = device.sweep_hz(samples)
        powers = device.powers(frequency, POWER_W, NOISE_W, rng=seed)
        x, y = seed % DIES_PER_ROW, seed // DIES_PER_ROW
        path = folder / f"die_x{x:02d}_y{y:02d}.csv"
        ports = {f"p{k + 1}_w": powers[:, k] for k in range(PORTS)}
        write_table(path, {"frequency_hz": frequency, **ports})
        paths.append(path)
    return paths


def _documents(folder: Path) -> dict[str, dict]:
    """Every calibration file's content but its time of writing, by name."""
    found = {}
    for path in sorted(folder.glob("*.wmcal.json")):
        document = json.loads(path.read_text())
        del document["created_utc"]
        found[path.name] = document
    return found


def cluster_start_s(workers: int) -> float:
    """Seconds to start and close a LocalCluster of ``workers`` processes with a client."""
    import distributed

    start = time.perf_counter()
    with (
        distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster),
    ):
        pass
    return time.perf_counter() - start


def run(devices: int = DEVICES, samples: int = SAMPLES, workers: int = WORKERS) -> dict:
    """Time the fleet serial and on a LocalCluster; the numbers, as a dict."""
    with tempfile.TemporaryDirectory(prefix="wavemeter-fleet-") as name:
        folder = Path(name)
        inputs = folder / "devices"
        inputs.mkdir()
        paths = write_devices(inputs, devices, samples)
        start = time.perf_counter()
        serial = calibrate_fleet(paths, folder / "serial", workers=0)
        serial_s = time.perf_counter() - start
        start = time.perf_counter()
        parallel = calibrate_fleet(paths, folder / "cluster", workers=workers)
        cluster_s = time.perf_counter() - start
        identical = serial.summary_csv.read_bytes() == parallel.summary_csv.read_bytes() and (
            _documents(serial.out_dir) == _documents(parallel.out_dir)
        )
        return {
            "devices": devices,
            "samples": samples,
            "workers": workers,
            "cores": os.cpu_count(),
            "calibrated": serial.calibrated,
            "serial_s": serial_s,
            "cluster_s": cluster_s,
            "cluster_start_s": cluster_start_s(workers),
            "identical": identical,
        }


def table(numbers: dict) -> str:
    """The benchmark's lines."""
    speedup = numbers["serial_s"] / numbers["cluster_s"]
    return "\n".join(
        [
            f"fleet: {numbers['devices']} devices x {numbers['samples']} samples "
            f"({numbers['calibrated']} calibrated), {numbers['cores']} cores",
            f"  serial (this process)          {numbers['serial_s']:8.1f} s  "
            f"{numbers['serial_s'] / numbers['devices'] * 1e3:6.0f} ms/device",
            f"  LocalCluster({numbers['workers']} workers)       {numbers['cluster_s']:8.1f} s  "
            f"{numbers['cluster_s'] / numbers['devices'] * 1e3:6.0f} ms/device "
            f"(cluster start and close alone {numbers['cluster_start_s']:.1f} s)",
            f"  serial / cluster               {speedup:8.2f}",
            f"  identical results              {'yes' if numbers['identical'] else 'NO'}",
        ]
    )


def main(argv=None) -> None:
    """Parse the arguments, run, print the lines."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=DEVICES)
    parser.add_argument("--samples", type=int, default=SAMPLES)
    parser.add_argument("--workers", type=int, default=WORKERS)
    arguments = parser.parse_args(argv)
    print(table(run(arguments.devices, arguments.samples, arguments.workers)))


if __name__ == "__main__":
    main()
