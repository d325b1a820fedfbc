"""Readings of a simulated device as the columns of a file: names, units, monitor, temperature.

A table is a dict of column name -> 1-D array, in the order the columns are written: the
axis (frequency or vacuum wavelength, ``frequency_hz``, ``wavelength_nm``, with ``true_``
before it for readings at random frequencies), one column per port (``p1_w, p2_w, ..``; a
cascade's ``p11, p12, .., p21, ..``: stage, then port, zero-padded past 9 ports), the
monitor (``monitor_<unit>``, the source power as the first stage's tap reads it) when the
source power varies, and ``temperature_k`` for a thermal device. In dBm a reading <= 0 W
(noise at a fringe null) is the readers' no-reading code
:data:`~wavemeter.units.SENTINEL_DBM`.
"""

from __future__ import annotations

import contextlib

import numpy as np

from ..progress import CHUNK_ROWS
from ..units import SENTINEL_DBM, w_to_power
from .cascade import CascadeInterferometer

__all__ = ["axis_column", "port_names", "readings"]


def _suffix(unit: str) -> str:
    """Unit suffix of a column name: ``frequency_hz``, ``p1_w``, ``freq_THz``, ``p1_dBm``."""
    return unit.lower() if unit in ("Hz", "W") else unit


def axis_column(unit: str, prefix: str = "") -> str:
    """Name of the axis column in ``unit``: ``frequency_hz``, ``true_wavelength_nm``."""
    word = "frequency" if unit.endswith("Hz") else "wavelength"
    return f"{prefix}{word}_{_suffix(unit)}"


def port_names(device) -> list[str]:
    """Names of the port columns without their unit: ``p1, p2, ..`` for a single device,
    ``p11, p12, .., p21, ..`` (stage, then port, zero-padded to the widest port number)
    for a cascade, so that the readers find them in reading order and the stage shows."""
    if not isinstance(device, CascadeInterferometer):
        return [f"p{k + 1}" for k in range(device.ports)]
    width = len(str(max(stage.ports for stage in device.stages)))
    return [
        f"p{index + 1}{port + 1:0{width}d}"
        for index, stage in enumerate(device.stages)
        for port in range(stage.ports)
    ]


def _power_columns(powers_w: np.ndarray, unit: str, names: list[str]) -> dict[str, np.ndarray]:
    """Port columns ``<name>_<unit>``; in dBm a reading <= 0 W becomes the no-reading code."""
    values = w_to_power(powers_w, unit)
    if unit == "dBm":
        values = np.where(np.isfinite(values), values, SENTINEL_DBM)
    return {f"{name}_{_suffix(unit)}": values[:, k] for k, name in enumerate(names)}


def _monitor_w(device, power_w: np.ndarray) -> np.ndarray:
    """The monitor reading (W) of the source power: a cascade's is its first stage's tap."""
    stage = device.stages[0] if isinstance(device, CascadeInterferometer) else device
    return stage.monitor(power_w)


def readings(
    device,
    frequency_hz: np.ndarray,
    rng: np.random.Generator,
    *,
    power_w: float,
    noise_w,
    power_fluctuation: float,
    power_unit: str,
    monitor: bool,
    power_factor: np.ndarray | None = None,
    bias_drift_rad: np.ndarray | None = None,
    temperature_k: np.ndarray | None = None,
    progress=None,
) -> dict[str, np.ndarray]:
    """Port columns (and the monitor, and ``temperature_k`` when given) of readings at
    frequencies ``frequency_hz``, simulated :data:`~wavemeter.progress.CHUNK_ROWS` at a
    time.

    Parameters
    ----------
    device : Interferometer or CascadeInterferometer
        The device read.
    frequency_hz : ndarray, shape (N,)
        Source frequency of each reading (Hz).
    rng : numpy.random.Generator
        Source of the power fluctuation (drawn first) and the detector noise.
    power_w : float
        Source power (W).
    noise_w : float or ndarray, shape (n,)
        Detector noise std per reading (W), for every port or per port.
    power_fluctuation : float
        Relative std of the source power per reading (0: none, nothing drawn).
    power_unit : str
        Unit of the port and monitor columns (a canonical power unit, not V).
    monitor : bool
        Whether to write the monitor column.
    power_factor : ndarray, shape (N,), optional
        Multiplies the source power (a drift).
    bias_drift_rad : ndarray, shape (N,), optional
        Adds to the bias phase (rad) of each reading (a single device only).
    temperature_k : ndarray, shape (N,), optional
        Chip temperature of each reading (K), also written as a column.
    progress : callable, optional
        A context manager yielding ``advance(rows)``, advanced after each chunk.

    Returns
    -------
    dict of str to ndarray, each shape (N,)
    """
    samples = frequency_hz.size
    power = np.full(samples, power_w)
    if power_factor is not None:
        power = power * power_factor
    if power_fluctuation > 0:
        power = power * (1 + power_fluctuation * rng.standard_normal(samples))
    powers = np.empty((samples, device.ports))
    with progress or contextlib.nullcontext(lambda rows: None) as advance:
        for start in range(0, samples, CHUNK_ROWS):
            rows = slice(start, min(start + CHUNK_ROWS, samples))
            extra = {}  # a cascade takes neither
            if bias_drift_rad is not None:
                extra["bias_drift_rad"] = bias_drift_rad[rows]
            if temperature_k is not None:
                extra["temperature_k"] = temperature_k[rows]
            powers[rows] = device.powers(frequency_hz[rows], power[rows], noise_w, rng, **extra)
            advance(rows.stop - rows.start)
    columns = _power_columns(powers, power_unit, port_names(device))
    if monitor:
        columns[f"monitor_{_suffix(power_unit)}"] = w_to_power(
            _monitor_w(device, power), power_unit
        )
    if temperature_k is not None:
        columns["temperature_k"] = temperature_k
    return columns
