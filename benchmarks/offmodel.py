"""OFF_MODEL on simulated and measured data: good readings flagged, injected faults caught.

The ``OFF_MODEL`` flag compares a reading's weighted distance to the calibrated cone with
a threshold. Three rules, side by side on the same calibrations and readings:

- detector noise (0.7): the noise's chi-square at p = 1e-6 (the calibration saved without
  its ``off_model`` record and loaded again, as a file of 0.7 has it);
- median-scaled (first round of issue 29): where the sweep's distances show a model error,
  the noise's distribution scaled to their median (the record without its ``residual``);
- residual subtracted (this round): where they show one, the residual the sweep's readings
  share at their phase (and source power) is learned and subtracted before the distance
  is taken, and the noise's distribution scaled to what remains (to its median, or per
  phase to cover its tail; the calibration as fitted).

Data sets:

- simulated, clean: Table 1 devices (3 or 4 ports, 1 mW, detector noise 5e-7 W),
  calibrated on 2001 readings over one FSR; good readings: ``--test`` fresh readings at
  random frequencies over the FSR;
- simulated, model error: the same devices read through detectors that compress by
  ``COMPRESSION`` (5 %) at the sweep's largest reading (``p - 0.05 p^2 / p_max``, sweep and
  test alike): the fit warns ``other_misfit``;
- measured: the MiniPTI 3x3 fibre coupler (``../shared/data/minipti-fiber-3x3``, 3726
  readings of ``DC CH1..3`` in V), calibrated with MiniPTI's published phase as the label
  (``f = 193.4 THz + unwrap(phase) / 2 pi x 50 GHz``); good readings: the calibration's own.

Faults, each injected into every good reading (one fault at a time), in two readings of
"a port's scatter": about the model (the fit's per-port residual RMS, ``diagnostics_``; the
first round's, by which the targets are judged) and the detector noise (the calibrated
per-port noise, ``port_noise_std_w_``; the model-free one where the fit found a misfit).
On a clean device the two agree; under a model error the first is the larger.

- glitch: one port, drawn at random, moved by ``GLITCH_SCATTER`` (10) scatters, with a
  random sign;
- two-tone: a second laser line at ``SECOND_LINE_SHARE`` (15 %) of the power, at an
  independent random frequency: ``0.85 p_i + 0.15 p_k`` with ``k`` another good reading;
- saturated: one port, drawn at random, clipped at the middle of its calibrated range;
  only readings it changes by more than ``GLITCH_SCATTER`` scatters count as faulty.

"vis.": the share of faulty readings a distance test at the detector-noise threshold can
see at all, whatever the rule: the fault applied to the reading's own point on the
calibrated cone (no noise, no model error) is beyond that threshold. A one-port fault has
no component off the cone at two phases per fringe on a 3-port device (the space off the
cone is one direction there), and one smaller than the threshold has too little near them;
a second line has none when it is in phase with the first. The last table shows that limit
by itself: the share of phases at which a one-port glitch of a given size is visible.
Medians over ``--seeds`` devices (simulated) or fault draws (measured).

Held out (measured data): the coupler calibrated on part of its readings, its good readings
the others: interleaved (even readings, then the odd ones), or split in time (70 % of the
record, then the other 30 %), with the frequency error (modulo the FSR) of both parts.

Usage: ``python benchmarks/offmodel.py [--seeds 5] [--test 5000] [--quick]``
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _montecarlo import NOISE_W, POWER_W, make_device, markdown_table, progress
from _script import Parser, positive_int
from scipy import stats

import wavemeter as wm

DESIGN_FSR_HZ = 50e9
SWEEP_SAMPLES = 2001
#: detector compression of the model-error devices at the sweep's largest reading
COMPRESSION = 0.05
#: a glitch, and the least clipping that counts, in the port's scatter
GLITCH_SCATTER = 10.0
#: power of the second laser line of a two-tone reading
SECOND_LINE_SHARE = 0.15
#: a saturated port clips at this fraction of its calibrated range
CLIP_LEVEL = 0.5
#: the severities of the severity table (the new rule only, scatter about the model)
SEVERITIES = {
    "glitch": (10.0, 30.0, 100.0),
    "two-tone": (0.15, 0.3, 0.5),
    "saturated": (0.75, 0.5, 0.25),
}
#: glitch sizes (detector-noise standard deviations) of the geometric-limit table
GLITCH_SIZES_NOISE = (5.0, 10.0, 20.0, 30.0, 100.0)
#: the measured data and how it is labelled
MEASURED_DIR = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
MEASURED_PORTS = ("DC CH1", "DC CH2", "DC CH3")
MEASURED_CENTER_HZ = 193.4e12
FAULTS = ("glitch", "two-tone", "saturated")
#: the two readings of "a port's scatter": about the model (targets), the detector noise
SCATTERS = ("model", "noise")
RULES = {
    "old": "detector noise (0.7)",
    "median": "median-scaled (round 1)",
    "new": "residual subtracted (new)",
}
OFF_MODEL = int(wm.ReadingFlag.OFF_MODEL)


@dataclass(frozen=True)
class Case:
    """One calibration with its good readings (W, or V for the measured data)."""

    calibration: object
    good: np.ndarray


@dataclass(frozen=True)
class Faulty:
    """Readings with one fault injected, which of them it changed, and the same fault
    applied to each reading's point on the calibrated cone."""

    readings: np.ndarray
    affected: np.ndarray
    on_cone: np.ndarray


def compressed(powers_w: np.ndarray, largest_w: float) -> np.ndarray:
    """Readings through detectors compressing by ``COMPRESSION`` at ``largest_w``."""
    return powers_w - COMPRESSION * powers_w**2 / largest_w


def simulated_case(ports: int, seed: int, model_error: bool, test: int) -> Case:
    """A Table 1 device calibrated on one FSR; ``test`` fresh readings of it."""
    rng = np.random.default_rng([seed, ports, int(model_error)])
    device = make_device(ports, rng)
    sweep_hz = device.sweep_hz(SWEEP_SAMPLES)
    sweep = device.powers(sweep_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
    half = device.true_fsr_hz / 2
    test_hz = device.center_hz + rng.uniform(-half, half, test)
    good = device.powers(test_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
    if model_error:
        largest = float(sweep.max())
        sweep, good = compressed(sweep, largest), compressed(good, largest)
    return Case(quiet_fit(wm.Calibrator(fsr_hz=DESIGN_FSR_HZ), sweep, sweep_hz), good)


def _columns(path: Path, names) -> np.ndarray:
    with path.open(encoding="utf-8") as handle:
        header = handle.readline().rstrip("\n").split(",")
    columns = [header.index(name) for name in names]
    return np.loadtxt(path, delimiter=",", skiprows=1, usecols=columns, ndmin=2)


def measured_sweep(folder: Path = MEASURED_DIR) -> tuple[np.ndarray, np.ndarray]:
    """The fibre coupler's readings (V) and frequencies (Hz) from MiniPTI's published
    phase (rad): ``MEASURED_CENTER_HZ + unwrap(phase) / (2 pi) * DESIGN_FSR_HZ``."""
    readings = _columns(folder / "Decimation_Comercial.csv", MEASURED_PORTS)
    phase = _columns(folder / "PTI_Inversion_Comercial.csv", ("Interferometric Phase",))[:, 0]
    frequency = MEASURED_CENTER_HZ + np.unwrap(phase) / (2 * np.pi) * DESIGN_FSR_HZ
    return readings, frequency


def measured_case(folder: Path = MEASURED_DIR) -> Case:
    """The fibre coupler calibrated on its published phase; its own readings are good."""
    readings, frequency = measured_sweep(folder)
    return Case(quiet_fit(wm.Calibrator(fsr_hz=DESIGN_FSR_HZ), readings, frequency), readings)


def quiet_fit(calibrator, powers, frequency_hz):
    """``calibrator.fit`` with its warnings (the model errors are on purpose) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return calibrator.fit(powers, frequency_hz)


def _reloaded(calibration, edit):
    """The calibration saved, its file's state changed by ``edit``, and loaded again."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rule.wmcal.json"
        calibration.save(path)
        document = json.loads(path.read_text())
        edit(document["state"])
        path.write_text(json.dumps(document))
        return wm.load_calibration(path)


def old_rule(calibration):
    """The calibration as a file of 0.7 has it: without its ``off_model`` record
    (``OFF_MODEL`` against the detector noise alone)."""
    return _reloaded(calibration, lambda state: state.pop("off_model", None))


def median_rule(calibration):
    """The calibration as the first round of issue 29 kept it: the record without its
    ``residual``, its scale the sweep's median distance over the noise's where the sign
    test found a model error (the record's ``median`` and ``above`` are that test's)."""

    def first_round(state: dict) -> None:
        record = state.get("off_model")
        if record is None or record.pop("residual", None) is None:
            return
        free = calibration.n_ports_ - 2
        noise_median = free * float(stats.f.median(free, calibration.noise_dof_))
        record["scale"] = max(record["median"] / noise_median, 1.0)
        record["beyond"] = 0  # the first round's count, not used by the flags

    return _reloaded(calibration, first_round)


def scatter(calibration, kind: str = "model") -> np.ndarray:
    """Each port's scatter (W): about the calibrated model (the fit's residual RMS), or the
    detector noise the calibration weighs with."""
    if kind == "noise":
        return np.asarray(calibration.port_noise_std_w_, dtype=float)
    return np.asarray(calibration.diagnostics_["fit"]["residual_rms_w"], dtype=float)


def cone_points(calibration, readings: np.ndarray) -> np.ndarray:
    """Each reading's point on the calibrated cone: the map at its retrieved phase and its
    weighted least-squares source power, plus the fitted offsets."""
    phase = calibration.phase(readings)
    image = wm.cone_vectors(phase) @ calibration.map_.T
    weight = 1.0 / calibration.port_noise_std_w_**2
    corrected = readings - calibration.offset_w_
    power = np.einsum("ij,ij,j->i", image, corrected, weight) / np.einsum(
        "ij,ij,j->i", image, image, weight
    )
    return power[:, None] * image + calibration.offset_w_


def inject(
    kind: str,
    case: Case,
    rng: np.random.Generator,
    severity: float | None = None,
    scatter_kind: str = "model",
) -> Faulty:
    """The fault ``kind`` injected into every good reading (module docstring), at the
    module's severity or at ``severity``: the glitch in scatters (``scatter_kind``), the
    second line's share of the power, the clipping level as a fraction of the port's
    calibrated range."""
    good, calibration = case.good, case.calibration
    points = cone_points(calibration, good)
    rows = np.arange(good.shape[0])
    port = rng.integers(0, good.shape[1], good.shape[0])
    size = GLITCH_SCATTER * scatter(calibration, scatter_kind)
    if kind == "glitch" and severity is not None:
        size = severity * scatter(calibration, scatter_kind)
    if kind == "glitch":
        step = np.zeros_like(good)
        step[rows, port] = rng.choice([-1.0, 1.0], good.shape[0]) * size[port]
        return Faulty(good + step, np.ones(good.shape[0], dtype=bool), points + step)
    if kind == "two-tone":
        other = (rows + rng.integers(1, good.shape[0], good.shape[0])) % good.shape[0]
        share = SECOND_LINE_SHARE if severity is None else severity
        mixed = (1 - share) * good + share * good[other]
        return Faulty(
            mixed, np.ones(good.shape[0], dtype=bool), (1 - share) * points + share * points[other]
        )
    if kind == "saturated":
        low, high = good.min(axis=0), good.max(axis=0)
        level = CLIP_LEVEL if severity is None else severity
        ceiling = (low + level * (high - low))[port]
        clipped, clipped_points = good.copy(), points.copy()
        clipped[rows, port] = np.minimum(good[rows, port], ceiling)
        clipped_points[rows, port] = np.minimum(points[rows, port], ceiling)
        affected = good[rows, port] - ceiling > size[port]
        return Faulty(clipped, affected, clipped_points)
    raise ValueError(f"unknown fault {kind!r}")


def off_model_share(calibration, readings: np.ndarray) -> float:
    """The share (%) of readings ``OFF_MODEL``."""
    return 100 * float(np.mean(calibration.flags(readings) & OFF_MODEL > 0))


def held_out_rows(folder: Path = MEASURED_DIR) -> list[list[str]]:
    """Per split of the measured readings (module docstring): the held-out readings
    flagged (%) by each rule, and the RMS frequency error (MHz) in and out of the sweep."""
    readings, frequency = measured_sweep(folder)
    order = np.arange(frequency.size)
    splits = {
        "even -> odd readings": order % 2 == 0,
        "first 70 % -> last 30 % in time": order < 0.7 * order.size,
        "last 70 % -> first 30 % in time": order >= 0.3 * order.size,
    }
    rows = []
    for label, sweep in splits.items():
        progress(f"measured fibre coupler: held out, {label}")
        calibration = quiet_fit(
            wm.Calibrator(fsr_hz=DESIGN_FSR_HZ), readings[sweep], frequency[sweep]
        )
        rules = (old_rule(calibration), median_rule(calibration), calibration)
        errors = []
        for part in (sweep, ~sweep):
            error = calibration.predict(readings[part]) - frequency[part]
            error = (error + DESIGN_FSR_HZ / 2) % DESIGN_FSR_HZ - DESIGN_FSR_HZ / 2
            errors.append(float(np.sqrt(np.mean(error**2))) / 1e6)
        flagged = [f"{off_model_share(rule, readings[~sweep]):.2f}" for rule in rules]
        rows.append([label, *flagged, f"{errors[0]:.0f} / {errors[1]:.0f}"])
    return rows


def shares(case: Case, rng: np.random.Generator) -> dict:
    """Per scatter reading and rule: good readings flagged (%) and each fault caught (%);
    per scatter reading and fault: visible (%) at the detector-noise threshold."""
    rules = {
        "old": old_rule(case.calibration),
        "median": median_rule(case.calibration),
        "new": case.calibration,
    }
    result = {}
    two_tone = inject("two-tone", case, rng)
    for kind in SCATTERS:
        faults = {
            fault: two_tone if fault == "two-tone" else inject(fault, case, rng, None, kind)
            for fault in FAULTS
        }
        table = {rule: {"good": off_model_share(cal, case.good)} for rule, cal in rules.items()}
        table["vis."] = {}
        for fault, faulty in faults.items():
            for rule, calibration in rules.items():
                table[rule][fault] = off_model_share(calibration, faulty.readings[faulty.affected])
            table["vis."][fault] = off_model_share(rules["old"], faulty.on_cone[faulty.affected])
        result[kind] = table
    return result


def severity_shares(case: Case, rng: np.random.Generator) -> dict[tuple[str, float], float]:
    """Per fault and severity (``SEVERITIES``): the share (%) caught by the new rule."""
    found = {}
    for kind, levels in SEVERITIES.items():
        for level in levels:
            faulty = inject(kind, case, rng, level)
            found[(kind, level)] = off_model_share(
                case.calibration, faulty.readings[faulty.affected]
            )
    return found


def geometric_shares(case: Case, rng: np.random.Generator) -> dict[float, float]:
    """Per glitch size (``GLITCH_SIZES_NOISE``, in detector-noise standard deviations): the
    share (%) of the good readings' points on the calibrated cone at which a glitch of
    that size on a random port (random sign) is beyond the detector-noise threshold."""
    points = cone_points(case.calibration, case.good)
    rows = np.arange(points.shape[0])
    port = rng.integers(0, points.shape[1], points.shape[0])
    sign = rng.choice([-1.0, 1.0], points.shape[0])
    noise = case.calibration.port_noise_std_w_
    found = {}
    for size in GLITCH_SIZES_NOISE:
        glitched = points.copy()
        glitched[rows, port] += sign * size * noise[port]
        found[size] = off_model_share(case.calibration, glitched)
    return found


def data_sets(seeds: int, test: int, measured: bool) -> Iterator[tuple[str, list[dict]]]:
    """Each data set's name and its shares per seed."""
    for model_error in (False, True):
        for ports in (3, 4):
            name = f"simulated {ports} ports, {'model error' if model_error else 'clean'}"
            runs = []
            for seed in range(seeds):
                progress(f"{name}: device {seed + 1} of {seeds}")
                case = simulated_case(ports, seed, model_error, test)
                rng = np.random.default_rng([seed, ports, 7])
                run = {**shares(case, rng), "severity": severity_shares(case, rng)}
                if not model_error:
                    run["geometry"] = geometric_shares(case, rng)
                runs.append(run)
            yield name, runs
    if measured:
        progress("measured fibre coupler: calibrating")
        case = measured_case()
        runs = []
        for seed in range(seeds):
            progress(f"measured fibre coupler: fault draw {seed + 1} of {seeds}")
            rng = np.random.default_rng([seed, 29])
            runs.append({**shares(case, rng), "severity": severity_shares(case, rng)})
        yield "measured fibre coupler (MiniPTI)", runs


def _median(values) -> float:
    return statistics.median(values)


def table_rows(name: str, runs: list[dict], kind: str, faults=FAULTS) -> list[list[str]]:
    """One row per rule and one of the visible shares: medians over the runs."""
    rows = []
    for rule, label in (*RULES.items(), ("vis.", "vis. (at the detector noise)")):
        cells = [name, label]
        if rule == "vis.":
            cells.append("")
        else:
            cells.append(f"{_median(run[kind][rule]['good'] for run in runs):.2f}")
        cells += [f"{_median(run[kind][rule][fault] for run in runs):.1f}" for fault in faults]
        rows.append(cells)
    return rows


def target_rows(found: list[tuple[str, list[dict]]]) -> list[list[str]]:
    """The new rule against the targets (scatter about the model): good readings flagged
    <= 1 % and each fault caught >= 90 % of the visible share."""
    rows = []
    for name, runs in found:
        good = _median(run["model"]["new"]["good"] for run in runs)
        cells = [name, f"{good:.2f} {'PASS' if good <= 1.0 else 'FAIL'}"]
        for fault in FAULTS:
            caught = _median(run["model"]["new"][fault] for run in runs)
            visible = _median(run["model"]["vis."][fault] for run in runs)
            ratio = caught / visible if visible else float("nan")
            verdict = "PASS" if ratio >= 0.9 else "FAIL"
            outright = " (>= 90 outright)" if caught >= 90 else ""
            cells.append(f"{caught:.1f} / {visible:.1f} = {ratio:.2f} {verdict}{outright}")
        rows.append(cells)
    return rows


def severity_cell(kind: str, level: float) -> str:
    if kind == "glitch":
        return f"glitch {level:g} scatters"
    if kind == "two-tone":
        return f"second line {level:.0%}"
    return f"clipped at {level:.0%} of range"


def main(argv=None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=positive_int, default=5, help="devices or fault draws")
    parser.add_argument("--test", type=positive_int, default=5000, help="good readings (simulated)")
    parser.add_argument("--quick", action="store_true", help="2 seeds, 1000 test readings")
    args = parser.parse_args(argv)
    seeds, test = (2, 1000) if args.quick else (args.seeds, args.test)
    measured = MEASURED_DIR.is_dir()
    found = list(data_sets(seeds, test, measured))
    held_out = held_out_rows() if measured else []
    progress("")
    sys.stderr.write("\r")
    print(f"OFF_MODEL: medians over {seeds} seeds; simulated good readings: {test} per device\n")
    print("Faults in scatters about the model (the fit's per-port residual RMS; the targets):\n")
    headers = ["data set", "OFF_MODEL rule", "good readings flagged %"]
    print(
        markdown_table(
            [*headers, *(f"{fault} caught %" for fault in FAULTS)],
            [row for name, runs in found for row in table_rows(name, runs, "model")],
        )
    )
    print(
        "\nFaults in detector-noise standard deviations (the calibrated per-port noise; "
        "the two-tone column is the table above's):\n"
    )
    print(
        markdown_table(
            [*headers, "glitch caught %", "saturated caught %"],
            [
                row
                for name, runs in found
                for row in table_rows(name, runs, "noise", ("glitch", "saturated"))
            ],
        )
    )
    print(
        "\nThe new rule against the targets: good readings <= 1 %; caught / vis. >= 0.9 "
        "(scatter about the model):\n"
    )
    print(
        markdown_table(
            ["data set", "good flagged %", *(f"{fault} caught / vis." for fault in FAULTS)],
            target_rows(found),
        )
    )
    print(
        "\nCaught % by the new rule as the fault grows (scatter about the model; medians over "
        "the same seeds, another draw of the faults than the tables above):\n"
    )
    names = [name for name, _ in found]
    severity_rows = [
        [severity_cell(kind, level)]
        + [f"{_median(run['severity'][(kind, level)] for run in runs):.1f}" for _, runs in found]
        for kind, levels in SEVERITIES.items()
        for level in levels
    ]
    print(markdown_table(["fault", *names], severity_rows))
    print(
        "\nThe geometric limit: the share (%) of the clean devices' readings (random phases) "
        "at which a glitch of one random port is beyond the detector-noise threshold at all, "
        "applied to the reading's point on the calibrated cone:\n"
    )
    clean = [(name, runs) for name, runs in found if "clean" in name]
    print(
        markdown_table(
            ["glitch (noise std)", *(name for name, _ in clean)],
            [
                [f"{size:g}"]
                + [f"{_median(run['geometry'][size] for run in runs):.1f}" for _, runs in clean]
                for size in GLITCH_SIZES_NOISE
            ],
        )
    )
    if not measured:
        print(f"\n> measured data skipped: {MEASURED_DIR} not found")
        return 0
    print(
        "\nHeld out: the measured coupler calibrated on part of its readings; good readings "
        "flagged % among the others, per rule:\n"
    )
    print(
        markdown_table(
            ["sweep -> good readings", *RULES.values(), "RMS error MHz (sweep / held out)"],
            held_out,
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
