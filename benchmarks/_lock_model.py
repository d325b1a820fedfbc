"""The best a PI lock can do, derived: the closed loop of benchmarks/lock.py in the z domain.

Readings every ``T = 1 / rate``. Reading ``k`` is the laser's mean frequency over interval
``k`` plus the meter's white noise (``sigma``) and its static error at the setpoint (``b``).
The output ``v_k`` set after reading ``k`` drives the actuator over interval ``k + 1``: a
first-order response (time constant ``tau_a``, ``d = exp(-T / tau_a)``) whose mean over an
interval is ``m = (tau_a / T)(1 - d)`` of the way from its start to the input, so the plant
(Hz per V) is

    P(z) = K [(1 - m) z + (m - d)] / (z (z - d)),

and the PI controller of :class:`wavemeter.service.LockLoop` (``average`` 1) is
``C(z) = kp + ki T z / (z - 1)``. With ``S = 1 / (1 + P C)`` and ``H = P C / (1 + P C)``, the
laser's error against the truth has the variance

    sigma_e^2 = int_0^{rate/2} |S|^2 S_L(f) df + sigma^2 (2 / rate) int_0^{rate/2} |H|^2 df
                + (D / (K ki))^2 + b^2

with ``S_L`` the one-sided PSD of the laser's interval means (white FM ``h0``; flicker FM
with its aliases summed, as :func:`wavemeter.simulation.laser_frequency_hz` draws it;
random-walk FM as a sampled Wiener process with its interval mean) and ``D / (K ki)`` the
error a type-1 loop keeps on a drift ``D``. :func:`best_pi` minimises it over ``(kp, ki)``
(Nelder-Mead on their logarithms, unstable loops refused by the roots of the characteristic
polynomial): that is the bound. :func:`best_bandwidth` does the same along the line of
:meth:`LockSettings.from_bandwidth` (``kp = ki tau_a``, ``ki = 2 pi B / K``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special

__all__ = ["LoopModel", "best_pi", "best_bandwidth"]

#: frequencies of the integrals: log-spaced from this fraction of the rate to rate / 2
_LOWEST = 1e-7
_POINTS = 20000


@dataclass(frozen=True)
class LoopModel:
    """The loop's physics: rate, actuator, meter and laser.

    Attributes
    ----------
    rate_hz : float
        Readings per second of the locked channel.
    actuator_hz_per_v, response_s : float
        The actuator's tuning (Hz/V) and time constant (s).
    meter_std_hz, meter_bias_hz : float
        The meter's per-reading standard deviation and its static error at the setpoint (Hz).
    white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s, drift_hz_per_s : float
        The free-running laser's noise.
    """

    rate_hz: float
    actuator_hz_per_v: float
    response_s: float
    meter_std_hz: float
    meter_bias_hz: float
    white_fm_hz2_per_hz: float
    flicker_fm_hz2: float
    random_walk_fm_hz2_per_s: float
    drift_hz_per_s: float

    def _grid(self):
        f = np.geomspace(_LOWEST * self.rate_hz, self.rate_hz / 2, _POINTS)
        return f, np.exp(2j * np.pi * f / self.rate_hz)

    def laser_psd(self, f: np.ndarray) -> np.ndarray:
        """One-sided PSD (Hz^2/Hz) of the free-running laser's interval means at ``f``."""
        rate = self.rate_hz
        x = f / rate
        omega = 2 * np.pi * x
        psd = np.full_like(f, self.white_fm_hz2_per_hz)
        if self.flicker_fm_hz2:
            psd += (
                self.flicker_fm_hz2
                / (np.pi**2 * rate)
                * np.sin(np.pi * x) ** 2
                * (special.zeta(3, x) + special.zeta(3, 1 - x))
            )
        if self.random_walk_fm_hz2_per_s:
            step = 2 * np.pi**2 * self.random_walk_fm_hz2_per_s / rate
            psd += 2 * step * np.cos(omega / 2) ** 2 / (4 * rate * np.sin(omega / 2) ** 2)
            psd += step / (6 * rate)
        return psd

    def open_loop(self, z: np.ndarray, kp: float, ki: float) -> np.ndarray:
        d, m = self._actuator()
        plant = self.actuator_hz_per_v * ((1 - m) * z + (m - d)) / (z * (z - d))
        control = kp + ki / self.rate_hz * z / (z - 1)
        return plant * control

    def _actuator(self) -> tuple[float, float]:
        if self.response_s == 0:
            return 0.0, 0.0
        ratio = 1.0 / (self.rate_hz * self.response_s)
        return math.exp(-ratio), -math.expm1(-ratio) / ratio

    def stable(self, kp: float, ki: float) -> bool:
        """Whether every root of ``z (z - d)(z - 1) + K [(1 - m) z + m - d][(kp + ki T) z -
        kp]`` lies inside the unit circle."""
        d, m = self._actuator()
        gain = self.actuator_hz_per_v
        left = np.polymul(np.polymul([1, 0], [1, -d]), [1, -1])
        right = gain * np.polymul([1 - m, m - d], [kp + ki / self.rate_hz, -kp])
        roots = np.roots(np.polyadd(left, right))
        return bool(np.all(np.abs(roots) < 1 - 1e-9))

    def error_rms_hz(self, kp: float, ki: float, *, bias: bool = True) -> float:
        """The locked laser's RMS error against the truth (Hz) with these gains; inf for
        an unstable loop."""
        if not self.stable(kp, ki):
            return math.inf
        f, z = self._grid()
        loop = self.open_loop(z, kp, ki)
        sensitivity = np.abs(1 / (1 + loop)) ** 2
        closed = np.abs(loop / (1 + loop)) ** 2
        laser = np.trapezoid(sensitivity * self.laser_psd(f), f)
        meter = self.meter_std_hz**2 * 2 / self.rate_hz * np.trapezoid(closed, f)
        drift = (self.drift_hz_per_s / (self.actuator_hz_per_v * ki)) ** 2 if ki else math.inf
        total = laser + meter + drift + (self.meter_bias_hz**2 if bias else 0.0)
        return math.sqrt(total)

    def bandwidth_gains(self, bandwidth_hz: float) -> tuple[float, float]:
        """``(kp, ki)`` of :meth:`LockSettings.from_bandwidth` at ``bandwidth_hz``."""
        ki = 2 * math.pi * bandwidth_hz / self.actuator_hz_per_v
        return ki * self.response_s, ki


def best_pi(model: LoopModel, start_bandwidth_hz: float = 1.0):
    """The gains of least RMS error, and that error (Hz): ``((kp, ki), rms)``."""
    kp0, ki0 = model.bandwidth_gains(start_bandwidth_hz)
    kp0 = kp0 or ki0 / model.rate_hz

    def cost(logs):
        return model.error_rms_hz(math.exp(logs[0]), math.exp(logs[1]))

    found = optimize.minimize(
        cost,
        [math.log(kp0), math.log(ki0)],
        method="Nelder-Mead",
        options={"xatol": 1e-4, "fatol": 1.0, "maxiter": 2000},
    )
    kp, ki = math.exp(found.x[0]), math.exp(found.x[1])
    return (kp, ki), float(found.fun)


def best_bandwidth(model: LoopModel) -> tuple[float, float]:
    """The bandwidth (Hz) of least RMS error along ``from_bandwidth``'s gains, and that
    error (Hz)."""
    found = optimize.minimize_scalar(
        lambda log_b: model.error_rms_hz(*model.bandwidth_gains(math.exp(log_b))),
        bounds=(math.log(1e-3), math.log(model.rate_hz / 20)),
        method="bounded",
        options={"xatol": 1e-4},
    )
    return math.exp(found.x), float(found.fun)
