"""n-port ellipse: the readings' best-fit plane in R^n, an ellipse fit there, Heydemann phase.

At a constant source power ``P`` the readings ``p = P A [cos t, sin t, sqrt 2]`` lie on an
ellipse in a 2-D affine plane of R^n: the section of the image cone by the plane of that
power. The plane is found without labels from the readings: through their mean, spanned by
the two leading right singular vectors of the mean-removed readings (the mean of points in
an affine plane lies in it, whatever phases the sweep covers). An ellipse is fitted to the
in-plane coordinates (:func:`wavemeter.baselines.ellipse.fit_ellipse`) and the Heydemann
correction gives the phase, right up to origin, direction and FSR, which come from the
labels (:mod:`wavemeter.baselines._labels`).

The cone's vertex is the origin of R^n (no light, no reading), so a reading at another
power, ``p' = (P'/P) p``, lies on the ray through the same calibration point. Readings are
therefore mapped onto the calibration plane by central projection from the vertex,
``q = p d / (nu . p)`` (``nu`` the unit normal of the plane inside the span of the plane
and the vertex, ``d = nu . mean``), not by orthogonal projection: this makes retrieval
invariant to source power, exactly when the detectors have no dark offset. At the
calibration power the two projections coincide.

Reference-free use (no labels): ``fit = fit_plane_ellipse(powers)``, then
``plane_ellipse_phase(fit, powers)`` gives the phase (rad) up to origin and sign.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....exceptions import InputError, shown
from ...files import fields
from ...files.state import state_array
from ._labels import LabelLockedCalibrator
from .ellipse import MIN_ELLIPSE_POINTS, FringeEllipse, ellipse_phase, ellipse_rules, fit_ellipse

__all__ = ["PlaneEllipse", "PlaneEllipseCalibrator", "fit_plane_ellipse", "plane_ellipse_phase"]

#: a loaded plane frame must be orthonormal to this accuracy (it is saved exactly)
FRAME_ATOL = 1e-9


@dataclass(frozen=True)
class PlaneEllipse:
    """An ellipse in a 2-D affine plane of R^n that does not contain the origin.

    Attributes
    ----------
    origin : ndarray, shape (n,)
        A point of the plane (the mean calibration reading, W).
    basis : ndarray, shape (n, 2)
        Orthonormal directions spanning the plane.
    normal : ndarray, shape (n,)
        Unit vector orthogonal to ``basis`` in the span of the plane and the origin of R^n,
        oriented so that ``normal . origin > 0``.
    ellipse : FringeEllipse
        The ellipse in the plane coordinates ``basis.T @ (q - origin)`` (W).
    """

    origin: np.ndarray
    basis: np.ndarray
    normal: np.ndarray
    ellipse: FringeEllipse

    def to_dict(self) -> dict:
        """JSON-ready form (lists of floats)."""
        return {
            "origin": self.origin.tolist(),
            "basis": self.basis.tolist(),
            "normal": self.normal.tolist(),
            "ellipse": self.ellipse.to_dict(),
        }

    @classmethod
    def from_dict(cls, state: dict, ports: int) -> PlaneEllipse:
        """Inverse of :meth:`to_dict`; checks shapes, finiteness and geometry for ``ports``
        ports: ``basis`` orthonormal, ``normal`` a unit vector orthogonal to it with
        ``normal . origin > 0``."""
        if not isinstance(state, dict):
            raise InputError(
                f"field 'plane_ellipse' must be an object, got {shown(state, as_in_file=True)}"
            )
        origin = state_array(state, "origin", (ports,))
        basis = state_array(state, "basis", (ports, 2))
        normal = state_array(state, "normal", (ports,))
        frame = np.column_stack([basis, normal])
        if not (np.allclose(frame.T @ frame, np.eye(3), atol=FRAME_ATOL) and normal @ origin > 0):
            raise InputError(
                "plane basis and normal must be orthonormal, with the origin on the side the "
                "normal points to"
            )
        return cls(origin, basis, normal, FringeEllipse.from_dict(state.get("ellipse")))


def _plane_coordinates(origin, basis, normal, powers: np.ndarray) -> np.ndarray:
    """Central projection of readings (N, n) onto a plane, in its coordinates (N, 2)."""
    along_normal = powers @ normal
    if not np.all(along_normal > 0):
        rows = np.flatnonzero(~(along_normal > 0))[:5].tolist()
        raise InputError(
            f"readings in rows {rows} (zero-based) lie on the far side of the cone vertex "
            "from the calibration plane: not readings of this interferometer"
        )
    projected = powers * ((normal @ origin) / along_normal)[:, None]
    return (projected - origin) @ basis


def _check_readings(powers) -> np.ndarray:
    array = np.asarray(powers, dtype=float)
    if array.ndim != 2 or array.shape[1] < 3:
        raise InputError(f"powers must have shape (samples, ports >= 3), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InputError("powers must be finite (no NaN or inf)")
    return array


def fit_plane_ellipse(powers) -> PlaneEllipse:
    """Fit the plane and the ellipse of constant-power readings (reference-free).

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W or any linear unit) at one source power, ``N >= 5``, ``n >= 3``.

    Returns
    -------
    PlaneEllipse

    Raises
    ------
    ValueError
        Too few or non-finite readings, or readings that span no plane away from zero.
    """
    readings = _check_readings(powers)
    if readings.shape[0] < MIN_ELLIPSE_POINTS:
        raise InputError(
            f"a plane ellipse fit needs at least {MIN_ELLIPSE_POINTS} readings, "
            f"got {readings.shape[0]}"
        )
    origin = readings.mean(axis=0)
    _, singular, right = np.linalg.svd(readings - origin, full_matrices=False)
    if not singular[1] > 0:
        raise InputError("the readings do not span a plane: they lie on a line or a point")
    basis = right[:2].T
    off_plane = origin - basis @ (basis.T @ origin)
    distance = np.linalg.norm(off_plane)
    if not distance > 0:
        raise InputError("the readings' plane passes through zero power: not an interferometer")
    normal = off_plane / distance
    coordinates = _plane_coordinates(origin, basis, normal, readings)
    ellipse = fit_ellipse(coordinates[:, 0], coordinates[:, 1])
    return PlaneEllipse(origin, basis, normal, ellipse)


def plane_ellipse_phase(plane: PlaneEllipse, powers) -> np.ndarray:
    """Phase (rad) in (-pi, pi] of readings on a fitted plane ellipse (reference-free).

    Parameters
    ----------
    plane : PlaneEllipse
    powers : array_like, shape (N, n)
        Readings (same unit as the fit); any source power.

    Returns
    -------
    ndarray, shape (N,), rad
        Heydemann phase, zero at the maximum of the first plane coordinate.
    """
    coordinates = _plane_coordinates(
        plane.origin, plane.basis, plane.normal, _check_readings(powers)
    )
    return ellipse_phase(plane.ellipse, coordinates[:, 0], coordinates[:, 1])


class PlaneEllipseCalibrator(LabelLockedCalibrator):
    """n-port ellipse fit in the readings' plane, with labels only for origin, sign, FSR.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz); the sweep refines it within +-20 %.

    Attributes
    ----------
    plane_ellipse_ : PlaneEllipse
        Fitted plane and ellipse (W).
    direction_ : int
        +1 or -1: the sign relating the Heydemann phase to increasing frequency.
    phase_origin_rad_ : float
        Heydemann phase at ``center_hz_`` (rad).
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.

    Notes
    -----
    The plane is estimated from the raw calibration readings, which assumes a nearly
    constant source power; the readings are then projected centrally onto it, so small
    power fluctuations during calibration largely cancel. With a power monitor the
    readings are scaled to the mean monitored power first. Retrieval is invariant to
    source power (central projection from the cone vertex).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.PlaneEllipseCalibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> print(f"fitted FSR {cal.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    fitted FSR 51.51 GHz, true 51.50 GHz

    The n-port ellipse reads this device as the learned map does (17 MHz; the bound is
    14 MHz):

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> print(f"RMS error {np.sqrt(np.mean((cal.predict(test) - test_hz) ** 2)) / 1e6:.0f} MHz")
    RMS error 17 MHz
    """

    method = "plane_ellipse"
    #: the mean reading's norm is the power scale; the frame is of unit vectors
    state_rules = fields.rule_table(
        {
            "plane_ellipse.origin": fields.ScaleRule(
                "the plane's origin", fields.vector_norm, "the mean reading's norm"
            ),
            "plane_ellipse.basis": fields.FieldRule(
                "a unit vector's entry", "", high=1.0, magnitude=True
            ),
            "plane_ellipse.normal": fields.FieldRule(
                "a unit vector's entry", "", high=1.0, magnitude=True
            ),
            **ellipse_rules("plane_ellipse.ellipse"),
        }
    )

    def __init__(self, fsr_hz: float = 50e9):
        self.fsr_hz = fsr_hz

    def _learn(self, sweep):
        powers, frequency_hz, monitor = sweep.powers_w, sweep.frequency_hz, sweep.monitor_w
        if monitor is not None:
            powers = powers * (monitor.mean() / monitor)[:, None]
        self.plane_ellipse_ = fit_plane_ellipse(powers)
        self._lock_to_labels(powers, frequency_hz)

    def _raw_phase(self, powers):
        return plane_ellipse_phase(self.plane_ellipse_, powers)

    def _state(self) -> dict:
        return {"plane_ellipse": self.plane_ellipse_.to_dict(), **self._lock_state()}

    def _set_state(self, state: dict) -> None:
        self.plane_ellipse_ = PlaneEllipse.from_dict(state.get("plane_ellipse"), self.n_ports_)
        self._set_lock_state(state)
