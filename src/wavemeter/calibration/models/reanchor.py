"""Re-anchoring a single-map calibration to reference lines of known frequency.

A calibration learned at one temperature reads a chip at another with its bias phase moved
by ``delta``: ``p = P A u(t + delta) = P (A R(delta)) u(t)``, ``R`` a rotation about the
cone axis. Readings of reference lines of known frequency measure ``delta``
(:func:`line_phases`: one circular-mean phase per line, with its variance) and, with lines
spread over enough of the FSR, a change of the delay (:func:`fit_reanchor`: weighted least
squares, the delay refitted only where the lines know it better than the calibration's
``delay_std_s_``). :func:`reanchored_copy` returns the corrected deep copy, its parameter
covariance rotated with the map and widened by the lines' uncertainty
(:func:`reanchored_covariance`).

Theory (the rules): the docs' thermal page (``docs/theory/thermal.rst``, "Re-anchoring to
reference lines").
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.spatial.transform import Rotation

from ...exceptions import InputError, shown
from ...model.cone import delay_phase_rad, wrap_phase_rad
from ...validation import check_per_reading, check_powers
from .reference_check import ReferenceCheck, check_reference_scatter, reference_warning

__all__ = [
    "LINE_SPREAD_MIN_READINGS",
    "ReanchorFit",
    "check_reference_readings",
    "fit_reanchor",
    "line_phases",
    "reanchored_copy",
    "reanchored_covariance",
    "rotation_about_axis",
]

#: readings of one line from which its own spread gives its variance (below: the model's)
LINE_SPREAD_MIN_READINGS = 5
#: smallest phase variance (rad^2) of a line: noiseless (simulated) readings stay finite
_MIN_LINE_VARIANCE_RAD2 = (np.pi * np.finfo(float).eps) ** 2


@dataclass(frozen=True)
class ReanchorFit:
    """What reference lines say about a calibration: a phase shift, perhaps a delay change.

    Attributes
    ----------
    phase_shift_rad : float
        Bias phase change ``delta`` (rad) in [-pi, pi): the corrected map is ``A R(delta)``.
    phase_shift_std_rad : float
        Its standard error (rad).
    delay_change_s : float or None
        Refitted ``tau' - tau`` (s); None when the delay is kept.
    delay_change_std_s : float or None
        Its standard error (s); None when the delay is kept.
    covariance : ndarray, shape (2, 2)
        Covariance of ``(delta, tau' - tau)`` (rad^2, rad s, s^2); zeros in the delay's row
        and column when the delay is kept.
    lines_hz : tuple of float
        The distinct line frequencies (Hz), increasing.
    readings : int
        Number of readings used.
    reference_check : ReferenceCheck or None
        How the readings of each line scattered against the calibration's noise; None
        without readings or a model noise.
    """

    phase_shift_rad: float
    phase_shift_std_rad: float
    delay_change_s: float | None
    delay_change_std_s: float | None
    covariance: np.ndarray
    lines_hz: tuple[float, ...]
    readings: int
    reference_check: ReferenceCheck | None = None

    def record(self) -> dict:
        """The JSON-ready entry ``diagnostics_["reanchor"]``."""
        check = self.reference_check
        return {
            "phase_shift_rad": self.phase_shift_rad,
            "phase_shift_std_rad": self.phase_shift_std_rad,
            "delay_change_s": self.delay_change_s,
            "delay_change_std_s": self.delay_change_std_s,
            "lines_hz": list(self.lines_hz),
            "readings": self.readings,
            "reference_check": None if check is None else check.record(),
        }


def check_reference_readings(
    powers, frequency_hz, ports: int, temperature_k=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Validated readings of reference lines and their known frequencies.

    Parameters
    ----------
    powers : array_like, shape (N, n) or (n,)
        Port readings (W, the unit of the calibration), ``N >= 1``.
    frequency_hz : float or array_like, shape (N,)
        Known frequency of each reading (Hz); one number for readings of one line.
    ports : int
        Port count ``n`` of the calibration.
    temperature_k : None, float or array_like, shape (N,)
        Chip temperature (K), checked for the common API.

    Returns
    -------
    readings : ndarray, shape (N, n), W
    frequency_hz : ndarray, shape (N,), Hz
    temperature_k : None or ndarray, shape (N,), K

    Raises
    ------
    InputError
        Naming ``powers``, ``frequency_hz`` or ``temperature_k``: no readings, NaN or inf,
        no light, a wrong port count or length.
    """
    try:
        readings = check_powers(powers, ports=ports)
    except InputError as exc:
        raise InputError(f"reference readings: {exc}", parameter="powers") from exc
    values = {"frequency_hz": frequency_hz, "temperature_k": temperature_k}
    checked = {}
    for name, value in values.items():
        if value is None:
            continue
        try:
            checked[name] = check_per_reading(name, value, readings.shape[0])
        except InputError as exc:
            raise InputError(str(exc), parameter=name) from exc
    if "frequency_hz" not in checked:
        raise InputError(
            "frequency_hz must give the known frequency (Hz) of the reference readings",
            parameter="frequency_hz",
        )
    if np.any(checked["frequency_hz"] <= 0):
        raise InputError("frequency_hz must be > 0 (Hz)", parameter="frequency_hz")
    return readings, checked["frequency_hz"], checked.get("temperature_k")


def line_phases(
    phase_rad: np.ndarray, frequency_hz: np.ndarray, reading_phase_std_rad=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean phase of each line on the circle and the variance of that mean.

    Parameters
    ----------
    phase_rad : ndarray, shape (N,)
        Retrieved phase of each reading (rad).
    frequency_hz : ndarray, shape (N,)
        Known frequency (Hz); equal values are one line.
    reading_phase_std_rad : None or ndarray, shape (N,)
        The model's standard deviation of each reading's phase (rad), for lines with fewer
        than ``LINE_SPREAD_MIN_READINGS`` readings.

    Returns
    -------
    lines_hz : ndarray, shape (L,), Hz
    mean_phase_rad : ndarray, shape (L,), rad in (-pi, pi]
    variance_rad2 : ndarray, shape (L,), rad^2
        Variance of each line's mean phase.

    Raises
    ------
    InputError
        When a line has too few readings for its spread and no model variance is given.
    """
    lines, line_of, counts = np.unique(frequency_hz, return_inverse=True, return_counts=True)
    mean = np.angle(
        np.bincount(line_of, weights=np.cos(phase_rad))
        + 1j * np.bincount(line_of, weights=np.sin(phase_rad))
    )
    deviation = wrap_phase_rad(phase_rad - mean[line_of])
    spread = np.bincount(line_of, weights=deviation**2) / np.maximum(counts - 1, 1)
    if reading_phase_std_rad is None:
        few = counts < LINE_SPREAD_MIN_READINGS
        if few.any():
            raise InputError(
                f"line {shown(lines[few][0])} Hz has {counts[few][0]} readings: give at least "
                f"{LINE_SPREAD_MIN_READINGS} per line, whose spread gives its uncertainty",
                parameter="powers",
            )
        model = spread
    else:
        model = np.bincount(line_of, weights=np.square(reading_phase_std_rad)) / counts
    reading_variance = np.where(counts >= LINE_SPREAD_MIN_READINGS, spread, model)
    return lines, mean, np.maximum(reading_variance / counts, _MIN_LINE_VARIANCE_RAD2)


def fit_reanchor(
    phase_rad,
    frequency_hz,
    center_hz: float,
    delay_s: float,
    *,
    delay_std_s: float | None,
    reading_phase_std_rad=None,
    noise_dof: float | None = None,
) -> ReanchorFit:
    """Bias phase shift (and delay change) that reference lines ask of a calibration, once
    their readings scatter like lines (:func:`check_reference_scatter`).

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        Phase the calibration retrieves from each reference reading (rad).
    frequency_hz : array_like, shape (N,)
        Known frequency of each reading (Hz).
    center_hz : float
        The calibration's phase origin (Hz).
    delay_s : float
        The calibration's delay ``tau`` (s).
    delay_std_s : float or None
        Its standard error (s); the delay is refitted only when the lines give a smaller
        one (never when None).
    reading_phase_std_rad : None or array_like, shape (N,)
        The model's phase standard deviation of each reading (rad); see :func:`line_phases`.
        Without it the readings' scatter is not checked.
    noise_dof : float or None
        Degrees of freedom of the calibration's noise estimate, for the check.

    Returns
    -------
    ReanchorFit

    Raises
    ------
    InputError
        When the readings of a line scatter far beyond the calibration's noise: not
        readings of the lines given (:mod:`~wavemeter.calibration.models.reference_check`).

    Warns
    -----
    CalibrationWarning
        (cause ``"reference_scatter"``) When a line scatters more than the noise, short of
        that.
    """
    phase = np.asarray(phase_rad, dtype=float)
    frequency = np.asarray(frequency_hz, dtype=float)
    check = None
    if reading_phase_std_rad is not None:
        check = check_reference_scatter(phase, frequency, reading_phase_std_rad, noise_dof)
    lines, mean, variance = line_phases(phase, frequency, reading_phase_std_rad)
    difference = wrap_phase_rad(mean - delay_phase_rad(lines, center_hz, delay_s))
    weight = 1.0 / variance
    middle = np.angle(np.sum(weight * np.exp(1j * difference)))
    difference = middle + wrap_phase_rad(difference - middle)
    # columns: delta (rad) and the relative delay change (rad per unit tau'/tau - 1)
    design = np.column_stack([np.ones(lines.size), delay_phase_rad(lines, center_hz, delay_s)])
    root = np.sqrt(weight)
    refit = False
    if lines.size >= 2 and delay_std_s is not None:
        scaled_covariance = linalg.inv(design.T @ (weight[:, None] * design))
        refit = np.sqrt(scaled_covariance[1, 1]) * delay_s < delay_std_s
    if refit:
        solution = linalg.lstsq(design * root[:, None], difference * root)[0]
        scale = np.array([1.0, delay_s])
        covariance = scaled_covariance * np.outer(scale, scale)
        shift, change = float(solution[0]), float(solution[1] * delay_s)
        change_std = float(np.sqrt(covariance[1, 1]))
    else:
        shift = float(np.sum(weight * difference) / np.sum(weight))
        covariance = np.diag([1.0 / np.sum(weight), 0.0])
        change = change_std = None
    return ReanchorFit(
        phase_shift_rad=float(wrap_phase_rad(shift)),
        phase_shift_std_rad=float(np.sqrt(covariance[0, 0])),
        delay_change_s=change,
        delay_change_std_s=change_std,
        covariance=covariance,
        lines_hz=tuple(float(line) for line in lines),
        readings=int(frequency.size),
        reference_check=check,
    )


def rotation_about_axis(phase_shift_rad: float, columns: int = 3) -> np.ndarray:
    """``R(delta)`` (columns x columns): ``u(t + delta) = R u(t)``; identity beyond the cone's
    3 components (a column of offsets)."""
    rotation = np.eye(columns)
    rotation[:3, :3] = Rotation.from_euler("z", phase_shift_rad).as_matrix()
    return rotation


def reanchored_covariance(
    covariance: np.ndarray, map_: np.ndarray, fit: ReanchorFit, nonlinear: int = 1
) -> np.ndarray:
    """Covariance of ``[vec(A R(delta)) row-major, tau', ...]`` after re-anchoring.

    Parameters
    ----------
    covariance : ndarray, shape (n k + q, n k + q)
        The calibration's parameter covariance (``k`` = 3, or 4 with offsets), its ``q``
        nonlinear parameters last, the delay first among them.
    map_ : ndarray, shape (n, 3)
        The corrected map ``A R(delta)`` (W).
    fit : ReanchorFit
    nonlinear : int
        ``q``: 1 (the delay), or 3 for the thermal model (delay, bias rate, delay rate).

    Returns
    -------
    ndarray, shape (n k + q, n k + q)
    """
    ports = map_.shape[0]
    size = covariance.shape[0] - nonlinear
    columns = size // ports
    # each map row a becomes a R: its entries transform by R^T
    transform = linalg.block_diag(
        np.kron(np.eye(ports), rotation_about_axis(fit.phase_shift_rad, columns).T),
        np.eye(nonlinear),
    )
    result = transform @ covariance @ transform.T
    if fit.delay_change_s is not None:
        # the lines determine the new delay; the sweep's delay and its correlations go
        result[size, :] = 0.0
        result[:, size] = 0.0
    # d(A R(delta)) / d delta = A R(delta) K, K the generator of the rotation
    generator = np.zeros((columns, columns))
    generator[1, 0], generator[0, 1] = 1.0, -1.0
    direction = np.zeros((size + nonlinear, 2))
    direction[:size, 0] = (np.pad(map_, ((0, 0), (0, columns - 3))) @ generator).ravel()
    direction[size, 1] = 1.0
    result += direction @ fit.covariance @ direction.T
    return 0.5 * (result + result.T)


def reanchored_copy(calibrator, fit: ReanchorFit, record: dict | None = None):
    """A deep copy of a single-map calibrator with the map rotated by ``fit.phase_shift_rad``
    (and the delay and FSR changed by ``fit.delay_change_s``).

    Parameters
    ----------
    calibrator : BaseCalibrator
        A fitted calibrator with ``map_`` (n, 3), ``_set_map`` and ``delay_s_``; untouched.
    fit : ReanchorFit
    record : None or dict
        JSON-ready ``diagnostics_["reanchor"]`` of the copy; default ``fit.record()``. A
        reference check that warned adds its warning to ``diagnostics_["warnings"]``.

    Returns
    -------
    BaseCalibrator
        Of the calibrator's class; ``delay_s_ * fsr_hz_ == 1`` (to rounding).
    """
    if not hasattr(calibrator, "map_") or not hasattr(calibrator, "_set_map"):
        raise InputError(
            f"{type(calibrator).__name__} has no cone map to re-anchor", parameter="calibrator"
        )
    corrected = copy.deepcopy(calibrator)
    corrected._set_map(calibrator.map_ @ rotation_about_axis(fit.phase_shift_rad))
    if fit.delay_change_s is not None:
        corrected.delay_s_ = calibrator.delay_s_ + fit.delay_change_s
        corrected.delay_std_s_ = fit.delay_change_std_s
        corrected.fsr_hz_ = 1.0 / corrected.delay_s_
    covariance = getattr(calibrator, "parameter_covariance_", None)
    if covariance is not None:
        corrected.parameter_covariance_ = reanchored_covariance(
            covariance, corrected.map_, fit, getattr(calibrator, "nonlinear_parameters", 1)
        )
    diagnostics = {
        **(corrected.diagnostics_ or {}),
        "reanchor": fit.record() if record is None else record,
    }
    if fit.reference_check is not None and fit.reference_check.verdict == "warned":
        notes = diagnostics.get("warnings")
        notes = list(notes) if isinstance(notes, list) else []
        diagnostics["warnings"] = [*notes, reference_warning(fit.reference_check).record()]
    corrected.diagnostics_ = diagnostics
    corrected._check_state()
    return corrected
