"""The simulated meter of ``serve --simulate``: a Table 1 device, calibrated at start-up,
read at a fixed rate through a switch of one laser per channel, each driven by its lock.

:func:`simulated_meter` builds the device (``Interferometer.table1`` with the thermal
coefficients of silicon nitride) and calibrates it at its reference temperature on a sweep
(``Calibrator``). A :class:`SimulatedSource` thread takes reading ``k`` at ``t0 + k /
rate`` (channel ``k % channels``) of that channel's :class:`~wavemeter.simulation.ActuatedLaser`
(a free-running external-cavity diode laser whose actuator is the channel's lock output,
:class:`SimulatedActuator`; a quiet reference laser on a reference channel), the chip's
temperature ramping as asked; each reading carries its laser's true frequency. For trying
locks out, :meth:`SimulatedSource.inject` spoils the next readings of a channel (NaN
readings, a port off the model, the laser shifted), through the control request
``simulate_fault``.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..calibration import Calibrator
from ..exceptions import InputError
from ..simulation import ActuatedLaser, Interferometer
from .blocks import RowBlock

__all__ = [
    "simulated_meter",
    "SimulatedSource",
    "SimulatedActuator",
    "FAULTS",
    "BLOCK_S",
    "POWER_W",
    "NOISE_W",
]

POWER_W = 1e-3
NOISE_W = 5e-7
FSR_HZ = 50e9
SWEEP_SAMPLES = 2001
#: seconds of each laser's free-running frequency drawn at a time
BLOCK_S = 10.0
#: the thread sleeps at least this long (s) between takes: above 1 / TICK_S readings per
#: second, the readings due are taken together
TICK_S = 5e-4
#: the most readings taken in one go (after the thread was held up)
_MAX_BLOCK = 50_000
#: what :meth:`SimulatedSource.inject` can do to a channel's next readings
FAULTS = ("invalid", "off_model", "shift")
#: an "off_model" reading has its first port's power times this
_OFF_MODEL_FACTOR = 1.5


def simulated_meter(seed: int = 7):
    """A Table 1 3x3 device (silicon-nitride thermal coefficients) and its calibration on
    a noisy sweep over one FSR at the reference temperature.

    Returns
    -------
    (Interferometer, Calibrator)
    """
    device = Interferometer.table1(ports=3, seed=seed).with_thermal("sin")
    sweep_hz = device.sweep_hz(SWEEP_SAMPLES)
    powers = device.powers(sweep_hz, power_w=POWER_W, noise_w=NOISE_W, rng=seed)
    return device, Calibrator(fsr_hz=FSR_HZ, fsr_tolerance=0.2).fit(powers, sweep_hz)


class SimulatedActuator:
    """The lock output of a simulated channel: its laser's actuator input (a sink of
    :mod:`.outputs`, which also knows the laser's tuning and response time)."""

    def __init__(self, laser: ActuatedLaser):
        self.laser = laser
        self.limits_v = laser.voltage_range_v
        self.tuning_hz_per_v = laser.tuning_hz_per_v
        self.response_s = laser.response_s

    @property
    def output_v(self) -> float:
        return self.laser.voltage_v

    def write(self, voltage_v: float) -> None:
        self.laser.set_voltage(voltage_v)


class SimulatedSource:
    """Readings of the simulated meter at ``rate_hz``, handed to ``submit`` from a thread.

    Parameters
    ----------
    device : Interferometer
        The simulated meter.
    calibration : Calibrator
        Its calibration (the lasers are placed inside its span).
    submit : callable
        ``submit(block)`` takes each :class:`RowBlock` (thread-safe).
    rate_hz : float
        Readings per second, all channels together.
    channels : int
        Lasers on the switch; reading ``k`` is of channel ``k % channels``.
    seed : int
        Seeds the lasers and the detector noise.
    references : mapping of int to float, optional
        Channels that see a stabilised reference laser, and its frequency (Hz).
    chip_ramp : (float, float), optional
        The chip warms by this many kelvin over this many seconds from the start, then
        stays.
    """

    def __init__(
        self,
        device,
        calibration,
        submit,
        *,
        rate_hz=1000.0,
        channels=1,
        seed=7,
        references=None,
        chip_ramp=None,
    ):
        self.device = device
        self.submit = submit
        self.rate_hz = float(rate_hz)
        self.channels = channels
        self.references = {int(k): float(v) for k, v in (references or {}).items()}
        self.chip_ramp = chip_ramp
        low, high = calibration.span_hz_
        rngs = np.random.default_rng(seed).spawn(channels + 1)
        self.rng = rngs[0]
        per_channel = self.rate_hz / channels
        self.lasers = [
            ActuatedLaser(
                self.references.get(k, low + (high - low) * (k + 1) / (channels + 1)),
                per_channel,
                noise="reference" if k in self.references else "ecdl",
                block_s=BLOCK_S,
                rng=rngs[k + 1],
            )
            for k in range(channels)
        ]
        self.name = f"simulated Table 1 meter, {channels} laser(s) at {self.rate_hz:g} readings/s"
        self.state = "starting"
        self._faults: dict[int, list] = {}  # channel -> [kind, readings left, shift_hz]
        self._faults_lock = threading.Lock()  # inject (the loop) and _spoil (the thread)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wavemeter-simulate", daemon=True)

    def actuators(self) -> dict[int, tuple[SimulatedActuator, str]]:
        """The lock outputs of the channels that are not references, with their names."""
        return {
            k: (SimulatedActuator(laser), f"simulated actuator of laser {k}")
            for k, laser in enumerate(self.lasers)
            if k not in self.references
        }

    def inject(self, channel: int, kind: str, readings: int = 1, shift_hz: float = 0.0) -> dict:
        """Spoil the next ``readings`` readings of ``channel`` (any thread): ``"invalid"``
        (NaN powers), ``"off_model"`` (the first port's power times 1.5) or ``"shift"``
        (the laser ``shift_hz`` away; its true frequency says so).

        Raises
        ------
        InputError
            For an unknown channel or kind, a count < 1 or a shift that is not finite.
        """
        if not isinstance(channel, int) or not 0 <= channel < self.channels:
            raise InputError(
                f"channel {channel!r}: the simulated switch has channels 0 .. {self.channels - 1}"
            )
        if kind not in FAULTS:
            raise InputError(f"fault {kind!r}: expected one of {FAULTS}")
        if isinstance(readings, bool) or not isinstance(readings, int) or readings < 1:
            raise InputError(f"readings {readings!r}: expected a whole number >= 1")
        if not (isinstance(shift_hz, int | float) and np.isfinite(shift_hz)):
            raise InputError(f"shift_hz {shift_hz!r}: expected a finite number of Hz")
        with self._faults_lock:
            self._faults.setdefault(channel, []).append([kind, readings, float(shift_hz)])
        return {"channel": channel, "kind": kind, "readings": readings, "shift_hz": shift_hz}

    def register_requests(self, control) -> None:
        """Add the ``simulate_fault`` request to a control socket."""

        def simulate_fault(channel, kind, readings=1, shift_hz=0.0):
            return self.inject(channel, kind, readings, shift_hz)

        control.register("simulate_fault", simulate_fault)

    def start(self) -> None:
        self.state = "running"
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self.state = "ended"

    def _run(self) -> None:
        start_ns = time.time_ns()
        taken = 0
        period_ns = 1e9 / self.rate_hz
        while not self._stop.is_set():
            due = int((time.time_ns() - start_ns) / period_ns) + 1
            if due > taken:
                n = min(due - taken, _MAX_BLOCK)
                self.submit(self._readings(taken, n, start_ns, period_ns))
                taken += n
            wait_s = (start_ns + taken * period_ns - time.time_ns()) * 1e-9
            if wait_s > 0:
                time.sleep(max(wait_s, TICK_S))

    def _readings(self, first: int, n: int, start_ns: int, period_ns: float) -> RowBlock:
        numbers = np.arange(first, first + n)
        channel = numbers % self.channels
        truth = np.empty(n)
        spoiled = {}
        for k, laser in enumerate(self.lasers):
            mine = np.flatnonzero(channel == k)
            if len(mine):
                truth[mine] = laser.take(len(mine))
                if k in self._faults:
                    with self._faults_lock:
                        spoiled[k] = self._spoil(k, mine, truth)
        temperature = None
        if self.chip_ramp is not None:
            kelvin, seconds = self.chip_ramp
            elapsed = numbers / self.rate_hz
            rise = kelvin * np.minimum(elapsed / seconds, 1.0)
            temperature = self.device.reference_temperature_k + rise
        powers = self.device.powers(
            truth, power_w=POWER_W, noise_w=NOISE_W, rng=self.rng, temperature_k=temperature
        )
        invalid = np.zeros(n, dtype=bool)
        for rows in spoiled.values():
            powers[rows["invalid"]] = np.nan
            invalid[rows["invalid"]] = True
            powers[rows["off_model"], 0] *= _OFF_MODEL_FACTOR
        return RowBlock(
            channel=channel.astype(np.int64),
            powers_w=powers,
            invalid=invalid,
            source_time_ns=(start_ns + numbers * period_ns).astype(np.int64),
            true_frequency_hz=truth,
        )

    def _spoil(self, k: int, rows: np.ndarray, truth: np.ndarray) -> dict:
        """Apply channel ``k``'s pending faults to its readings at ``rows`` (in order):
        shifts to ``truth`` now; the rows to make invalid or off the model."""
        spoiled = {"invalid": [], "off_model": []}
        pending = self._faults[k]
        at = 0
        while pending and at < len(rows):
            kind, left, shift = pending[0]
            chosen = rows[at : at + left]
            if kind == "shift":
                truth[chosen] += shift
            else:
                spoiled[kind] += chosen.tolist()
            at += len(chosen)
            pending[0][1] -= len(chosen)
            if pending[0][1] == 0:
                pending.pop(0)
        if not pending:
            self._faults.pop(k, None)
        return spoiled
