"""The simulated lock of benchmarks/lock.py, in process: a laser, the meter, the loop.

The loop is :class:`wavemeter.service.LockLoop`, stepped reading by reading as the service
steps it; the laser is :class:`wavemeter.simulation.ActuatedLaser`; the meter is the
service's simulated meter (a Table 1 device with silicon-nitride thermal coefficients and
its learned calibration), read through ``device.powers`` and ``calibration.readout``.

Reading ``k`` depends on the laser's frequency, which depends on the output after reading
``k - 1``: a closed loop, one reading at a time. Reading the meter a row at a time costs a
millisecond, so :func:`closed_loop` solves the loop by fixed-point passes instead: a pass
reads the meter, in one block per calibration in force, at the true frequencies of the
previous pass (same detector noise: a fresh generator of the same seed), keeps each
reading's error (reading - truth) and flags, and runs laser and loop reading by reading
with ``reading_k = truth_k + error_k``. The error moves with the frequency by a part in 1e3
per MHz, so the passes converge within a few; when the truths of two passes agree within
``TOLERANCE_HZ`` every reading is the meter's reading of the final truth to that tolerance
(``LoopRun.change_hz`` says how close). A reference channel's re-anchors do not depend on
the lock: :func:`reference_schedule` runs the :class:`~wavemeter.service.ReferenceKeeper` on
the reference's readings first and gives the calibration in force at each reading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wavemeter import ReadingFlag
from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter

__all__ = ["Meter", "LoopRun", "closed_loop", "reference_schedule", "TOLERANCE_HZ"]

#: the largest change of the truth between the last two passes of a converged loop (Hz)
TOLERANCE_HZ = 1.0
MAX_PASSES = 8
#: an injected off-model reading: its first port's power times this (the service's fault)
OFF_MODEL_FACTOR = 1.5


class Meter:
    """The service's simulated meter (seed 7), chip temperature as given."""

    def __init__(self, seed: int = 7):
        self.device, self.calibration = simulated_meter(seed)

    def powers(self, truth_hz, temperature_k, seed):
        return self.device.powers(
            truth_hz,
            power_w=POWER_W,
            noise_w=NOISE_W,
            rng=np.random.default_rng(seed),
            temperature_k=temperature_k,
        )

    def read(self, powers, epochs=None, calibrations=None):
        """Readings (frequency, std, flags) of ``powers``, each with the calibration
        ``calibrations[epochs[k]]`` (the base for all when None)."""
        if epochs is None:
            found = self.calibration.readout(powers)
            return found.frequency_hz, found.frequency_std_hz, np.asarray(found.flags)
        n = len(powers)
        frequency, std = np.empty(n), np.empty(n)
        flags = np.empty(n, dtype=np.int64)
        bounds = np.flatnonzero(np.diff(epochs)) + 1
        for start, stop in zip(np.r_[0, bounds], np.r_[bounds, n], strict=True):
            found = calibrations[epochs[start]].readout(powers[start:stop])
            frequency[start:stop] = found.frequency_hz
            std[start:stop] = found.frequency_std_hz
            flags[start:stop] = found.flags
        return frequency, std, flags

    def static_error(self, frequency_hz: float, readings: int = 40_000, seed: int = 99):
        """The meter's mean error and per-reading standard deviation at ``frequency_hz``
        (Hz), at its reference temperature, from ``readings`` readings."""
        powers = self.powers(np.full(readings, frequency_hz), None, seed)
        frequency = self.calibration.readout(powers).frequency_hz
        return float(np.mean(frequency) - frequency_hz), float(np.std(frequency))


@dataclass
class LoopRun:
    """A solved closed loop: per reading, the laser's truth, the meter's reading and flags,
    the output after it and the loop's state; the loop itself; the passes it took and the
    last pass's largest change of the truth (Hz)."""

    truth_hz: np.ndarray
    reading_hz: np.ndarray
    flags: np.ndarray
    output_v: np.ndarray
    state: np.ndarray
    loop: object
    passes: int
    change_hz: float


def closed_loop(
    meter,
    make_laser,
    make_loop,
    readings: int,
    rate_hz: float,
    *,
    seed: int,
    temperature_k=None,
    epochs=None,
    calibrations=None,
    spoil=None,
    act=None,
) -> LoopRun:
    """Solve a locked laser read by the meter.

    Parameters
    ----------
    make_laser, make_loop : callable
        Fresh laser (ActuatedLaser) and loop (LockLoop, engaged) for each pass.
    readings, rate_hz : int, float
        Readings of the locked channel and their rate.
    seed : int
        The detector noise's seed.
    temperature_k : ndarray, shape (readings,), optional
        The chip's temperature at each reading.
    epochs, calibrations : optional
        The calibration in force at each reading (:func:`reference_schedule`).
    spoil : dict, optional
        Reading index -> ``"invalid"`` (NaN powers), ``"off_model"`` (a port times 1.5) or
        ``"order_ambiguous"`` (a wrong-order reading, 50 GHz off, flagged as a set would).
    act : callable, optional
        ``act(k, loop, laser, reading_hz)`` before reading ``k`` (setpoint changes,
        re-locking), with reading ``k - 1`` (NaN before the first).
    """
    spoil = spoil or {}
    times = np.arange(readings) / rate_hz
    previous = make_laser().take(readings)
    flags_before = None
    passes = 0
    while True:
        passes += 1
        powers = meter.powers(previous, temperature_k, seed)
        for index, kind in spoil.items():
            if kind == "invalid":
                powers[index] = np.nan
            elif kind == "off_model":
                powers[index, 0] *= OFF_MODEL_FACTOR
        frequency, _, flags = meter.read(powers, epochs, calibrations)
        flags = np.where(np.isnan(powers).any(axis=1), int(ReadingFlag.INVALID), flags)
        error = frequency - previous
        for index, kind in spoil.items():
            if kind == "order_ambiguous":
                error[index] += 50e9
                flags[index] |= int(ReadingFlag.ORDER_AMBIGUOUS)
        laser, loop = make_laser(), make_loop()
        truth, output = np.empty(readings), np.empty(readings)
        state = np.empty(readings, dtype=object)
        step = loop.step
        last = float("nan")
        for k in range(readings):
            if act is not None:
                act(k, loop, laser, last)
            x = float(laser.take(1)[0])
            last = x + error[k]
            truth[k] = x
            output[k] = step(times[k], x + error[k], int(flags[k]))
            state[k] = loop.state
            laser.set_voltage(output[k])
        change = float(np.max(np.abs(truth - previous)))
        same_flags = flags_before is not None and np.array_equal(flags, flags_before)
        previous, flags_before = truth, flags
        if (change < TOLERANCE_HZ and same_flags) or passes == MAX_PASSES:
            break
    return LoopRun(truth, truth + error, flags, output, state, loop, passes, change)


def reference_schedule(meter, keeper, truth_hz, temperature_k, rate_hz, *, seed, chunk=10):
    """Run ``keeper`` on the reference's readings, ``chunk`` at a time (a service block);
    the calibration in force at each reading: ``(epochs, calibrations, events)``."""
    readings = len(truth_hz)
    times = np.arange(readings) / rate_hz
    powers = meter.powers(truth_hz, temperature_k, seed)
    calibrations = [keeper.calibration]
    epochs = np.empty(readings, dtype=np.int64)
    events = []
    for start in range(0, readings, chunk):
        part = slice(start, start + chunk)
        epochs[part] = len(calibrations) - 1
        found = calibrations[-1].readout(powers[part])
        event = keeper.add(times[part], powers[part], found.frequency_hz, found.flags)
        if event is not None:
            events.append(event)
            if event.accepted:
                calibrations.append(keeper.calibration)
    return epochs, calibrations, events
