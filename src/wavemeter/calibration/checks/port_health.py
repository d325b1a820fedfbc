"""Ports that carry no usable fringe: dead (dark noise only), stuck, or saturated.

Each port's readings are fitted with the learned map at the sweep's delay (the design FSR
checked against the sweep, :mod:`wavemeter.calibration.checks.fsr_guard`): row ``j`` of the map is
``[a_j cos phi_j, a_j sin phi_j, c_j / sqrt 2]``. With white noise of standard deviation
``s_j`` on the port, the two fringe entries ``a_j = (A[j, 0], A[j, 1])`` are estimated with
covariance ``s_j^2 C``, ``C`` the 2 x 2 block of ``(X' X)^-1`` for the object matrix ``X``;
for a sweep over whole FSRs ``C = (2 / N) I``, so the standard error of the amplitude is
``s_j sqrt(2 / N)``. A port whose fringe is absent gives ``z^2 = a_j' C^-1 a_j / s_j^2``
distributed as chi-square with 2 degrees of freedom; ``z < MIN_FRINGE_Z`` (5 standard
errors, which a port without a fringe exceeds by chance with probability
``exp(-25 / 2) = 4e-6``) marks the port dead. ``s_j`` is the port's own residual, so a
dark port is judged by its dark noise.

A port is stuck when all its readings are equal, and saturated when at least
``SATURATED_FRACTION`` (5 %) of its readings, and at least 3, sit exactly at its largest
value: clipping makes a plateau, while a quantised but unclipped fringe puts only about
``sqrt(2 / levels) / pi`` of its readings in the top level (3 % for 8 bits).

The cone model needs 3 ports with fringes: with fewer good ports the fit is an error, with
enough a :class:`~wavemeter.exceptions.CalibrationWarning` (cause ``"dead_port"``) names
the bad ports with their numbers.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ...exceptions import CalibrationWarning, InputError
from ...model.cone import cone_vectors
from ..models.linear_map import map_cost, object_vectors

__all__ = [
    "MIN_FRINGE_Z",
    "MIN_GOOD_PORTS",
    "SATURATED_FRACTION",
    "PortHealth",
    "check_port_health",
    "port_health",
]

MIN_FRINGE_Z = 5.0
SATURATED_FRACTION = 0.05
MIN_SATURATED_READINGS = 3
MIN_GOOD_PORTS = 3
REMEDY = (
    "check the detector, fibre and amplifier of these ports (for a saturated port lower the "
    "source power or the gain), or leave these ports out of the calibration readings"
)


@dataclass(frozen=True)
class PortHealth:
    """What one port's calibration readings show.

    Attributes
    ----------
    name : str
        Port name.
    status : {"ok", "dead", "stuck", "saturated"}
    fringe_amplitude_w : float
        Fitted fringe amplitude ``|(A[j, 0], A[j, 1])|`` (W).
    amplitude_std_w : float
        Its standard error ``s_j sqrt(trace(C) / 2)`` (W).
    fringe_z : float or None
        Significance of the fringe in standard errors (None when the port has no noise).
    noise_std_w : float
        The port's residual noise ``s_j`` (W).
    readings_at_maximum : int
        Readings exactly at the port's largest value (1 for an unclipped port; many when
        it saturates).
    """

    name: str
    status: str
    fringe_amplitude_w: float
    amplitude_std_w: float
    fringe_z: float | None
    noise_std_w: float
    readings_at_maximum: int

    def to_dict(self) -> dict:
        """JSON-ready fields."""
        return asdict(self)

    def describe(self, samples: int) -> str:
        """One clause with the numbers behind the status."""
        if self.status == "stuck":
            return f"{self.name} is stuck (all {samples} readings equal)"
        if self.status == "saturated":
            share = 100.0 * self.readings_at_maximum / samples
            return (
                f"{self.name} is saturated ({self.readings_at_maximum} readings, {share:.3g} %, "
                "at its largest value)"
            )
        return (
            f"{self.name} has a fringe amplitude of {self.fringe_amplitude_w:.3g} W, only "
            f"{self.fringe_z:.2g} standard errors ({self.amplitude_std_w:.3g} W, noise "
            f"{self.noise_std_w:.3g} W over {samples} readings; a fringe needs "
            f"{MIN_FRINGE_Z:g})"
        )


def _status(readings: np.ndarray, fringe_z: float | None, at_maximum: int) -> str:
    if np.ptp(readings) == 0:
        return "stuck"
    if at_maximum >= max(MIN_SATURATED_READINGS, SATURATED_FRACTION * readings.size):
        return "saturated"
    if fringe_z is not None and fringe_z < MIN_FRINGE_Z:
        return "dead"
    return "ok"


def port_health(
    powers: np.ndarray,
    frequency_hz: np.ndarray,
    center_hz: float,
    delay_s: float,
    names,
    scale=None,
    *,
    phase_rad=None,
    objects=None,
) -> list[PortHealth]:
    """Fringe amplitude, its significance and the clipping of every port.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated calibration readings (W).
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    center_hz : float
        Phase origin (Hz).
    delay_s : float
        Delay at which to fit the map (s): the sweep's own, or the design one.
    names : sequence of str, length n
        Port names.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    phase_rad : None or ndarray, shape (N,)
        The model phase of each reading (rad) when it is not ``2 pi (f - f0) tau`` (the
        thermal model's); ``center_hz`` and ``delay_s`` are then not used.
    objects : None or ndarray, shape (N, q)
        The design columns of the method's own model (the wide-band one: Legendre orders
        times the cone vector), its first two the fringe averaged over the sweep; the noise
        is then each port's residual under that model, on ``N - q`` degrees of freedom.
        ``center_hz``, ``delay_s``, ``scale`` and ``phase_rad`` are then not used.

    Returns
    -------
    list of PortHealth, one per port
    """
    if objects is not None:
        objects = np.asarray(objects, dtype=float)
    elif phase_rad is None:
        objects = object_vectors(frequency_hz, center_hz, delay_s, scale)
    else:
        objects = cone_vectors(phase_rad, 1.0 if scale is None else scale)
    matrix, _ = map_cost(objects, powers)
    residual = powers - objects @ matrix.T
    samples = powers.shape[0]
    dof = max(samples - objects.shape[1], 1)
    noise = np.sqrt(np.einsum("ij,ij->j", residual, residual) / dof)
    fringe_block = np.linalg.pinv(objects.T @ objects)[:2, :2]
    precision = np.linalg.pinv(fringe_block)
    spread = float(np.sqrt(max(np.trace(fringe_block), 0.0) / 2.0))
    health = []
    for port, name in enumerate(names):
        fringe = matrix[port, :2]
        amplitude = float(np.hypot(*fringe))
        information = float(fringe @ precision @ fringe)
        if noise[port] > 0:
            fringe_z = float(np.sqrt(max(information, 0.0))) / float(noise[port])
        else:
            fringe_z = None if amplitude > 0 else 0.0
        readings = powers[:, port]
        at_maximum = int(np.count_nonzero(readings == readings.max()))
        health.append(
            PortHealth(
                name=str(name),
                status=_status(readings, fringe_z, at_maximum),
                fringe_amplitude_w=amplitude,
                amplitude_std_w=float(noise[port]) * spread,
                fringe_z=fringe_z,
                noise_std_w=float(noise[port]),
                readings_at_maximum=at_maximum,
            )
        )
    return health


def check_port_health(
    health: list[PortHealth], samples: int, needed: int = MIN_GOOD_PORTS
) -> list[CalibrationWarning]:
    """Raise when fewer than ``needed`` ports carry a fringe; otherwise warn about the rest.

    Parameters
    ----------
    health : list of PortHealth
        The ports the method reads.
    samples : int
        Number of calibration readings, for the messages.
    needed : int
        Good ports the method needs: 3 for the cone model, 2 for a two-port ellipse.

    Returns
    -------
    list of CalibrationWarning
        Empty when every port is good; one ``"dead_port"`` warning naming the bad ports.

    Raises
    ------
    InputError
        When fewer than ``needed`` ports are good; the message names the others.
    """
    bad = [port for port in health if port.status != "ok"]
    if not bad:
        return []
    good = len(health) - len(bad)
    names = ", ".join(port.name for port in bad)
    details = "; ".join(port.describe(samples) for port in bad)
    if good < needed:
        raise InputError(
            f"port(s) {names} carry no usable fringe ({details}): {good} good port(s) remain "
            f"but the method needs at least {needed}; {REMEDY}",
            parameter="powers",
        )
    message = (
        f"port(s) {names} carry no usable fringe ({details}); the calibration rests on the "
        f"other {good} ports, and these add noise (dead, stuck) or bias (saturated)"
    )
    return [CalibrationWarning(f"{message}; {REMEDY}", cause="dead_port", remedy=REMEDY)]
