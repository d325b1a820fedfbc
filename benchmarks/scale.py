"""Scale (issue 13): fit, predict, measure, live readout and fleets, side by side in one run.

- **fit**: a Table 1 3x3 device (seed 7) swept over 4 FSRs of 50 GHz (noise 5e-7 W at 1 mW),
  N = 1e3 .. 1e7 samples. Today's method before issue 13 (the golden-section search on the
  direct cost: every evaluation a least-squares fit over all N samples, as
  ``search_delay(cost=map_cost(...))``) against the moment method
  (:func:`wavemeter.calibration.methods.learned.fit_learned_map`: one pass to accumulate, then the
  search on the moments), with the relative differences of the delay and the map; beside
  them the whole ``Calibrator.fit`` (FSR guard, diagnostics included). Peak memory of
  :func:`~wavemeter.calibration.methods.learned.fit_learned_map_chunks` on chunks of 1e5 samples,
  in a child process per N. Targets: 1e6 samples <= 0.5 s, 1e7 <= 5 s in bounded memory,
  delay within 1e-10 and map within 1e-9 of today's.
- **whole fit**: the calibration a user gets, ``Calibrator.fit`` with its checks and
  diagnostics, with every reading diagnosed (the path before sampling, reached by setting
  ``diagnostic_samples`` beyond N) against the fit on moments with the checks on every
  k-th reading (at most ``DIAGNOSTIC_SAMPLES``, :mod:`wavemeter.calibration.models.subsample`),
  on the fit's sweeps. Targets as the fit's.
- **predict**: ``Calibrator.predict`` (pinv and ml retrievals) over ``np.arctan2`` alone on
  two columns of the same N, numba and numpy paths (``WAVEMETER_NO_NUMBA``) timed in this
  one process; 1e8 readings as 10 chunks of 1e7, smaller N predicted again and again for
  at least 2e6 readings per timing; the same runs as throughputs (readings/s).
  Targets: pinv <= 1.2x with numba, <= 2x without; ml <= 5x.
- **measure**: ``wavemeter measure`` on CSV and Parquet files of 1e5, 1e6, 1e7 rows
  (``benchmarks/_scale_measure.py``). Target: the 1e7-row peak within 1.2x the 1e5-row
  peak plus the chunk.
- **calibrate**: ``wavemeter calibrate`` on CSV and Parquet sweep files of 1e5, 1e6, 1e7
  rows (``benchmarks/_scale_calibrate.py``), read in chunks. Target as for measure.
- **stream**: ``wavemeter stream`` latency per reading over a pipe
  (``benchmarks/_stream_latency.py``). Target: < 1 ms.
- **fleet**: 1000 devices x 2000 samples, serial vs a LocalCluster of 2 workers
  (``benchmarks/_fleet_bench.py``), identical results.

Times are medians of ``--runs`` runs (one fit at 1e7 samples); the machine is shared, so
read the ratios. BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1``, as the command line
sets it): the products here are skinny, and threads only contend.

Usage: ``python benchmarks/scale.py [--runs 3] [--quick]
[--only fit,predict,measure,calibrate,stream,fleet]``
(``--quick``: small sizes, for the smoke test).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import _fleet_bench  # noqa: E402
import _scale_calibrate  # noqa: E402
import _scale_measure  # noqa: E402
import _stream_latency  # noqa: E402
import numpy as np  # noqa: E402
from _montecarlo import markdown_table, median_time_s, progress  # noqa: E402

import wavemeter as wm  # noqa: E402
from wavemeter.calibration.models.delay_search import search_delay  # noqa: E402
from wavemeter.calibration.models.learned_fit import fit_learned_map  # noqa: E402
from wavemeter.calibration.models.linear_map import map_cost, object_vectors, unfitted_cost  # noqa: E402
from wavemeter.calibration.models.subsample import DIAGNOSTIC_SAMPLES  # noqa: E402
from wavemeter.model import kernels, numba_kernel  # noqa: E402

SEED = 7
FSR_HZ = 50e9
FSR_TOLERANCE = 0.2
START_HZ = 193.3e12
SPAN_FSR = 4
POWER_W = 1e-3
NOISE_W = 5e-7
FIT_SIZES = (1_000, 10_000, 100_000, 1_000_000, 10_000_000)
PREDICT_SIZES = (1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000)
MEASURE_SIZES = (100_000, 1_000_000, 10_000_000)
#: the largest array predicted at once; bigger N is predicted in chunks of it
PREDICT_CHUNK = 10_000_000
#: fewest readings a predict timing takes: smaller N is predicted again and again (a single
#: call of 1e5 readings, 0.2-0.5 ms, is at the mercy of the shared machine's scheduler)
MIN_TIMED_READINGS = 2_000_000
#: sizes timed once (a run takes seconds to minutes)
ONCE_FROM = 10_000_000
CHUNKED_FIT_ROWS = 100_000
FIT_TARGETS_S = {1_000_000: 0.5, 10_000_000: 5.0}
DELAY_RTOL, MAP_RTOL = 1e-10, 1e-9
PREDICT_TARGETS = {("pinv", "numba"): 1.2, ("pinv", "numpy"): 2.0, ("ml", "numba"): 5.0}
QUICK = {
    "fit": (1_000, 10_000),
    "predict": (1_000, 100_000),
    "measure": (10_000, 100_000),
    "calibrate": (10_000, 100_000),
    "fleet": (8, 500),
}
#: ``diagnostic_samples`` that makes a calibrator diagnose every reading (the old path)
EVERY_READING = 1 << 62


def sweep(samples: int, rng_seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) evenly over 4 FSRs and the device's readings (W)."""
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    frequency = np.linspace(START_HZ, START_HZ + SPAN_FSR * FSR_HZ, samples)
    return frequency, device.powers(frequency, power_w=POWER_W, noise_w=NOISE_W, rng=rng_seed)


# ---------------------------------------------------------------------------- fit
def direct_fit(powers, frequency, center_hz):
    """Today's method before issue 13: golden-section search, each step a fit over all N."""

    def cost(delay_s: float) -> float:
        return map_cost(object_vectors(frequency, center_hz, delay_s), powers)[1]

    result = search_delay(
        cost,
        fsr_hz=FSR_HZ,
        fsr_tolerance=FSR_TOLERANCE,
        span_hz=float(np.ptp(frequency)),
        unfitted_cost=unfitted_cost(powers),
    )
    return result.delay_s, map_cost(object_vectors(frequency, center_hz, result.delay_s), powers)[0]


def chunked_fit_peak_bytes(samples: int) -> int:
    """Peak resident memory of a child that fits ``samples`` samples in chunks."""
    folder = str(Path(__file__).parent)
    code = f"import sys; sys.path.insert(0, {folder!r}); import scale; "
    code += f"scale.chunked_fit_child({samples})"
    return _scale_measure.child_wall_and_peak([sys.executable, "-c", code])[1]


def chunked_fit_child(samples: int) -> None:
    """Fit ``samples`` samples generated and accumulated a chunk at a time."""
    from wavemeter.calibration.models.learned_fit import fit_learned_map_chunks

    device = wm.Interferometer.table1(ports=3, seed=SEED)
    frequency = np.linspace(START_HZ, START_HZ + SPAN_FSR * FSR_HZ, samples)
    center = 0.5 * (frequency[0] + frequency[-1])
    rng = np.random.default_rng(1)

    def chunks():
        for start in range(0, samples, CHUNKED_FIT_ROWS):
            part = frequency[start : start + CHUNKED_FIT_ROWS]
            yield part, device.powers(part, power_w=POWER_W, noise_w=NOISE_W, rng=rng), None

    fit_learned_map_chunks(chunks(), center, fsr_hz=FSR_HZ, fsr_tolerance=FSR_TOLERANCE)


def fit_row(samples: int, runs: int) -> list[str]:
    """One size: today's search, the moments, the whole fit, their agreement, the memory."""
    repeats = 1 if samples >= ONCE_FROM else runs
    progress(f"fit: {samples:.0e} samples")
    frequency, powers = sweep(samples)
    center = 0.5 * (frequency[0] + frequency[-1])
    direct_s, (delay, matrix) = median_time_s(partial(direct_fit, powers, frequency, center), 1)
    moments = partial(
        fit_learned_map, powers, frequency, center, fsr_hz=FSR_HZ, fsr_tolerance=FSR_TOLERANCE
    )
    moments_s, fit = median_time_s(moments, repeats)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        whole = partial(wm.Calibrator(fsr_hz=FSR_HZ).fit, powers, frequency)
        whole_s, _ = median_time_s(whole, repeats)
    delay_rel = abs(fit.delay_s / delay - 1.0)
    map_rel = np.abs(fit.map_ - matrix).max() / np.abs(matrix).max()
    peak = chunked_fit_peak_bytes(samples)
    target = FIT_TARGETS_S.get(samples)
    verdict = "-" if target is None else f"{status(moments_s <= target)} (<= {target:g} s)"
    return [
        f"{samples:.0e}",
        f"{direct_s:.3g}",
        f"{moments_s:.3g}",
        f"{direct_s / moments_s:.3g}",
        f"{whole_s:.3g}",
        f"{delay_rel:.1e}",
        f"{map_rel:.1e}",
        f"{peak / 2**20:.0f}",
        verdict,
        status(delay_rel <= DELAY_RTOL and map_rel <= MAP_RTOL),
    ]


def status(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


FIT_HEADERS = (
    "samples",
    "today's search (s)",
    "moments (s)",
    "speed-up",
    "Calibrator.fit, all checks (s)",
    "delay rel. diff",
    "map rel. diff",
    "chunked fit peak RSS (MiB)",
    "moment fit time target",
    "same delay (1e-10) and map (1e-9)",
)


# ---------------------------------------------------------------------------- whole fit
def whole_fit_row(samples: int, runs: int) -> list[str]:
    """One size: ``Calibrator.fit`` with every reading diagnosed against the sampled path."""
    repeats = 1 if samples >= ONCE_FROM else runs
    progress(f"whole fit: {samples:.0e} samples")
    frequency, powers = sweep(samples)
    every = wm.Calibrator(fsr_hz=FSR_HZ)
    every.diagnostic_samples = EVERY_READING
    sampled = wm.Calibrator(fsr_hz=FSR_HZ)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        every_s, _ = median_time_s(partial(every.fit, powers, frequency), repeats)
        sampled_s, _ = median_time_s(partial(sampled.fit, powers, frequency), repeats)
    target = FIT_TARGETS_S.get(samples)
    verdict = "-" if target is None else f"{status(sampled_s <= target)} (<= {target:g} s)"
    return [
        f"{samples:.0e}",
        f"{every_s:.3g}",
        f"{sampled_s:.3g}",
        str(sampled.diagnostics_["diagnostic_samples"]),
        f"{every_s / sampled_s:.3g}",
        verdict,
    ]


def whole_fit_rows(sizes, runs: int) -> list[list[str]]:
    frequency, powers = sweep(2 * DIAGNOSTIC_SAMPLES)
    with warnings.catch_warnings():  # load the multi-core kernels before any clock runs
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        wm.Calibrator(fsr_hz=FSR_HZ).fit(powers, frequency)
    return [whole_fit_row(samples, runs) for samples in sizes]


WHOLE_FIT_HEADERS = (
    "samples",
    "every reading diagnosed (s)",
    "moments, checks on a sample (s)",
    "readings diagnosed",
    "speed-up",
    "Calibrator.fit time target",
)


# ---------------------------------------------------------------------------- predict
def use_numpy(flag: bool) -> None:
    """Switch the fused kernels between numba and numpy for the calls that follow."""
    if flag:
        os.environ[numba_kernel.NO_NUMBA_VARIABLE] = "1"
    else:
        os.environ.pop(numba_kernel.NO_NUMBA_VARIABLE, None)
    numba_kernel.numba_module.cache_clear()


def predict_rows(sizes, runs: int) -> tuple[list[list[str]], list[list[str]]]:
    """Per size: the times over np.arctan2's (``PREDICT_HEADERS``) and the throughputs
    (``THROUGHPUT_HEADERS``), from the same runs."""
    frequency, powers = sweep(20_000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        cals = {
            retrieval: wm.Calibrator(fsr_hz=FSR_HZ, retrieval=retrieval).fit(powers, frequency)
            for retrieval in ("pinv", "ml")
        }
    device = wm.Interferometer.table1(ports=3, seed=SEED)
    rng = np.random.default_rng(2)
    largest = min(max(sizes), PREDICT_CHUNK)
    test_hz = rng.uniform(START_HZ, START_HZ + SPAN_FSR * FSR_HZ, largest)
    readings = device.powers(test_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
    for cal in cals.values():  # compile (or load) the kernels before any clock runs
        cal.predict(readings[: kernels.NUMBA_MIN_READINGS["pinv"]])
    ratios, throughputs = zip(
        *(predict_row(samples, readings, cals, runs) for samples in sizes), strict=True
    )
    return list(ratios), list(throughputs)


def repeat_call(func, argument, times: int) -> None:
    for _ in range(times):
        func(argument)


def predict_row(
    samples: int, readings: np.ndarray, cals: dict, runs: int
) -> tuple[list[str], list[str]]:
    """One size: np.arctan2 alone, then each retrieval and path; their times over
    np.arctan2's and their throughputs (readings/s)."""
    repeats = runs  # a single first call at 1e7 pays for touching new memory
    count = min(samples, PREDICT_CHUNK)
    # calls per timing: N readings in chunks, and at least MIN_TIMED_READINGS readings
    calls = max(samples // count, -(-MIN_TIMED_READINGS // count))
    per_n = samples / (calls * count)  # a timing's share that N readings take
    part = readings[:count]
    y, x = np.ascontiguousarray(part[:, 0]), np.ascontiguousarray(part[:, 1])
    progress(f"predict: {samples:.0e} readings")
    arctan_s, _ = median_time_s(
        partial(repeat_call, lambda pair: np.arctan2(*pair), (y, x), calls), repeats
    )
    arctan_s *= per_n
    row = [f"{samples:.0e}", f"{arctan_s * 1e3:.3g}"]
    throughput = [f"{samples:.0e}", f"{samples / arctan_s:.3g}"]
    for retrieval, backend in (
        ("pinv", "numba"),
        ("pinv", "numpy"),
        ("ml", "numba"),
        ("ml", "numpy"),
    ):
        if retrieval == "ml" and backend == "numpy" and samples > 1_000_000:
            row.append("-")  # two orders of magnitude slower: seconds per 1e6
            throughput.append("-")
            continue
        use_numpy(backend == "numpy")
        seconds, _ = median_time_s(
            partial(repeat_call, cals[retrieval].predict, part, calls), repeats
        )
        seconds *= per_n
        ratio = seconds / arctan_s
        target = PREDICT_TARGETS.get((retrieval, backend))
        judged = target is not None and samples >= 100_000
        row.append(f"{ratio:.3g}" + (f" ({status(ratio <= target)})" if judged else ""))
        throughput.append(f"{samples / seconds:.3g}")
    use_numpy(False)
    return row, throughput


PREDICT_HEADERS = (
    "readings",
    "np.arctan2 alone (ms)",
    "pinv, numba (x arctan2)",
    "pinv, numpy",
    "ml, numba",
    "ml, numpy",
)
THROUGHPUT_HEADERS = (
    "readings",
    "np.arctan2 alone (readings/s)",
    "pinv, numba",
    "pinv, numpy",
    "ml, numba",
    "ml, numpy",
)


# ---------------------------------------------------------------------------- measure
def file_table(runs, command: str, chunk_bytes: int) -> str:
    """The runs of a command on files, and the memory target per format."""
    rows = [
        [
            run.file_format,
            f"{run.rows:.0e}",
            f"{run.file_bytes / 2**20:.0f}",
            f"{run.wall_s:.3g}",
            f"{run.rows_per_s:.3g}",
            f"{run.peak_rss_bytes / 2**20:.0f}",
            f"{run.arrow_read_s:.3g}",
        ]
        for run in runs
    ]
    headers = (
        "format",
        "rows",
        "file (MiB)",
        f"wavemeter {command} wall (s)",
        "rows/s",
        "peak RSS (MiB)",
        "pyarrow alone reads it (s)",
    )
    targets = _scale_measure.memory_target(runs, chunk_bytes)
    verdicts = [[name, cell, status(ok)] for name, cell, ok in targets]
    return (
        markdown_table(headers, rows)
        + "\n\n"
        + markdown_table(("format", "memory target (issue 13)", "status"), verdicts)
    )


def measure_table(sizes) -> str:
    with tempfile.TemporaryDirectory(prefix="wavemeter-scale-") as folder:
        runs = _scale_measure.measure_runs(Path(folder), sizes, progress)
    return file_table(runs, "measure", _scale_measure.chunk_bytes())


def calibrate_table(sizes) -> str:
    with tempfile.TemporaryDirectory(prefix="wavemeter-scale-") as folder:
        runs = _scale_calibrate.calibrate_runs(Path(folder), sizes, progress)
    return file_table(runs, "calibrate", _scale_calibrate.chunk_bytes())


# ---------------------------------------------------------------------------- main
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", default="fit,predict,measure,calibrate,stream,fleet")
    args = parser.parse_args(argv)
    quick = args.quick or os.environ.get("WAVEMETER_BENCH_QUICK") == "1"
    parts = set(args.only.split(","))
    start = time.perf_counter()
    print(
        f"# Scale (issue 13): fused kernels on the {numba_kernel.kernel_backend()} path, "
        f"{os.cpu_count()} cores, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}"
    )
    if "fit" in parts:
        sizes = QUICK["fit"] if quick else FIT_SIZES
        print("\n## Fit: delay search on the direct cost (today) vs on the moments\n")
        print(markdown_table(FIT_HEADERS, [fit_row(samples, args.runs) for samples in sizes]))
        print("\n## Calibrator.fit whole: every reading diagnosed vs checks on a sample\n")
        print(markdown_table(WHOLE_FIT_HEADERS, whole_fit_rows(sizes, args.runs)))
    if "predict" in parts:
        sizes = QUICK["predict"] if quick else PREDICT_SIZES
        ratios, throughputs = predict_rows(sizes, args.runs)
        print("\n## Predict: time over np.arctan2 alone on the same readings\n")
        print(markdown_table(PREDICT_HEADERS, ratios))
        print("\n## Predict: throughput (readings/s), the same runs\n")
        print(markdown_table(THROUGHPUT_HEADERS, throughputs))
    if "measure" in parts:
        sizes = QUICK["measure"] if quick else MEASURE_SIZES
        print("\n## wavemeter measure on large files (one child process per file)\n")
        print(measure_table(sizes))
    if "calibrate" in parts:
        sizes = QUICK["calibrate"] if quick else MEASURE_SIZES
        print("\n## wavemeter calibrate on large sweep files (one child process per file)\n")
        print(calibrate_table(sizes))
    if "stream" in parts:
        print("\n## wavemeter stream: latency per reading over a pipe\n")
        with tempfile.TemporaryDirectory(prefix="wavemeter-stream-") as folder:
            runs = _stream_latency.latency_runs(Path(folder), progress=progress)
        print(_stream_latency.table(runs))
    if "fleet" in parts:
        devices, samples = QUICK["fleet"] if quick else (_fleet_bench.DEVICES, _fleet_bench.SAMPLES)
        progress(f"fleet: {devices} devices")
        print(f"\n## Fleet: {devices} devices x {samples} samples\n")
        print(_fleet_bench.table(_fleet_bench.run(devices, samples, _fleet_bench.WORKERS)))
    progress("")
    print(f"\nfull run: {time.perf_counter() - start:.0f} s wall clock")


if __name__ == "__main__":
    main()
