"""Absolute accuracy from a reference cell (issue 32): plain, axis-corrected, self-calibrated.

Hidden truth: a simulated gas cell (``ReferenceCell.simulated("hcn-like")``: 54 lines of a
simulated P/R band over 191.6-196.3 THz, about 1527-1565 nm; its true centres drawn from the
table's 5 MHz uncertainty, its pressure from the stated 13.3 +- 0.4 kPa) recorded beside the
ports of a Table 1 device with the silicon-nitride spectral preset (3, 4 and 5 ports, design
FSR 50 GHz, 1 mW, noise 5e-7 W), swept across the cell's band (40 GHz margins) by each laser
preset of ``wavemeter.simulation.laser_sweep``: ``tls-spec`` (smooth axis error peaking at
10 pm), ``tls-typical`` (3.6 pm), ``dfb`` (current-tuned, nominal coefficient only). Per
case, every calibration is a ``wm.WidebandCalibrator(fsr_hz=50e9)`` (orders by
cross-validation) on the same sweep readings, fitted on:

- **true**: the true axis (the reference for precision);
- **(a) plain**: the recorded axis;
- **(b) corrected**: ``wavemeter.reference.correct_sweep_axis``: the meter's phase from (a)
  (``cal.phase(p, coarse_hz=recorded)``; where (a) refuses, the reference-free phase of
  ``sweep_phase_reference_free``), lines fitted and identified (the nearest line when the
  stated axis error, the 10 pm specification plus 5 jitter sigma, is below a quarter
  spacing; else by the pattern of spacings), the axis ``g(phi)`` with its budget;
- **(c) self-calibrated**: ``wavemeter.calibration.self_calibrate``: no axis at all, the band.

Test readings: independent noise, uniform over the lines' span, ``coarse_hz`` = truth.
Absolute error = predicted - true. Stated absolute uncertainty of (b), (c): the
calibrator's ``frequency_std_hz`` and the axis budget at the reading's frequency
(``SweepAxis.budget_at_hz``) in quadrature; z = error / that. Precision: the RMS error left
after removing its Legendre fit of order 12 in frequency over the test band (the smooth,
absolute part), compared with the true-axis calibration's on the same readings.

Targets (issue 32): (b) and (c) absolute RMS <= 1.2x the stated budget (RMS of the stated
uncertainty), pooled per laser preset; z std 0.9-1.1 pooled per preset; (a) inherits the
laser's error or is refused (below); identification right in every case or refused with
the reason; precision of (b), (c) <= 1.05x the true-axis calibration's in every case.
"(a) inherits the laser's error": its RMS
is at least half the laser's axis RMS error over the test band, or, where that error
exceeds half an FSR, half of ``FSR / sqrt 12`` (the coarse value, the truth here, picks the
fringe, so an error spread over a whole fringe is what a wrong axis leaves); or (a) is
refused. Stdout carries only the tables.

Usage: ``python benchmarks/absolute.py [--seeds 3] [--samples 50000] [--test 4000]
[--quick]`` (``--quick`` or ``WAVEMETER_BENCH_QUICK=1``: one seed, 3 ports, 30000 samples).
"""

from __future__ import annotations

import os
import sys
import time
import warnings
import zlib
from dataclasses import dataclass, field

import numpy as np
from _montecarlo import markdown_table, progress, rms, status
from _script import Parser, positive_int

import wavemeter as wm
from wavemeter.calibration import self_calibrate, sweep_phase_reference_free
from wavemeter.reference import BUDGET_TERMS, correct_sweep_axis
from wavemeter.simulation import SWEEP_PRESETS, ReferenceCell, laser_sweep
from wavemeter.units import SPEED_OF_LIGHT_M_S

PRESETS = ("tls-spec", "tls-typical", "dfb")
PORTS = (3, 4, 5)
POWER_W = 1e-3
NOISE_W = 5e-7
DESIGN_FSR_HZ = 50e9
MARGIN_HZ = 40e9
DETREND_ORDER = 12
#: the stated error bound of a tunable laser's axis: its 10 pm specification and 5 sigma of
#: its jitter, at the band's shortest wavelength (a user states the spec, not the typical)
SPEC_M = 10e-12
QUICK_ENV = "WAVEMETER_BENCH_QUICK"
#: absolute accuracies stated for instruments in the issue (Hz, at 1550 nm / 193.4 THz)
ANCHORS = {
    "MOGLabs FZW (1 part in 1e7)": 19.3e6,
    "comb-calibrated meter": 12e6,
    "Agilent 86120C (+-2 ppm)": 2e-6 * 193.4e12,
}
METHODS = ("true", "a", "b", "c")
LABELS = {"true": "true axis", "a": "(a) plain", "b": "(b) corrected", "c": "(c) self-cal"}


@dataclass
class Outcome:
    """One calibration's test errors (Hz), stated absolute uncertainty (Hz), or refusal."""

    error_hz: np.ndarray | None = None
    std_hz: np.ndarray | None = None
    terms_hz: dict = field(default_factory=dict)
    refused: str | None = None
    identified: str = ""
    right: bool | None = None


@dataclass
class Case:
    preset: str
    ports: int
    seed: int
    axis_error_rms_hz: float
    outcomes: dict
    test_hz: np.ndarray


def _fit(frequency_hz, powers):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return wm.WidebandCalibrator(fsr_hz=DESIGN_FSR_HZ).fit(powers, frequency_hz)


def _identified_right(axis, cell, sweep) -> bool:
    """Whether each fitted line got the label of the true line nearest its true frequency."""
    truth = cell.line_centers_hz()
    at = np.interp(axis.lines.index, np.arange(sweep.true_hz.size), sweep.true_hz)
    nearest = np.argmin(np.abs(at[:, None] - truth[None, :]), axis=1)
    return bool(np.array_equal(nearest, axis.identification.table_index))


def _evaluate(calibration, axis, powers, truth_hz) -> Outcome:
    predicted = calibration.predict(powers, coarse_hz=truth_hz)
    own = calibration.frequency_std_hz(powers, coarse_hz=truth_hz)
    if axis is None:
        return Outcome(predicted - truth_hz, own, {"calibration": own})
    budget = axis.budget_at_hz(predicted)
    terms = {name: budget[name] for name in BUDGET_TERMS} | {"calibration": own}
    return Outcome(predicted - truth_hz, np.hypot(own, budget["total"]), terms)


def run_case(preset: str, ports: int, seed: int, samples: int, test: int) -> Case:
    key = zlib.crc32(f"{preset}/{ports}/{seed}".encode())
    rng = np.random.default_rng(key)
    cell = ReferenceCell.simulated(rng=rng.spawn(1)[0])
    lines = cell.lines
    band = (lines.center_hz[0] - MARGIN_HZ, lines.center_hz[-1] + MARGIN_HZ)
    sweep = laser_sweep(band, samples, preset, rng=rng.spawn(1)[0])
    device = wm.Interferometer.table1(ports, seed=seed).with_spectral("sin", seed=seed)
    powers = device.powers(sweep.true_hz, POWER_W, NOISE_W, rng=rng.spawn(1)[0])
    transmission = cell.transmission(sweep.true_hz, rng=rng.spawn(1)[0])
    test_hz = rng.uniform(lines.center_hz[0], lines.center_hz[-1], test)
    test_powers = device.powers(test_hz, POWER_W, NOISE_W, rng=rng.spawn(1)[0])
    inside = (sweep.true_hz >= test_hz.min()) & (sweep.true_hz <= test_hz.max())
    outcomes = {"true": _evaluate(_fit(sweep.true_hz, powers), None, test_powers, test_hz)}
    pressure = {"pressure_pa": cell.nominal_pressure_pa, "pressure_std_pa": cell.pressure_std_pa}
    plain = None
    try:
        plain = _fit(sweep.recorded_hz, powers)
        outcomes["a"] = _evaluate(plain, None, test_powers, test_hz)
    except wm.WavemeterError as exc:
        outcomes["a"] = Outcome(refused=str(exc))
    spec = SWEEP_PRESETS[preset]
    if spec.tuning == "wavelength":
        shortest = SPEED_OF_LIGHT_M_S / band[1]
        axis_error = SPEED_OF_LIGHT_M_S * (SPEC_M + 5 * spec.jitter_std_m) / shortest**2
    else:
        axis_error = None
    if plain is not None:
        recorded = sweep.recorded_hz

        def phase_of(p):
            return plain.phase(p, coarse_hz=recorded)
    else:

        def phase_of(p):
            return sweep_phase_reference_free(p)[0]

    try:
        axis = correct_sweep_axis(
            powers,
            sweep.recorded_hz,
            transmission,
            lines,
            phase_of=phase_of,
            axis_error_hz=axis_error,
            **pressure,
        )
        outcomes["b"] = _evaluate(_fit(axis.frequency_hz, powers), axis, test_powers, test_hz)
        outcomes["b"].identified = axis.identification.method + (
            "" if plain is not None else " (reference-free phase)"
        )
        outcomes["b"].right = _identified_right(axis, cell, sweep)
    except wm.WavemeterError as exc:
        outcomes["b"] = Outcome(refused=str(exc))
    try:
        selfcal = self_calibrate(
            powers, transmission, lines, band, fsr_hz=DESIGN_FSR_HZ, **pressure
        )
        outcomes["c"] = _evaluate(
            _fit(selfcal.frequency_hz, powers), selfcal.axis, test_powers, test_hz
        )
        outcomes["c"].identified = selfcal.axis.identification.method
        outcomes["c"].right = _identified_right(selfcal.axis, cell, sweep)
    except wm.WavemeterError as exc:
        outcomes["c"] = Outcome(refused=str(exc))
    return Case(preset, ports, seed, rms(sweep.axis_error_hz[inside]), outcomes, test_hz)


def precision_hz(error_hz: np.ndarray, frequency_hz: np.ndarray) -> float:
    """RMS of the error less its Legendre fit of order DETREND_ORDER in frequency (Hz)."""
    u = 2 * (frequency_hz - frequency_hz.min()) / np.ptp(frequency_hz) - 1
    coefficients = np.polynomial.legendre.legfit(u, error_hz, DETREND_ORDER)
    return rms(error_hz - np.polynomial.legendre.legval(u, coefficients))


def _mhz(value: float, digits: int = 3) -> str:
    return f"{value / 1e6:.{digits}g}"


def _pooled(cases, method):
    done = [c.outcomes[method] for c in cases if c.outcomes[method].error_hz is not None]
    if not done:
        return None
    error = np.concatenate([o.error_hz for o in done])
    std = np.concatenate([o.std_hz for o in done])
    return error, std


def case_table(cases) -> str:
    headers = [
        "laser",
        "ports",
        "seed",
        "laser axis error RMS (MHz)",
        "(a) abs RMS (MHz)",
        "(b) abs RMS / budget (MHz)",
        "(b) z std",
        "(c) abs RMS / budget (MHz)",
        "(c) z std",
        "precision (b)/true, (c)/true",
        "identification (b); (c)",
    ]
    rows = []
    for case in cases:
        o = case.outcomes
        cells = [case.preset, case.ports, case.seed, _mhz(case.axis_error_rms_hz, 4)]
        cells.append(
            f"refused: {o['a'].refused[:70]}" if o["a"].refused else _mhz(rms(o["a"].error_hz), 4)
        )
        for method in ("b", "c"):
            if o[method].refused:
                cells += ["refused", "-"]
            else:
                cells.append(f"{_mhz(rms(o[method].error_hz))} / {_mhz(rms(o[method].std_hz))}")
                cells.append(f"{np.std(o[method].error_hz / o[method].std_hz):.3f}")
        test_hz = case.test_hz
        ratios = []
        for method in ("b", "c"):
            if o[method].refused or o["true"].error_hz is None:
                ratios.append("-")
            else:
                ratio = precision_hz(o[method].error_hz, test_hz) / precision_hz(
                    o["true"].error_hz, test_hz
                )
                ratios.append(f"{ratio:.4f}")
        cells.append(", ".join(ratios))
        ident = []
        for method in ("b", "c"):
            if o[method].refused:
                ident.append(f"refused: {o[method].refused[:90]}")
            else:
                ident.append(f"{o[method].identified}, {'right' if o[method].right else 'WRONG'}")
        cells.append("; ".join(ident))
        rows.append(cells)
    return markdown_table(headers, rows)


def budget_table(cases) -> str:
    headers = [
        "laser",
        "calibration",
        *BUDGET_TERMS,
        "axis total",
        "calibrator's own (reading + fit)",
        "total stated",
        "abs RMS error",
    ]
    rows = []
    for preset in dict.fromkeys(c.preset for c in cases):
        for method in ("b", "c"):
            done = [
                c.outcomes[method]
                for c in cases
                if c.preset == preset and c.outcomes[method].error_hz is not None
            ]
            if not done:
                continue
            cells = [preset, LABELS[method]]
            for name in BUDGET_TERMS:
                cells.append(_mhz(rms(np.concatenate([o.terms_hz[name] for o in done]))))
            axis = [np.sqrt(sum(o.terms_hz[name] ** 2 for name in BUDGET_TERMS)) for o in done]
            cells.append(_mhz(rms(np.concatenate(axis))))
            cells.append(_mhz(rms(np.concatenate([o.terms_hz["calibration"] for o in done]))))
            cells.append(_mhz(rms(np.concatenate([o.std_hz for o in done]))))
            cells.append(_mhz(rms(np.concatenate([o.error_hz for o in done]))))
            rows.append(cells)
    return markdown_table(headers, rows)


def targets_table(cases) -> tuple[str, bool]:
    rows = []
    passed = True

    def add(target, figure, ok):
        nonlocal passed
        passed &= ok
        rows.append([target, figure, status(ok)])

    for preset in dict.fromkeys(c.preset for c in cases):
        mine = [c for c in cases if c.preset == preset]
        for method in ("b", "c"):
            pooled = _pooled(mine, method)
            refused = [c for c in mine if c.outcomes[method].refused]
            if pooled is None:
                add(f"{preset}: {LABELS[method]} calibrates", f"refused in all {len(mine)}", False)
                continue
            error, std = pooled
            ratio = rms(error) / rms(std)
            add(
                f"{preset}: {LABELS[method]} abs RMS <= 1.2x stated budget",
                f"{_mhz(rms(error))} / {_mhz(rms(std))} MHz = {ratio:.3f}"
                + (f" ({len(refused)} refused)" if refused else ""),
                ratio <= 1.2,
            )
            z = np.std(error / std)
            add(f"{preset}: {LABELS[method]} z std in 0.9-1.1", f"{z:.3f}", 0.9 <= z <= 1.1)
            worst = max(
                precision_hz(c.outcomes[method].error_hz, c.test_hz)
                / precision_hz(c.outcomes["true"].error_hz, c.test_hz)
                for c in mine
                if c.outcomes[method].error_hz is not None
            )
            add(
                f"{preset}: {LABELS[method]} precision <= 1.05x true-axis calibration's",
                f"worst {worst:.4f}",
                worst <= 1.05,
            )
            wrong = [c for c in mine if c.outcomes[method].right is False]
            add(
                f"{preset}: {LABELS[method]} identification right or refused with reason",
                f"{len(mine) - len(wrong) - len(refused)} right, {len(refused)} refused, "
                f"{len(wrong)} wrong",
                not wrong,
            )
        plain = [c for c in mine if not c.outcomes["a"].refused]
        inherits = all(rms(c.outcomes["a"].error_hz) >= 0.5 * _expected_plain_hz(c) for c in plain)
        figure = ", ".join(
            f"{_mhz(rms(c.outcomes['a'].error_hz), 4)} vs {_mhz(_expected_plain_hz(c), 4)}"
            for c in plain[:3]
        )
        refused = len(mine) - len(plain)
        add(
            f"{preset}: (a) plain shows the laser's error (RMS >= half the laser's, or refused)",
            (figure or "-") + (f"; {refused} refused" if refused else ""),
            inherits,
        )
    return markdown_table(["target", "measured", "status"], rows), passed


def _expected_plain_hz(case) -> float:
    """The error (Hz RMS) a calibration that inherits the laser's axis shows: the axis's own
    RMS error, or, where that exceeds half an FSR, the RMS of an error spread evenly over one
    FSR (``FSR / sqrt 12``): the coarse value, here the truth, then picks the fringe."""
    return min(case.axis_error_rms_hz, DESIGN_FSR_HZ / np.sqrt(12.0))


def anchors_table(cases) -> str:
    rows = []
    for preset in dict.fromkeys(c.preset for c in cases):
        for method in ("a", "b", "c"):
            pooled = _pooled([c for c in cases if c.preset == preset], method)
            if pooled is None:
                rows.append([preset, LABELS[method], "refused", "-"])
                continue
            error = rms(pooled[0])
            rows.append([preset, LABELS[method], _mhz(error, 4), f"{error / 193.4e12:.2g}"])
    anchors = "; ".join(f"{name}: {_mhz(value, 3)} MHz" for name, value in ANCHORS.items())
    return markdown_table(["laser", "calibration", "abs RMS (MHz)", "relative"], rows) + (
        f"\n\nAnchors (issue 32): {anchors}."
    )


def main(argv=None) -> int:
    parser = Parser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=positive_int, default=3)
    parser.add_argument("--samples", type=positive_int, default=50_000)
    parser.add_argument("--test", type=positive_int, default=4000)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    quick = args.quick or os.environ.get(QUICK_ENV) == "1"
    seeds = 1 if quick else args.seeds
    samples = 30_000 if quick else args.samples
    test = 1000 if quick else args.test
    ports_list = (3,) if quick else PORTS
    cases = []
    start = time.perf_counter()
    for preset in PRESETS:
        for ports in ports_list:
            for seed in range(1, seeds + 1):
                progress(
                    f"{preset}, {ports} ports, seed {seed} ({time.perf_counter() - start:.0f} s)"
                )
                case = run_case(preset, ports, seed, samples, test)
                cases.append(case)
    progress("")
    sys.stderr.write("\n")

    print(
        f"# Absolute accuracy from a reference cell ({len(cases)} cases, {samples} sweep "
        f"samples, {test} test readings each)\n"
    )
    print(case_table(cases) + "\n")
    print("## Budget terms (RMS over the test readings, MHz)\n")
    print(budget_table(cases) + "\n")
    print("## Absolute accuracy beside the anchors\n")
    print(anchors_table(cases) + "\n")
    table, passed = targets_table(cases)
    print("## Targets\n")
    print(table)
    sys.stderr.write(f"total {time.perf_counter() - start:.0f} s\n")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
