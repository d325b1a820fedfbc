"""The cone of readings learned from the powers alone: reference-free phase retrieval.

Readings ``p = A x + b``, ``x = P [cos t, sin t, sqrt 2]``, lie on a cone in R^n with its
vertex at the detector offsets ``b`` (zero when they are subtracted), whatever the source
power ``P`` of each reading. :func:`fit_cone` learns it without labels:

1. the readings' span: the 3 leading right singular vectors of ``p - b``;
2. the cone: the quadric ``u^T Q u = 0`` through the readings' directions ``u / |u|``
   (algebraic least squares: the last right singular vector of their quadratic
   monomials), of signature (2, 1); ``Q = L^T diag(1, 1, -1) L``;
3. the frame: the cone is invariant under Lorentz boosts of ``x = L u``, which change the
   phase non-uniformly; the one frame in which the power coordinate ``x_3`` is most nearly
   constant over the readings (least squares of ``m . x = 1``; of ``m . x = monitor`` with
   a power monitor) is taken. It is the true frame when the source power is constant (or
   monitored); a power that varies at random leaves a statistical error of the frame, an
   RMS phase distortion of about ``spread sqrt(2 / N)`` (``ConeFit.frame_std_rad``), and
   a power that drifts with the phase over part of a fringe biases it.

With ``offsets="fit"`` the vertex is fitted too (a general quadric's centre, refined); that
needs a source power that varies (a constant power puts the readings on one ellipse, which
any vertex off its plane fits), and is refused with the reason when the spread of a
bootstrap leaves the offsets undetermined. The phase is ``atan2(x_2, x_1)``: right up to
an origin and a direction, which :mod:`.reference_free` fixes by convention or labels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError

__all__ = ["ConeFit", "OFFSET_MODES", "cone_phase_rad", "fit_cone"]

#: detector offsets: taken as zero (subtract known dark readings first) or fitted
OFFSET_MODES = ("none", "fit")
#: bootstrap resamples that judge fitted offsets
BOOTSTRAP_DRAWS = 16
#: fitted offsets are refused when their bootstrap spread exceeds this share of the mean
#: reading of a port
MAX_OFFSET_SPREAD = 0.01
_ETA = np.array([1.0, 1.0, -1.0])


@dataclass(frozen=True)
class ConeFit:
    """A cone fitted to readings; :func:`cone_phase_rad` reads phases with it.

    Attributes
    ----------
    vertex_w : ndarray, shape (n,)
        The cone's vertex: the detector offsets (W, the readings' unit); zeros unless fitted.
    basis : ndarray, shape (n, 3)
        Orthonormal directions spanning ``p - vertex_w``.
    frame : ndarray, shape (3, 3)
        ``L``: ``x = L basis^T (p - vertex_w)`` lies on ``x_1^2 + x_2^2 = x_3^2``, ``x_3 > 0``
        the source power (relative) in the frame of least power variation.
    power_spread : float
        Relative standard deviation of ``x_3`` over the fit's readings.
    frame_std_rad : float
        Expected RMS phase distortion (rad) from the frame's estimate when the power varies
        at random: ``power_spread sqrt(2 / N)`` (0 with a power monitor: the frame is then
        exact).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import fit_cone
    >>> cone = fit_cone(powers)
    >>> cone.vertex_w, cone.basis.shape, cone.frame.shape  # no offsets fitted: vertex at 0
    (array([0., 0., 0.]), (3, 3), (3, 3))
    >>> print(f"power spread {cone.power_spread:.1e}")  # a source of constant power
    power spread 1.1e-03
    """

    vertex_w: np.ndarray
    basis: np.ndarray
    frame: np.ndarray
    power_spread: float
    frame_std_rad: float = 0.0

    def objects(self, powers: np.ndarray) -> np.ndarray:
        """``x`` of readings (N, n) -> (N, 3)."""
        return (powers - self.vertex_w) @ self.basis @ self.frame.T

    def map_w(self) -> np.ndarray:
        """A map ``A`` (n, 3) in the package's object space, ``p - b = A P [cos t, sin t,
        sqrt 2]``: right up to a rotation about the cone axis, a reflection and a scale."""
        return self.basis @ np.linalg.inv(self.frame) @ np.diag([1.0, 1.0, 1.0 / np.sqrt(2)])

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {
            "vertex_w": self.vertex_w.tolist(),
            "basis": self.basis.tolist(),
            "frame": self.frame.tolist(),
            "power_spread": float(self.power_spread),
            "frame_std_rad": float(self.frame_std_rad),
        }

    @classmethod
    def from_dict(cls, state, ports: int, array) -> ConeFit:
        """Inverse of :meth:`to_dict`; ``array(state, key, shape)`` reads a checked array."""
        if not isinstance(state, dict):
            raise InputError(f"a cone fit must be an object, got {type(state).__name__}")
        basis = array(state, "basis", (ports, 3))
        frame = array(state, "frame", (3, 3))
        if not np.allclose(basis.T @ basis, np.eye(3), atol=1e-9):
            raise InputError("the cone's basis must be orthonormal")
        singular = np.linalg.svd(frame, compute_uv=False)
        if not singular[-1] > 1e-12 * singular[0]:
            raise InputError("the cone's frame must be invertible")
        spread = float(array(state, "power_spread", ()))
        frame_std = float(array(state, "frame_std_rad", ()))
        return cls(array(state, "vertex_w", (ports,)), basis, frame, spread, frame_std)


def _quadratic_monomials(u: np.ndarray) -> np.ndarray:
    a, b, c = u.T
    return np.column_stack([a * a, b * b, c * c, 2 * a * b, 2 * a * c, 2 * b * c])


def _symmetric(q: np.ndarray) -> np.ndarray:
    return np.array([[q[0], q[3], q[4]], [q[3], q[1], q[5]], [q[4], q[5], q[2]]])


def _cone_frame(u: np.ndarray, power) -> tuple[np.ndarray, float]:
    """``L`` (3, 3) of the cone through points ``u`` (N, 3) in the frame of least power
    variation (or the one whose power coordinate follows ``power``)."""
    scale = np.sqrt(np.mean(u * u, axis=0).sum())
    moments = (u.T @ u) / u.shape[0] / scale**2
    eigenvalues, eigenvectors = np.linalg.eigh(moments)
    whiten = eigenvectors @ np.diag(eigenvalues**-0.5) @ eigenvectors.T / scale
    white = u @ whiten
    rays = white / np.linalg.norm(white, axis=1)[:, None]
    _, singular, right = np.linalg.svd(_quadratic_monomials(rays), full_matrices=False)
    quadric = whiten @ _symmetric(right[-1]) @ whiten  # in the coordinates u
    values, vectors = np.linalg.eigh(quadric)
    if np.sum(values > 0) == 1:
        values, vectors = -values[::-1], vectors[:, ::-1]
    if not (values[0] < 0 < values[1] <= values[2]):
        raise InputError(
            "the readings do not lie on a cone (the fitted quadric has eigenvalues "
            f"{values.tolist()}): not the readings of one interferometer over its fringes"
        )
    frame = np.sqrt(np.abs(values))[[1, 2, 0], None] * vectors[:, [1, 2, 0]].T
    objects = u @ frame.T
    if np.mean(objects[:, 2]) < 0:
        frame[2] *= -1
        objects[:, 2] *= -1
    target = np.ones(u.shape[0]) if power is None else np.asarray(power, dtype=float)
    plane = np.linalg.lstsq(objects, target, rcond=None)[0]
    normal = _ETA * plane
    norm = -(normal @ (_ETA * normal))
    if not norm > 0:
        raise InputError(
            "the readings' power cannot be separated from their phase: the best constant-"
            "power plane does not cut the cone in an ellipse (the phase covers too little of "
            "a fringe, or the power follows the phase)"
        )
    normal /= np.sqrt(norm) * np.sign(normal[2])
    gamma, beta = normal[2], normal[:2]
    boost = np.eye(3)
    if beta @ beta > 0:
        boost[:2, :2] += (gamma - 1.0) * np.outer(beta, beta) / (beta @ beta)
    boost[:2, 2] = -beta
    boost[2, :2] = -beta
    boost[2, 2] = gamma
    frame = boost @ frame
    power_coordinate = u @ frame[2]
    spread = float(np.std(power_coordinate) / np.mean(power_coordinate))
    return frame, spread


def _readings(powers) -> np.ndarray:
    array = np.asarray(powers, dtype=float)
    if array.ndim != 2 or array.shape[1] < 3 or array.shape[0] < 6:
        raise InputError(
            f"powers must have shape (samples >= 6, ports >= 3), got {array.shape}",
            parameter="powers",
        )
    if not np.all(np.isfinite(array)):
        raise InputError("powers must be finite (no NaN or inf)", parameter="powers")
    return array


def _vertex(readings: np.ndarray) -> np.ndarray:
    """The cone's vertex (n,) from a general quadric through the readings' 3-D span."""
    mean = readings.mean(axis=0)
    _, singular, right = np.linalg.svd(readings - mean, full_matrices=False)
    basis = right[:3].T
    w = (readings - mean) @ basis
    scale = np.sqrt(np.mean(w * w))
    w = w / scale
    design = np.column_stack([_quadratic_monomials(w), 2 * w, np.ones(w.shape[0])])
    q = np.linalg.svd(design, full_matrices=False)[2][-1]
    center = -np.linalg.lstsq(_symmetric(q[:6]), q[6:9], rcond=None)[0]

    def cost(v):
        rays = w - v
        rays /= np.linalg.norm(rays, axis=1)[:, None]
        return np.linalg.svd(_quadratic_monomials(rays), compute_uv=False)[-1] ** 2

    from scipy.optimize import minimize

    refined = minimize(
        cost,
        center,
        method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-16, "maxiter": 4000},
    ).x
    return mean + basis @ (refined * scale)


def fit_cone(powers, *, power=None, offsets: str = "none") -> ConeFit:
    """Fit the cone of readings without labels (module docstring).

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Readings (W or any unit linear in power), ``N >= 6``, ``n >= 3``, covering at least
        a good part of a fringe; known dark readings already subtracted.
    power : None or array_like, shape (N,)
        A power monitor's reading of each sample: fixes the frame exactly.
    offsets : {"none", "fit"}
        Detector offsets: zero, or fitted (needs a source power that varies).

    Returns
    -------
    ConeFit

    Raises
    ------
    InputError
        For readings that are not a cone's, a frame that cannot be told (power following
        the phase), or offsets that the record cannot determine.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import cone_phase_rad, fit_cone
    >>> cone = fit_cone(powers)  # the readings' cone, without their frequencies
    >>> cone.basis.shape
    (3, 3)
    >>> phase = cone_phase_rad(cone, powers)

    The cone's phase is the fringe phase up to its origin and direction: its steps
    between readings are those of the true phase:

    >>> true_step = 2 * np.pi * np.diff(f_hz) / device.true_fsr_hz
    >>> step = np.abs(wm.wrap_phase_rad(np.diff(phase)))
    >>> print(f"{np.median(step / true_step):.3f}")
    0.998
    """
    readings = _readings(powers)
    if offsets not in OFFSET_MODES:
        raise InputError(f"offsets must be one of {OFFSET_MODES}, got {offsets!r}")
    vertex = np.zeros(readings.shape[1])
    if offsets == "fit":
        vertex = _vertex(readings)
        draws = np.random.default_rng(0).integers(
            0, readings.shape[0], (BOOTSTRAP_DRAWS, readings.shape[0])
        )
        spread = np.std([_vertex(readings[rows]) for rows in draws], axis=0)
        level = np.abs(readings.mean(axis=0))
        if np.any(spread > MAX_OFFSET_SPREAD * level):
            raise InputError(
                "detector offsets cannot be told from the light in these readings (bootstrap "
                f"spread {np.max(spread / level):.2g} of a port's mean reading; the source "
                "power must vary for the cone's vertex to show): subtract dark readings "
                "measured with the source off, or take offsets as zero",
                parameter="offsets",
            )
    shifted = readings - vertex
    _, singular, right = np.linalg.svd(shifted, full_matrices=False)
    if not singular[2] > 1e-9 * singular[0]:
        raise InputError(
            "the readings span fewer than 3 dimensions (singular values "
            f"{singular[:3].tolist()}): an interferometer's readings span 3; are two port "
            "columns copies or sums of others?",
            parameter="powers",
        )
    basis = right[:3].T
    frame, spread = _cone_frame(shifted @ basis, power)
    frame_std = 0.0 if power is not None else spread * np.sqrt(2.0 / readings.shape[0])
    return ConeFit(vertex, basis, frame, spread, frame_std)


def cone_phase_rad(fit: ConeFit, powers) -> np.ndarray:
    """Phase (rad) in (-pi, pi] of readings on a fitted cone, ``atan2(x_2, x_1)``.

    Raises
    ------
    InputError
        For readings on the far side of the vertex (negative power): not this cone's.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import cone_phase_rad, fit_cone
    >>> cone = fit_cone(powers)
    >>> phase = cone_phase_rad(cone, powers[:3])
    >>> print(np.all(np.abs(phase) <= np.pi))
    True
    >>> try:
    ...     cone_phase_rad(cone, -powers[:1])  # the far side of the vertex
    ... except wm.InputError as error:
    ...     print(type(error).__name__)
    InputError
    """
    objects = fit.objects(_readings_any(powers))
    if not np.all(objects[:, 2] > 0):
        rows = np.flatnonzero(~(objects[:, 2] > 0))[:5].tolist()
        raise InputError(
            f"readings in rows {rows} (zero-based) lie on the far side of the cone's vertex: "
            "not readings of this interferometer"
        )
    return np.arctan2(objects[:, 1], objects[:, 0])


def _readings_any(powers) -> np.ndarray:
    array = np.atleast_2d(np.asarray(powers, dtype=float))
    if array.ndim != 2 or not np.all(np.isfinite(array)):
        raise InputError("powers must be finite readings of shape (N, n)")
    return array
