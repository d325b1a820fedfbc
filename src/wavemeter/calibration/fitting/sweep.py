"""The calibration sweep as a fit sees it, and the state a fit carries from step to step.

:func:`checked_sweep` validates what ``fit`` was given into a :class:`Sweep` (read-only
arrays, the dark readings subtracted). :class:`FitContext` is the fit's own state while it
runs: the sweep, what each step found (the check of the design FSR, the ports' health,
the warnings so far) and, in a method's subclass of it, what its learning steps pass on.
A calibrator keeps only what it learned; nothing of the fit is stored on it and deleted.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from ...exceptions import InputError
from ...units import OPTICAL_BAND_HZ, WAVELENGTH_UNITS, optical_unit_guess
from ...validation import (
    MIN_SAMPLES,
    check_dark,
    check_frequency,
    check_monitor,
    check_per_reading,
    check_powers,
)

__all__ = [
    "FitContext",
    "Sweep",
    "checked_port_names",
    "checked_powers",
    "checked_sweep",
    "checked_temperature",
    "value_range",
]


def checked_port_names(port_names, ports: int) -> list[str]:
    """Names of the port columns: ``p1 .. pn`` by default, else ``ports`` strings."""
    names = [f"p{k + 1}" for k in range(ports)] if port_names is None else list(port_names)
    if len(names) != ports or not all(isinstance(name, str) for name in names):
        raise InputError(f"port_names must be {ports} strings, got {port_names!r}")
    return names


def value_range(values: np.ndarray | None) -> list[float] | None:
    """``[lowest, highest]`` of some values (None for None), as diagnostics keep ranges."""
    return None if values is None else [float(values.min()), float(values.max())]


@dataclass(frozen=True, eq=False)
class Sweep:
    """A validated calibration sweep.

    Attributes
    ----------
    powers_w : ndarray, shape (N, n)
        Port readings less the dark readings (W, or the unit of the readings).
    frequency_hz : ndarray, shape (N,)
        Known frequency of each reading (Hz).
    monitor_w : None or ndarray, shape (N,)
        Source-power monitor readings.
    port_names : list of str
        Names of the port columns.
    dark_w : None or ndarray, shape (n,)
        The dark readings subtracted.
    temperature_k : None or ndarray, shape (N,)
        Chip temperature of each reading (K).
    monitor_mean_w : None or float
        The monitor's mean over the whole sweep, when these readings are a sample of it.
    axis_bandwidth_per_reading : float
        When the axis was made from the meter's own phase smoothed along the sweep (a
        reference cell's corrected axis), the frequency (cycles per reading) up to which it
        follows that phase's noise; 0 for an axis given.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import Sweep
    >>> sweep = Sweep(powers, f_hz, None, ["p1", "p2", "p3"])  # what a calibrator's _learn is given
    >>> sweep.samples, sweep.ports, sweep.scale is None
    (200, 3, True)
    >>> print(f"{sweep.center_hz / 1e12:.4f} THz, {np.ptp(sweep.span_hz) / 1e9:.2f} GHz span")
    193.3999 THz, 51.25 GHz span
    >>> sweep.rows(slice(0, 50)).samples
    50
    """

    powers_w: np.ndarray
    frequency_hz: np.ndarray
    monitor_w: np.ndarray | None
    port_names: list
    dark_w: np.ndarray | None = None
    temperature_k: np.ndarray | None = None
    monitor_mean_w: float | None = None
    axis_bandwidth_per_reading: float = 0.0

    @functools.cached_property
    def scale(self) -> np.ndarray | None:
        """The monitored power relative to its mean over the sweep (N,), or None."""
        if self.monitor_w is None:
            return None
        return self.monitor_w / self.monitor_mean

    @property
    def samples(self) -> int:
        return self.powers_w.shape[0]

    @property
    def ports(self) -> int:
        return self.powers_w.shape[1]

    @property
    def span_hz(self) -> tuple[float, float]:
        return float(self.frequency_hz.min()), float(self.frequency_hz.max())

    @property
    def center_hz(self) -> float:
        low, high = self.span_hz
        return 0.5 * (low + high)

    def rows(self, rows) -> Sweep:
        """The sweep of some readings (a boolean mask or indices)."""
        return Sweep(
            self.powers_w[rows],
            self.frequency_hz[rows],
            None if self.monitor_w is None else self.monitor_w[rows],
            self.port_names,
            self.dark_w,
            None if self.temperature_k is None else self.temperature_k[rows],
            None if self.monitor_w is None else self.monitor_mean,
            self.axis_bandwidth_per_reading,
        )

    @property
    def monitor_mean(self) -> float:
        """The monitor's mean over the whole sweep."""
        return self.monitor_w.mean() if self.monitor_mean_w is None else self.monitor_mean_w


def checked_temperature(temperature_k, samples: int, required_by: str | None) -> np.ndarray | None:
    """The sweep's chip temperatures (K), one per reading; None when not given (an error
    when ``required_by`` names a calibrator that needs them)."""
    if temperature_k is None:
        if required_by is not None:
            raise InputError(
                f"{required_by} needs temperature_k (K) for each calibration reading: give the "
                "chip temperature the sweep was recorded at",
                parameter="temperature_k",
            )
        return None
    try:
        temperature = check_per_reading("temperature_k", temperature_k, samples)
    except InputError as exc:
        raise InputError(str(exc), parameter="temperature_k") from exc
    if np.any(temperature <= 0):
        raise InputError(
            "temperature_k must be > 0 (K, absolute temperature); convert from Celsius",
            parameter="temperature_k",
        )
    return temperature


def checked_powers(powers) -> np.ndarray:
    """A sweep's readings checked (N, n): finite, at least ``MIN_SAMPLES`` rows."""
    return check_powers(powers, min_samples=MIN_SAMPLES)


def checked_sweep(
    powers,
    frequency_hz,
    power_monitor_w=None,
    port_names=None,
    *,
    dark_w=None,
    temperature_k=None,
    temperature_required_by: str | None = None,
    axis_bandwidth_per_reading: float = 0.0,
) -> Sweep:
    """What ``fit`` was given, validated (:class:`Sweep`); raises :class:`InputError` naming
    the value that is wrong."""
    raw = check_powers(powers, min_samples=MIN_SAMPLES)
    samples, ports = raw.shape
    frequency = check_frequency(frequency_hz, samples)
    check_frequency_unit(frequency)
    monitor = check_monitor(power_monitor_w, samples)
    dark = check_dark(dark_w, ports)
    names = checked_port_names(port_names, ports)
    temperature = checked_temperature(temperature_k, samples, temperature_required_by)
    return Sweep(
        raw if dark is None else raw - dark,
        frequency,
        monitor,
        names,
        dark,
        temperature,
        axis_bandwidth_per_reading=axis_bandwidth_per_reading,
    )


def check_frequency_unit(frequency_hz: np.ndarray) -> None:
    """Refuse frequencies that are not optical in Hz but would be in another unit (THz,
    nm...): a unit slip, named with the unit the values look like."""
    low, high = OPTICAL_BAND_HZ
    if low <= frequency_hz.min() and frequency_hz.max() <= high:
        return
    unit = optical_unit_guess(frequency_hz)
    if unit is not None and unit != "Hz":
        kind = "wavelengths" if unit in WAVELENGTH_UNITS else "frequencies"
        raise InputError(
            f"frequency_hz must be in Hz; its values {frequency_hz.min():.6g} to "
            f"{frequency_hz.max():.6g} look like {kind} in {unit}: convert them to "
            "frequencies in Hz",
            parameter="frequency_hz",
        )


@dataclass(eq=False)
class FitContext:
    """What a fit has found so far, passed from step to step (module docstring).

    Attributes
    ----------
    sweep : Sweep
        The readings the checks see (every reading, or a sample of a large sweep).
    estimate : FsrEstimate or None
        The sweep's own FSR, from the check of the design FSR.
    delay_s : float
        The sweep's own delay (s): the estimate's, else the design one.
    health : list of PortHealth
        Every port's fringe.
    notes : list of CalibrationWarning
        The fit's warnings so far, in order.
    affine : bool
        Per-port offsets are fitted (a monitored power that varied, no dark readings).
    temperature_range_k : None or list of float
        The whole sweep's lowest and highest chip temperature (K), where given.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import FitContext, Sweep

    What a fit has found so far, handed from step to step of a calibrator whose fit has
    steps of its own; it starts from the checked sweep:

    >>> ctx = FitContext(Sweep(powers, f_hz, None, ["p1", "p2", "p3"]))
    >>> ctx.sweep.samples, ctx.notes, ctx.affine, ctx.temperature_range_k
    (200, [], False, None)
    """

    sweep: Sweep
    estimate: object = None
    delay_s: float = float("nan")
    health: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    affine: bool = False
    temperature_range_k: list | None = None

    def __post_init__(self):
        if self.temperature_range_k is None:
            self.temperature_range_k = value_range(self.sweep.temperature_k)
