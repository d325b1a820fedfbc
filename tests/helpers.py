"""What several test files share: the Table 1 source and noise, the command line run in
process, simulated sweeps and files, CSV text with comments and blank lines, a dead port,
the FSR's Cramer-Rao bound, the wrap rate of a cascade's coarsest stage by quadrature, the
benchmarks' tables, the wide-band model of the misfit tests, a batch of the service's
readings, and the names of the hypothesis profiles.

Test files import these from here (``from .helpers import ...``), never from another test
file or from ``conftest.py``, which holds the fixtures; ``tests/test_test_layout.py``
checks it.
"""

from __future__ import annotations

import csv
import dataclasses
import shlex
from pathlib import Path

import numpy as np
from scipy import integrate, linalg, special

import wavemeter as wm
from wavemeter.calibration.checks.misfit import MisfitReport, misfit_report
from wavemeter.calibration.models.learned_fit import fit_learned_map
from wavemeter.cli import main
from wavemeter.model.cone import cone_vectors, delay_phase_rad
from wavemeter.model.orders import edge_error_probability
from wavemeter.simulation.drift import slow_power_drift

#: source power (W) of the simulated sweeps
POWER_W = 1e-3
#: detector noise (W), Table 1: 5e-4 mW at 1 mW
NOISE_W = 5e-7
#: a dark port's offset (W), so that no row sums to zero
DARK_W = 1e-6
#: the hypothesis profile of the default run (conftest.py loads it): the same examples on every
#: run and machine, no database, no deadline
DEFAULT_PROFILE = "wavemeter"
#: ``make fuzz``'s profile: new examples from the seed it prints, no database, no deadline
FUZZ_PROFILE = "fuzz"
#: the repository's ``benchmarks/`` folder (its scripts are imported by the smoke tests)
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


# ---------------------------------------------------------------------------- readings
def random_test_frequencies(device: wm.Interferometer, samples: int, rng) -> np.ndarray:
    """Frequencies (Hz) uniform over one true FSR about the device centre, shape (samples,)."""
    half = device.true_fsr_hz / 2
    return device.center_hz + rng.uniform(-half, half, samples)


def darken(readings: np.ndarray, ports, seed: int = 0) -> np.ndarray:
    """``readings`` (N, n), W, with ``ports`` replaced by dark noise: the offset
    :data:`DARK_W` and the detector noise :data:`NOISE_W`, no fringe."""
    rng = np.random.default_rng(seed)
    dark = readings.copy()
    for port in ports:
        dark[:, port] = DARK_W + NOISE_W * rng.standard_normal(dark.shape[0])
    return dark


#: calibration temperatures of the thermal tests (K): four, symmetric about the simulator's
#: reference temperature 293.15 K, the closest two 1.5 K apart
THERMAL_SWEEP_TEMPERATURES_K = (289.15, 292.4, 293.9, 297.15)


def thermal_sweep(
    device: wm.Interferometer,
    samples_per_temperature: int,
    noise_w: float,
    rng,
    temperatures_k=THERMAL_SWEEP_TEMPERATURES_K,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-FSR sweeps of a device at several temperatures, stacked in acquisition order.

    Returns
    -------
    powers : ndarray, shape (N, n), W
    frequency_hz : ndarray, shape (N,), Hz
    temperature_k : ndarray, shape (N,), K (the true chip temperature of each reading)
    """
    frequency = device.sweep_hz(samples_per_temperature)
    generator = np.random.default_rng(rng)
    powers = [
        device.powers(frequency, POWER_W, noise_w, rng=generator, temperature_k=temperature)
        for temperature in temperatures_k
    ]
    count = len(temperatures_k)
    return (
        np.vstack(powers),
        np.tile(frequency, count),
        np.repeat(np.asarray(temperatures_k, dtype=float), frequency.size),
    )


def fsr_crlb_std_hz(device: wm.Interferometer, frequency_hz: np.ndarray) -> float:
    """Cramer-Rao standard deviation (Hz) of the FSR fitted on a sweep, map unknown.

    Model ``p_k = A x(t_k)`` with ``t_k = 2 pi (f_k - f0) tau``; for each port the
    derivative by ``tau`` is projected off the span of the object vectors (the derivatives
    by that port's map row), ``var(tau) = sigma^2 / sum ||residual||^2``, and
    ``sigma_FSR = FSR^2 sigma_tau``. ``frequency_hz`` (N,), Hz; readings at :data:`POWER_W`
    with noise :data:`NOISE_W`.
    """
    offset = frequency_hz - device.center_hz
    phase = delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    objects = cone_vectors(phase, POWER_W)
    tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=-1)
    derivative = (POWER_W * tangent @ device.true_map().T) * (2 * np.pi * offset)[:, None]
    q, _ = linalg.qr(objects, mode="economic")
    residual = derivative - q @ (q.T @ derivative)
    delay_std = NOISE_W / np.sqrt(np.sum(residual**2))
    return device.true_fsr_hz**2 * delay_std


def band_average_edge_rate(coarsest_fsr_hz: float, std_hz: float, width_hz: float) -> float:
    """Wrap rate of a cascade's coarsest stage at both ends of a band ``width_hz`` (Hz) wide,
    averaged over the band, by quadrature of ``Q(d / s)`` (the stage's error std ``s``,
    Hz; its FSR ``coarsest_fsr_hz``, Hz)."""
    near = (coarsest_fsr_hz - width_hz) / 2.0
    one_end, _ = integrate.quad(
        lambda distance: float(edge_error_probability(distance, std_hz)),
        near,
        near + width_hz,
        points=[near + k * std_hz for k in (1, 3, 10) if k * std_hz < width_hz],
        limit=500,
        epsabs=0.0,
        epsrel=1e-10,
    )
    return 2.0 * one_end / width_hz


# ---------------------------------------------------------------------------- command line
def run_cli(capsys, command: str) -> tuple[int, str, str]:
    """Run ``wavemeter COMMAND`` in process: exit code, stdout, stderr."""
    code = main(shlex.split(command))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error(code: int, err: str) -> str:
    """The single ``error:`` line of a refused command (exit code 2)."""
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err


def simulated_files(folder: Path, test_rows: int, seed: int = 1) -> dict[str, Path]:
    """A simulated sweep with a test file in ``folder``, and its learned calibration."""
    sweep, cal = folder / "sweep.csv", folder / "chip.wmcal.json"
    simulate = f"simulate -o {sweep} --seed {seed} --samples 400 --test {test_rows} --quiet"
    assert main(shlex.split(simulate)) == 0
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --quiet")) == 0
    return {"sweep": sweep, "test": folder / "sweep-test.csv", "cal": cal}


def text_with_comments_and_blank_lines(chip, newline: str = "\n") -> tuple[str, list[int]]:
    """The readings ``chip["time_s"]`` (N,), s, and ``chip["powers"]`` (N, 3), W (NaN for a
    missing reading) as CSV text after two comment lines, with blank lines here and there;
    and the file line (1-based) of each data row."""
    text = ["# chip 7", "# measured 2026-11-24", "time_s,p1_w,p2_w,p3_w"]
    line_of_row = []
    for row, values in enumerate(zip(chip["time_s"], *chip["powers"].T, strict=True)):
        if row % 9 == 4:
            text.append("")
        text.append(",".join("" if np.isnan(v) else repr(float(v)) for v in values))
        line_of_row.append(len(text))
    return newline.join(text) + newline, line_of_row


# ---------------------------------------------------------------------------- the service
def reading_batch(first: int = 0, count: int = 5, run: str = "r1", channel: int = 3):
    """A ``ReadingBatch`` of ``count`` readings numbered from ``first``, near 193.4 THz, the
    second one invalid (NaN frequency), with the simulator's true frequencies as an extra
    column; its randomness seeded by ``first``."""
    from wavemeter.service.records import ReadingBatch

    rng = np.random.default_rng(first)
    columns = {
        "sequence": np.arange(first, first + count),
        "source_time_ns": 1_800_000_000_000_000_000 + np.arange(count) * 1_000_000,
        "time_ns": 1_800_000_000_000_100_000 + np.arange(count) * 1_000_000,
        "frequency_hz": 193.4e12 + rng.normal(0, 1e7, count),
        "frequency_std_hz": np.full(count, 1.2e7),
        "flags": np.array([0, 8, 0, 2, 0][:count] + [0] * max(0, count - 5)),
        "true_frequency_hz": 193.4e12 + rng.normal(0, 1e6, count),
    }
    columns["frequency_hz"][1] = np.nan
    return ReadingBatch(channel, columns, run=run, name="Ti:Sa")


# ---------------------------------------------------------------------------- benchmarks
def table_rows(table: str) -> list[list[str]]:
    """The cells of a Markdown table a benchmark printed, row by row, stripped."""
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in table.splitlines()]


# ---------------------------------------------------------------------------- wide band
#: the wide-band model's sweeps: 20 FSRs of 50 GHz, 200 readings per FSR
WIDEBAND_FSR_HZ = 50e9
WIDEBAND_FSRS = 20
WIDEBAND_READINGS_PER_FSR = 200
#: its map coefficients A_1, A_2 relative to A_0, elementwise
MAP_VARIATION = 0.02
#: b_2: group-delay dispersion of a few 1e-26 s^2 over 1 THz
QUADRATIC_PHASE_RAD = 1.0


@dataclasses.dataclass(frozen=True)
class WidebandSweep:
    """Readings of the wide-band model ``p_k = A(y_k) u(t_k)`` plus white noise."""

    frequency_hz: np.ndarray  # (N,)
    center_hz: float
    half_span_hz: float
    phase_coefficients_rad: np.ndarray  # true b_1..b_P (P,)
    powers_w: np.ndarray  # (N, n)

    @property
    def y(self) -> np.ndarray:
        """``(f - f0) / h`` (N,), in [-1, 1]."""
        return (self.frequency_hz - self.center_hz) / self.half_span_hz


def legendre_columns(y: np.ndarray, degree: int) -> np.ndarray:
    """``L_j(y)`` for ``j = 0..degree`` (N, degree + 1)."""
    return np.column_stack([special.eval_legendre(j, y) for j in range(degree + 1)])


def model_phase_rad(y: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """``sum_i b_i y^i``, ``i = 1..P`` (rad)."""
    return sum(b * y ** (i + 1) for i, b in enumerate(coefficients))


def wideband_sweep(
    ports: int,
    seed: int,
    *,
    map_degree: int = 2,
    higher_phase_rad: tuple = (QUADRATIC_PHASE_RAD,),
    power: np.ndarray | None = None,
) -> WidebandSweep:
    """Readings of the wide-band model; ``higher_phase_rad`` are ``b_2, b_3, ...``."""
    rng = np.random.default_rng(seed)
    device = wm.Interferometer.table1(ports, seed=seed)
    base = device.true_map() * POWER_W
    coefficients = [base] + [
        MAP_VARIATION * rng.standard_normal(base.shape) * base for _ in range(map_degree)
    ]
    samples = WIDEBAND_FSRS * WIDEBAND_READINGS_PER_FSR
    half_span = WIDEBAND_FSRS * WIDEBAND_FSR_HZ / 2.0
    frequency = device.center_hz + half_span * (2.0 * (np.arange(samples) + 0.5) / samples - 1.0)
    y = (frequency - device.center_hz) / half_span
    phase_coefficients = np.array([2.0 * np.pi * half_span / WIDEBAND_FSR_HZ, *higher_phase_rad])
    maps = np.einsum("kj,jab->kab", legendre_columns(y, map_degree), np.array(coefficients))
    objects = cone_vectors(model_phase_rad(y, phase_coefficients), 1.0 if power is None else power)
    powers = np.einsum("kab,kb->ka", maps, objects)
    powers += NOISE_W * rng.standard_normal(powers.shape)
    return WidebandSweep(frequency, device.center_hz, half_span, phase_coefficients, powers)


def fit_map(sweep: WidebandSweep, coefficients: np.ndarray, degree: int):
    """Least-squares map of ``degree`` at the phase coefficients: the phases (N,), design
    (N, 3 (degree + 1)), each reading's map (N, n, 3) and the residual (N, n)."""
    y = sweep.y
    phase = model_phase_rad(y, coefficients)
    design = np.einsum("kj,ki->kji", legendre_columns(y, degree), cone_vectors(phase))
    design = design.reshape(y.size, -1)
    solution, *_ = np.linalg.lstsq(design, sweep.powers_w, rcond=None)
    map_coefficients = solution.reshape(degree + 1, 3, -1)  # (j, object, port)
    maps = np.einsum("kj,jip->kpi", legendre_columns(y, degree), map_coefficients)
    return phase, design, maps, sweep.powers_w - design @ solution


def wideband_report(
    sweep: WidebandSweep, coefficients: np.ndarray, degree: int, **options
) -> MisfitReport:
    """``misfit_report`` of the wide-band fit of ``degree`` at the phase ``coefficients``."""
    phase, design, maps, _ = fit_map(sweep, coefficients, degree)
    derivatives = np.array([sweep.y ** (i + 1) for i in range(coefficients.size)])
    return misfit_report(
        sweep.powers_w,
        sweep.frequency_hz,
        sweep.center_hz,
        coefficients[0] / (2.0 * np.pi * sweep.half_span_hz),
        maps,
        phase_rad=phase,
        design=design,
        phase_derivatives=derivatives,
        **options,
    )


def narrow_band_case(kind: str):
    """A one-map sweep and its learned fit (``kind``: ``"plain"``, ``"offsets"`` or
    ``"phase"``): the arguments of today's ``misfit_report`` call, and the design and phase
    derivatives today's defaults stand for."""
    device = wm.Interferometer.table1(4, seed=50)
    frequency = device.sweep_hz(600, 3.0)
    power = POWER_W * slow_power_drift(600, 0.3, rng=50) if kind == "offsets" else POWER_W
    powers = device.powers(frequency, power, NOISE_W, rng=51)
    center = 0.5 * (frequency.min() + frequency.max())
    scale = power / power.mean() if kind == "offsets" else None
    fit = fit_learned_map(
        powers,
        frequency,
        center,
        fsr_hz=WIDEBAND_FSR_HZ,
        fsr_tolerance=0.2,
        scale=scale,
        affine=kind == "offsets",
    )
    options = {"scale": scale}
    phase = delay_phase_rad(frequency, center, fit.delay_s)
    if kind == "offsets":
        options.update(offset_w=fit.map_[:, 3], offset_std_w=np.full(4, 1e-7))
    if kind == "phase":  # a thermal model's phase, with its expected scatter
        phase = phase + 0.02 * np.sin(np.linspace(0.0, 6.0, frequency.size))
        options.update(phase_rad=phase, phase_noise_std_rad=np.full(frequency.size, 1e-3))
    objects = cone_vectors(phase, 1.0 if scale is None else scale)
    design = objects if kind != "offsets" else np.column_stack([objects, np.ones(600)])
    derivatives = (2.0 * np.pi * (frequency - center))[None]
    arguments = (powers, frequency, center, fit.delay_s, fit.map_[:, :3])
    return arguments, options, design, derivatives


def read_csv_values(path) -> tuple[list[str], np.ndarray]:
    """Header and values of a CSV, each cell parsed with ``float()`` (no unit handling)."""
    with open(path, newline="") as file:
        rows = list(csv.reader(file))
    return rows[0], np.array([[float(cell) for cell in row] for row in rows[1:]])


def assert_file_holds(path, table: dict) -> None:
    header, values = read_csv_values(path)
    assert header == list(table)
    for index, (name, expected) in enumerate(table.items()):
        # == on every value (NaN nowhere): the written text is the shortest round trip
        assert values[:, index].tolist() == np.asarray(expected, dtype=float).tolist(), name


class RecordingSink:
    """An output that records every voltage written; it fails while ``failing``."""

    def __init__(self, limits_v=(-5.0, 5.0), output_v=1.25):
        self.limits_v = limits_v
        self.output_v = output_v
        self.written: list[float] = []
        self.failing = False

    def write(self, voltage_v: float) -> None:
        if self.failing:
            raise OSError("the DAC does not answer")
        self.written.append(voltage_v)
        self.output_v = voltage_v


def with_bad_readings(readings: np.ndarray, inputs: dict, rng) -> tuple[np.ndarray, dict]:
    """Copies of test ``readings`` (N >= 20, n) and their per-reading ``inputs`` (each one
    value or N) with bad ones put in: a NaN cell, no light, negative power, a dim reading
    (lit, below the no-light fraction of the sweep's power), tenfold power, a reading far
    off the cone, an inf cell, ten readings at 0.3-3x the power; for each input a NaN, and
    for ``coarse_hz`` two values terahertz outside the band."""
    rows = readings.copy()
    inputs = {
        name: np.full(len(rows), float(value)) if np.ndim(value) == 0 else np.array(value)
        for name, value in inputs.items()
    }
    rows[0, 1], rows[1], rows[2], rows[6, -1] = np.nan, 0.0, -rows[2], np.inf
    rows[3] *= 0.002
    rows[4] *= 10.0
    rows[5, 0] += 50 * NOISE_W
    picked = rng.choice(np.arange(10, len(rows)), size=10, replace=False)
    rows[picked] *= rng.uniform(0.3, 3.0, (10, 1))
    for name, values in inputs.items():
        values[7] = np.nan
        if name == "coarse_hz":
            values[8] += 3e12
            values[9] -= 5e12
    return rows, inputs


def bound_rms_hz(device, frequency_hz, ports, known_power: bool) -> float:
    """RMS over test frequencies of the per-sample Cramer-Rao bound (Hz).

    ``known_power``: the source power is known (information ``|a_t|^2 / sigma^2`` of the
    ports read); otherwise it is a nuisance (:func:`wavemeter.crlb_frequency_std`).
    """
    phase = 2 * np.pi * (frequency_hz - device.center_hz) * device.delay_s
    matrix = device.true_map()[list(ports)]
    if known_power:
        tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=-1)
        slope = POWER_W * np.linalg.norm(tangent @ matrix.T, axis=1)
        per_sample = device.true_fsr_hz / (2 * np.pi) * NOISE_W / slope
    else:
        per_sample = wm.crlb_frequency_std(matrix, phase, POWER_W, NOISE_W, device.true_fsr_hz)
    return float(np.sqrt(np.mean(per_sample**2)))
