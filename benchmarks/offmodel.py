"""OFF_MODEL on simulated and measured data: good readings flagged, injected faults caught.

The ``OFF_MODEL`` flag compares a reading's weighted distance to the calibrated cone with
a threshold. The old rule takes it from the detector noise alone; the new one (issue 29)
does so too unless the calibration sweep's own distances show a model error, and then
scales the noise's distribution to the sweep's median distance. This script measures both
side by side on the same calibrations and readings: the old rule is the same calibration
saved without its ``off_model`` record and loaded again (what a file of 0.7 gives).

Data sets:

- simulated, clean: Table 1 devices (3 or 4 ports, 1 mW, detector noise 5e-7 W),
  calibrated on 2001 readings over one FSR; good readings: ``--test`` fresh readings at
  random frequencies over the FSR;
- simulated, model error: the same devices read through detectors that compress by
  ``COMPRESSION`` (5 %) at the sweep's largest reading (``p - 0.05 p^2 / p_max``, sweep and
  test alike): the fit warns ``other_misfit``, the sweep's median distance is 12-130 times
  the noise's;
- measured: the MiniPTI 3x3 fibre coupler (``../shared/data/minipti-fiber-3x3``, 3726
  readings of ``DC CH1..3`` in V), calibrated with MiniPTI's published phase as the label
  (``f = 193.4 THz + unwrap(phase) / 2 pi x 50 GHz``); good readings: the calibration's own.

Faults, each injected into every good reading (one fault at a time):

- glitch: one port, drawn at random, moved by ``GLITCH_SCATTER`` (10) times that port's
  scatter about the calibrated model (the fit's per-port residual RMS, ``diagnostics_``),
  with a random sign;
- two-tone: a second laser line at ``SECOND_LINE_SHARE`` (15 %) of the power, at an
  independent random frequency: ``0.85 p_i + 0.15 p_k`` with ``k`` another good reading;
- saturated: one port, drawn at random, clipped at the middle of its calibrated range;
  only readings it changes by more than ``GLITCH_SCATTER`` scatters count as faulty.

Columns: the share (%) of good readings with ``OFF_MODEL``; of faulty readings caught
(``OFF_MODEL``); and, for the faults, the share a distance test can see at all at that
rule's threshold ("visible"): the fault applied to the reading's own point on the
calibrated cone (no noise, no model error) is beyond the threshold. A one-port fault has
no component off the cone at two phases per fringe on a 3-port device (the residual space
is one-dimensional), a second line has none when it is in phase with the first: no
threshold catches those. Medians over ``--seeds`` devices (simulated) or fault draws
(measured).

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

import wavemeter as wm

DESIGN_FSR_HZ = 50e9
SWEEP_SAMPLES = 2001
#: detector compression of the model-error devices at the sweep's largest reading
COMPRESSION = 0.05
#: a glitch, and the least clipping that counts, in the port's scatter about the model
GLITCH_SCATTER = 10.0
#: power of the second laser line of a two-tone reading
SECOND_LINE_SHARE = 0.15
#: a saturated port clips at this fraction of its calibrated range
CLIP_LEVEL = 0.5
#: the severities of the second table (the new rule only)
SEVERITIES = {
    "glitch": (10.0, 30.0, 100.0),
    "two-tone": (0.15, 0.3, 0.5),
    "saturated": (0.75, 0.5, 0.25),
}
#: the measured data and how it is labelled
MEASURED_DIR = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
MEASURED_PORTS = ("DC CH1", "DC CH2", "DC CH3")
MEASURED_CENTER_HZ = 193.4e12
FAULTS = ("glitch", "two-tone", "saturated")
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


def old_rule(calibration):
    """The calibration as a file of 0.7 has it: saved without its ``off_model`` record
    and loaded again (``OFF_MODEL`` against the detector noise alone)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "old.wmcal.json"
        calibration.save(path)
        document = json.loads(path.read_text())
        document["state"].pop("off_model", None)
        path.write_text(json.dumps(document))
        return wm.load_calibration(path)


def scatter(calibration) -> np.ndarray:
    """Each port's scatter about the calibrated model: the fit's residual RMS (W)."""
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
    kind: str, case: Case, rng: np.random.Generator, severity: float | None = None
) -> Faulty:
    """The fault ``kind`` injected into every good reading (module docstring), at the
    module's severity or at ``severity``: the glitch in scatters, the second line's share
    of the power, the clipping level as a fraction of the port's calibrated range."""
    good, calibration = case.good, case.calibration
    points = cone_points(calibration, good)
    rows = np.arange(good.shape[0])
    port = rng.integers(0, good.shape[1], good.shape[0])
    size = GLITCH_SCATTER * scatter(calibration)
    if kind == "glitch" and severity is not None:
        size = severity * scatter(calibration)
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


def shares(case: Case, rng: np.random.Generator) -> dict[str, dict[str, float]]:
    """Per rule: good readings flagged (%), and per fault caught and visible (%)."""
    faults = {kind: inject(kind, case, rng) for kind in FAULTS}
    result = {}
    for rule, calibration in (("old", old_rule(case.calibration)), ("new", case.calibration)):
        row = {"good": 100 * np.mean(calibration.flags(case.good) & OFF_MODEL > 0)}
        for kind, faulty in faults.items():
            flagged = calibration.flags(faulty.readings[faulty.affected]) & OFF_MODEL > 0
            visible = calibration.flags(faulty.on_cone[faulty.affected]) & OFF_MODEL > 0
            row[kind], row[f"{kind} visible"] = 100 * np.mean(flagged), 100 * np.mean(visible)
        result[rule] = row
    return result


def severity_shares(case: Case, rng: np.random.Generator) -> dict[tuple[str, float], float]:
    """Per fault and severity (``SEVERITIES``): the share (%) caught by the new rule."""
    found = {}
    for kind, levels in SEVERITIES.items():
        for level in levels:
            faulty = inject(kind, case, rng, level)
            flags = case.calibration.flags(faulty.readings[faulty.affected])
            found[(kind, level)] = 100 * np.mean(flags & OFF_MODEL > 0)
    return found


def severity_cell(kind: str, level: float) -> str:
    if kind == "glitch":
        return f"glitch {level:g} scatters"
    if kind == "two-tone":
        return f"second line {level:.0%}"
    return f"clipped at {level:.0%} of range"


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
                runs.append({**shares(case, rng), "severity": severity_shares(case, rng)})
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


def table_rows(name: str, runs: list[dict]) -> list[list[str]]:
    """Two rows (old rule, new rule): medians over the runs."""
    rows = []
    for rule, label in (("old", "detector noise (0.7)"), ("new", "calibration's distances")):
        cells = [name, label]
        for key in ("good", *FAULTS):
            value = statistics.median(run[rule][key] for run in runs)
            cell = f"{value:.2f}" if key == "good" else f"{value:.1f}"
            if key != "good":
                seen = statistics.median(run[rule][f"{key} visible"] for run in runs)
                cell += f" ({seen:.1f})"
            cells.append(cell)
        rows.append(cells)
    return rows


def main(argv=None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=positive_int, default=5, help="devices or fault draws")
    parser.add_argument("--test", type=positive_int, default=5000, help="good readings (simulated)")
    parser.add_argument("--quick", action="store_true", help="2 seeds, 1000 test readings")
    args = parser.parse_args(argv)
    seeds, test = (2, 1000) if args.quick else (args.seeds, args.test)
    measured = MEASURED_DIR.is_dir()
    found = list(data_sets(seeds, test, measured))
    rows = [row for name, runs in found for row in table_rows(name, runs)]
    progress("")
    sys.stderr.write("\r")
    headers = [
        "data set",
        "OFF_MODEL rule",
        "good readings flagged %",
        *(f"{kind} caught % (visible %)" for kind in FAULTS),
    ]
    print(f"OFF_MODEL: medians over {seeds} seeds; simulated good readings: {test} per device\n")
    print(markdown_table(headers, rows))
    print(
        "\nCaught % by the new rule as the fault grows (medians over the same seeds; another "
        "draw of the faults than the table above):\n"
    )
    names = [name for name, _ in found]
    severity_rows = [
        [severity_cell(kind, level)]
        + [
            f"{statistics.median(run['severity'][(kind, level)] for run in runs):.1f}"
            for _, runs in found
        ]
        for kind, levels in SEVERITIES.items()
        for level in levels
    ]
    print(markdown_table(["fault", *names], severity_rows))
    if not measured:
        print(f"\n> measured data skipped: {MEASURED_DIR} not found")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
