"""A laser with a tuning actuator: what a lock drives, read reading by reading.

An :class:`ActuatedLaser` is the free-running laser of :func:`laser_frequency_hz` (drift,
white, flicker and random-walk FM), optional mode hops, and an actuator: a voltage input
(clipped to its range) that tunes the laser by ``tuning_hz_per_v`` through a first-order
response of time constant ``response_s``. :meth:`ActuatedLaser.take` gives the true
frequency of the next readings, the input voltage held over them; each is the mean over its
sample interval, as :func:`laser_frequency_hz` defines a reading. The free-running part is
drawn ahead in blocks of ``block_s`` seconds, drift, random walk and mode hops carried from
block to block (the flicker of each block is drawn on its own).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..validation import as_rng, check_finite, check_non_negative, check_positive
from .laser import laser_frequency_hz
from .laser_presets import LASER_PRESETS, LaserNoise

__all__ = ["ActuatedLaser"]


class ActuatedLaser:
    """A laser whose frequency an actuator voltage tunes.

    Parameters
    ----------
    center_hz : float
        Free-running frequency at ``t = 0`` with the actuator at 0 V (Hz), > 0.
    rate_hz : float
        Readings per second (Hz), > 0: reading ``k`` is the mean over ``[k, k + 1] / rate``.
    noise : LaserNoise or str
        The free-running noise, or the name of a preset of :data:`LASER_PRESETS`.
    tuning_hz_per_v : float
        Frequency change per volt at the actuator (Hz/V), non-zero, any sign.
    response_s : float
        Time constant of the actuator's first-order response (s), >= 0 (0: immediate).
    voltage_range_v : (float, float)
        The actuator's input range (V); a voltage outside is clipped to it.
    mode_hop_hz : float
        Size of a mode hop (Hz), >= 0; each hop moves the free-running frequency by
        ``+-mode_hop_hz`` (sign at random) for good.
    mode_hop_rate_per_s : float
        Mean mode hops per second (a Poisson process), >= 0; 0: none.
    block_s : float
        Seconds of free-running frequency drawn at a time.
    rng : None, int or numpy.random.Generator
        Source of the noise and the hops.

    Attributes
    ----------
    voltage_v : float
        The voltage at the actuator's input (V).
    actuator_v : float
        Where the actuator's response has got to (V): the laser is tuned by
        ``tuning_hz_per_v * actuator_v``.
    hops : int
        Mode hops so far.

    Examples
    --------
    A quiet laser on an actuator of 500 MHz/V with a 1 ms response, read at 1 kHz; 2 V at
    the input tune it by 1 GHz, approached as ``1 - exp(-t / 1 ms)`` (the first reading is
    the mean over its millisecond, ``exp(-1)`` = 0.368 of the way):

    >>> import numpy as np
    >>> from wavemeter.simulation import ActuatedLaser
    >>> laser = ActuatedLaser(193.4e12, 1e3, noise="reference", tuning_hz_per_v=5e8,
    ...                       response_s=1e-3, rng=1)
    >>> free_hz = laser.take(5)
    >>> laser.set_voltage(2.0)
    2.0
    >>> print(np.round((laser.take(6) - 193.4e12) / 1e6))
    [368. 767. 914. 969. 988. 996.]

    A voltage beyond the input range is clipped to it:

    >>> laser.set_voltage(25.0)
    10.0
    """

    def __init__(
        self,
        center_hz: float,
        rate_hz: float,
        *,
        noise: LaserNoise | str = "ecdl",
        tuning_hz_per_v: float = 5e8,
        response_s: float = 1e-3,
        voltage_range_v: tuple[float, float] = (-10.0, 10.0),
        mode_hop_hz: float = 0.0,
        mode_hop_rate_per_s: float = 0.0,
        block_s: float = 10.0,
        rng=None,
    ):
        self.center_hz = check_positive("center_hz", center_hz)
        self.rate_hz = check_positive("rate_hz", rate_hz)
        if isinstance(noise, str):
            if noise not in LASER_PRESETS:
                raise InputError(
                    f"noise {noise!r}: expected a LaserNoise or one of {tuple(LASER_PRESETS)}",
                    parameter="noise",
                )
            noise = LASER_PRESETS[noise]
        self.noise = noise
        self.tuning_hz_per_v = check_finite("tuning_hz_per_v", tuning_hz_per_v)
        if self.tuning_hz_per_v == 0:
            raise InputError("tuning_hz_per_v must not be 0", parameter="tuning_hz_per_v")
        self.response_s = check_non_negative("response_s", response_s)
        low, high = (check_finite("voltage_range_v", v) for v in voltage_range_v)
        if not low < high:
            raise InputError(
                f"voltage_range_v {voltage_range_v!r}: expected (low, high) with low < high",
                parameter="voltage_range_v",
            )
        self.voltage_range_v = (low, high)
        self.mode_hop_hz = check_non_negative("mode_hop_hz", mode_hop_hz)
        self.mode_hop_rate_per_s = check_non_negative("mode_hop_rate_per_s", mode_hop_rate_per_s)
        self.block_s = check_positive("block_s", block_s)
        self.rng = as_rng(rng)
        self.voltage_v = float(np.clip(0.0, low, high))
        self.actuator_v = self.voltage_v
        self.hops = 0
        self._slow_hz = self.center_hz  # where drift, walk and hops have got to
        step_s = 1.0 / self.rate_hz
        ratio = step_s / self.response_s if self.response_s > 0 else np.inf
        self._decay = float(np.exp(-ratio))
        self._mean_factor = float(-np.expm1(-ratio) / ratio) if self.response_s > 0 else 0.0
        self._buffer = np.empty(0)
        self._at = 0  # the next sample of the buffer
        self._hop_at = np.empty(0, dtype=np.int64)  # samples of the buffer where a hop is

    def set_voltage(self, voltage_v: float) -> float:
        """Set the actuator's input (V), clipped to its range; the voltage applied."""
        low, high = self.voltage_range_v
        value = float(voltage_v)
        if not np.isfinite(value):
            raise InputError(f"voltage {voltage_v!r} is not finite", parameter="voltage_v")
        self.voltage_v = min(max(value, low), high)
        return self.voltage_v

    def take(self, n: int) -> np.ndarray:
        """The true frequencies (Hz) of the next ``n`` readings, shape (n,), the input
        voltage held over them."""
        while len(self._buffer) - self._at < n:
            block, hops = self._block()
            self._buffer = np.concatenate([self._buffer[self._at :], block])
            self._hop_at = np.concatenate(
                [
                    self._hop_at[self._hop_at >= self._at] - self._at,
                    hops + len(self._buffer) - len(block),
                ]
            )
            self._at = 0
        start, self._at = self._at, self._at + n
        free = self._buffer[start : self._at]
        if len(self._hop_at):
            taken = (self._hop_at >= start) & (self._hop_at < self._at)
            if taken.any():
                self.hops += int(taken.sum())
        return free + self.tuning_hz_per_v * self._actuator(n)

    def _actuator(self, n: int):
        """The actuator's mean over each of the next ``n`` sample intervals (V)."""
        target, start = self.voltage_v, self.actuator_v
        if self.response_s == 0 or start == target:
            self.actuator_v = target
            return target
        # a(t) = v + (a0 - v) exp(-t / response): its mean over [k, k + 1] sample intervals
        decay, mean_factor = self._decay, self._mean_factor
        if n == 1:
            self.actuator_v = target + (start - target) * decay
            return target + (start - target) * mean_factor
        at_starts = (start - target) * decay ** np.arange(n)
        self.actuator_v = target + (start - target) * decay**n
        return target + at_starts * mean_factor

    def _block(self) -> tuple[np.ndarray, np.ndarray]:
        samples = max(16, int(round(self.block_s * self.rate_hz)))
        levels = self.noise.levels()
        slow = laser_frequency_hz(
            samples,
            self.rate_hz,
            center_hz=self._slow_hz,
            random_walk_fm_hz2_per_s=levels["random_walk_fm_hz2_per_s"],
            drift_hz_per_s=levels["drift_hz_per_s"],
            rng=self.rng,
        )
        fast = laser_frequency_hz(
            samples,
            self.rate_hz,
            center_hz=self.center_hz,
            white_fm_hz2_per_hz=levels["white_fm_hz2_per_hz"],
            flicker_fm_hz2=levels["flicker_fm_hz2"],
            rng=self.rng,
        )
        hops = np.empty(0, dtype=np.int64)
        if self.mode_hop_rate_per_s > 0 and self.mode_hop_hz > 0:
            count = self.rng.poisson(self.mode_hop_rate_per_s * samples / self.rate_hz)
            if count:
                hops = np.sort(self.rng.integers(0, samples, count))
                steps = np.zeros(samples)
                np.add.at(steps, hops, self.mode_hop_hz * self.rng.choice((-1.0, 1.0), count))
                slow = slow + np.cumsum(steps)
        self._slow_hz = float(slow[-1])
        return slow + (fast - self.center_hz), hops
