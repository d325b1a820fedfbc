"""Do the wide-band fit's standard errors hold? Coverage of the truth across seeds.

For each seed, ``wavemeter simulate``'s scenario (:class:`wavemeter.simulation.Scenario`:
a Table 1 device with the silicon-nitride spectral preset, its own slopes and noise drawn
from the seed) is calibrated, and every reported phase coefficient is compared with the
simulation's true value of the same quantity: ``z = (fit - truth) / stated std``. Where
the standard errors hold, ``z`` has a standard deviation of 1 and ``|z| < 1.96`` for 95 %
of the seeds.

The fringe phase's truth (what ``phase_coefficients_`` report): the device's phase
``t(f)`` (delay ``tau + D w0`` and dispersion ``D`` at the calibration's centre, from
``group_delay_s`` and ``dispersion_s2``) plus the mean over the ports of the phase of each
port's fringe amplitude ``z_k = A_k0 - i A_k1`` in the true map (``true_map``), weighted
by ``|z_k|^2`` at the centre, its Taylor coefficients from a Chebyshev fit of degree
``TRUTH_DEGREE`` over the band (an implementation independent of the calibrator's power
series). The model phase's truth (what was reported before): ``t`` alone, the
decomposition of the simulator (whose map is exactly cubic in frequency), with the
standard errors of the model phase coefficients ``b`` from the fit's covariance.

The readings: each seed also draws ``TEST_READINGS`` test readings uniform over the band
(``simulate --test``, independent noise); each is read (the wide-band calibrations with the
true frequency as ``coarse_hz``, the cascade without) and ``z = (read - truth) /
frequency_std_hz``; per seed the standard deviation of ``z`` over the readings, the table
the median over the seeds.

Cases: ``simulate --spectral sin --span-fsr 88 --samples 35200`` (the C band) with the
orders chosen and with the orders (2, 3) fixed (the map order that holds the simulated map
exactly, where the model phase is told worst from the map), the user guide's
``--dispersion 1e-26 --span-fsr 24 --samples 9600``, and every stage of the cascade
``--cascade 5THz,500GHz,50GHz --spectral sin --samples 20000``.

Targets (PASS/FAIL from the numbers printed), each within ``BAND_SIGMAS`` standard errors
of its statistic: a coefficient's ``z`` std over ``S`` seeds within ``1 +- BAND_SIGMAS /
sqrt(2 (S - 1))`` and its share within 1.96 at least ``0.95 - BAND_SIGMAS sqrt(0.95 x
0.05 / S)``; the readings' median ``z`` std within ``1 +- BAND_SIGMAS / sqrt(2 (N - 1))``
for ``N`` readings per seed. A coefficient fitted in fewer than ``MIN_JUDGED_SEEDS`` seeds
(a higher order the search chose in a few) is shown, not judged.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np
from _montecarlo import markdown_table, progress, status
from numpy.polynomial import Chebyshev

import wavemeter as wm
from wavemeter.simulation import Scenario

__all__ = ["CASES", "coverage_table", "reading_table", "run_coverage"]

#: degree of the Chebyshev fit of the ports' fringe-amplitude phase across the band
TRUTH_DEGREE = 16
#: the ports' fringe-amplitude phase is sampled at this many Chebyshev nodes
TRUTH_NODES = 65
#: two-sided 95 % point of the standard normal
Z_95 = 1.959964
NAMES = {1: "delay c1 (and FSR)", 2: "dispersion c2", 3: "c3", 4: "c4"}
#: test readings per seed
TEST_READINGS = 2000
#: a target holds within this many standard errors of its statistic
BAND_SIGMAS = 3.0
#: a coefficient fitted in fewer seeds is shown but not judged (its z std over so few
#: seeds could not tell standard errors that hold from ones off by half)
MIN_JUDGED_SEEDS = 10


@dataclass(frozen=True)
class CoverageCase:
    """One scenario of the coverage run.

    Attributes
    ----------
    key : str
        Short name (table rows).
    title : str
        What it is, as the ``simulate`` options.
    fields : dict
        :class:`~wavemeter.simulation.Scenario` fields besides the seed.
    settings : dict
        Settings of the calibrator besides ``fsr_hz``.
    """

    key: str
    title: str
    fields: dict
    settings: dict = dataclasses.field(default_factory=dict)

    @property
    def cascade(self) -> bool:
        return "cascade_fsrs_hz" in self.fields


CASES = (
    CoverageCase(
        "C band",
        "--spectral sin --span-fsr 88 --samples 35200",
        {"spectral": "sin", "span_fsr": 88.0, "samples": 35200},
    ),
    CoverageCase(
        "C band, orders (2, 3)",
        "--spectral sin --span-fsr 88 --samples 35200, phase_order 2, map_order 3",
        {"spectral": "sin", "span_fsr": 88.0, "samples": 35200},
        {"phase_order": 2, "map_order": 3},
    ),
    CoverageCase(
        "user guide",
        "--spectral sin --dispersion 1e-26 --span-fsr 24 --samples 9600",
        {"spectral": "sin", "dispersion_s2": 1e-26, "span_fsr": 24.0, "samples": 9600},
    ),
    CoverageCase(
        "cascade",
        "--cascade 5THz,500GHz,50GHz --spectral sin --samples 20000",
        {"cascade_fsrs_hz": (5e12, 500e9, 50e9), "spectral": "sin", "samples": 20000},
    ),
)


def true_fringe_coefficients_s(device, center_hz: float, half_span_hz: float, order: int):
    """The fringe phase's Taylor coefficients ``c_1..c_order`` (s^i) of a simulated
    ``Interferometer`` at ``center_hz``, the band ``center_hz +- half_span_hz`` (module
    docstring)."""
    nodes = np.cos(np.pi * (np.arange(TRUTH_NODES) + 0.5) / TRUTH_NODES)
    maps = device.true_map(frequency_hz=center_hz + half_span_hz * nodes)
    amplitudes = maps[:, :, 0] - 1j * maps[:, :, 1]
    centre = device.true_map(frequency_hz=np.array([center_hz]))[0]
    power = np.abs(centre[:, 0] - 1j * centre[:, 1]) ** 2
    rotation = np.unwrap(np.angle(amplitudes), axis=0) @ (power / power.sum())
    series = Chebyshev.fit(nodes, rotation, TRUTH_DEGREE)
    orders = np.arange(1, order + 1)
    derivatives = np.array([series.deriv(i)(0.0) for i in orders])  # d^i / dy^i at 0
    model = true_model_coefficients_s(device, center_hz, order)
    return model + derivatives / (2.0 * np.pi * half_span_hz) ** orders


def true_model_coefficients_s(device, center_hz: float, order: int) -> np.ndarray:
    """The simulator's phase ``t``: delay ``tau + D w0`` and dispersion ``D`` at
    ``center_hz`` (s, s^2), higher orders 0."""
    values = np.zeros(order)
    values[0] = float(device.group_delay_s(np.array([center_hz]))[0])
    if order > 1:
        values[1] = float(device.dispersion_s2)
    return values


def model_coefficients(calibration) -> tuple[np.ndarray, np.ndarray]:
    """The model phase ``t``'s coefficients (s^i) and their standard errors from the
    fit's covariance: what the calibration reported before the fringe phase."""
    order = calibration.phase_order_
    orders = np.arange(1, order + 1)
    factorials = np.array([math.factorial(i) for i in orders], dtype=float)
    per_rad = factorials / (2.0 * np.pi * calibration.half_span_hz_) ** orders
    std = np.sqrt(np.diag(calibration.parameter_covariance_)[-order:])
    return calibration.phase_coefficients_rad_ * per_rad, std * per_rad


def stage_outcome(stage, device, label: str) -> dict:
    """The z-scores of one fitted wide-band calibration against its device."""
    order = stage.phase_order_
    record = stage.diagnostics_["wideband"]
    fringe = np.asarray(record["phase_coefficients_s"])
    fringe_std = np.asarray(record["phase_coefficients_std_s"])
    truth = true_fringe_coefficients_s(device, stage.center_hz_, stage.half_span_hz_, order)
    model, model_std = model_coefficients(stage)
    model_truth = true_model_coefficients_s(device, stage.center_hz_, order)
    return {
        "label": label,
        "orders": (order, stage.map_order_),
        "z": (fringe - truth) / fringe_std,
        "std": fringe_std,
        "model_z": (model - model_truth) / model_std,
        "model_std": model_std,
    }


def run_seed(case: CoverageCase, seed: int) -> list[dict]:
    """Calibrate the case's sweep of ``seed`` and read its test readings: one outcome per
    wide-band calibration and one of the readings."""
    scenario = Scenario(seed=seed, test=TEST_READINGS, **case.fields)
    sweep, test = scenario.tables()
    frequency_hz = sweep.pop("frequency_hz")
    powers_w = np.column_stack(list(sweep.values()))
    true_hz = test.pop("true_frequency_hz")
    test_w = np.column_stack(list(test.values()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        if case.cascade:
            fsrs = case.fields["cascade_fsrs_hz"]
            calibration = wm.CascadeCalibrator(fsr_hz=fsrs, **case.settings)
            calibration.fit(powers_w, frequency_hz)
            stages = zip(calibration.stages_, scenario.device.stages, fsrs, strict=True)
            outcomes = [
                stage_outcome(stage, device, f"{case.key}, {frequency_label(fsr)} stage")
                for stage, device, fsr in stages
            ]
            readout = calibration.readout(test_w)
        else:
            calibration = wm.WidebandCalibrator(fsr_hz=50e9, **case.settings)
            calibration.fit(powers_w, frequency_hz)
            outcomes = [stage_outcome(calibration, scenario.device, case.key)]
            readout = calibration.readout(test_w, coarse_hz=true_hz)
    z = (readout.frequency_hz - true_hz) / readout.frequency_std_hz
    reading = {"label": case.key, "reading_z": z, "flagged": np.count_nonzero(readout.flags)}
    return [*outcomes, reading]


def frequency_label(fsr_hz: float) -> str:
    return f"{fsr_hz / 1e12:g} THz" if fsr_hz >= 1e12 else f"{fsr_hz / 1e9:g} GHz"


def run_coverage(seeds: int, first_seed: int = 1) -> list[dict]:
    """Every case over ``seeds`` seeds from ``first_seed``: the outcomes."""
    outcomes = []
    for case in CASES:
        for seed in range(first_seed, first_seed + seeds):
            progress(f"coverage: {case.key}, seed {seed}")
            outcomes += run_seed(case, seed)
    progress("")
    return outcomes


def std_band(count: int) -> float:
    """Half width of the target band of a standard deviation of ``count`` Gaussian values
    about 1: ``BAND_SIGMAS`` of its standard errors."""
    return BAND_SIGMAS / math.sqrt(2.0 * (count - 1))


def coverage_floor(count: int) -> float:
    """Least share of ``count`` seeds within 1.96 that the target accepts."""
    return 0.95 - BAND_SIGMAS * math.sqrt(0.95 * 0.05 / count)


def _cells(values: list[float]) -> tuple[list[str], bool]:
    z = np.asarray(values)
    spread, share = z.std(ddof=1), float(np.mean(np.abs(z) < Z_95))
    ok = abs(spread - 1.0) <= std_band(z.size) and share >= coverage_floor(z.size)
    return [f"{spread:.2f}", f"{share:.0%}"], ok


def coverage_table(outcomes: list[dict]) -> str:
    """Per calibration and phase coefficient: the seeds, the orders fitted, the median
    stated standard error, and the spread of ``z`` and the share within 1.96, of the
    fringe phase (reported now, with the target) and of the model phase (reported before)."""
    rows = []
    stages = [outcome for outcome in outcomes if "z" in outcome]
    for label in dict.fromkeys(outcome["label"] for outcome in stages):
        group = [outcome for outcome in stages if outcome["label"] == label]
        for order in range(1, max(o["orders"][0] for o in group) + 1):
            fitted = [o for o in group if o["orders"][0] >= order]
            counts = sorted(Counter(o["orders"] for o in fitted).items())
            orders = ", ".join(f"({p}, {j}) x{count}" for (p, j), count in counts)
            std = float(np.median([o["std"][order - 1] for o in fitted]))
            model_std = float(np.median([o["model_std"][order - 1] for o in fitted]))
            if len(fitted) < 2:
                cells, ok, model_cells = ["-", "-"], None, ["-", "-"]
            else:
                cells, ok = _cells([o["z"][order - 1] for o in fitted])
                model_cells, _ = _cells([o["model_z"][order - 1] for o in fitted])
            target = (
                f"not judged (< {MIN_JUDGED_SEEDS} seeds)"
                if len(fitted) < MIN_JUDGED_SEEDS
                else f"{status(ok)} (z std 1 +- {std_band(len(fitted)):.2f}, "
                f">= {coverage_floor(len(fitted)):.0%})"
            )
            rows.append(
                [
                    label,
                    NAMES[order],
                    len(fitted),
                    orders,
                    f"{std:.3g} s^{order}",
                    *cells,
                    target,
                    f"{model_std:.3g} s^{order}",
                    *model_cells,
                ]
            )
    headers = (
        "calibration",
        "coefficient",
        "seeds",
        "orders (P, J) fitted",
        "fringe phase: median std",
        "z std",
        "within 1.96",
        "target",
        "model phase t: median std",
        "z std",
        "within 1.96",
    )
    return markdown_table(headers, rows)


def reading_table(outcomes: list[dict]) -> str:
    """Per case: the readings' ``z`` std (median over the seeds, and the lowest and
    highest), the share within 1.96 over every reading, the flagged readings, the target."""
    rows = []
    readings = [outcome for outcome in outcomes if "reading_z" in outcome]
    for label in dict.fromkeys(outcome["label"] for outcome in readings):
        group = [outcome for outcome in readings if outcome["label"] == label]
        count = group[0]["reading_z"].size
        spreads = [float(np.std(o["reading_z"], ddof=1)) for o in group]
        pooled = np.concatenate([o["reading_z"] for o in group])
        middle = float(np.median(spreads))
        ok = abs(middle - 1.0) <= std_band(count)
        rows.append(
            [
                label,
                len(group),
                count,
                f"{middle:.3f}",
                f"{min(spreads):.3f} - {max(spreads):.3f}",
                f"{np.mean(np.abs(pooled) < Z_95):.1%}",
                sum(o["flagged"] for o in group),
                f"{status(ok)} (1 +- {std_band(count):.3f})",
            ]
        )
    headers = (
        "calibration",
        "seeds",
        "readings per seed",
        "z std median",
        "z std lowest - highest",
        "within 1.96 (all readings)",
        "flagged",
        "target",
    )
    return markdown_table(headers, rows)
