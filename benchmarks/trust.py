"""Fault catalogue: does the calibration say when it cannot be trusted, and does the remedy work?

Every fault of issue 9 at three severities, simulated on Table 1 devices (3 ports, FSR
50 GHz, 1 mW, detector noise 5e-7 W) and calibrated without the remedy. Per row, over
``--devices`` devices (each a fresh calibration and fresh test readings):

- RMS/CRLB: RMS frequency error on the test readings over the RMS of the true device's
  per-reading Cramer-Rao bound (median over devices);
- warned: calibrations whose fit emitted a ``CalibrationWarning`` (or refused the sweep),
  with the causes named and their counts;
- flagged: share of the affected test readings that carry a ``ReadingFlag``. A reading is
  affected when the fault alone (the same reading without detector noise, through the
  faulty calibration) moves it by more than ``sqrt(1.25)`` times its bound, so that its
  RMS error exceeds 1.5 CRLB; readings outside a partial span, and every reading of a fault
  that raises the variance only (unequal noise, weak port), are affected by definition;
- z std: standard deviation of ``error / frequency_std_hz`` over the row's test readings;
- RMS/CRLB with the remedy the warning names (median over devices; a remedy that refuses
  the sweep counts as infinite);
- silent: calibrations with RMS/CRLB > 1.5 that neither warned nor flagged >= 90 % of their
  affected readings (the issue's "silent failure").

Errors are taken modulo the device's FSR at the centre; the bound is the true device's
(its map, the test reading's power and bias, its local FSR where there is dispersion).

Faults (the fault is in the calibration sweep; test readings are at the nominal source
power, at the sweep's mean chip temperature, unless said otherwise):

- slow source-power drift during an unmonitored sweep, and 1/f power noise; remedy: the
  power monitor;
- detector offsets not subtracted, as a fraction of each port's mean signal (random sign),
  test readings at source power 0.5-1.5x: calibrated at constant power without a monitor
  (the offset is then part of the map and only readings at other powers show it), and with
  a monitored source power varying 0.5-1.5x during the sweep (the calibrator fits the
  offsets itself and should say so); remedy: dark readings;
- chip temperature drift at 1 rad/K during the sweep: a linear ramp over a one-way sweep
  (indistinguishable from another FSR: documented, not expected to be caught), a cycling
  thermostat, a ramp over an up-then-down sweep; no remedy yet (thermal calibrator);
- group-delay dispersion over a 10-FSR sweep; remedy: one calibration per FSR
  (``CalibrationSet``, coarse frequency = truth + 1 GHz Gaussian error, clipped to the
  span the set covers);
- a calibration over part of an FSR, test readings over the whole FSR; remedy: calibrate
  over one FSR;
- one port noisier than the other two (noise 1:1:r); remedy: ``retrieval="ml"``;
- one port with a weak responsivity (an ill-conditioned map); remedy: ``retrieval="ml"``;
- clean, in-model devices of 3, 4 and 5 ports: ``--clean-calibrations`` in all, for the
  false-alarm rate.

A verdict block checks the issue's targets (the one-way thermal ramp is reported apart
from the silent-failure target, as a documented limitation). Stdout carries only the
tables; device ``k`` of a row is device ``k`` of every row with that port count.

A second table (:mod:`trust_causes`, issue 29) names the cause on the sweeps users make:
plain calibrations over 24 FSRs of a device that changes with the wavelength, with a drift
in time as a control, rounded frequency axes, and clean sweeps of every method (plain,
thermal, wide-band, cascade), with the right-cause rate over ``--cause-seeds`` seeds and
the clean sweeps' false-alarm rate over ``--clean-seeds``.

Usage: ``python benchmarks/trust.py [--devices 5] [--clean-calibrations 200] [--samples 2001]
[--test 5000] [--seed 0] [--faults KEY,...] [--cause-seeds 20] [--clean-seeds 50]
[--cause-rows KEY,...|none] [--quick]``
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import warnings
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trust_causes
from _montecarlo import NOISE_W, POWER_W, make_device, markdown_table, progress

import wavemeter as wm
from wavemeter.simulation.drift import flicker_power_noise, slow_power_drift, thermal_ramp_rad

PORTS = 3
DESIGN_FSR_HZ = 50e9
#: bias phase per kelvin of the thermal rows (rad/K)
RAD_PER_K = 1.0
#: periods of the cycling thermostat over one sweep
THERMOSTAT_CYCLES = 3.0
#: sweep of the dispersion rows, in FSRs
DISPERSION_SPAN_FSR = 10.0
#: standard deviation of the coarse frequency given to a calibration set (Hz)
COARSE_STD_HZ = 1e9
#: relative source power of readings at varying power (offset rows)
VARYING_POWER_RANGE = (0.5, 1.5)
#: a reading whose fault-only error exceeds this many bounds has an RMS error > 1.5 CRLB
AFFECTED_BIAS_CRLB = np.sqrt(1.5**2 - 1.0)
#: targets of issue 9
SILENT_RMS_OVER_CRLB = 1.5
CAUGHT_FLAGGED_SHARE = 0.9
RIGHT_CAUSE_SHARE = 0.8
CLEAN_FALSE_ALARM_RATE = 0.01
Z_STD_RANGE = (0.95, 1.05)
REMEDY_RMS_OVER_CRLB = 1.1


@dataclass(frozen=True)
class Case:
    """One faulty device with its calibration sweep and its test readings.

    Attributes
    ----------
    device : wavemeter.Interferometer
        The faulty device (the truth: map, dispersion, offsets).
    train_w : ndarray, shape (N, n), W
    train_hz : ndarray, shape (N,), Hz
    train_power_w : ndarray, shape (N,), W
        Source power of each calibration reading (a monitor reads ``monitor_ratio`` times it).
    test_w : ndarray, shape (M, n), W
    test_clean_w : ndarray, shape (M, n), W
        The same test readings without detector noise.
    test_hz : ndarray, shape (M,), Hz
    test_power_w : float or ndarray, shape (M,), W
    test_bias_rad : float
        Bias phase drift of the test readings (rad): the chip's temperature then.
    noise_w : float or ndarray, shape (n,), W
        Detector noise standard deviation.
    affected : None or ndarray of bool, shape (M,)
        Test readings affected by definition; None: decided by the fault-only error.
    """

    device: wm.Interferometer
    train_w: np.ndarray
    train_hz: np.ndarray
    train_power_w: np.ndarray
    test_w: np.ndarray
    test_clean_w: np.ndarray
    test_hz: np.ndarray
    test_power_w: float | np.ndarray
    test_bias_rad: float
    noise_w: float | np.ndarray
    affected: np.ndarray | None = None

    def monitor_w(self) -> np.ndarray:
        """Power-monitor reading (W) of each calibration reading."""
        return self.device.monitor(self.train_power_w)


@dataclass(frozen=True)
class Fault:
    """One fault of the catalogue and what to expect of it.

    Attributes
    ----------
    key : str
        Short identifier (seeds the data).
    label : str
        Row name in the table.
    severities : tuple of float
        The three severities, in the unit ``build`` takes.
    severity_text : callable
        Severity as printed.
    build : callable
        ``build(device, severity, rng, samples, test) -> Case``.
    cause : None or str
        The ``CalibrationWarning.cause`` expected (None: none is expected).
    remedy : str
        The remedy as printed ("n/a" when there is none yet).
    apply_remedy : None or callable
        ``apply_remedy(case, rng) -> predicted test frequencies (Hz)``.
    monitored : bool
        The calibration without the remedy has the power monitor.
    in_model : bool
        The readings follow the model (per-port noise allowed): z-scores must have unit spread.
    blind : bool
        Documented as undetectable at fit time (kept out of the silent-failure target).
    ports : int
    """

    key: str
    label: str
    severities: tuple[float, ...]
    severity_text: Callable[[float], str]
    build: Callable[..., Case]
    cause: str | None
    remedy: str
    apply_remedy: Callable[[Case, np.random.Generator], np.ndarray] | None = None
    monitored: bool = False
    in_model: bool = False
    blind: bool = False
    ports: int = PORTS


@dataclass(frozen=True)
class Outcome:
    """What one calibration of one row gave."""

    causes: tuple[str, ...]
    refused: str | None
    rms_over_crlb: float
    flagged: int
    affected: int
    z: np.ndarray
    remedy_rms_over_crlb: float | None
    remedy_refused: str | None = None

    @property
    def warned(self) -> bool:
        return bool(self.causes) or self.refused is not None

    @property
    def silent(self) -> bool:
        """RMS above 1.5 CRLB with no warning and fewer than 90 % of affected readings flagged."""
        caught = self.affected > 0 and self.flagged >= CAUGHT_FLAGGED_SHARE * self.affected
        return (
            self.refused is None
            and self.rms_over_crlb > SILENT_RMS_OVER_CRLB
            and not self.warned
            and not caught
        )


# ---------------------------------------------------------------------- simulation
def crlb_hz(device: wm.Interferometer, frequency_hz, power_w, noise_w, bias_rad=0.0):
    """Per-reading Cramer-Rao bound (Hz) of the true device, at its local FSR.

    Parameters
    ----------
    device : wavemeter.Interferometer
    frequency_hz : ndarray, shape (M,), Hz
    power_w : float or ndarray, shape (M,), W
    noise_w : float or ndarray, shape (n,), W
    bias_rad : float
        Bias phase drift of the readings (rad): a rotation of the true map's phase.

    Returns
    -------
    ndarray, shape (M,), Hz
    """
    phase_rad = device.phase_rad(frequency_hz) + bias_rad
    per_fsr = wm.crlb_frequency_std(device.true_map(), phase_rad, power_w, noise_w, 1.0)
    return per_fsr / device.group_delay_s(frequency_hz)


def make_case(
    device,
    rng,
    samples: int,
    test: int,
    *,
    train_hz=None,
    test_span_fsr: float = 1.0,
    train_power_w=POWER_W,
    test_power_w=POWER_W,
    noise_w=NOISE_W,
    train_bias_rad=None,
    affected=None,
) -> Case:
    """Calibration sweep and test readings of ``device``.

    Parameters
    ----------
    device : wavemeter.Interferometer
        The (faulty) device.
    rng : numpy.random.Generator
        Source of test frequencies and detector noise.
    samples, test : int
        Calibration readings (when ``train_hz`` is None) and test readings.
    train_hz : None or ndarray, shape (N,), Hz
        Calibration frequencies in acquisition order; None: ``device.sweep_hz(samples)``.
    test_span_fsr : float
        Test frequencies are uniform over this many true FSRs about the centre.
    train_power_w, test_power_w : float or ndarray, W
        Source power, one value or one per reading.
    noise_w : float or ndarray, shape (n,), W
        Detector noise standard deviation.
    train_bias_rad : None or ndarray, shape (N,), rad
        Bias phase drift during the sweep; the test readings get its mean (the chip's mean
        temperature during the sweep).
    affected : None or callable
        ``affected(train_hz, test_hz) -> bool mask`` of the test readings affected by
        definition; None: decided later by the fault-only error.

    Returns
    -------
    Case
    """
    train_hz = device.sweep_hz(samples) if train_hz is None else train_hz
    train_power = np.broadcast_to(np.asarray(train_power_w, dtype=float), train_hz.shape)
    train_w = device.powers(train_hz, train_power, noise_w, rng, bias_drift_rad=train_bias_rad)
    half_hz = 0.5 * test_span_fsr * device.true_fsr_hz
    test_hz = device.center_hz + rng.uniform(-half_hz, half_hz, test)
    test_bias = 0.0 if train_bias_rad is None else float(np.mean(train_bias_rad))
    test_w = device.powers(test_hz, test_power_w, noise_w, rng, bias_drift_rad=test_bias)
    test_clean = device.powers(test_hz, test_power_w, 0.0, bias_drift_rad=test_bias)
    if callable(affected):
        affected = affected(train_hz, test_hz)
    return Case(
        device,
        train_w,
        train_hz,
        train_power,
        test_w,
        test_clean,
        test_hz,
        test_power_w,
        test_bias,
        noise_w,
        affected,
    )


def every_reading(_train_hz, test_hz) -> np.ndarray:
    """All test readings are affected (a fault that raises the variance only)."""
    return np.ones(test_hz.shape, dtype=bool)


def outside_sweep(train_hz, test_hz) -> np.ndarray:
    """Test readings outside the calibrated span."""
    return (test_hz < train_hz.min()) | (test_hz > train_hz.max())


def clean(device, _severity, rng, samples, test) -> Case:
    return make_case(device, rng, samples, test)


def power_drift(device, amplitude, rng, samples, test) -> Case:
    power_w = POWER_W * slow_power_drift(samples, amplitude, rng)
    return make_case(device, rng, samples, test, train_power_w=power_w)


def flicker(device, relative_std, rng, samples, test) -> Case:
    power_w = POWER_W * flicker_power_noise(samples, relative_std, rng)
    return make_case(device, rng, samples, test, train_power_w=power_w)


def with_offsets(device, fraction, rng) -> wm.Interferometer:
    """``device`` with dark offsets of ``fraction`` of each port's mean signal, random sign."""
    mean_signal_w = POWER_W * np.sqrt(2.0) * device.true_map()[:, 2]
    sign = rng.choice([-1.0, 1.0], device.ports)
    return dataclasses.replace(device, dark_offset_w=fraction * sign * mean_signal_w)


def offsets_constant_power(device, fraction, rng, samples, test) -> Case:
    test_power_w = POWER_W * rng.uniform(*VARYING_POWER_RANGE, test)
    return make_case(
        with_offsets(device, fraction, rng), rng, samples, test, test_power_w=test_power_w
    )


def offsets_varying_power(device, fraction, rng, samples, test) -> Case:
    return make_case(
        with_offsets(device, fraction, rng),
        rng,
        samples,
        test,
        train_power_w=POWER_W * rng.uniform(*VARYING_POWER_RANGE, samples),
        test_power_w=POWER_W * rng.uniform(*VARYING_POWER_RANGE, test),
    )


def thermal_one_way(device, total_k, rng, samples, test) -> Case:
    drift_rad = thermal_ramp_rad(samples, total_k, RAD_PER_K)
    return make_case(device, rng, samples, test, train_bias_rad=drift_rad)


def thermal_cycle(device, total_k, rng, samples, test) -> Case:
    drift_rad = thermal_ramp_rad(samples, total_k, RAD_PER_K, "cycle", THERMOSTAT_CYCLES)
    return make_case(device, rng, samples, test, train_bias_rad=drift_rad)


def thermal_two_way(device, total_k, rng, samples, test) -> Case:
    up_hz = device.sweep_hz(samples // 2)
    train_hz = np.concatenate([up_hz, up_hz[::-1]])
    drift_rad = thermal_ramp_rad(train_hz.size, total_k, RAD_PER_K)
    return make_case(device, rng, samples, test, train_hz=train_hz, train_bias_rad=drift_rad)


def dispersion(device, dispersion_s2, rng, samples, test) -> Case:
    device = dataclasses.replace(device, dispersion_s2=dispersion_s2)
    return make_case(
        device,
        rng,
        samples,
        test,
        train_hz=device.sweep_hz(samples, DISPERSION_SPAN_FSR),
        test_span_fsr=DISPERSION_SPAN_FSR,
    )


def partial_span(device, span_fsr, rng, samples, test) -> Case:
    train_hz = device.sweep_hz(samples, span_fsr)
    return make_case(device, rng, samples, test, train_hz=train_hz, affected=outside_sweep)


def unequal_noise(device, ratio, rng, samples, test) -> Case:
    noise_w = np.full(device.ports, NOISE_W)
    noise_w[-1] *= ratio
    return make_case(device, rng, samples, test, noise_w=noise_w, affected=every_reading)


def weak_port(device, responsivity, rng, samples, test) -> Case:
    weak = np.array(device.responsivity)
    weak[-1] = responsivity
    device = dataclasses.replace(device, responsivity=weak)
    return make_case(device, rng, samples, test, affected=every_reading)


# ---------------------------------------------------------------------- remedies
def fit_quietly(calibrator, *args, **kwargs):
    """``calibrator.fit(...)`` with its calibration warnings silenced (a remedied fit)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return calibrator.fit(*args, **kwargs)


def monitor_remedy(case: Case, _rng) -> np.ndarray:
    calibrator = fit_quietly(
        wm.Calibrator(DESIGN_FSR_HZ), case.train_w, case.train_hz, power_monitor_w=case.monitor_w()
    )
    return calibrator.predict(case.test_w)


def dark_remedy(monitored: bool) -> Callable[[Case, np.random.Generator], np.ndarray]:
    def remedy(case: Case, _rng) -> np.ndarray:
        calibrator = fit_quietly(
            wm.Calibrator(DESIGN_FSR_HZ),
            case.train_w,
            case.train_hz,
            power_monitor_w=case.monitor_w() if monitored else None,
            dark_w=case.device.dark_offset_w,
        )
        return calibrator.predict(case.test_w)

    return remedy


def per_fsr_remedy(case: Case, rng) -> np.ndarray:
    calibration = fit_quietly(
        wm.CalibrationSet(DESIGN_FSR_HZ, window=wm.Calibrator()), case.train_w, case.train_hz
    )
    coarse_hz = case.test_hz + rng.normal(0.0, COARSE_STD_HZ, case.test_hz.shape)
    # a coarse value just beyond the sweep's ends picks the outer window
    coarse_hz = np.clip(coarse_hz, *calibration.covered_hz())
    return calibration.predict(case.test_w, coarse_hz=coarse_hz)


def full_span_remedy(case: Case, rng) -> np.ndarray:
    train_hz = case.device.sweep_hz(case.train_hz.size)
    train_w = case.device.powers(train_hz, POWER_W, case.noise_w, rng)
    return fit_quietly(wm.Calibrator(DESIGN_FSR_HZ), train_w, train_hz).predict(case.test_w)


def ml_remedy(case: Case, _rng) -> np.ndarray:
    calibrator = fit_quietly(
        wm.Calibrator(DESIGN_FSR_HZ, retrieval="ml"), case.train_w, case.train_hz
    )
    return calibrator.predict(case.test_w)


def percent(value: float) -> str:
    return f"{100 * value:g} %"


FAULTS = (
    Fault(
        key="power_drift",
        label="slow power drift, no monitor",
        severities=(0.05, 0.2, 0.5),
        severity_text=lambda v: f"+-{percent(v)}",
        build=power_drift,
        cause="power_drift",
        remedy="power monitor",
        apply_remedy=monitor_remedy,
    ),
    Fault(
        key="flicker",
        label="1/f power noise, no monitor",
        severities=(0.001, 0.01, 0.03),
        severity_text=percent,
        build=flicker,
        cause="power_drift",
        remedy="power monitor",
        apply_remedy=monitor_remedy,
    ),
    Fault(
        key="offset_constant",
        label="detector offsets, constant power",
        severities=(0.003, 0.01, 0.05),
        severity_text=percent,
        build=offsets_constant_power,
        cause="detector_offset",
        remedy="dark readings",
        apply_remedy=dark_remedy(monitored=False),
    ),
    Fault(
        key="offset_monitored",
        label="detector offsets, monitored power 0.5-1.5x",
        severities=(0.003, 0.01, 0.05),
        severity_text=percent,
        build=offsets_varying_power,
        cause="detector_offset",
        remedy="dark readings",
        apply_remedy=dark_remedy(monitored=True),
        monitored=True,
    ),
    Fault(
        key="thermal_ramp",
        label="thermal ramp, one-way sweep",
        severities=(0.01, 0.1, 1.0),
        severity_text=lambda v: f"{v:g} K",
        build=thermal_one_way,
        cause="phase_drift",
        remedy="n/a",
        blind=True,
    ),
    Fault(
        key="thermal_cycle",
        label="thermostat cycling",
        severities=(0.01, 0.1, 1.0),
        severity_text=lambda v: f"{v:g} K p-p",
        build=thermal_cycle,
        cause="phase_drift",
        remedy="n/a",
    ),
    Fault(
        key="thermal_two_way",
        label="thermal ramp, up-down sweep",
        severities=(0.01, 0.1, 1.0),
        severity_text=lambda v: f"{v:g} K",
        build=thermal_two_way,
        cause="phase_drift",
        remedy="n/a",
    ),
    Fault(
        key="dispersion",
        label=f"dispersion, {DISPERSION_SPAN_FSR:g}-FSR sweep",
        severities=(1e-26, 1e-25, 1e-24),
        severity_text=lambda v: f"{v:g} s^2",
        build=dispersion,
        cause="dispersion",
        remedy="per-FSR set",
        apply_remedy=per_fsr_remedy,
    ),
    Fault(
        key="partial_span",
        label="partial span",
        severities=(0.3, 0.6, 0.9),
        severity_text=lambda v: f"{v:g} FSR",
        build=partial_span,
        cause="partial_span",
        remedy="span 1 FSR",
        apply_remedy=full_span_remedy,
    ),
    Fault(
        key="unequal_noise",
        label="unequal port noise",
        severities=(2.0, 4.0, 8.0),
        severity_text=lambda v: f"1:1:{v:g}",
        build=unequal_noise,
        cause="unequal_noise",
        remedy="retrieval=ml",
        apply_remedy=ml_remedy,
        in_model=True,
    ),
    Fault(
        key="weak_port",
        label="weak port responsivity",
        severities=(0.1, 0.05, 0.03),
        severity_text=lambda v: f"{v:g}",
        build=weak_port,
        cause="ill_conditioned",
        remedy="retrieval=ml",
        apply_remedy=ml_remedy,
        in_model=True,
    ),
)


def clean_fault(ports: int) -> Fault:
    """The in-model row of ``ports``-port devices (no fault, no cause expected)."""
    return Fault(
        key="clean",
        label=f"clean, {ports} ports",
        severities=(0.0,),
        severity_text=lambda _: "-",
        build=clean,
        cause=None,
        remedy="-",
        in_model=True,
        ports=ports,
    )


# ---------------------------------------------------------------------- evaluation
def fit_causes(calibrator, case: Case, monitored: bool) -> tuple[tuple[str, ...], str | None]:
    """Fit without the remedy: the warning causes, or the error that refused the sweep."""
    monitor = case.monitor_w() if monitored else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            calibrator.fit(case.train_w, case.train_hz, power_monitor_w=monitor)
        except wm.WavemeterError as error:
            return (), type(error).__name__
    causes = (w.message.cause for w in caught if issubclass(w.category, wm.CalibrationWarning))
    return tuple(sorted(set(causes))), None


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def evaluate(fault: Fault, case: Case, rng: np.random.Generator) -> Outcome:
    """Calibrate ``case`` without the remedy, test it, then with the remedy."""
    bound_hz = crlb_hz(
        case.device, case.test_hz, case.test_power_w, case.noise_w, case.test_bias_rad
    )
    fsr_hz = case.device.true_fsr_hz
    calibrator = wm.Calibrator(DESIGN_FSR_HZ)
    causes, refused = fit_causes(calibrator, case, fault.monitored)
    remedy, remedy_refused = None, None
    if fault.apply_remedy is not None:
        try:
            remedied_hz = fault.apply_remedy(case, rng)
        except wm.WavemeterError as error:
            remedy, remedy_refused = np.inf, type(error).__name__
        else:
            remedy = rms(wm.frequency_error_hz(remedied_hz, case.test_hz, fsr_hz)) / rms(bound_hz)
    if refused is not None:
        return Outcome((), refused, np.nan, 0, 0, np.empty(0), remedy, remedy_refused)
    error_hz = wm.frequency_error_hz(calibrator.predict(case.test_w), case.test_hz, fsr_hz)
    if case.affected is None:
        fault_only_hz = wm.frequency_error_hz(
            calibrator.predict(case.test_clean_w), case.test_hz, fsr_hz
        )
        affected = np.abs(fault_only_hz) > AFFECTED_BIAS_CRLB * bound_hz
    else:
        affected = case.affected
    flagged = calibrator.flags(case.test_w) != 0
    z = error_hz / calibrator.frequency_std_hz(case.test_w)
    return Outcome(
        causes,
        None,
        rms(error_hz) / rms(bound_hz),
        int(np.count_nonzero(flagged & affected)),
        int(np.count_nonzero(affected)),
        z,
        remedy,
        remedy_refused,
    )


def run_row(
    fault: Fault, severity: float, devices: int, seed: int, samples: int, test: int
) -> list[Outcome]:
    """``devices`` calibrations of one row; device ``k`` is the same in every row."""
    row_code = zlib.crc32(f"{fault.key}:{severity!r}".encode())
    outcomes = []
    for k in range(devices):
        device = make_device(
            fault.ports, np.random.default_rng(np.random.SeedSequence([seed, fault.ports, k]))
        )
        rng = np.random.default_rng(np.random.SeedSequence([seed, fault.ports, k, row_code]))
        case = fault.build(device, severity, rng, samples, test)
        outcomes.append(evaluate(fault, case, rng))
    return outcomes


# ---------------------------------------------------------------------- reporting
def row_name(fault: Fault, severity: float) -> str:
    text = fault.severity_text(severity)
    return fault.label if text == "-" else f"{fault.label} {text}"


@dataclass(frozen=True)
class Row:
    fault: Fault
    severity: float
    outcomes: list[Outcome]

    @property
    def name(self) -> str:
        return row_name(self.fault, self.severity)

    @property
    def warned(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.warned]

    def right_cause_count(self) -> int:
        return sum(self.fault.cause in o.causes for o in self.warned)

    def median_rms_over_crlb(self) -> float:
        values = [o.rms_over_crlb for o in self.outcomes if o.refused is None]
        return statistics.median(values) if values else np.nan

    def median_remedy(self) -> float | None:
        """Median over calibrations (a remedy that refused counts as infinite); None: none."""
        values = [o.remedy_rms_over_crlb for o in self.outcomes]
        return None if values[0] is None else statistics.median(values)

    def remedy_cell(self) -> str:
        remedy = self.median_remedy()
        if remedy is None:
            return "n/a"
        refused = Counter(o.remedy_refused for o in self.outcomes if o.remedy_refused)
        return f"{remedy:.3g}" + "".join(
            f" (refused {count}/{len(self.outcomes)}: {name})" for name, count in refused.items()
        )

    def z_std(self) -> float:
        z = np.concatenate([o.z for o in self.outcomes])
        return float(np.std(z)) if z.size else np.nan

    def cells(self) -> list[str]:
        warned = self.warned
        counts = Counter(cause for o in warned for cause in o.causes)
        counts.update(f"refused ({o.refused})" for o in warned if o.refused)
        named = ", ".join(f"{cause} {count}" for cause, count in counts.most_common())
        affected = sum(o.affected for o in self.outcomes)
        flagged = sum(o.flagged for o in self.outcomes)
        silent = sum(o.silent for o in self.outcomes)
        return [
            self.fault.label,
            self.fault.severity_text(self.severity),
            f"{self.median_rms_over_crlb():.3g}",
            f"{len(warned)}/{len(self.outcomes)}" + (f": {named}" if named else ""),
            f"{100 * flagged / affected:.1f} % of {affected}" if affected else "-",
            f"{self.z_std():.3f}" if self.z_std() < 100 else f"{self.z_std():.3g}",
            self.fault.remedy,
            self.remedy_cell(),
            f"{silent}/{len(self.outcomes)}",
        ]


HEADERS = (
    "fault",
    "severity",
    "RMS/CRLB",
    "warned (causes)",
    "flagged (affected readings)",
    "z std",
    "remedy",
    "RMS/CRLB with remedy",
    "silent",
)


def status(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def verdict(rows: list[Row]) -> list[str]:
    """One line per target of issue 9: PASS/FAIL and the numbers."""
    faults = [row for row in rows if row.fault.cause is not None]
    clean_rows = [row for row in rows if row.fault.cause is None]
    lines = []

    def named(selected) -> str:
        return "; ".join(row.name for row in selected)

    watched = [row for row in faults if not row.fault.blind]
    bad = [o for row in watched for o in row.outcomes if o.rms_over_crlb > SILENT_RMS_OVER_CRLB]
    silent_rows = [row for row in watched if any(o.silent for o in row.outcomes)]
    silent = sum(o.silent for row in watched for o in row.outcomes)
    lines.append(
        f"{status(silent == 0)} no silent failure: {silent} of {len(bad)} calibrations with "
        f"RMS/CRLB > {SILENT_RMS_OVER_CRLB} neither warned nor flagged "
        f">= {CAUGHT_FLAGGED_SHARE:.0%} of their affected readings"
        + (f" (rows: {named(silent_rows)})" if silent_rows else "")
    )
    blind = [row for row in faults if row.fault.blind]
    blind_silent = sum(o.silent for row in blind for o in row.outcomes)
    blind_total = sum(len(row.outcomes) for row in blind)
    lines.append(
        f"  documented limitation (not in the target): {blind_silent} of {blind_total} "
        f"calibrations silent in rows {named(blind)}"
    )

    warned_rows = [row for row in faults if row.warned]
    right_rows = [row for row in warned_rows if row.right_cause_count() * 2 > len(row.warned)]
    right_share = len(right_rows) / len(warned_rows) if warned_rows else np.nan
    warned_fits = sum(len(row.warned) for row in warned_rows)
    right_fits = sum(row.right_cause_count() for row in warned_rows)
    wrong = [row for row in warned_rows if row not in right_rows]
    lines.append(
        f"{status(right_share >= RIGHT_CAUSE_SHARE)} right cause in >= {RIGHT_CAUSE_SHARE:.0%} "
        f"of warned rows: {len(right_rows)} of {len(warned_rows)} rows ({right_share:.0%}; a row "
        f"counts when most of its warned calibrations name the cause), {right_fits} of "
        f"{warned_fits} warned calibrations"
        + (f" (wrong or missing cause: {named(wrong)})" if wrong else "")
    )

    alarms = sum(len(row.warned) for row in clean_rows)
    total = sum(len(row.outcomes) for row in clean_rows)
    rate = alarms / total if total else np.nan
    lines.append(
        f"{status(rate <= CLEAN_FALSE_ALARM_RATE)} clean false alarms <= "
        f"{CLEAN_FALSE_ALARM_RATE:.0%}: {alarms} of {total} calibrations ({rate:.1%})"
    )

    in_model = [row for row in rows if row.fault.in_model]
    low, high = Z_STD_RANGE
    outside = [row for row in in_model if not low <= row.z_std() <= high]
    values = ", ".join(f"{row.name}: {row.z_std():.3f}" for row in in_model)
    lines.append(f"{status(not outside)} z std in [{low}, {high}] on in-model rows: {values}")

    remedied = [row for row in faults if row.median_remedy() is not None]
    failing = [row for row in remedied if not row.median_remedy() <= REMEDY_RMS_OVER_CRLB]
    worst = max(remedied, key=lambda r: r.median_remedy(), default=None)
    lines.append(
        f"{status(not failing)} remedy median RMS/CRLB <= {REMEDY_RMS_OVER_CRLB}: "
        f"{len(remedied) - len(failing)} of {len(remedied)} rows"
        + (f", worst {worst.median_remedy():.3g} ({named([worst])})" if worst else "")
        + (f"; over: {named(failing)}" if failing else "")
    )
    return lines


def fault_keys(text: str) -> list[str]:
    """Fault keys from a comma-separated list (argparse type)."""
    keys = [key.strip() for key in text.split(",") if key.strip()]
    unknown = set(keys) - {fault.key for fault in FAULTS}
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown fault keys {sorted(unknown)}")
    return keys


def cause_keys(text: str) -> list[str]:
    """Rows of the causes table from a comma-separated list, or 'none' (argparse type)."""
    if text.strip() == "none":
        return []
    keys = [key.strip() for key in text.split(",") if key.strip()]
    unknown = set(keys) - {row.key for row in trust_causes.ROWS}
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown cause rows {sorted(unknown)}")
    return keys


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=5, help="calibrations per fault row")
    parser.add_argument(
        "--clean-calibrations", type=int, default=200, help="clean calibrations over 3-5 ports"
    )
    parser.add_argument("--samples", type=int, default=2001, help="readings per calibration")
    parser.add_argument("--test", type=int, default=5000, help="test readings per calibration")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--faults",
        type=fault_keys,
        default=[fault.key for fault in FAULTS],
        help=f"comma-separated fault rows to run (default all: {','.join(f.key for f in FAULTS)})",
    )
    parser.add_argument("--cause-seeds", type=int, default=20, help="seeds per cause row")
    parser.add_argument("--clean-seeds", type=int, default=50, help="seeds per clean sweep row")
    parser.add_argument(
        "--cause-rows",
        type=cause_keys,
        default=None,
        help="comma-separated rows of the causes table, or 'none' (default all; none with "
        f"--quick): {','.join(row.key for row in trust_causes.ROWS)}",
    )
    parser.add_argument(
        "--quick", action="store_true", help="tiny sizes (smoke test): overrides the sizes"
    )
    args = parser.parse_args(argv)
    if args.cause_rows is None:
        args.cause_rows = [] if args.quick else [row.key for row in trust_causes.ROWS]
    if args.quick:
        args.devices, args.clean_calibrations, args.samples, args.test = 1, 3, 201, 300
        args.cause_seeds = args.clean_seeds = 1
    plan = [
        (fault, severity, args.devices)
        for fault in FAULTS
        if fault.key in args.faults
        for severity in fault.severities
    ]
    for index, ports in enumerate((3, 4, 5)):
        count = (args.clean_calibrations + 2 - index) // 3
        plan.append((clean_fault(ports), 0.0, count))
    rows = []
    for number, (fault, severity, devices) in enumerate(plan, 1):
        progress(f"row {number}/{len(plan)}: {row_name(fault, severity)}")
        outcomes = run_row(fault, severity, devices, args.seed, args.samples, args.test)
        rows.append(Row(fault, severity, outcomes))
    progress("")
    print(file=sys.stderr)
    print(
        f"## Fault catalogue: Table 1 devices ({PORTS} ports unless said), {args.devices} per "
        f"fault row, {args.samples} calibration and {args.test} test readings each, noise "
        f"{NOISE_W:g} W at {POWER_W:g} W, seed {args.seed}\n"
    )
    print(markdown_table(HEADERS, [row.cells() for row in rows]))
    print("\n## Verdict\n")
    print("\n".join(verdict(rows)))
    if args.cause_rows:
        results = trust_causes.run_rows(
            args.cause_rows, args.cause_seeds, args.clean_seeds, args.seed
        )
        progress("")
        print(file=sys.stderr)
        print(
            f"\n## Causes: wide and rounded sweeps, {args.cause_seeds} seeds per row; clean "
            f"sweeps of every method, {args.clean_seeds} seeds per row; seed {args.seed}\n"
        )
        print(trust_causes.table(results))
        print("\n## Verdict (causes)\n")
        print("\n".join(trust_causes.verdict(results)))


if __name__ == "__main__":
    main()
