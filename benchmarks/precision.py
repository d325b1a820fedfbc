"""Precision and speed of the learned calibration against the conventional method and the CRLB.

Monte Carlo over Table 1 devices (3 and 4 ports): 2,001 training samples over one FSR,
20,000 test samples at random frequencies, noise 5e-4 mW at 1 mW. Prints markdown tables:
per method (the paper's learned calibration, the same with cone-constrained ML retrieval,
the conventional method) and port count the RMS and max error (MHz), RMS/CRLB (median and
worst over devices) and the improvement of learned over conventional; then fit times and predict
throughput next to ``np.arctan2`` alone on the same sample count (median of several runs).

Usage: ``python benchmarks/precision.py [--devices 50] [--seed 0]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from _montecarlo import NOISE_W, POWER_W, crlb_rms_hz, median_time_s, progress

import wavemeter as wm

TRAIN = 2001
TEST = 20000
TARGETS = {"learned median": 1.02, "learned worst": 1.08, "conventional / learned": 50.0}


def evaluate_device(ports: int, seed: int) -> dict[str, dict[str, float]]:
    """Fit both methods on one Table 1 device; errors (Hz) and RMS/CRLB on its test set."""
    device = wm.Interferometer.table1(ports, seed=seed)
    rng = np.random.default_rng(10_000 + seed)
    train_hz = device.sweep_hz(TRAIN)
    train_w = device.powers(train_hz, POWER_W, NOISE_W, rng)
    half = device.true_fsr_hz / 2
    test_hz = device.center_hz + rng.uniform(-half, half, TEST)
    test_w = device.powers(test_hz, POWER_W, NOISE_W, rng)
    crlb_rms = crlb_rms_hz(device, test_hz, POWER_W, NOISE_W)
    methods = {
        "learned": wm.Calibrator(50e9),
        "learned, cone ML": wm.Calibrator(50e9, retrieval="ml"),
        "conventional": wm.ConventionalCalibrator(50e9, device.design_port_phases_rad),
    }
    result = {}
    for name, cal in methods.items():
        cal.fit(train_w, train_hz)
        error = wm.frequency_error_hz(cal.predict(test_w), test_hz, device.true_fsr_hz)
        stats = wm.error_summary_hz(error)
        result[name] = {**stats, "rms_over_crlb": stats["rms_hz"] / crlb_rms}
    return result


def precision_table(devices: int, seed: int) -> str:
    lines = [
        "| ports | method | median RMS (MHz) | worst RMS (MHz) | worst max (MHz) "
        "| median RMS/CRLB | worst RMS/CRLB | median improvement (conv/learned RMS) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    summary = {}
    for ports in (3, 4):
        results = []
        for k in range(devices):
            results.append(evaluate_device(ports, seed + k))
            progress(f"{ports}x{ports}: device {k + 1}/{devices}")
        print(file=sys.stderr)
        improvement = np.array(
            [r["conventional"]["rms_hz"] / r["learned"]["rms_hz"] for r in results]
        )
        for name in ("learned", "learned, cone ML", "conventional"):
            rms = np.array([r[name]["rms_hz"] for r in results]) / 1e6
            peak = np.array([r[name]["max_hz"] for r in results]) / 1e6
            ratio = np.array([r[name]["rms_over_crlb"] for r in results])
            cell = f"{np.median(improvement):.0f}x (min {improvement.min():.0f}x)"
            lines.append(
                f"| {ports} | {name} | {np.median(rms):.3f} | {rms.max():.3f} | {peak.max():.3f} "
                f"| {np.median(ratio):.4f} | {ratio.max():.4f} | "
                f"{cell if name == 'learned' else ''} |"
            )
            summary[(ports, name)] = (np.median(ratio), ratio.max(), np.median(rms))
    lines += ["", "| target | 3 ports | 4 ports | met |", "|---|---|---|---|"]
    for label, column, limit, better in (
        ("learned median RMS/CRLB <= 1.02", 0, TARGETS["learned median"], "le"),
        ("learned worst RMS/CRLB <= 1.08", 1, TARGETS["learned worst"], "le"),
    ):
        values = [summary[(p, "learned")][column] for p in (3, 4)]
        met = all(v <= limit for v in values) if better == "le" else None
        lines.append(f"| {label} | {values[0]:.4f} | {values[1]:.4f} | {'yes' if met else 'NO'} |")
    factors = [summary[(p, "conventional")][2] / summary[(p, "learned")][2] for p in (3, 4)]
    met = all(f >= TARGETS["conventional / learned"] for f in factors)
    lines.append(
        f"| conventional median RMS >= 50x learned | {factors[0]:.0f}x | {factors[1]:.0f}x "
        f"| {'yes' if met else 'NO'} |"
    )
    return "\n".join(lines)


def speed_table(seed: int) -> str:
    device = wm.Interferometer.table1(3, seed=seed)
    rng = np.random.default_rng(seed)
    lines = ["| task | samples | median time (s) | throughput (samples/s) |", "|---|---|---|---|"]
    for samples, repeats in ((TRAIN, 7), (1_000_000, 3)):
        train_hz = device.sweep_hz(samples)
        train_w = device.powers(train_hz, POWER_W, NOISE_W, rng)
        cal = wm.Calibrator(50e9)
        seconds, _ = median_time_s(lambda c=cal, w=train_w, f=train_hz: c.fit(w, f), repeats)
        lines.append(f"| Calibrator.fit | {samples:,} | {seconds:.4f} | {samples / seconds:.3g} |")
    count = 1_000_000
    test_w = device.powers(device.sweep_hz(count), POWER_W, NOISE_W, rng)
    y, x = test_w[:, 0].copy(), test_w[:, 1].copy()
    predict_s, _ = median_time_s(lambda: cal.predict(test_w), 7)
    arctan_s, _ = median_time_s(lambda: np.arctan2(y, x), 7)
    lines.append(f"| Calibrator.predict | {count:,} | {predict_s:.4f} | {count / predict_s:.3g} |")
    lines.append(f"| np.arctan2 alone | {count:,} | {arctan_s:.4f} | {count / arctan_s:.3g} |")
    lines.append("")
    lines.append(
        f"predict costs {predict_s / arctan_s:.2f}x np.arctan2 alone on the same {count:,} "
        "samples (measured side by side in this run)"
    )
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=50, help="devices per port count")
    parser.add_argument("--seed", type=int, default=0, help="first device seed")
    args = parser.parse_args(argv)
    print(
        f"## Precision: {args.devices} Table 1 devices per port count, {TRAIN} training and "
        f"{TEST} test samples, noise {NOISE_W * 1e3:g} mW at {POWER_W * 1e3:g} mW\n"
    )
    print(precision_table(args.devices, args.seed))
    print("\n## Speed\n")
    print(speed_table(args.seed))


if __name__ == "__main__":
    main()
