"""The residual a calibration sweep's readings share at their phase, learned for ``OFF_MODEL``.

Where the sweep's distances to the cone show a model error, part of each reading's residual
(its offset from the cone at its retrieved phase ``t``, the source power ``P`` fitted there)
repeats from reading to reading: ``r = P g(t, p) + rest``, with ``g`` per port a Fourier
series of ``harmonics`` in ``t`` times a polynomial of ``power_degree`` in the normalised
source power ``p``. :func:`learn_residual` chooses both orders by 5-fold cross-validation
(one-standard-error rule) and fits ``g`` by least squares trimmed of the worst
``1 - TRIM_KEEP`` of the readings; :meth:`ResidualModel.distance` subtracts ``g`` from a
reading's residual and takes the weighted squared length of the part off the cone. Where
what remains still exceeds the detector noise, :func:`learn_spread` gives the log of its
level as a Fourier series in ``t``. Theory: the docs' diagnostics page (``OFF_MODEL`` when
the model does not hold).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...exceptions import InputError, shown
from ...model.cone import cone_vectors
from ...model.retrieval import source_power_ratio

__all__ = [
    "CV_FOLDS",
    "MAX_HARMONICS",
    "MAX_POWER_DEGREE",
    "MAX_SPREAD_HARMONICS",
    "TRIM_KEEP",
    "ResidualModel",
    "fourier_columns",
    "learn_residual",
    "learn_spread",
]

#: most harmonics of the phase the residual and its spread may take
MAX_HARMONICS = 12
MAX_SPREAD_HARMONICS = 8
#: highest power of the normalised source power in the residual
MAX_POWER_DEGREE = 2
#: cross-validation folds (reading ``i`` is in fold ``i mod CV_FOLDS``)
CV_FOLDS = 5
#: share of the sweep's readings the trimmed fits keep (robust to the rest being outliers)
TRIM_KEEP = 0.99
#: a model may have at most this share of its training readings as coefficients per port
MAX_COEFFICIENT_SHARE = 0.05
#: concentration steps of the trimmed least squares
TRIM_STEPS = 3


def fourier_columns(phase_rad, harmonics: int) -> np.ndarray:
    """``[1, cos t, sin t, ..., cos Kt, sin Kt]`` (N, 2K + 1) of phases (rad)."""
    t = np.asarray(phase_rad, dtype=float)
    columns = np.empty((t.size, 2 * harmonics + 1))
    columns[:, 0] = 1.0
    for k in range(1, harmonics + 1):
        np.cos(k * t, out=columns[:, 2 * k - 1])
        np.sin(k * t, out=columns[:, 2 * k])
    return columns


class ConeParts(NamedTuple):
    """A reading's fit to the cone at a given phase: source power ratio (N,), residual (N, n)
    in W, and an orthonormal basis (two (N, n) arrays) of the cone's tangent there in the
    noise-weighted metric (the directions of a change of power and of phase)."""

    power: np.ndarray
    residual_w: np.ndarray
    tangent: tuple[np.ndarray, np.ndarray]


def cone_parts(readings, maps, phase_rad, noise_std_w) -> ConeParts:
    """:class:`ConeParts` of offset-corrected readings (N, n) at ``phase_rad`` (N,), under
    one map (n, 3) or one per reading (N, n, 3), with the port noise (n,) in W."""
    t = np.asarray(phase_rad, dtype=float)
    slope = np.zeros((t.size, 3))
    slope[:, 0], slope[:, 1] = -np.sin(t), np.cos(t)
    if maps.ndim == 2:
        image, along = cone_vectors(t) @ maps.T, slope @ maps.T
    else:
        image = np.einsum("knc,kc->kn", maps, cone_vectors(t))
        along = np.einsum("knc,kc->kn", maps, slope)
    power = source_power_ratio(readings, maps, t, noise_std_w)
    first = image / noise_std_w
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = along / noise_std_w
    second -= np.einsum("ij,ij->i", second, first)[:, None] * first
    second /= np.linalg.norm(second, axis=1, keepdims=True)
    return ConeParts(power, readings - power[:, None] * image, (first, second))


def _off_cone(weighted: np.ndarray, tangent) -> np.ndarray:
    """The part (N, n) of noise-weighted vectors off the cone (orthogonal to ``tangent``)."""
    first, second = tangent
    along = np.einsum("ij,ij->i", weighted, first)[:, None] * first
    return weighted - along - np.einsum("ij,ij->i", weighted, second)[:, None] * second


class ResidualModel(NamedTuple):
    """What the sweep's readings share off the cone, and the level of what remains.

    Plain numbers (a named tuple), as learned attributes are.

    Attributes
    ----------
    harmonics : int
        Harmonics ``K`` of the phase in the residual (-1: none subtracted).
    power_degree : int
        Degree of the polynomial in the normalised source power ``p``.
    power_range : tuple of float
        The source power ratios mapped to ``p = -1`` and ``p = 1`` (the sweep's 1st and
        99th percentiles); ``p`` is clipped to ``[-1, 1]`` beyond them.
    coefficients_w : tuple of tuple of float
        ``(K + 1 + K) (degree + 1)`` rows (the Fourier columns times ``p^0``, then ``p^1``,
        ...) of ``n`` values (W per unit source power ratio).
    readings : int
        Sweep readings it was learned from (every k-th of a long sweep).
    median : float
        Median cross-validated distance that remains (unitless).
    spread_coefficients : tuple of float
        ``[0, a_1, b_1, ..., a_L, b_L]``: the log of the remaining distances' level is
        ``sum_k a_k cos kt + b_k sin kt`` (zero mean over the phase); empty when the
        remainder is like the detector noise.
    """

    harmonics: int
    power_degree: int
    power_range: tuple[float, float]
    coefficients_w: tuple[tuple[float, ...], ...]
    readings: int
    median: float
    spread_coefficients: tuple[float, ...]

    def _design(self, phase_rad, power) -> np.ndarray:
        fourier = fourier_columns(phase_rad, self.harmonics)
        return _with_power(fourier, _normalised(power, self.power_range), self.power_degree)

    def distance(self, readings, maps, phase_rad, noise_std_w) -> np.ndarray:
        """Weighted squared distance (N,) of offset-corrected readings to the cone at
        ``phase_rad`` less the learned residual (the part off the cone), unitless."""
        parts = cone_parts(readings, maps, phase_rad, noise_std_w)
        return self._remaining(parts, phase_rad, noise_std_w)

    def _remaining(self, parts: ConeParts, phase_rad, noise_std_w) -> np.ndarray:
        residual = parts.residual_w
        if self.harmonics >= 0:
            coefficients = np.asarray(self.coefficients_w, dtype=float)
            shared = parts.power[:, None] * (self._design(phase_rad, parts.power) @ coefficients)
            residual = residual - shared
        off = _off_cone(residual / noise_std_w, parts.tangent)
        return np.einsum("ij,ij->i", off, off)

    def spread(self, phase_rad) -> np.ndarray | float:
        """Log (N,) of the remaining distances' level at ``phase_rad`` relative to its mean
        over the phase; 0 when the remainder is like the noise."""
        if not self.spread_coefficients:
            return 0.0
        harmonics = (len(self.spread_coefficients) - 1) // 2
        return fourier_columns(phase_rad, harmonics) @ np.asarray(self.spread_coefficients)

    @property
    def spread_harmonics(self) -> int | None:
        """Harmonics of the spread; None when the remainder is like the noise."""
        return (len(self.spread_coefficients) - 1) // 2 if self.spread_coefficients else None

    def to_dict(self) -> dict:
        """The record a calibration file keeps."""
        return {
            "harmonics": self.harmonics,
            "power_degree": self.power_degree,
            "power_range": list(self.power_range),
            "coefficients_w": [list(row) for row in self.coefficients_w],
            "readings": self.readings,
            "median": self.median,
            "spread_coefficients": list(self.spread_coefficients),
        }


def _normalised(power, power_range) -> np.ndarray:
    """Source power ratios mapped to ``[-1, 1]`` over ``power_range`` (clipped beyond)."""
    low, high = power_range
    if high <= low:
        return np.zeros(np.shape(power))
    return np.clip(2.0 * (np.asarray(power) - low) / (high - low) - 1.0, -1.0, 1.0)


def _with_power(fourier: np.ndarray, power: np.ndarray, degree: int) -> np.ndarray:
    """The Fourier columns times ``p^0 .. p^degree`` side by side."""
    return np.hstack([fourier * (power**j)[:, None] for j in range(degree + 1)])


def _columns(harmonics: int, degree: int) -> np.ndarray:
    """Indices of a model's columns in the design of every model (``MAX_HARMONICS``
    Fourier columns per power of ``p``)."""
    width = 2 * MAX_HARMONICS + 1
    return np.concatenate([j * width + np.arange(2 * harmonics + 1) for j in range(degree + 1)])


def _cv_scores(design, targets, score, keep, models):
    """Mean and standard error of the held-out score of each model over the kept readings.

    ``design`` (N, q) holds every model's columns, ``targets`` (N, m); a model is its column
    indices (empty: nothing fitted, ``score`` of zero predictions). ``score(rows,
    prediction)`` gives the held-out readings' losses (len(rows),).
    """
    fold = np.arange(design.shape[0]) % CV_FOLDS
    losses = np.empty((len(models), design.shape[0]))
    for number in range(CV_FOLDS):
        train, test = (fold != number) & keep, np.flatnonzero(fold == number)
        gram = design[train].T @ design[train]
        moment = design[train].T @ targets[train]
        for index, columns in enumerate(models):
            if columns.size == 0:
                prediction = np.zeros((test.size, targets.shape[1]))
            else:
                solution = np.linalg.lstsq(
                    gram[np.ix_(columns, columns)], moment[columns], rcond=None
                )[0]
                prediction = design[np.ix_(test, columns)] @ solution
            losses[index, test] = score(test, prediction)
    kept = losses[:, keep]
    return kept.mean(axis=1), kept.std(axis=1) / math.sqrt(kept.shape[1]), losses


def _one_standard_error(sizes, means, errors) -> int:
    """The model with fewest coefficients whose score is within one standard error of the
    best's (ties: the better score)."""
    best = int(np.argmin(means))
    within = [i for i in range(len(means)) if means[i] <= means[best] + errors[best]]
    return min(within, key=lambda i: (sizes[i], means[i]))


def learn_residual(readings, maps, phase_rad, noise_std_w) -> tuple[ResidualModel, np.ndarray]:
    """The residual the sweep's readings share at their phase and source power.

    Parameters
    ----------
    readings : ndarray, shape (N, n)
        Offset-corrected sweep readings (W).
    maps : ndarray, shape (n, 3) or (N, n, 3)
        The calibrated map, or each reading's.
    phase_rad : ndarray, shape (N,)
        Each reading's retrieved phase (rad), by the calibration's own retrieval.
    noise_std_w : ndarray, shape (n,)
        The calibrated port noise (W).

    Returns
    -------
    model : ResidualModel
        Without a spread (:func:`learn_spread` adds it).
    distance : ndarray, shape (N,)
        Each reading's remaining distance, cross-validated: under the model fitted to the
        other folds (unitless).
    """
    parts = cone_parts(readings, maps, phase_rad, noise_std_w)
    samples = phase_rad.size
    low, high = (float(v) for v in np.quantile(parts.power, [0.01, 0.99]))
    degrees = MAX_POWER_DEGREE if high > low else 0
    power = _normalised(parts.power, (low, high))
    design = _with_power(fourier_columns(phase_rad, MAX_HARMONICS), power, degrees)
    targets = parts.residual_w / parts.power[:, None]
    largest = MAX_COEFFICIENT_SHARE * samples * (CV_FOLDS - 1) / CV_FOLDS
    models = [(-1, 0)] + [
        (k, j)
        for j in range(degrees + 1)
        for k in range(MAX_HARMONICS + 1)
        if (2 * k + 1) * (j + 1) <= largest
    ]
    columns = [np.array([], dtype=int) if k < 0 else _columns(k, j) for k, j in models]

    def remaining(rows, prediction):
        shared = parts.power[rows, None] * prediction
        off = _off_cone(
            (parts.residual_w[rows] - shared) / noise_std_w,
            (parts.tangent[0][rows], parts.tangent[1][rows]),
        )
        return np.einsum("ij,ij->i", off, off)

    keep = np.ones(samples, dtype=bool)
    if len(models) > 1:  # trimmed by the largest model's fit
        keep = _trimmed(design[:, columns[-1]], targets, remaining, keep)
    means, errors, losses = _cv_scores(design, targets, remaining, keep, columns)
    chosen = _one_standard_error([c.size for c in columns], means, errors)
    harmonics, degree = models[chosen]
    if harmonics < 0:
        coefficients = ()
    else:
        chosen_design = design[:, columns[chosen]]
        keep = _trimmed(chosen_design, targets, remaining, keep)
        solution = np.linalg.lstsq(chosen_design[keep], targets[keep], rcond=None)[0]
        coefficients = tuple(tuple(float(v) for v in row) for row in solution)
    distance = losses[chosen]
    model = ResidualModel(
        harmonics, degree, (low, high), coefficients, samples, float(np.median(distance)), ()
    )
    return model, distance


def _trimmed(design, targets, remaining, keep) -> np.ndarray:
    """The readings a least-squares fit keeps after ``TRIM_STEPS`` concentration steps, each
    refitted on the ``TRIM_KEEP`` share nearest the last fit (from ``keep``)."""
    rows = np.arange(design.shape[0])
    for _ in range(TRIM_STEPS):
        solution = np.linalg.lstsq(design[keep], targets[keep], rcond=None)[0]
        distance = remaining(rows, design @ solution)
        keep = distance <= np.quantile(distance, TRIM_KEEP)
    return keep


def learn_spread(phase_rad, distance, noise_median: float) -> tuple[float, ...]:
    """Coefficients of the log level of remaining distances (N,) as a Fourier series in the
    phase (rad): ``log(distance + noise_median)`` fitted by least squares on the readings
    below the ``TRIM_KEEP`` quantile, its harmonics (up to ``MAX_SPREAD_HARMONICS``) chosen
    by cross-validation, its constant set to zero (:attr:`ResidualModel.spread_coefficients`)."""
    keep = distance <= np.quantile(distance, TRIM_KEEP)
    level = np.log(distance + noise_median)[:, None]
    design = fourier_columns(phase_rad, MAX_SPREAD_HARMONICS)
    largest = MAX_COEFFICIENT_SHARE * phase_rad.size * (CV_FOLDS - 1) / CV_FOLDS
    orders = [k for k in range(MAX_SPREAD_HARMONICS + 1) if 2 * k + 1 <= largest]
    columns = [np.arange(2 * k + 1) for k in orders]

    def squared_error(rows, prediction):
        return (level[rows, 0] - prediction[:, 0]) ** 2

    means, errors, _ = _cv_scores(design, level, squared_error, keep, columns)
    harmonics = orders[_one_standard_error([c.size for c in columns], means, errors)]
    fit = np.linalg.lstsq(design[keep, : 2 * harmonics + 1], level[keep], rcond=None)[0][:, 0]
    return (0.0, *(float(v) for v in fit[1:]))


def residual_from_record(record, ports: int, key: str) -> ResidualModel:
    """A :class:`ResidualModel` from a calibration file's record, checked; ``key`` names it
    in messages."""
    if not isinstance(record, dict):
        raise InputError(f"field {key!r} must be an object, got {type(record).__name__}")

    def field(name: str):
        if name not in record:
            raise InputError(f"field '{key}.{name}' is missing")
        return record[name]

    def integer(name: str, low: int, high: int) -> int:
        value = field(name)
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise InputError(
                f"field '{key}.{name}' must be an integer {low} to {high}, got {shown(value)}"
            )
        return value

    def numbers(name: str, shape: tuple) -> np.ndarray:
        try:
            array = np.asarray(field(name), dtype=float)
        except (TypeError, ValueError):
            array = np.array([np.nan])
        if array.shape != shape or not np.all(np.isfinite(array)):
            raise InputError(
                f"field '{key}.{name}' must hold {' x '.join(map(str, shape)) or 'one'} "
                f"finite numbers, got {shown(field(name))[:80]}"
            )
        return array

    harmonics = integer("harmonics", -1, MAX_HARMONICS)
    degree = integer("power_degree", 0, MAX_POWER_DEGREE)
    low, high = numbers("power_range", (2,))
    if not 0 < low <= high:
        raise InputError(
            f"field '{key}.power_range' must be 0 < low <= high, got {shown((low, high))}"
        )
    rows = 0 if harmonics < 0 else (2 * harmonics + 1) * (degree + 1)
    coefficients = numbers("coefficients_w", (rows, ports) if rows else (0,))
    readings = integer("readings", 1, 2**62)
    median = float(numbers("median", ()))
    if median < 0:
        raise InputError(f"field '{key}.median' must be >= 0, got {shown(median)}")
    given = field("spread_coefficients")
    spread = numbers("spread_coefficients", (len(given) if isinstance(given, list) else -1,))
    if spread.size and (spread.size % 2 == 0 or spread[0] != 0.0):
        raise InputError(
            f"field '{key}.spread_coefficients' must be [0, a_1, b_1, ...] (odd length), "
            f"got {spread.size} numbers"
        )
    return ResidualModel(
        harmonics,
        degree,
        (float(low), float(high)),
        tuple(tuple(float(v) for v in row) for row in coefficients.reshape(rows, ports)),
        readings,
        median,
        tuple(float(v) for v in spread),
    )
