"""The fault catalogue's second part: the right cause on wide and rounded sweeps, and silence
on clean sweeps of every method.

Every row is simulated as ``wavemeter simulate`` writes it (``wavemeter.simulation.Scenario``)
and calibrated as a user would, over ``seeds`` seeds (a new device and new noise each):

- a plain calibration (``Calibrator``) over 24 FSRs of a device whose couplers and detectors
  change with the wavelength (``spectral="sin"``), with 25x the platform's dispersion (the
  wide-band page's example) and with the platform's own: the cause is ``dispersion``, whose
  remedy is the wide-band calibration;
- controls on the same 24 FSRs whose cause is a drift in time, not the device: a cycling
  thermostat (``phase_drift``) and a slow source-power drift without a monitor
  (``power_drift``);
- an axis rounded as a spreadsheet rounds it: wavelength to 0.001 nm (about 400 distinct
  values in 2001 rows) and 0.0001 nm (every value its own, on a grid), frequency to 100 MHz:
  the cause is ``quantised_axis``; a stepped laser whose five readings per set point
  share their (exact, round) frequency is a control that must not warn;
- clean sweeps, where nothing may warn: plain (the default ``simulate``), thermal (SiN, a
  290-300 K ramp over five sweeps, ``ThermalCalibrator``), wide-band (the wide-band page's
  example, ``WidebandCalibrator``) and the cascade page's 5 THz / 500 GHz / 50 GHz cascade
  (``CascadeCalibrator``).

Per row: the causes named and counted, the right-cause rate (calibrations naming the
expected cause), and for rows that expect none the false-alarm rate with its one-sided 95 %
upper bound (Clopper-Pearson). Each test of the fit diagnostics fails an in-model sweep with
probability ``TEST_P_VALUE`` (1e-6), so a false alarm is a model error, not chance.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from _montecarlo import NOISE_W, POWER_W, Fit, causes_cell, fit_recorded, markdown_table, progress
from scipy import stats

import wavemeter as wm
from wavemeter.simulation import Scenario
from wavemeter.units import FREQUENCY_UNITS, SPEED_OF_LIGHT_M_S

#: the targets: right cause in this share of a fault row's calibrations, false alarms of
#: clean rows below this rate
RIGHT_CAUSE_RATE = 0.9
FALSE_ALARM_RATE = 0.01
#: wide rows: FSRs and readings (the wide-band page's example)
WIDE_SPAN_FSR = 24.0
WIDE_SAMPLES = 9600
#: thermostat of the wide control: 3 cycles of 0.025 K at 1 rad/K (the diagnostics' test case)
THERMOSTAT_CYCLES = 3.0
THERMOSTAT_K = 0.025
CASCADE_FSRS_HZ = (5e12, 500e9, 50e9)
#: readings per set point of the stepped laser, and the set points' grid (Hz)
STEPPED_READINGS = 5
STEPPED_GRID_HZ = 1e8


@dataclass(frozen=True)
class Sweep:
    """One calibration sweep and how it is calibrated."""

    powers_w: np.ndarray
    frequency_hz: np.ndarray
    calibrator: object
    inputs: dict


@dataclass(frozen=True)
class CauseRow:
    """A row: its label, how a seed's sweep is made, the cause expected (None: none)."""

    key: str
    label: str
    build: Callable[[int], Sweep]
    cause: str | None
    clean: bool = False


def _ports(table: dict) -> np.ndarray:
    return np.column_stack([values for name, values in table.items() if name.startswith("p")])


def _scenario_sweep(calibrator, **fields) -> Callable[[int], Sweep]:
    def build(seed: int) -> Sweep:
        sweep, _ = Scenario(seed=seed, **fields).tables()
        inputs = {}
        if "temperature_k" in sweep:
            inputs["temperature_k"] = sweep["temperature_k"]
        axis = next(name for name in sweep if name.startswith("frequency"))
        return Sweep(_ports(sweep), sweep[axis], calibrator(), inputs)

    return build


def _rounded(unit: str, decimals: int) -> Callable[[int], Sweep]:
    """The default sweep with its axis written in ``unit`` and rounded to ``decimals``."""

    def build(seed: int) -> Sweep:
        sweep, _ = Scenario(seed=seed, x_unit=unit).tables()
        axis = next(name for name in sweep if name.startswith(("frequency", "wavelength")))
        recorded = np.round(sweep[axis], decimals)
        if unit == "nm":
            frequency = SPEED_OF_LIGHT_M_S / (recorded * 1e-9)
        else:
            frequency = recorded * 10.0 ** FREQUENCY_UNITS[unit]
        return Sweep(_ports(sweep), frequency, wm.Calibrator(), {})

    return build


def _wide_thermostat(seed: int) -> Sweep:
    device = dataclasses.replace(
        wm.Interferometer.table1(3, seed=seed), thermal_phase_rad_per_k=1.0
    )
    rows = np.arange(WIDE_SAMPLES) / WIDE_SAMPLES
    cycle = THERMOSTAT_K * np.sin(2.0 * np.pi * THERMOSTAT_CYCLES * rows)
    frequency = device.sweep_hz(WIDE_SAMPLES, WIDE_SPAN_FSR)
    powers = device.powers(
        frequency,
        POWER_W,
        NOISE_W,
        rng=seed,
        temperature_k=device.reference_temperature_k + cycle,
    )
    return Sweep(powers, frequency, wm.Calibrator(), {})


def _stepped(seed: int) -> Sweep:
    device = wm.Interferometer.table1(3, seed=seed)
    points = np.round(device.sweep_hz(2000 // STEPPED_READINGS) / STEPPED_GRID_HZ) * STEPPED_GRID_HZ
    frequency = np.repeat(points, STEPPED_READINGS)
    return Sweep(
        device.powers(frequency, POWER_W, NOISE_W, rng=seed), frequency, wm.Calibrator(), {}
    )


WIDE = {"span_fsr": WIDE_SPAN_FSR, "samples": WIDE_SAMPLES}
ROWS = (
    CauseRow(
        "wide_dispersion",
        "SiN slopes, 25x dispersion (1e-26 s^2), 24 FSRs, plain",
        _scenario_sweep(wm.Calibrator, spectral="sin", dispersion_s2=1e-26, **WIDE),
        "dispersion",
    ),
    CauseRow(
        "wide_slopes",
        "SiN slopes and dispersion (4e-28 s^2), 24 FSRs, plain",
        _scenario_sweep(wm.Calibrator, spectral="sin", **WIDE),
        "dispersion",
    ),
    CauseRow(
        "wide_thermostat",
        "thermostat cycling, 24 FSRs, plain (control)",
        _wide_thermostat,
        "phase_drift",
    ),
    CauseRow(
        "wide_power_drift",
        "power drift +-5 %, no monitor, 24 FSRs, plain (control)",
        _scenario_sweep(wm.Calibrator, power_drift=0.05, monitor=False, **WIDE),
        "power_drift",
    ),
    CauseRow("rounded_pm", "wavelength rounded to 0.001 nm", _rounded("nm", 3), "quantised_axis"),
    CauseRow(
        "rounded_subpm", "wavelength rounded to 0.0001 nm", _rounded("nm", 4), "quantised_axis"
    ),
    CauseRow("rounded_mhz", "frequency rounded to 100 MHz", _rounded("THz", 4), "quantised_axis"),
    CauseRow(
        "stepped",
        f"stepped laser, {STEPPED_READINGS} readings per set point (control)",
        _stepped,
        None,
        clean=True,
    ),
    CauseRow(
        "clean_plain",
        "clean, plain (simulate defaults)",
        _scenario_sweep(wm.Calibrator),
        None,
        True,
    ),
    CauseRow(
        "clean_thermal",
        "clean, thermal (SiN, 290-300 K ramp, 5 sweeps)",
        _scenario_sweep(wm.ThermalCalibrator, platform="sin", ramp_k=(290.0, 300.0), repeat=5),
        None,
        True,
    ),
    CauseRow(
        "clean_wideband",
        "clean, wide-band (the wide-band page's sweep)",
        _scenario_sweep(wm.WidebandCalibrator, spectral="sin", dispersion_s2=1e-26, **WIDE),
        None,
        True,
    ),
    CauseRow(
        "clean_cascade",
        "clean, cascade (the cascade page's sweep)",
        _scenario_sweep(
            lambda: wm.CascadeCalibrator(fsr_hz=CASCADE_FSRS_HZ),
            cascade_fsrs_hz=CASCADE_FSRS_HZ,
            spectral="sin",
            samples=20000,
        ),
        None,
        True,
    ),
)
HEADERS = (
    "sweep",
    "calibrations",
    "warned (causes)",
    "expected",
    "right cause",
    "false alarms (95 % bound)",
)


def upper_bound(count: int, total: int, level: float = 0.95) -> float:
    """One-sided Clopper-Pearson upper bound of a rate seen ``count`` times in ``total``."""
    return 1.0 if count >= total else float(stats.beta.ppf(level, count + 1, total - count))


@dataclass(frozen=True)
class CauseResult:
    row: CauseRow
    fits: list[Fit]

    def right(self) -> int:
        return sum(self.row.cause in fit.causes for fit in self.fits)

    def alarms(self) -> int:
        return sum(bool(fit.causes or fit.refused) for fit in self.fits)

    def cells(self) -> list[str]:
        total = len(self.fits)
        if self.row.cause is None:
            right = "-"
            alarms = f"{self.alarms()}/{total} ({100 * upper_bound(self.alarms(), total):.2g} %)"
        else:
            right = f"{self.right()}/{total}"
            alarms = "-"
        return [
            self.row.label,
            str(total),
            causes_cell(self.fits),
            self.row.cause or "none",
            right,
            alarms,
        ]


def run_rows(keys, seeds: int, clean_seeds: int, seed: int) -> list[CauseResult]:
    """Every row of ``keys``: ``seeds`` calibrations (``clean_seeds`` for clean rows)."""
    results = []
    rows = [row for row in ROWS if row.key in keys]
    for number, row in enumerate(rows, 1):
        fits = []
        count = clean_seeds if row.clean else seeds
        for index in range(count):
            progress(f"causes row {number}/{len(rows)}: {row.label} ({index + 1}/{count})")
            sweep = row.build(seed + index)
            fits.append(
                fit_recorded(sweep.calibrator, sweep.powers_w, sweep.frequency_hz, **sweep.inputs)
            )
        results.append(CauseResult(row, fits))
    return results


def table(results: list[CauseResult]) -> str:
    return markdown_table(HEADERS, [result.cells() for result in results])


def verdict(results: list[CauseResult]) -> list[str]:
    """Two lines: the right-cause rate of the fault rows, the clean rows' false alarms."""
    faults = [result for result in results if result.row.cause is not None]
    clean = [result for result in results if result.row.cause is None]
    lines = []
    if faults:
        low = [r for r in faults if r.right() < RIGHT_CAUSE_RATE * len(r.fits)]
        rates = ", ".join(f"{r.row.key} {r.right()}/{len(r.fits)}" for r in faults)
        lines.append(
            f"{'PASS' if not low else 'FAIL'} right cause in >= {RIGHT_CAUSE_RATE:.0%} of each "
            f"wide or rounded row's calibrations: {rates}"
        )
    if clean:
        alarms = sum(r.alarms() for r in clean)
        total = sum(len(r.fits) for r in clean)
        bound = upper_bound(alarms, total)
        lines.append(
            f"{'PASS' if alarms <= FALSE_ALARM_RATE * total else 'FAIL'} clean sweeps of every "
            f"method warn in <= {FALSE_ALARM_RATE:.0%}: {alarms} of {total} calibrations "
            f"(95 % upper bound {100 * bound:.2g} %)"
        )
    return lines
