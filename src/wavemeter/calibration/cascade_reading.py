"""What a cascade read, stage by stage, and the readings' own noise.

:class:`CascadeReading` holds every stage's frequency, uncertainty and order probability
for a batch of readings (:meth:`~wavemeter.calibration.cascade.CascadeCalibrator.read`);
:func:`noise_scale` tells from the readings' distances to each stage's cone whether they
carry more detector noise than the calibration sweep did.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from ..model.orders import any_error_probability

__all__ = ["CascadeReading", "NOISE_P_VALUE", "chi2_median", "noise_scale"]

#: readings of one call whose cone distances exceed the calibrated noise at this p-value
#: carry a noise of their own, which scales their uncertainties (:func:`noise_scale`)
NOISE_P_VALUE = 1e-6


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


def chi2_median(free: int, noise_dof: float) -> float:
    """The median of a cone distance under the calibrated noise: ``free F(free, noise_dof)``
    (``free = n - 2`` degrees of freedom, the noise estimated on ``noise_dof``)."""
    return free * float(stats.f.median(free, noise_dof))


def noise_scale(distance: np.ndarray, reference_median: float, noise_median: float) -> float:
    """The readings' detector noise over the calibration sweep's, from their cone distances.

    Under the sweep's conditions a reading's distance exceeds the sweep's median distance
    ``reference_median`` with probability 1/2. When more of the readings do than that
    allows at ``NOISE_P_VALUE`` (binomial), they carry more noise. A distance is the
    noise's part (median ``noise_median`` at the calibrated noise, :func:`chi2_median`)
    plus what the model misses (``reference_median - noise_median`` on the sweep, which the
    noise does not change), so the scale is ``sqrt(1 + (median(distance) -
    reference_median) / noise_median)``. Medians keep a few glitches from scaling every
    reading; a single reading is never scaled (a far one is ``OFF_MODEL`` instead).
    """
    above = int(np.count_nonzero(distance > reference_median))
    if stats.binom.sf(above - 1, distance.size, 0.5) >= NOISE_P_VALUE:
        return 1.0
    excess = (float(np.median(distance)) - reference_median) / noise_median
    return math.sqrt(1.0 + max(excess, 0.0))
