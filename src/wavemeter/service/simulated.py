"""The simulated meter of ``serve --simulate``: a Table 1 device, calibrated at start-up,
read at a fixed rate through a switch of one drifting, jittering laser per channel.

:func:`simulated_meter` builds the device (``Interferometer.table1``) and calibrates it on a
sweep (``Calibrator``). A :class:`SimulatedSource` thread takes reading ``k`` at ``t0 + k /
rate`` (channel ``k % channels``), of the laser whose frequency the package's laser model
(:func:`wavemeter.simulation.laser_frequency_hz`) draws ahead in blocks of
:data:`BLOCK_S` seconds, drift and random walk carried from block to block (the flicker
of each block is drawn on its own). Each reading carries its laser's true frequency.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..calibration import Calibrator
from ..simulation import Interferometer, laser_frequency_hz
from .blocks import RowBlock

__all__ = ["simulated_meter", "SimulatedSource", "LASER", "BLOCK_S", "POWER_W", "NOISE_W"]

POWER_W = 1e-3
NOISE_W = 5e-7
FSR_HZ = 50e9
SWEEP_SAMPLES = 2001
#: the laser model's noise: white FM (Hz^2/Hz), flicker FM (Hz^2), random-walk FM
#: (Hz^2/s) and drift (Hz/s): a few MHz of wander over a minute, under the meter's ~10 MHz
#: per-reading noise from reading to reading
LASER = {
    "white_fm_hz2_per_hz": 1e3,
    "flicker_fm_hz2": 1e12,
    "random_walk_fm_hz2_per_s": 2e10,
    "drift_hz_per_s": 1e4,
}
BLOCK_S = 10.0
#: the thread sleeps at least this long (s) between takes: above 1 / TICK_S readings per
#: second, the readings due are taken together
TICK_S = 5e-4
#: the most readings taken in one go (after the thread was held up)
_MAX_BLOCK = 50_000


def simulated_meter(seed: int = 7):
    """A Table 1 3x3 device and its calibration on a noisy sweep over one FSR.

    Returns
    -------
    (Interferometer, Calibrator)
    """
    device = Interferometer.table1(ports=3, seed=seed)
    sweep_hz = device.sweep_hz(SWEEP_SAMPLES)
    powers = device.powers(sweep_hz, power_w=POWER_W, noise_w=NOISE_W, rng=seed)
    return device, Calibrator(fsr_hz=FSR_HZ, fsr_tolerance=0.2).fit(powers, sweep_hz)


class _Laser:
    """One channel's laser, drawn ahead a block at a time."""

    def __init__(self, center_hz: float, rate_hz: float, rng):
        self.rate_hz = rate_hz
        self.rng = rng
        self.slow_hz = center_hz  # where drift and random walk have got to
        self.center_hz = center_hz
        self.buffer = np.empty(0)

    def take(self, n: int) -> np.ndarray:
        while len(self.buffer) < n:
            self.buffer = np.concatenate([self.buffer, self._block()])
        taken, self.buffer = self.buffer[:n], self.buffer[n:]
        return taken

    def _block(self) -> np.ndarray:
        samples = max(16, int(BLOCK_S * self.rate_hz))
        slow = laser_frequency_hz(
            samples,
            self.rate_hz,
            center_hz=self.slow_hz,
            random_walk_fm_hz2_per_s=LASER["random_walk_fm_hz2_per_s"],
            drift_hz_per_s=LASER["drift_hz_per_s"],
            rng=self.rng,
        )
        fast = laser_frequency_hz(
            samples,
            self.rate_hz,
            center_hz=self.center_hz,
            white_fm_hz2_per_hz=LASER["white_fm_hz2_per_hz"],
            flicker_fm_hz2=LASER["flicker_fm_hz2"],
            rng=self.rng,
        )
        self.slow_hz = float(slow[-1])
        return slow + (fast - self.center_hz)


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
    """

    def __init__(self, device, calibration, submit, *, rate_hz=1000.0, channels=1, seed=7):
        self.device = device
        self.submit = submit
        self.rate_hz = float(rate_hz)
        self.channels = channels
        low, high = calibration.span_hz_
        rngs = np.random.default_rng(seed).spawn(channels + 1)
        self.rng = rngs[0]
        self.lasers = [
            _Laser(
                low + (high - low) * (k + 1) / (channels + 1), self.rate_hz / channels, rngs[k + 1]
            )
            for k in range(channels)
        ]
        self.name = f"simulated Table 1 meter, {channels} laser(s) at {self.rate_hz:g} readings/s"
        self.state = "starting"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wavemeter-simulate", daemon=True)

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
        for k, laser in enumerate(self.lasers):
            mine = channel == k
            truth[mine] = laser.take(int(mine.sum()))
        powers = self.device.powers(truth, power_w=POWER_W, noise_w=NOISE_W, rng=self.rng)
        return RowBlock(
            channel=channel.astype(np.int64),
            powers_w=powers,
            invalid=np.zeros(n, dtype=bool),
            source_time_ns=(start_ns + numbers * period_ns).astype(np.int64),
            true_frequency_hz=truth,
        )
