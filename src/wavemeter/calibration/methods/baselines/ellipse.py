"""Two-port ellipse fit (Fitzgibbon / Halir-Flusser) and the Heydemann correction.

Two fringes of one interferometer, ``x = x0 + ax cos t`` and ``y = y0 + ay cos(t - phi)``,
trace an ellipse as the phase ``t`` turns (a Lissajous figure). The ellipse is fitted by the
direct least-squares method of Fitzgibbon, Pilu and Fisher (IEEE TPAMI 21, 476, 1999) in the
numerically stable form of Halir and Flusser (WSCG 1998); the fringe parameters follow from
the conic in closed form, and the Heydemann correction (Appl. Opt. 20, 3382, 1981) turns a
point into its phase: ``u = (x - x0) / ax = cos t``, ``sin t = ((y - y0) / ay - u cos phi) /
sin phi``. The sign of ``phi`` (the sense in which the ellipse is traversed) is not
knowable from the points, so ``phi`` is taken in (0, pi) and the direction comes from the
frequency labels, with the origin and the FSR (:mod:`wavemeter.baselines._labels`).

Reference-free use (no labels): ``ellipse = fit_ellipse(x, y)``, then
``ellipse_phase(ellipse, x, y)`` gives the phase (rad) up to origin and sign.

The fit assumes a constant source power: at another power the ellipse scales about the
origin and the retrieved phase is biased (two readings cannot tell power from phase).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....exceptions import InputError, shown
from ...files import fields
from ...files.state import state_float
from ._labels import LabelLockedCalibrator

__all__ = [
    "EllipseCalibrator",
    "FringeEllipse",
    "conic_to_fringes",
    "ellipse_phase",
    "ellipse_rules",
    "fit_conic",
    "fit_ellipse",
]

#: a conic has five degrees of freedom
MIN_ELLIPSE_POINTS = 5

#: inverse of the Fitzgibbon constraint matrix ``4 a c - b^2`` on ``(a, b, c)``
_CONSTRAINT_INVERSE = np.array([[0.0, 0.0, 0.5], [0.0, -1.0, 0.0], [0.5, 0.0, 0.0]])


#: closest the two fringes of a saved ellipse may be to in or out of phase (rad)
MIN_FRINGE_PHASE_RAD = 1e-6


def ellipse_rules(prefix: str) -> dict:
    """The file rules of a :class:`FringeEllipse` saved under ``prefix``: its x fringe's
    amplitude is the power scale (W) of a file without another."""
    amplitude = fields.FieldRule(
        "a fringe amplitude", "W", *fields.NOISE_RELATIVE, scale="power_w", open_low=True
    )
    center = fields.FieldRule(
        "an ellipse centre", "W", high=fields.SPREAD_RELATIVE, scale="power_w", magnitude=True
    )
    return {
        f"{prefix}.amplitude_x": (
            fields.ScaleRule("a fringe amplitude", fields.largest_magnitude, "the x amplitude"),
            amplitude,
        ),
        f"{prefix}.amplitude_y": amplitude,
        f"{prefix}.center_x": center,
        f"{prefix}.center_y": center,
        # the phase is read through 1 / sin(phase_rad): a millionfold at MIN_FRINGE_PHASE_RAD
        f"{prefix}.phase_rad": fields.FieldRule(
            "the y fringe's phase behind x",
            "rad",
            MIN_FRINGE_PHASE_RAD,
            np.pi - MIN_FRINGE_PHASE_RAD,
        ),
    }


@dataclass(frozen=True)
class FringeEllipse:
    """An ellipse written as two fringes of one phase ``t``.

    ``x = center_x + amplitude_x cos t``, ``y = center_y + amplitude_y cos(t - phase_rad)``.

    Attributes
    ----------
    center_x, center_y : float
        Centre (units of the coordinates, e.g. W).
    amplitude_x, amplitude_y : float
        Fringe amplitudes (> 0, units of the coordinates).
    phase_rad : float
        Phase of the ``y`` fringe behind the ``x`` fringe, in (0, pi) (rad).
    """

    center_x: float
    center_y: float
    amplitude_x: float
    amplitude_y: float
    phase_rad: float

    def to_dict(self) -> dict:
        """The five parameters as JSON-ready floats."""
        return {name: float(getattr(self, name)) for name in self.__dataclass_fields__}

    @classmethod
    def from_dict(cls, state: dict) -> FringeEllipse:
        """Inverse of :meth:`to_dict`; checks that the ellipse is proper."""
        if not isinstance(state, dict):
            raise InputError(
                f"field 'ellipse' must be an object, got {shown(state, as_in_file=True)}"
            )
        ellipse = cls(**{name: state_float(state, name) for name in cls.__dataclass_fields__})
        if not (
            ellipse.amplitude_x > 0 and ellipse.amplitude_y > 0 and 0 < ellipse.phase_rad < np.pi
        ):
            raise InputError(
                "an ellipse needs finite parameters, amplitudes > 0 and 0 < phase_rad < pi, "
                f"got {ellipse}"
            )
        return ellipse


def _as_coordinates(x, y) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1 or x.shape != y.shape:
        raise InputError(f"x and y must be vectors of equal length, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError("x and y must be finite (no NaN or inf)")
    return x, y


def fit_conic(x, y) -> np.ndarray:
    """Direct least-squares ellipse fit (Halir-Flusser form of Fitzgibbon's method).

    Minimises the algebraic distance ``sum (a x^2 + b xy + c y^2 + d x + e y + f)^2``
    subject to ``4 a c - b^2 = 1``, which admits only ellipses. Call it on centred and
    scaled coordinates (as :func:`fit_ellipse` does) for a well-conditioned problem.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Points, ``N >= 5``.

    Returns
    -------
    ndarray, shape (6,)
        ``(a, b, c, d, e, f)`` with ``4 a c - b^2 = 1``.

    Raises
    ------
    ValueError
        Fewer than 5 points, non-finite points, or points that trace no ellipse.
    """
    x, y = _as_coordinates(x, y)
    if x.size < MIN_ELLIPSE_POINTS:
        raise InputError(f"an ellipse fit needs at least {MIN_ELLIPSE_POINTS} points, got {x.size}")
    quadratic = np.column_stack([x * x, x * y, y * y])
    linear = np.column_stack([x, y, np.ones_like(x)])
    s1, s2, s3 = quadratic.T @ quadratic, quadratic.T @ linear, linear.T @ linear
    try:
        elimination = -np.linalg.solve(s3, s2.T)  # best linear part for a quadratic part
    except np.linalg.LinAlgError as exc:
        raise InputError("the points do not trace an ellipse: they are collinear") from exc
    eigenvalues, eigenvectors = np.linalg.eig(_CONSTRAINT_INVERSE @ (s1 + s2 @ elimination))
    eigenvectors = np.real(eigenvectors)
    constraint = 4.0 * eigenvectors[0] * eigenvectors[2] - eigenvectors[1] ** 2
    admissible = np.flatnonzero(constraint > 0)
    if admissible.size == 0:
        raise InputError("the points do not trace an ellipse (no elliptic solution)")
    # the ellipse minimising the algebraic distance has the smallest admissible eigenvalue
    best = admissible[np.argmin(np.real(eigenvalues[admissible]))]
    quad = eigenvectors[:, best] / np.sqrt(constraint[best])
    return np.concatenate([quad, elimination @ quad])


def conic_to_fringes(conic) -> FringeEllipse:
    """Fringe form (centre, amplitudes, relative phase) of an ellipse's conic coefficients.

    Parameters
    ----------
    conic : array_like, shape (6,)
        ``(a, b, c, d, e, f)`` of ``a x^2 + b xy + c y^2 + d x + e y + f = 0``.

    Returns
    -------
    FringeEllipse
    """
    a, b, c, d, e, f = np.asarray(conic, dtype=float) * np.sign(conic[0])  # make a > 0
    discriminant = 4.0 * a * c - b * b
    if not discriminant > 0:
        raise InputError(f"the conic is not an ellipse (4ac - b^2 = {discriminant:.3g})")
    center_x = (b * e - 2.0 * c * d) / discriminant
    center_y = (b * d - 2.0 * a * e) / discriminant
    level = -(f + 0.5 * (d * center_x + e * center_y))  # a X^2 + b XY + c Y^2 = level
    if not level > 0:
        raise InputError("the conic is an imaginary ellipse (no real points)")
    # (X/ax)^2 - 2 (X/ax)(Y/ay) cos phi + (Y/ay)^2 = sin^2 phi
    phase = float(np.arctan2(np.sqrt(discriminant), -b))
    sin_phase = np.sqrt(discriminant / (4.0 * a * c))
    return FringeEllipse(
        center_x=float(center_x),
        center_y=float(center_y),
        amplitude_x=float(np.sqrt(level / a) / sin_phase),
        amplitude_y=float(np.sqrt(level / c) / sin_phase),
        phase_rad=phase,
    )


def fit_ellipse(x, y) -> FringeEllipse:
    """Fit an ellipse to points and return its fringe form (reference-free, no labels).

    The points are centred and scaled to unit standard deviation for the fit, and the
    fringe parameters mapped back, so the result keeps its precision whatever the offsets.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Two port readings (any linear unit) over a range of phases, ``N >= 5``.

    Returns
    -------
    FringeEllipse

    Raises
    ------
    ValueError
        Fewer than 5 points, non-finite points, or points that trace no ellipse.
    """
    x, y = _as_coordinates(x, y)
    mean_x, mean_y, scale_x, scale_y = x.mean(), y.mean(), x.std(), y.std()
    if not (scale_x > 0 and scale_y > 0):
        raise InputError("the points do not trace an ellipse: one coordinate is constant")
    unit = conic_to_fringes(fit_conic((x - mean_x) / scale_x, (y - mean_y) / scale_y))
    return FringeEllipse(
        center_x=float(mean_x + scale_x * unit.center_x),
        center_y=float(mean_y + scale_y * unit.center_y),
        amplitude_x=float(scale_x * unit.amplitude_x),
        amplitude_y=float(scale_y * unit.amplitude_y),
        phase_rad=unit.phase_rad,
    )


def ellipse_phase(ellipse: FringeEllipse, x, y) -> np.ndarray:
    """Heydemann-corrected phase (rad) in (-pi, pi] of points on a fitted ellipse.

    Zero where ``x`` is at its maximum; increases in the sense ``y`` lags ``x`` by
    ``ellipse.phase_rad``.

    Parameters
    ----------
    ellipse : FringeEllipse
    x, y : array_like, shape (N,)

    Returns
    -------
    ndarray, shape (N,), rad
    """
    x, y = _as_coordinates(x, y)
    cosine = (x - ellipse.center_x) / ellipse.amplitude_x
    lagging = (y - ellipse.center_y) / ellipse.amplitude_y
    # sin t = (lagging - cos t cos phi) / sin phi, with sin phi > 0
    return np.arctan2(
        lagging - cosine * np.cos(ellipse.phase_rad), cosine * np.sin(ellipse.phase_rad)
    )


class EllipseCalibrator(LabelLockedCalibrator):
    """Ellipse fit of one port pair with the Heydemann correction.

    The ellipse traced by two ports is fitted without the frequency labels; the labels fix
    only the phase origin, the direction and the FSR.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz); the sweep refines it within +-20 %.
    ports : (int, int)
        Zero-based indices of the two ports used.

    Attributes
    ----------
    ellipse_ : FringeEllipse
        Fitted ellipse of the two ports (W).
    direction_ : int
        +1 or -1: the sign relating the Heydemann phase to increasing frequency.
    phase_origin_rad_ : float
        Heydemann phase at ``center_hz_`` (rad).
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.

    Notes
    -----
    With a power monitor, the calibration readings are scaled to the mean monitored power
    before the fit; retrieval assumes that power.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.EllipseCalibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> print(f"fitted FSR {cal.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    fitted FSR 51.50 GHz, true 51.50 GHz

    The ellipse of ports 1 and 2 alone reads the same test readings less well than the
    learned map of all three ports (17 MHz, the Cramer-Rao bound is 14 MHz):

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> print(f"RMS error {np.sqrt(np.mean((cal.predict(test) - test_hz) ** 2)) / 1e6:.0f} MHz")
    RMS error 25 MHz
    """

    method = "ellipse"
    fringe_ports_needed = 2
    state_rules = fields.rule_table(ellipse_rules("ellipse"))

    def __init__(self, fsr_hz: float = 50e9, ports=(0, 1)):
        self.fsr_hz = fsr_hz
        self.ports = ports

    def _check_params(self) -> None:
        super()._check_params()
        ports = self.ports
        if (
            not isinstance(ports, (tuple, list))
            or len(ports) != 2
            or not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in ports)
            or ports[0] == ports[1]
            or min(ports) < 0
        ):
            raise InputError(f"ports must be two different port indices >= 0, got {ports!r}")

    def _ports_read(self, ports: int) -> list[int]:
        if max(self.ports) >= ports:
            raise InputError(
                f"ports must index the {ports} port columns (0..{ports - 1}), got {self.ports!r}"
            )
        return list(self.ports)

    def _learn(self, sweep):
        powers, frequency_hz, monitor = sweep.powers_w, sweep.frequency_hz, sweep.monitor_w
        first, second = self.ports
        if powers.shape[0] < MIN_ELLIPSE_POINTS:
            raise InputError(
                f"the ellipse method needs at least {MIN_ELLIPSE_POINTS} samples, "
                f"got {powers.shape[0]}"
            )
        if monitor is not None:
            powers = powers * (monitor.mean() / monitor)[:, None]
        self.ellipse_ = fit_ellipse(powers[:, first], powers[:, second])
        self._lock_to_labels(powers, frequency_hz)

    def _raw_phase(self, powers):
        first, second = self.ports
        return ellipse_phase(self.ellipse_, powers[:, first], powers[:, second])

    def _state(self) -> dict:
        return {"ellipse": self.ellipse_.to_dict(), **self._lock_state()}

    def _set_state(self, state: dict) -> None:
        self.ellipse_ = FringeEllipse.from_dict(state.get("ellipse"))
        self._set_lock_state(state)

    def _check_state(self) -> None:
        super()._check_state()
        if max(self.ports) >= self.n_ports_:
            raise InputError(
                f"ports {self.ports!r} must index the {self.n_ports_} ports of the calibration"
            )
