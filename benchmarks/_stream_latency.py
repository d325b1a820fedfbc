"""The live-readout part of ``benchmarks/scale.py``: ``wavemeter stream`` latency per reading.

Issue 13 asks for a latency below 1 ms per reading. Each case starts ``python -m wavemeter
stream CAL`` as a child with pipes for standard input and output, writes the header line,
then the readings one at a time: a reading is written (and flushed), and the clock runs
until its output line has been read back, before the next reading is written. That is the
latency a live consumer sees: the pipe both ways, parsing the line and converting its
units, the calibration (the numbers of ``predict``, ``frequency_std_hz`` and ``flags`` of one
reading, read in one pass by :meth:`~wavemeter.calibration.contract.base.BaseCalibrator.stream`),
writing the line. The first ``WARMUP_READINGS`` readings are left out of the statistics (the
child imports what the first reading needs), the first one reported on its own. Beside it,
measured in this process over the same readings: ``jobs.stream_lines`` per line (parsing,
the calibration, the output line: everything but the pipes and the child's scheduling) and
``calibration.stream`` alone per reading, which tell the pipe from the parsing and the
numerics.

Cases: the Table 1 3x3 device (seed 7) calibrated by the learned method over 4 FSRs (the
scale benchmark's calibration) and over one FSR; a thermal calibration of the same device
(four temperatures, a temperature column in degrees Celsius; its sweeps end one step short
of an FSR, a partial span: ``flags`` also tests each reading against the span); a 3-stage
cascade (1 THz / 100 GHz / 10 GHz, 9 ports), with fewer readings.
"""

from __future__ import annotations

import io
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import wavemeter as wm
from wavemeter.jobs import stream_lines

SEED = 7
FSR_HZ = 50e9
START_HZ = 193.3e12
POWER_W = 1e-3
NOISE_W = 5e-7
#: readings timed per case (the cascade's are fewer: ``CASCADE_READINGS``)
READINGS = 2000
CASCADE_READINGS = 300
#: readings at the start left out of the statistics
WARMUP_READINGS = 20
#: the target of issue 13 (s)
TARGET_S = 1e-3
THERMAL_TEMPERATURES_K = (289.15, 292.4, 293.9, 297.15)
CASCADE_FSRS_HZ = (1e12, 100e9, 10e9)
CASCADE_BAND_HZ = 0.8e12


@dataclass(frozen=True)
class LatencyRun:
    """Latencies of one ``wavemeter stream`` child.

    Attributes
    ----------
    case : str
        What was streamed.
    latency_s : ndarray, shape (M,)
        Write-reading to read-result time of each reading after the warm-up (s).
    first_s : float
        The first reading's latency (s).
    line_s : float
        ``jobs.stream_lines`` per line in this process: parsing, calibration, output (s).
    compute_s : float
        The calibration alone per reading, ``calibration.stream`` in this process (s).
    """

    case: str
    latency_s: np.ndarray
    first_s: float
    line_s: float
    compute_s: float

    @property
    def median_s(self) -> float:
        return float(np.median(self.latency_s))

    @property
    def p99_s(self) -> float:
        return float(np.percentile(self.latency_s, 99))


def _text(value: float) -> str:
    return repr(float(value))


def stream_latency(
    calibration_path: Path, header: str, lines: list[str], case: str, in_process: tuple
) -> LatencyRun:
    """Time every line of ``lines`` through a ``wavemeter stream`` child, one at a time.

    Parameters
    ----------
    calibration_path : Path
        The calibration file.
    header : str
        The header line (no newline).
    lines : list of str
        Data lines (no newline), one reading each.
    case : str
        The case's name in the table.
    in_process : (float, float)
        The time per line of ``stream_lines`` and per reading of the calibration alone in
        this process (s), kept with the run.

    Returns
    -------
    LatencyRun
    """
    command = [sys.executable, "-m", "wavemeter", "stream", str(calibration_path), "--quiet"]
    child = subprocess.Popen(
        command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        child.stdin.write(f"{header}\n".encode())
        child.stdin.flush()
        if not child.stdout.readline():
            raise RuntimeError(f"wavemeter stream wrote no header: {child.stderr.read().decode()}")
        latency = np.empty(len(lines))
        for index, line in enumerate(lines):
            start = time.perf_counter()
            child.stdin.write(f"{line}\n".encode())
            child.stdin.flush()
            answer = child.stdout.readline()
            latency[index] = time.perf_counter() - start
            if not answer:
                raise RuntimeError(f"wavemeter stream stopped: {child.stderr.read().decode()}")
        child.stdin.close()
        if child.wait(timeout=60) != 0:
            raise RuntimeError(f"wavemeter stream failed: {child.stderr.read().decode()}")
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        child.stdout.close()
        child.stderr.close()
    return LatencyRun(case, latency[WARMUP_READINGS:], float(latency[0]), *in_process)


def in_process_s(calibration, header: str, lines: list[str], powers: np.ndarray, **inputs):
    """Per line, ``stream_lines`` over ``lines`` in this process (s), and per reading, the
    calibration alone: ``calibration.stream`` over ``powers`` with ``inputs`` (s)."""
    out = io.StringIO()
    stream_lines(calibration, [header, *lines[:WARMUP_READINGS]], out)
    start = time.perf_counter()
    stream_lines(calibration, [header, *lines], out)
    line = (time.perf_counter() - start) / len(lines)
    records = calibration.stream(iter(powers), **inputs)
    for _ in range(WARMUP_READINGS):
        next(records)
    start = time.perf_counter()
    for _ in range(powers.shape[0] - WARMUP_READINGS):
        next(records)
    return line, (time.perf_counter() - start) / (powers.shape[0] - WARMUP_READINGS)


def _fitted(estimator, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return estimator.fit(*args, **kwargs)


def learned_case(folder: Path, fsrs: int, retrieval: str = "pinv") -> LatencyRun:
    """The learned calibration of a sweep over ``fsrs`` FSRs with ``retrieval``; readings
    inside the sweep."""
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    span = fsrs * device.true_fsr_hz
    sweep_hz = np.linspace(device.center_hz - span / 2, device.center_hz + span / 2, 4000)
    sweep = device.powers(sweep_hz, power_w=POWER_W, noise_w=NOISE_W, rng=1)
    calibration = _fitted(wm.Calibrator(fsr_hz=FSR_HZ, retrieval=retrieval), sweep, sweep_hz)
    path = folder / f"learned_{fsrs}fsr_{retrieval}.wmcal.json"
    calibration.save(path)
    rng = np.random.default_rng(2)
    truth = rng.uniform(sweep_hz[0], sweep_hz[-1], READINGS)
    powers = device.powers(truth, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
    lines = [",".join(_text(value * 1e3) for value in row) for row in powers]
    name = f"learned 3x3, sweep over {fsrs} FSR{'s' if fsrs > 1 else ''}"
    name += ", ml" if retrieval == "ml" else ""
    header = "P1_mW,P2_mW,P3_mW"
    timed = in_process_s(calibration, header, lines, powers)
    return stream_latency(path, header, lines, name, timed)


def thermal_case(folder: Path) -> LatencyRun:
    """A thermal calibration; each line carries the chip temperature in degrees Celsius."""
    device = wm.Interferometer.table1(ports=3, seed=SEED).with_thermal("sin")
    sweep_hz = device.sweep_hz(400)
    rng = np.random.default_rng(3)
    sweep = np.vstack(
        [
            device.powers(sweep_hz, POWER_W, NOISE_W, rng=rng, temperature_k=temperature)
            for temperature in THERMAL_TEMPERATURES_K
        ]
    )
    temperatures = np.repeat(THERMAL_TEMPERATURES_K, sweep_hz.size)
    calibration = _fitted(
        wm.ThermalCalibrator(), sweep, np.tile(sweep_hz, 4), temperature_k=temperatures
    )
    path = folder / "thermal.wmcal.json"
    calibration.save(path)
    temperature = rng.uniform(THERMAL_TEMPERATURES_K[0], THERMAL_TEMPERATURES_K[-1], READINGS)
    truth = rng.uniform(sweep_hz[0], sweep_hz[-1], READINGS)
    powers = np.vstack(
        [
            device.powers([f], POWER_W, NOISE_W, rng=rng, temperature_k=t)
            for f, t in zip(truth, temperature, strict=True)
        ]
    )
    lines = [
        ",".join([*(_text(value) for value in row), _text(t - 273.15)])
        for row, t in zip(powers, temperature, strict=True)
    ]
    header = "p1_w,p2_w,p3_w,temp_C"
    timed = in_process_s(calibration, header, lines, powers, temperature_k=iter(temperature))
    return stream_latency(path, header, lines, "thermal 3x3", timed)


def cascade_case(folder: Path) -> LatencyRun:
    """A 3-stage cascade over 0.8 THz (9 ports)."""
    device = wm.CascadeInterferometer.table1(CASCADE_FSRS_HZ, ports=3, seed=4, spectral="sin")
    low = device.center_hz - CASCADE_BAND_HZ / 2
    sweep_hz = low + CASCADE_BAND_HZ * np.arange(3000) / 2999
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=11)
    calibration = _fitted(wm.CascadeCalibrator(fsr_hz=CASCADE_FSRS_HZ), sweep, sweep_hz)
    path = folder / "cascade.wmcal.json"
    calibration.save(path)
    rng = np.random.default_rng(5)
    truth = low + CASCADE_BAND_HZ * rng.random(CASCADE_READINGS)
    powers = device.powers(truth, POWER_W, NOISE_W, rng=rng)
    lines = [",".join(_text(value) for value in row) for row in powers]
    header = ",".join(f"p{port + 1}_w" for port in range(powers.shape[1]))
    timed = in_process_s(calibration, header, lines, powers)
    return stream_latency(path, header, lines, "cascade 3 stages x 3 ports", timed)


def latency_runs(folder: Path, progress=print) -> list[LatencyRun]:
    """Every case, one after another."""
    runs = []
    for name, case in (
        ("learned, 4 FSRs", lambda: learned_case(folder, 4)),
        ("learned, 1 FSR", lambda: learned_case(folder, 1)),
        ("learned, 4 FSRs, ml", lambda: learned_case(folder, 4, "ml")),
        ("thermal", lambda: thermal_case(folder)),
        ("cascade", lambda: cascade_case(folder)),
    ):
        progress(f"stream latency: {name}")
        runs.append(case())
    return runs


def table(runs: list[LatencyRun]) -> str:
    """The runs as a text table (ms)."""
    head = (
        f"{'case':<36}{'readings':>9}{'median ms':>11}{'p99 ms':>9}{'max ms':>9}"
        f"{'first ms':>10}{'line ms':>9}{'calibration ms':>16}  < 1 ms (median, p99)"
    )
    rows = [head, "-" * len(head)]
    for run in runs:
        verdict = ", ".join("yes" if v < TARGET_S else "no" for v in (run.median_s, run.p99_s))
        rows.append(
            f"{run.case:<36}{run.latency_s.size:>9}{run.median_s * 1e3:>11.3f}"
            f"{run.p99_s * 1e3:>9.3f}{run.latency_s.max() * 1e3:>9.3f}{run.first_s * 1e3:>10.1f}"
            f"{run.line_s * 1e3:>9.3f}{run.compute_s * 1e3:>16.3f}  {verdict}"
        )
    return "\n".join(rows)


def main() -> None:
    """Run every case in a temporary folder and print the table."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="wavemeter-stream-") as folder:
        runs = latency_runs(Path(folder), progress=lambda text: print(text, file=sys.stderr))
    print(
        f"wavemeter stream: write one reading, read its line back ({WARMUP_READINGS} warm-up "
        "readings left out; in this process: 'line' is jobs.stream_lines per line, "
        "'calibration' is calibration.stream alone)"
    )
    print(table(runs))


if __name__ == "__main__":
    main()
