"""Monte Carlo helpers shared by the benchmark scripts.

One place for what every benchmark needs: the simulation regimes (device impairments,
noise, training sweep and test conditions), seeded device and data generation, the
Cramer-Rao bound of each device's test set, wall-clock timing as a median of several runs,
a fit that records its warnings and refusal instead of raising, the cells of the tables
(RMS, median, PASS/FAIL, warned-or-refused counts), markdown tables on stdout and a
progress line on stderr.

Seeding: device ``k`` with ``ports`` ports is drawn from ``SeedSequence([seed, ports, k])``
in every regime, so the regimes that only rescale an impairment see the same devices (the
same standard normal draws, scaled); its training and test data come from
``SeedSequence([seed, ports, k, crc32(regime key)])``.
"""

from __future__ import annotations

import statistics
import sys
import time
import zlib
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

import wavemeter as wm
from wavemeter.exceptions import recorded_calibration_warnings

__all__ = [
    "DESIGN_FSR_HZ",
    "NOISE_W",
    "POWER_W",
    "REGIMES",
    "TEST_SAMPLES",
    "Regime",
    "Trial",
    "Fit",
    "causes_cell",
    "crlb_rms_hz",
    "fit_recorded",
    "make_device",
    "make_trial",
    "markdown_table",
    "median",
    "median_time_s",
    "progress",
    "rms",
    "status",
    "trials",
    "wideband_crlb_hz",
]

DESIGN_FSR_HZ = 50e9
POWER_W = 1e-3
NOISE_W = 5e-7
TRAIN_SAMPLES = 2001
TEST_SAMPLES = 5000
#: draws of a device before giving up on an impairment spread that yields no physical device
MAX_DRAWS = 100


@dataclass(frozen=True)
class Regime:
    """One simulated operating condition.

    Attributes
    ----------
    key : str
        Short identifier (command-line friendly).
    title : str
        Human-readable description for table headings.
    device : dict
        Keyword overrides for :meth:`wavemeter.Interferometer.table1` (impairment sigmas).
    noise_factor : float
        Detector noise as a multiple of ``NOISE_W``.
    train_samples : int
        Number of calibration readings, evenly over the sweep.
    span_fsr : float
        Calibration sweep span in true FSRs; test frequencies lie in the same span.
    test_power_factor : float
        Test source power as a multiple of the calibration power ``POWER_W``.
    test_power_fluctuation : float
        Relative half width of a uniform per-sample fluctuation of the test source power.
    """

    key: str
    title: str
    device: dict = field(default_factory=dict)
    noise_factor: float = 1.0
    train_samples: int = TRAIN_SAMPLES
    span_fsr: float = 1.0
    test_power_factor: float = 1.0
    test_power_fluctuation: float = 0.0


REGIMES = (
    Regime("table1", "Table 1 impairments"),
    Regime("breaking", "symmetry-breaking perturbation 5 %", device={"breaking_sigma": 0.05}),
    Regime("responsivity", "responsivity spread 30 %", device={"responsivity_sigma": 0.30}),
    Regime("noise10", "detector noise x10", noise_factor=10.0),
    Regime("train10", "only 10 training samples", train_samples=10),
    Regime("span30", "training and test over 30 % of an FSR", span_fsr=0.3),
    Regime("power05", "test source power x0.5 of calibration", test_power_factor=0.5),
    Regime(
        "fluct30", "test source power fluctuating +-30 % per sample", test_power_fluctuation=0.3
    ),
)


@dataclass(frozen=True)
class Trial:
    """One device of one regime with its calibration sweep and its test readings.

    Attributes
    ----------
    device : wavemeter.Interferometer
    regime : Regime
    train_powers : ndarray, shape (N, n), W
    train_hz : ndarray, shape (N,), Hz
    test_powers : ndarray, shape (M, n), W
    test_hz : ndarray, shape (M,), Hz
    test_power_w : ndarray, shape (M,), W
        Source power of each test reading.
    noise_w : float
        Detector noise standard deviation (W).
    """

    device: wm.Interferometer
    regime: Regime
    train_powers: np.ndarray
    train_hz: np.ndarray
    test_powers: np.ndarray
    test_hz: np.ndarray
    test_power_w: np.ndarray
    noise_w: float

    def crlb_rms_hz(self) -> float:
        """RMS over the test set of the per-sample Cramer-Rao bound (Hz)."""
        return crlb_rms_hz(self.device, self.test_hz, self.test_power_w, self.noise_w)

    def error_hz(self, predicted_hz) -> np.ndarray:
        """Wrapped retrieval error (Hz) of predictions for the test readings."""
        return wm.frequency_error_hz(predicted_hz, self.test_hz, self.device.true_fsr_hz)


def make_device(ports: int, seed, regime: Regime = REGIMES[0]) -> wm.Interferometer:
    """A Table 1 device with the regime's impairment overrides.

    ``seed`` is an int or a numpy Generator. A draw that is not a physical device (a
    responsivity <= 0, possible at a wide spread) is rejected and drawn again from the same
    generator: the impairments are Gaussians truncated to physical devices.
    """
    rng = np.random.default_rng(seed)
    for _ in range(MAX_DRAWS):
        try:
            return wm.Interferometer.table1(ports=ports, seed=rng, **regime.device)
        except ValueError:
            continue
    raise ValueError(f"no physical device in {MAX_DRAWS} draws for regime {regime.key!r}")


def make_trial(
    device: wm.Interferometer,
    regime: Regime,
    rng,
    test_samples: int = TEST_SAMPLES,
) -> Trial:
    """Calibration sweep and random-frequency test readings of ``device`` under ``regime``.

    Parameters
    ----------
    device : wavemeter.Interferometer
    regime : Regime
    rng : int or numpy.random.Generator
        Source of test frequencies, power fluctuations and detector noise.
    test_samples : int
        Number of test readings.

    Returns
    -------
    Trial
    """
    rng = np.random.default_rng(rng)
    noise_w = NOISE_W * regime.noise_factor
    train_hz = device.sweep_hz(regime.train_samples, span_fsr=regime.span_fsr)
    train_powers = device.powers(train_hz, POWER_W, noise_w, rng)
    span_hz = regime.span_fsr * device.true_fsr_hz
    test_hz = device.center_hz + span_hz * (rng.random(test_samples) - 0.5)
    fluctuation = regime.test_power_fluctuation * rng.uniform(-1.0, 1.0, test_samples)
    test_power_w = POWER_W * regime.test_power_factor * (1.0 + fluctuation)
    test_powers = device.powers(test_hz, test_power_w, noise_w, rng)
    return Trial(
        device, regime, train_powers, train_hz, test_powers, test_hz, test_power_w, noise_w
    )


def trials(
    regime: Regime, ports: int, devices: int, seed: int, test_samples: int = TEST_SAMPLES
) -> Iterator[Trial]:
    """The ``devices`` trials of one regime and port count (see the module's seeding note)."""
    regime_code = zlib.crc32(regime.key.encode())
    for k in range(devices):
        device_rng = np.random.default_rng(np.random.SeedSequence([seed, ports, k]))
        device = make_device(ports, device_rng, regime)
        data_seed = np.random.SeedSequence([seed, ports, k, regime_code])
        yield make_trial(device, regime, np.random.default_rng(data_seed), test_samples)


def crlb_rms_hz(device: wm.Interferometer, frequency_hz, power_w, noise_w: float) -> float:
    """RMS of the per-sample Cramer-Rao bound (Hz) of ``device`` at the given readings.

    Parameters
    ----------
    device : wavemeter.Interferometer
    frequency_hz : array_like, shape (N,)
        Source frequencies (Hz).
    power_w : float or array_like, shape (N,)
        Source power (W).
    noise_w : float
        Detector noise standard deviation (W).

    Returns
    -------
    float, Hz
    """
    phase = 2.0 * np.pi * (np.asarray(frequency_hz) - device.center_hz) * device.delay_s
    bound = wm.crlb_frequency_std(device.true_map(), phase, power_w, noise_w, device.true_fsr_hz)
    return float(np.sqrt(np.mean(bound**2)))


def median_time_s(func: Callable[[], object], repeats: int = 5) -> tuple[float, object]:
    """Median wall-clock time (s) of ``repeats`` calls of ``func()`` and the last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A GitHub markdown table; cells are converted with ``str``."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def progress(message: str) -> None:
    """Overwrite the progress line on stderr (stdout carries only the tables)."""
    sys.stderr.write("\r" + message.ljust(100))
    sys.stderr.flush()


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def median(values) -> float:
    return float(statistics.median(values))


def status(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


@dataclass(frozen=True)
class Fit:
    """One calibration: the fitted calibrator or why it refused, its warnings and time.

    Attributes
    ----------
    calibrator : object or None
        The fitted calibrator; None when the fit refused the data.
    refused : str or None
        ``"ExceptionName: message"`` of the refusal.
    causes : tuple of str
        Causes of the ``CalibrationWarning`` s the fit emitted, sorted, one per cause.
    seconds : float
        Wall-clock fit time (s).
    """

    calibrator: object | None
    refused: str | None
    causes: tuple[str, ...]
    seconds: float


def fit_recorded(calibrator, powers_w, frequency_hz, **fit_inputs) -> Fit:
    """Fit ``calibrator`` timed, recording its warnings; a refusal is recorded, not raised."""
    with recorded_calibration_warnings() as notes:
        start = time.perf_counter()
        try:
            calibrator.fit(powers_w, frequency_hz, **fit_inputs)
        except wm.WavemeterError as error:
            refused = f"{type(error).__name__}: {error}"
        else:
            refused = None
        seconds = time.perf_counter() - start
    if refused is not None:
        return Fit(None, refused, (), seconds)
    return Fit(calibrator, None, tuple(sorted({note.cause for note in notes})), seconds)


def causes_cell(fits: Sequence[Fit]) -> str:
    """How many fits warned or refused, with the causes (and refusals, by exception) named
    and counted."""
    counts = Counter(cause for fit in fits for cause in fit.causes)
    counts.update(f"refused ({fit.refused.split(':')[0]})" for fit in fits if fit.refused)
    warned = sum(bool(fit.causes or fit.refused) for fit in fits)
    named = ", ".join(f"{cause} {count}" for cause, count in counts.most_common())
    return f"{warned}/{len(fits)}" + (f": {named}" if named else "")


def wideband_crlb_hz(device: wm.Interferometer, frequency_hz, power_w, noise_w) -> np.ndarray:
    """Per-reading Cramer-Rao bound (Hz) of a device with spectral effects, at the true
    frequencies.

    The phase bound under the device's map at each frequency (``true_map(frequency_hz=f)``,
    the bias inside it) at its phase ``phase_rad(f)``, over ``dt/df = 2 pi`` times the group
    delay there: dispersion and coupler slopes are those of the truth.

    Parameters
    ----------
    device : wavemeter.Interferometer
    frequency_hz : ndarray, shape (N,)
        Source frequencies (Hz).
    power_w : float or array_like, shape (N,)
        Power reaching the device (W).
    noise_w : float or array_like, shape (n,)
        Detector noise standard deviation per reading (W), one or one per port.

    Returns
    -------
    ndarray, shape (N,), Hz
    """
    phase_bound_rad = wm.crlb_frequency_std(
        device.true_map(frequency_hz=frequency_hz),
        device.phase_rad(frequency_hz),
        power_w,
        noise_w,
        2.0 * np.pi,
    )
    return phase_bound_rad / (2.0 * np.pi * device.group_delay_s(frequency_hz))
