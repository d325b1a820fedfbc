"""Faulty ports: the error without the remedy, the warning the fit gives, the error with it.

A 4-port Table 1 device (a 90-degree hybrid) with one port broken in three ways:

- dead: the port's photodiode sees no light, only its dark noise (5e-7 W);
- stuck: the port reads one constant value (a hung ADC channel);
- saturated: the port clips at 70 % of its largest reading (a detector or ADC at full scale).

For each fault and device the learned calibration is fitted on the faulty sweep (the fit
warns, ``CalibrationWarning`` with cause ``dead_port``), then with the remedy the warning
names: drop the port(s) it names and calibrate on the rest. RMS errors are divided by the
Cramer-Rao bound of the ports used (the remedy's bound for both columns, so the ratio shows
what the fault costs against what the good ports allow). Prints a markdown table of the
median over devices.

Usage: ``python benchmarks/port_faults.py [--devices 10] [--seed 0]``
"""

from __future__ import annotations

import argparse
import statistics
import warnings

import numpy as np
from _montecarlo import NOISE_W, POWER_W, markdown_table, progress

import wavemeter as wm

PORTS = 4
BROKEN = 2  # zero-based port index
TRAIN = 2001
TEST = 20000


def break_port(powers_w: np.ndarray, fault: str, rng: np.random.Generator) -> np.ndarray:
    """A copy of the readings with port ``BROKEN`` broken by ``fault``."""
    broken = np.array(powers_w)
    column = broken[:, BROKEN]
    if fault == "dead":
        broken[:, BROKEN] = rng.normal(0.0, NOISE_W, column.shape)
    elif fault == "stuck":
        broken[:, BROKEN] = column[0]
    elif fault == "saturated":
        broken[:, BROKEN] = np.minimum(column, 0.7 * column.max())
    return broken


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def crlb_rms_hz(device: wm.Interferometer, frequency_hz, ports) -> float:
    """RMS Cramer-Rao bound (Hz) of the given ports of the healthy device."""
    phase = 2 * np.pi * (frequency_hz - device.center_hz) * device.delay_s
    matrix = device.true_map()[list(ports)]
    bound = wm.crlb_frequency_std(matrix, phase, POWER_W, NOISE_W, device.true_fsr_hz)
    return rms(bound)


def fit_warnings(calibrator, powers_w, frequency_hz) -> list[wm.CalibrationWarning]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrator.fit(powers_w, frequency_hz)
    return [w.message for w in caught if issubclass(w.category, wm.CalibrationWarning)]


def one_device(fault: str, seed: int) -> dict:
    device = wm.Interferometer.table1(PORTS, seed=seed)
    rng = np.random.default_rng(1000 + seed)
    train_hz = device.sweep_hz(TRAIN)
    test_hz = rng.uniform(train_hz[0], train_hz[-1], TEST)
    train = break_port(device.powers(train_hz, POWER_W, NOISE_W, rng), fault, rng)
    test = break_port(device.powers(test_hz, POWER_W, NOISE_W, rng), fault, rng)
    faulty = wm.Calibrator(50e9)
    caught = fit_warnings(faulty, train, train_hz)
    named = [
        index
        for index, name in enumerate(faulty.port_names_)
        if any(w.cause == "dead_port" and f"p{index + 1}" in str(w) for w in caught)
    ]
    good = [port for port in range(PORTS) if port not in named]
    remedied = wm.Calibrator(50e9).fit(train[:, good], train_hz)
    bound = crlb_rms_hz(device, test_hz, good)
    return {
        "warned": bool(caught) and named == [BROKEN],
        "cause": caught[0].cause if caught else "-",
        "without": rms(wm.frequency_error_hz(faulty.predict(test), test_hz, faulty.fsr_hz_))
        / bound,
        "with": rms(
            wm.frequency_error_hz(remedied.predict(test[:, good]), test_hz, remedied.fsr_hz_)
        )
        / bound,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rows = []
    for fault in ("dead", "stuck", "saturated"):
        results = []
        for k in range(args.devices):
            progress(f"{fault}: device {k + 1}/{args.devices}")
            results.append(one_device(fault, args.seed + k))
        warned = sum(r["warned"] for r in results)
        rows.append(
            [
                f"p{BROKEN + 1} {fault}",
                f"{statistics.median(r['without'] for r in results):.3g}",
                f"{warned}/{len(results)} ({results[0]['cause']}, names p{BROKEN + 1})",
                f"{statistics.median(r['with'] for r in results):.3g}",
            ]
        )
    progress("")
    print()
    headers = [
        "fault (4-port Table 1)",
        "median RMS/CRLB, all ports",
        "warned",
        "median RMS/CRLB, named port dropped",
    ]
    print(markdown_table(headers, rows))


if __name__ == "__main__":
    main()
