"""Fit diagnostics: how often clean sweeps warn, and which faults they catch and name.

Clean part (always): in-model sweeps (the simulator is the cone model plus white noise) of
3, 4 and 5 ports, Table 1 devices and ideal ones alternately, for each number of readings
and span in FSRs; each is calibrated by the learned map (``fit_learned_map``, centre in the
middle of the sweep) and tested by ``misfit_report``. Every warning is a false alarm. The
table gives warned/total with the one-sided 95 % Clopper-Pearson upper bound on the rate,
and, per test, the share of p-values below 0.01 (at most 0.01 for a valid test) and the
smallest p-value (a test fails below ``TEST_P_VALUE`` = 1e-6).

Fault part (``--faults``): each fault at a few severities on Table 1 devices (``--ports``,
``--readings`` over one FSR; dispersion over 10 FSR); the RMS error of the calibration on a clean
test set over one FSR divided by the RMS Cramer-Rao bound, how often the fit warned, how
often the first warning names the fault's cause, and the silent failures (RMS > 1.5x the
bound without a warning).

Timing part (``--timing``, instead of the others): the median time of 5 calls of
``misfit_report`` and of the learned fit it diagnoses, Table 1 devices of 3 and 5 ports, one
FSR, 8 to 20001 readings (set ``OPENBLAS_NUM_THREADS=1`` for single-thread times).

Usage: ``python benchmarks/misfit_false_alarms.py [--sweeps 40] [--seed 0]
[--faults [--devices 10] [--readings 2001] [--ports 3]] [--timing]``
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import statistics

import numpy as np
from _montecarlo import NOISE_W, POWER_W, markdown_table, median_time_s, progress
from scipy import stats

import wavemeter as wm
from wavemeter.calibration.checks.misfit import misfit_report
from wavemeter.calibration.models.learned_fit import fit_learned_map, predict_frequency_hz
from wavemeter.simulation.drift import flicker_power_noise, slow_power_drift, thermal_ramp_rad

DESIGN_FSR_HZ = 50e9
SAMPLES = (8, 16, 64, 400, 2001)
SPANS_FSR = (1.0, 3.0)
TESTS = (
    "power",
    "phase",
    "dispersion",
    "harmonics",
    "smooth",
    "power_scatter",
    "phase_scatter",
    "unequal_noise",
)
TEST_READINGS = 4000


def calibrate(frequency_hz, powers_w):
    """Learned fit and its misfit report."""
    center = 0.5 * (frequency_hz.min() + frequency_hz.max())
    fit = fit_learned_map(powers_w, frequency_hz, center, fsr_hz=DESIGN_FSR_HZ, fsr_tolerance=0.2)
    return fit, center, misfit_report(powers_w, frequency_hz, center, fit.delay_s, fit.map_)


def clean_row(samples: int, span_fsr: float, sweeps: int, seed: int) -> list:
    warned, p_values = 0, {name: [] for name in TESTS}
    for k in range(sweeps):
        progress(f"clean: {samples} readings over {span_fsr:g} FSR, sweep {k + 1}/{sweeps}")
        rng = np.random.default_rng([seed, samples, int(10 * span_fsr), k])
        ports = 3 + k % 3
        device = (
            wm.Interferometer.table1(ports, seed=rng)
            if k % 2 == 0
            else wm.Interferometer.ideal(ports)
        )
        frequency = device.sweep_hz(samples, span_fsr)
        _, _, report = calibrate(frequency, device.powers(frequency, POWER_W, NOISE_W, rng))
        warned += report.misfit
        for name in TESTS:
            if report.p_values[name] is not None:
                p_values[name].append(report.p_values[name])
    upper = stats.beta.ppf(0.95, warned + 1, sweeps - warned) if warned < sweeps else 1.0
    cells = [
        "n/a" if not values else f"{np.mean(np.array(values) < 0.01):.3f} / {min(values):.2g}"
        for values in p_values.values()
    ]
    return [samples, f"{span_fsr:g}", f"{warned}/{sweeps}", f"{100 * upper:.2g} %", *cells]


# ---------------------------------------------------------------------- faults
FAULTS = {
    # name: (cause, severities, span in FSRs)
    "slow power drift (peak)": ("power_drift", (0.001, 0.003, 0.01, 0.5), 1.0),
    "flicker power (RMS)": ("power_drift", (0.0003, 0.001, 0.003, 0.01), 1.0),
    "thermostat, 1 cycle (rad p-p)": ("phase_drift", (0.001, 0.003, 0.01), 1.0),
    "thermostat, 3 cycles (rad p-p)": ("phase_drift", (0.003, 0.01, 0.03), 1.0),
    "ramp, two-way sweep (rad)": ("phase_drift", (0.001, 0.003, 0.01), 1.0),
    "dispersion (GDD, s^2)": ("dispersion", (1e-27, 3e-27, 1e-26, 1e-25), 10.0),
    "detector compression": ("other_misfit", (0.001, 0.003, 0.01), 1.0),
}


def faulty_sweep(fault: str, severity: float, device, readings: int, rng):
    """Training frequencies and readings with the fault."""
    span = FAULTS[fault][2]
    frequency = device.sweep_hz(readings, span)
    power, bias = POWER_W, None
    if fault.startswith("slow power"):
        power = POWER_W * slow_power_drift(frequency.size, severity, rng)
    elif fault.startswith("flicker"):
        power = POWER_W * flicker_power_noise(frequency.size, severity, rng)
    elif fault.startswith("thermostat"):
        cycles = 1 if "1 cycle" in fault else 3
        bias = thermal_ramp_rad(frequency.size, severity, 1.0, "cycle", cycles)
    elif fault.startswith("ramp"):
        frequency = np.concatenate([frequency[::2], frequency[::-2]])
        bias = thermal_ramp_rad(frequency.size, severity, 1.0)
    elif fault.startswith("dispersion"):
        device = dataclasses.replace(device, dispersion_s2=severity)
    powers = device.powers(frequency, power, NOISE_W, rng, bias_drift_rad=bias)
    if fault.startswith("detector"):
        powers = powers - severity * powers**2 / powers.max()
    return frequency, powers


def fault_trial(fault: str, severity: float, seed: int, readings: int, ports: int) -> dict:
    rng = np.random.default_rng([seed, int(1e6 * severity) % (1 << 31)])
    device = wm.Interferometer.table1(ports, seed=rng)
    frequency, powers = faulty_sweep(fault, severity, device, readings, rng)
    try:
        fit, center, report = calibrate(frequency, powers)
    except wm.WavemeterError:
        return {"refused": True}
    test_hz = device.center_hz + device.true_fsr_hz * rng.uniform(-0.5, 0.5, TEST_READINGS)
    test = device.powers(test_hz, POWER_W, NOISE_W, rng)
    if fault.startswith("detector"):
        test = test - severity * test**2 / test.max()
    predicted = predict_frequency_hz(test, fit.map_, center, 1.0 / fit.delay_s)
    error = wm.frequency_error_hz(predicted, test_hz, 1.0 / fit.delay_s)
    phase = 2 * np.pi * (test_hz - device.center_hz) * device.delay_s
    bound = wm.crlb_frequency_std(device.true_map(), phase, POWER_W, NOISE_W, device.true_fsr_hz)
    ratio = float(np.sqrt(np.mean(error**2) / np.mean(bound**2)))
    return {"refused": False, "ratio": ratio, "causes": report.causes}


def fault_rows(devices: int, seed: int, readings: int, ports: int) -> list[list]:
    rows = []
    for fault, (cause, severities, _) in FAULTS.items():
        for severity in severities:
            progress(f"faults: {fault} {severity:g}")
            trials = [
                fault_trial(fault, severity, seed + k, readings, ports) for k in range(devices)
            ]
            fitted = [t for t in trials if not t["refused"]]
            warned = [t for t in fitted if t["causes"]]
            named = sum(t["causes"][0] == cause for t in warned)
            silent = sum(t["ratio"] > 1.5 and not t["causes"] for t in fitted)
            rows.append(
                [
                    fault,
                    f"{severity:g}",
                    f"{statistics.median(t['ratio'] for t in fitted):.3g}" if fitted else "-",
                    f"{len(warned)}/{len(fitted)}",
                    f"{named}/{len(warned)} {cause}",
                    silent,
                    len(trials) - len(fitted),
                ]
            )
    return rows


def timing_rows(seed: int) -> list[list]:
    rows = []
    for samples in (*SAMPLES, 20001):
        for ports in (3, 5):
            progress(f"timing: {samples} readings, {ports} ports")
            device = wm.Interferometer.table1(ports, seed=seed)
            frequency = device.sweep_hz(samples)
            powers = device.powers(frequency, POWER_W, NOISE_W, rng=seed)
            center = 0.5 * (frequency.min() + frequency.max())
            fit_s, fit = median_time_s(
                functools.partial(
                    fit_learned_map,
                    powers,
                    frequency,
                    center,
                    fsr_hz=DESIGN_FSR_HZ,
                    fsr_tolerance=0.2,
                )
            )
            report = functools.partial(
                misfit_report, powers, frequency, center, fit.delay_s, fit.map_
            )
            report_s, _ = median_time_s(report)
            rows.append(
                [
                    samples,
                    ports,
                    f"{1e3 * fit_s:.3g}",
                    f"{1e3 * report_s:.3g}",
                    f"{report_s / fit_s:.2g}",
                ]
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=40, help="clean sweeps per row")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--faults", action="store_true", help="also the fault table")
    parser.add_argument("--devices", type=int, default=10, help="devices per fault severity")
    parser.add_argument("--readings", type=int, default=2001, help="readings per faulty sweep")
    parser.add_argument("--ports", type=int, default=3, help="ports of the faulty devices")
    parser.add_argument("--timing", action="store_true", help="only the timing table")
    args = parser.parse_args()
    if args.timing:
        rows = timing_rows(args.seed)
        progress("")
        print()
        headers = ["readings", "ports", "learned fit (ms)", "misfit_report (ms)", "report / fit"]
        print(markdown_table(headers, rows))
        return
    rows = [
        clean_row(samples, span, args.sweeps, args.seed)
        for samples in SAMPLES
        for span in SPANS_FSR
    ]
    warned = sum(int(row[2].split("/")[0]) for row in rows)
    total = args.sweeps * len(rows)
    progress("")
    print()
    headers = ["readings", "span (FSR)", "warned", "rate, 95 % upper bound"]
    headers += [f"{name}: p<0.01 / min p" for name in TESTS]
    print(markdown_table(headers, rows))
    upper = stats.beta.ppf(0.95, warned + 1, total - warned) if warned < total else 1.0
    print(f"\nall clean sweeps: {warned}/{total} warned (95 % upper bound {100 * upper:.2g} %)")
    if args.faults:
        rows = fault_rows(args.devices, args.seed, args.readings, args.ports)
        progress("")
        print()
        headers = [
            f"fault ({args.ports} ports, {args.readings} readings)",
            "severity",
            "median RMS/CRLB",
            "warned",
            "first cause right",
            "silent (>1.5x)",
            "fit refused",
        ]
        print(markdown_table(headers, rows))


if __name__ == "__main__":
    main()
