"""What a cascade read, stage by stage, and the readings' own noise.

:class:`CascadeReading` holds every stage's frequency, uncertainty and order probability
for a batch of readings (:meth:`~wavemeter.calibration.methods.cascade.CascadeCalibrator.read`);
:func:`noise_scale` tells from the readings' distances to each stage's cone whether they
carry more detector noise than the calibration sweep did. :class:`StageReader` reads a
single reading through one stage, for a live stream.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy import stats

from ...model.orders import any_error_probability
from ...model.uncertainty import student_factor
from ..contract.flags import off_model_threshold
from ..contract.off_model import chi2_median
from ..contract.streaming import SCREEN_MARGIN
from ..models.band_reading import band_cone_distance
from ..models.wideband_fit import NEWTON_STEPS, PREDICT_ITERATIONS

__all__ = [
    "CascadeReading",
    "MIN_SCALED_READINGS",
    "NOISE_P_VALUE",
    "StageReader",
    "chi2_median",
    "distance_in_noise",
    "noise_scale",
]

#: readings of one call whose cone distances exceed the calibrated noise at this p-value
#: carry a noise of their own, which scales their uncertainties (:func:`noise_scale`)
NOISE_P_VALUE = 1e-6
#: fewest readings whose distances can show a noise of their own: with fewer, even all of
#: them above the sweep's median is likelier than ``NOISE_P_VALUE`` (``0.5**n``)
MIN_SCALED_READINGS = math.ceil(-math.log2(NOISE_P_VALUE))


@dataclasses.dataclass(frozen=True)
class CascadeReading:
    """What the cascade found for each of ``N`` readings, stage by stage (coarsest first).

    Attributes
    ----------
    frequency_hz, std_hz : ndarray, shape (K, N)
        Each stage's frequency (Hz) at the order it took and its standard deviation (Hz).
    phase_rad : ndarray, shape (K, N)
        Each stage's retrieved phase (rad).
    maps : list of ndarray, shape (N, n_k, 3)
        Each stage's map at its frequency.
    error_probability : ndarray, shape (K, N)
        Probability that stage ``k`` took a wrong order: the coarsest stage's edge
        probability, then each hand-over's posterior.
    disagreement_std : ndarray, shape (K - 1, N)
        Each hand-over's residual in its standard deviations.
    cone_distance : ndarray, shape (K, N)
        Each stage's weighted squared distance of the reading to its cone, in the noise
        of the readings (``noise_scale``).
    noise_scale : ndarray, shape (K,)
        Each stage's detector noise in these readings over the calibrated one
        (:func:`noise_scale`: 1 unless their cone distances show more noise). Every
        uncertainty above is in that noise.
    flags : None or ndarray of int64, shape (N,)
        The quality mask :meth:`CascadeCalibrator.flags` gives (from
        :meth:`CascadeCalibrator.read`).
    """

    frequency_hz: np.ndarray
    std_hz: np.ndarray
    phase_rad: np.ndarray
    maps: list
    error_probability: np.ndarray
    disagreement_std: np.ndarray
    cone_distance: np.ndarray
    noise_scale: np.ndarray
    flags: np.ndarray | None = None

    @property
    def order_error_probability(self) -> np.ndarray:
        """Probability (per reading) that some stage took a wrong order."""
        return any_error_probability(self.error_probability)


def noise_scale(distance: np.ndarray, reference_median: float, noise_median: float) -> float:
    """The readings' detector noise over the calibration sweep's, from their cone distances.

    Under the sweep's conditions a reading's distance exceeds the sweep's median distance
    ``reference_median`` with probability 1/2. When more of the readings do than that
    allows at ``NOISE_P_VALUE`` (binomial), they carry more noise. A distance is the
    noise's part (median ``noise_median`` at the calibrated noise, :func:`chi2_median`)
    plus what the model misses (``reference_median - noise_median`` on the sweep, which the
    noise does not change), so the scale is ``sqrt(1 + (median(distance) -
    reference_median) / noise_median)``. Medians keep a few glitches from scaling every
    reading; a single reading is never scaled (a far one is ``OFF_MODEL`` instead), nor
    are fewer than ``MIN_SCALED_READINGS``.
    """
    if distance.size < MIN_SCALED_READINGS:
        return 1.0
    above = int(np.count_nonzero(distance > reference_median))
    if stats.binom.sf(above - 1, distance.size, 0.5) >= NOISE_P_VALUE:
        return 1.0
    excess = (float(np.median(distance)) - reference_median) / noise_median
    return math.sqrt(1.0 + max(excess, 0.0))


def distance_in_noise(distance, reference_median: float, noise_median: float, scale: float):
    """Cone distances in the noise of the readings (``scale`` times the calibrated one),
    beside what the model missed on the sweep (``reference_median - noise_median``, which
    the noise does not change): what ``OFF_MODEL`` tests (:func:`noise_scale`)."""
    missed = max(reference_median - noise_median, 0.0)
    return distance * (noise_median / (scale**2 * noise_median + missed))


def _polynomial(y: float, coefficients: list[float]) -> float:
    """``sum_i c_i y^i`` by Horner's rule, in the order ``numpy.polynomial.polyval`` takes."""
    value = coefficients[-1] + y * 0.0
    for coefficient in coefficients[-2::-1]:
        value = coefficient + value * y
    return value


class StageReader:
    """One reading through one stage of a cascade in one light pass (pseudo-inverse
    retrieval), for a live stream.

    The steps :func:`~wavemeter.calibration.models.wideband_fit.band_frequency_hz`, the stage's
    ``_frequency_std_of`` and :func:`~wavemeter.calibration.models.band_reading.band_cone_distance`
    take for a batch, for a single reading: the phase polynomial and the Legendre basis
    evaluated as numpy's ``polyval`` and ``legvander`` do, the map's pseudo-inverse solved
    as :func:`~wavemeter.model.retrieval.stacked_pinv` solves it, the variance of
    :func:`~wavemeter.calibration.models.band_reading.band_frequency_variance_hz2`, on numbers
    and short vectors instead of arrays of readings, whose per-call costs rule at one
    reading (about 60 us a stage, against 600 us through those functions). What the stage
    fixes (its model, noise, covariance, thresholds) is taken once. The frequency and its
    standard deviation are theirs to rounding (~1e-14 relative).

    A reading alone carries no noise of its own (:data:`MIN_SCALED_READINGS`). Its distance
    to the cone matters only against the ``OFF_MODEL`` threshold: the distance at the
    retrieved phase (source power fitted) bounds the one at the maximum-likelihood phase
    from above, so where it lies below the threshold by more than
    :data:`~wavemeter.calibration.contract.base.SCREEN_MARGIN` (relative) the distance is not worked
    out (NaN); else it is, as ``band_cone_distance`` gives it.

    Parameters
    ----------
    stage : WidebandCalibrator
        A fitted stage (pseudo-inverse retrieval).
    model_error_hz : float
        What the stage's frequency missed on the sweep beyond its uncertainty (Hz).
    reference_median : float
        The sweep's median cone distance on the stage.
    """

    def __init__(self, stage, model_error_hz: float, reference_median: float):
        model = stage.band_model_
        coefficients = model.phase_coefficients_rad
        self.center_hz, self.half_span_hz = model.center_hz, model.half_span_hz
        self.orders = np.arange(1, coefficients.size + 1)
        self.phase_coefficients = [0.0, *coefficients.tolist()]
        self.slope_coefficients = (self.orders * coefficients).tolist()
        legendre = model.map_coefficients_w
        self.map_order, self.ports = legendre.shape[0] - 1, legendre.shape[1]
        self.map_coefficients = legendre.reshape(legendre.shape[0], -1)
        self.noise_std_w = stage.port_noise_std_w_
        self.noise_w2 = self.noise_std_w**2
        self.covariance = stage.parameter_covariance_
        self.affine = stage._affine()
        dof = stage.noise_dof_
        self.student = student_factor(dof) if dof > 2 else math.inf
        self.model_error_hz = float(model_error_hz)
        self.in_noise = functools.partial(
            distance_in_noise,
            reference_median=float(reference_median),
            noise_median=chi2_median(self.ports - 2, dof),
            scale=1.0,
        )
        self.on_model = off_model_threshold(self.ports, dof) * (1.0 - SCREEN_MARGIN)

    def _basis(self, y: float) -> np.ndarray:
        """Legendre polynomials ``L_0 .. L_J`` at ``y`` (forward recursion, as legvander)."""
        basis = [1.0, y]
        for order in range(2, self.map_order + 1):
            basis.append(
                (basis[order - 1] * y * (2 * order - 1) - basis[order - 2] * (order - 1)) / order
            )
        return np.array(basis[: self.map_order + 1])

    def read(self, rows: np.ndarray, coarse_hz: float) -> tuple:
        """The stage's reading of offset-corrected port readings ``rows`` (n,) (W) at the
        fringe order nearest ``coarse_hz`` (Hz).

        Returns
        -------
        frequency_hz, std_hz, phase_rad : float
            As the stage's batch functions give them (``std_hz`` with the model error).
        map_w : ndarray, shape (n, 3)
            The map the phase was retrieved with (W).
        cone_distance : float
            In the readings' noise; NaN where its bound shows it below the ``OFF_MODEL``
            threshold.
        """
        center, half = self.center_hz, self.half_span_hz
        phase_coefficients, slope_coefficients = self.phase_coefficients, self.slope_coefficients
        reference = _polynomial((coarse_hz - center) / half, phase_coefficients)
        frequency = coarse_hz
        for _ in range(PREDICT_ITERATIONS):
            y = (frequency - center) / half
            map_w = (self._basis(y) @ self.map_coefficients).reshape(self.ports, 3)
            inverse = np.linalg.solve(map_w.T @ map_w, map_w.T)
            x_1, x_2 = float(inverse[0] @ rows), float(inverse[1] @ rows)
            phase = math.atan2(x_2, x_1)
            target = reference + ((phase - reference + math.pi) % (2.0 * math.pi) - math.pi)
            for _ in range(NEWTON_STEPS):
                step = _polynomial(y, phase_coefficients) - target
                y = y - step / _polynomial(y, slope_coefficients)
            frequency = center + y * half
        # the variance of band_frequency_variance_hz2 at the frequency read
        gradient = (x_1 * inverse[1] - x_2 * inverse[0]) / (x_1**2 + x_2**2)
        y = (frequency - center) / half
        per_rad = 1.0 / (_polynomial(y, slope_coefficients) / half)
        variance = (math.sqrt(float(np.square(gradient * self.noise_std_w).sum())) * per_rad) ** 2
        cone = np.array([math.cos(phase), math.sin(phase), math.sqrt(2.0)])
        image = map_w @ cone
        weighted = (map_w / self.noise_w2[:, None]) @ cone
        power = float(weighted @ rows) / float(weighted @ image)
        objects = (self._basis(y)[:, None] * (power * cone)[None, :]).ravel()
        if self.affine:
            objects = np.append(objects, 1.0)
        along = np.concatenate(
            [-(gradient[:, None] * objects[None, :]).ravel() * per_rad, -(y**self.orders) * per_rad]
        )
        variance += float(along @ self.covariance @ along)
        std = math.hypot(math.sqrt(variance) * self.student, self.model_error_hz)
        residual = (rows - power * image) / self.noise_std_w
        distance = math.nan
        if self.in_noise(float(residual @ residual)) > self.on_model:
            exact = band_cone_distance(rows[np.newaxis], map_w[np.newaxis], self.noise_std_w)
            distance = float(self.in_noise(exact[0]))
        return frequency, std, phase, map_w, distance
