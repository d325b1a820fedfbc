"""The tests a calibration residual is put to, and the statistics the misfit report gives.

On the residual of a fitted sweep (whitened by the noise), with the fit's directions
projected out (:mod:`wavemeter.stats`): nested discrete cosines of the row along each
reading's image ``a_P`` (power drift) and fringe tangent ``a_t`` (phase drift), even
Legendre polynomials of the frequency along ``a_t`` (dispersion), harmonics 2 and 3 of the
fringe phase and cosines of the row on every port (other structure) (:func:`structure_tests`),
and the scatter of each reading along ``a_P`` and ``a_t`` against the rest
(:func:`scatter_tests`); also the per-reading directions themselves, the effective span in
FSRs, the lag-1 autocorrelation and the pseudo-inverse's phase variance over the bound. The
theory is in ``docs/theory/diagnostics.rst``; the report that runs these is
:func:`~wavemeter.calibration.checks.misfit.misfit_report`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import linalg, special, stats

from ...model.retrieval import stacked_pinv
from ...stats.blocks import row_blocks
from ...stats.cosine_transform import discrete_cosines
from ...stats.nested_tests import TEST_P_VALUE, ResidualTest

__all__ = [
    "HARMONICS",
    "SMOOTH_ORDERS",
    "MAX_COUPLED_ORDER",
    "DISPERSION_MIN_SPAN_FSR",
    "images",
    "tangents",
    "harmonic_columns",
    "span_fsr",
    "lag1_autocorrelation",
    "pinv_variance_ratio",
    "Scatter",
    "scatter_tests",
    "Structure",
    "structure_tests",
    "smooth_scales",
    "axis_phase_columns",
    "off_axis_phase",
    "rms",
]

#: numbers of discrete cosines of the row index tested as "smooth in time"
SMOOTH_ORDERS = (3, 6, 12, 24, 48, 96, 192)
#: the largest of them for a drift of power or phase (their columns couple the ports)
MAX_COUPLED_ORDER = 96
#: dispersion is told from a phase drift only on sweeps longer than this (FSRs)
DISPERSION_MIN_SPAN_FSR = 1.5
#: harmonics of the fringe phase tested for a fringe that is not a sinusoid
HARMONICS = (2, 3)


def images(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``A x_k`` (N, n) of vectors (N, 3) through one map (n, 3) or each reading's (N, n, 3)."""
    if matrix.ndim == 2:
        return vectors @ matrix.T
    return np.einsum("kij,kj->ki", matrix, vectors)


def tangents(matrix: np.ndarray, unit: np.ndarray, power) -> np.ndarray:
    """Fringe tangents ``m_k A [-sin t_k, cos t_k, 0]`` (N, n) from the unit objects (N, 3)
    ``[cos t_k, sin t_k, sqrt 2]`` and the relative power ``m_k`` (None: 1)."""
    if matrix.ndim == 2:
        tangent = unit[:, :2] @ np.array([matrix[:, 1], -matrix[:, 0]])
    else:
        tangent = matrix[:, :, 1] * unit[:, :1]
        tangent -= matrix[:, :, 0] * unit[:, 1:2]
    if power is not None:
        tangent *= power[:, None]
    return tangent


def harmonic_columns(unit: np.ndarray, power, rows: slice) -> np.ndarray:
    """``m_k cos h t_k``, ``m_k sin h t_k`` for each order ``h`` of ``HARMONICS`` (L, 2 H) of
    the readings ``rows``, by angle addition from the unit objects' ``cos t_k``, ``sin t_k``."""
    unit = unit[rows]
    power = None if power is None else power[rows]
    cos, sin = unit[:, 0], unit[:, 1]
    columns = np.empty((unit.shape[0], 2 * len(HARMONICS)))
    harmonic_cos, harmonic_sin = cos, sin
    for order in range(2, max(HARMONICS) + 1):
        harmonic_cos, harmonic_sin = (
            harmonic_cos * cos - harmonic_sin * sin,
            harmonic_sin * cos + harmonic_cos * sin,
        )
        if order in HARMONICS:
            index = 2 * HARMONICS.index(order)
            columns[:, index], columns[:, index + 1] = harmonic_cos, harmonic_sin
    if power is not None:
        columns *= power[:, None]
    return columns


def span_fsr(phase_rad: np.ndarray) -> float:
    steps = np.diff(phase_rad)
    if np.all(steps >= 0.0) or np.all(steps <= 0.0):
        # a one-way sweep: its distinct phases without sorting
        distinct = 1 + np.count_nonzero(steps)
        extent = abs(float(phase_rad[-1] - phase_rad[0]))
    else:
        values = np.unique(phase_rad)
        distinct, extent = values.size, float(values[-1] - values[0])
    if distinct < 2:
        return 0.0
    return (extent + extent / (distinct - 1)) / (2.0 * np.pi)


def lag1_autocorrelation(residual: np.ndarray, energy: np.ndarray) -> np.ndarray:
    """Lag-1 autocorrelation per port of the residual (N, n); ``energy`` (n,) its sums of
    squares."""
    lagged = np.einsum("ij,ij->j", residual[1:], residual[:-1])
    return np.divide(lagged, energy, out=np.zeros_like(energy), where=energy > 0)


def pinv_variance_ratio(matrix, image, tangent) -> float:
    """Mean pseudo-inverse phase variance over the mean Cramer-Rao variance, unit noise, for
    one map (n, 3) or each reading's (N, n, 3), at the readings' images ``a_P`` and fringe
    tangents ``a_t`` (N, n) (their inverses from the normal equations, several times
    faster than SVDs: a stack with a map of rank < 3 raises InputError).

    With ``x = A+ a_P`` and ``A+`` rows ``g_1``, ``g_2``, the arctangent's gradient is
    ``(x_1 g_2 - x_2 g_1) / r^2`` (:func:`~wavemeter.model.uncertainty.pinv_phase_gradient`,
    ``r^2 = x_1^2 + x_2^2``), of squared norm ``(x_1^2 |g_2|^2 - 2 x_1 x_2 g_1 g_2 + x_2^2
    |g_1|^2) / r^4``; the bound's information is ``|a_t|^2 - (a_t a_P)^2 / |a_P|^2``
    (:func:`~wavemeter.model.limits.crlb_frequency_std`, the power a nuisance)."""
    inverse = linalg.pinv(matrix) if matrix.ndim == 2 else stacked_pinv(matrix)
    first, second = inverse[..., 0, :], inverse[..., 1, :]
    pinv_variance = bound_variance = 0.0
    for rows in row_blocks(image.shape[0]):
        images, tangents = image[rows], tangent[rows]
        # ports x readings: the sums over the ports run down contiguous readings
        image_rows, tangent_rows = np.ascontiguousarray(images.T), np.ascontiguousarray(tangents.T)
        if matrix.ndim == 2:
            x_1, x_2 = images @ first, images @ second
            gram = first @ first, first @ second, second @ second
        else:
            rows_1, rows_2 = first[rows], second[rows]
            x_1, x_2 = np.einsum("ij,ij->i", images, rows_1), np.einsum("ij,ij->i", images, rows_2)
            gram = [np.einsum("ij,ij->i", *pair) for pair in ((rows_1, rows_1), (rows_1, rows_2))]
            gram.append(np.einsum("ij,ij->i", rows_2, rows_2))
        radius2 = x_1**2 + x_2**2
        variance = x_1**2 * gram[2] - 2.0 * x_1 * x_2 * gram[1] + x_2**2 * gram[0]
        pinv_variance += float(np.sum(variance / radius2**2))
        along = np.einsum("ij,ij->j", image_rows, tangent_rows)
        information = np.einsum("ij,ij->j", tangent_rows, tangent_rows) - along**2 / np.einsum(
            "ij,ij->j", image_rows, image_rows
        )
        bound_variance += float(np.sum(1.0 / information))
    return pinv_variance / bound_variance


@dataclass(frozen=True)
class Scatter:
    """Residual energy along each reading's power and phase directions against the rest."""

    power_p: float
    phase_p: float
    power_excess: float  # statistic minus degrees of freedom (whitened energy)
    phase_excess: float
    power_rms: float  # relative source-power noise, RMS over the readings
    phase_rms_rad: float

    @property
    def failed(self) -> bool:
        return min(self.power_p, self.phase_p) < TEST_P_VALUE


def scatter_tests(
    residual, image, tangent, dof: float, pooled: bool, phase_noise_rad, removed_phase=0.0
) -> Scatter:
    """Tests 6 and 7 (``docs/theory/diagnostics.rst``) on the residual (N, n) and the directions
    ``a_P`` (``image``) and ``a_t`` (``tangent``) of every reading (N, n); ``pooled``: one
    noise level for every port; ``phase_noise_rad`` (N,) the phase scatter the model
    expects besides the detector noise (0 for none); ``removed_phase`` the degrees of
    freedom removed along ``a_t`` beyond ``dof``'s share of them (a corrected axis's,
    :func:`off_axis_phase`).

    Per reading, with ``r``, ``a``, ``t`` whitened by the level: the component along ``a``
    is ``r a / |a|``, the one along the part of ``t`` orthogonal to ``a`` (of squared norm
    ``|t|^2 - (a t)^2 / |a|^2``) is ``(r t - (a t)(r a) / |a|^2) / |t - ...|``; these
    come from row products, block by block (each block whitened into ports x readings, the
    sums over the ports then run down contiguous readings)."""
    samples, ports = residual.shape
    level = np.einsum("ij,ij->j", residual, residual) / dof
    level = np.sqrt(np.full(ports, level.mean()) if pooled else level)
    inverse = (1.0 / np.maximum(level, np.finfo(float).tiny))[:, None]
    along_norm, across_norm, power, phase = np.empty((4, samples))
    energy = 0.0
    for rows in row_blocks(samples):
        whitened, along, across = np.empty((3, ports, rows.stop - rows.start))
        for values, out in zip((residual, image, tangent), (whitened, along, across), strict=True):
            np.multiply(values[rows].T, inverse, out=out)
        squares = np.einsum("ij,ij->j", along, along)
        cross = np.einsum("ij,ij->j", along, across)
        on_along = np.einsum("ij,ij->j", whitened, along)
        along_norm[rows] = np.sqrt(squares)
        power[rows] = on_along / along_norm[rows]
        across_norm[rows] = np.sqrt(np.einsum("ij,ij->j", across, across) - cross**2 / squares)
        on_across = np.einsum("ij,ij->j", whitened, across) - cross * on_along / squares
        phase[rows] = on_across / across_norm[rows]
        energy += np.einsum("ij,ij->", whitened, whitened)
    rest = float(energy - power @ power - phase @ phase)
    rest_dof = dof * (ports - 2)
    unit = max(rest / rest_dof, np.finfo(float).tiny)  # whitened variance per direction

    def test(component, norm, expected_rad=0.0):
        statistic = excess = 0.0
        for rows in row_blocks(samples):
            expected = expected_rad if np.ndim(expected_rad) == 0 else expected_rad[rows]
            variance = unit + (norm[rows] * expected) ** 2
            squares = component[rows] ** 2
            statistic += float(np.sum(squares / variance))
            excess += float(np.sum((squares - variance) / norm[rows] ** 2))
        return (
            float(stats.f.sf(statistic / dof, dof, rest_dof)),
            statistic - dof,
            float(np.sqrt(max(excess / samples, 0.0))),
        )

    power_p, power_excess, power_rms = test(power, along_norm)
    dof -= removed_phase
    phase_p, phase_excess, phase_rms = test(phase, across_norm, phase_noise_rad)
    return Scatter(power_p, phase_p, power_excess, phase_excess, power_rms, phase_rms)


@dataclass(frozen=True)
class Structure:
    """The residual tests and the drifts they estimate."""

    power: ResidualTest
    power_error: np.ndarray  # relative source-power error (N,)
    phase: ResidualTest
    phase_error_rad: np.ndarray  # (N,)
    dispersion: ResidualTest | None
    dispersion_amplitude: Callable[[], np.ndarray] | None  # the dispersion's (N,), rad
    harmonics: ResidualTest
    smooth: ResidualTest
    scatter: Scatter

    @property
    def dispersion_rad(self) -> np.ndarray:
        """The phase error even in ``f - f0`` left in the residual (N,), rad (computed when
        a warning states it)."""
        return self.dispersion_amplitude()

    def p_values(self) -> dict:
        return {
            "power": self.power.p_value,
            "phase": self.phase.p_value,
            "dispersion": None if self.dispersion is None else self.dispersion.p_value,
            "harmonics": self.harmonics.p_value,
            "smooth": self.smooth.p_value,
            "power_scatter": self.scatter.power_p,
            "phase_scatter": self.scatter.phase_p,
        }

    @property
    def smooth_failed(self) -> bool:
        """Whether a test of structure along the rows (1-5) failed."""
        tests = (self.power, self.phase, self.dispersion, self.harmonics, self.smooth)
        return any(test is not None and test.failed for test in tests)

    @property
    def failed(self) -> bool:
        return self.smooth_failed or self.scatter.failed


def smooth_scales(samples: int, largest: int) -> tuple[int, ...]:
    """Scales of SMOOTH_ORDERS up to ``largest`` and a quarter of the readings."""
    top = max(min(samples // 4, largest), 1)
    return tuple(k for k in SMOOTH_ORDERS if k <= top) or (top,)


def structure_tests(tests, harmonic_test, image, tangent, frequency, center, span, scatter):
    """Tests 1-3 and 5 on the whitened residual (``image`` and ``tangent`` whitened too)."""
    samples = frequency.size
    orders = smooth_scales(samples, MAX_COUPLED_ORDER)
    background = smooth_scales(samples, SMOOTH_ORDERS[-1])
    # first: its columns are the largest set, while the fewest other arrays are held
    smooth, _ = tests.per_port(tests.cosines(background[-1]), background)
    image_weight, tangent_weight = (np.einsum("ij,ij->i", a, a) for a in (image, tangent))
    power, power_error = tests.coupled(
        tests.cosines(orders[-1], image, image_weight), image, orders, image_weight
    )
    phase, phase_error = tests.coupled(
        tests.cosines(orders[-1], tangent, tangent_weight), tangent, orders, tangent_weight
    )
    dispersion = dispersion_amplitude = None
    if span > DISPERSION_MIN_SPAN_FSR:
        largest = max(float(frequency.max() - center), float(center - frequency.min()))
        scale = max(largest, np.finfo(float).tiny)

        def even(rows):
            relative = (frequency[rows] - center) / scale
            return np.column_stack([special.eval_legendre(degree, relative) for degree in (2, 4)])

        dispersion, dispersion_amplitude = tests.coupled_test(
            tests.columns(even, tangent), tangent, (2,), tangent_weight
        )
    return Structure(
        power=power,
        power_error=power_error,
        phase=phase,
        phase_error_rad=phase_error,
        dispersion=dispersion,
        dispersion_amplitude=dispersion_amplitude,
        harmonics=harmonic_test,
        smooth=smooth,
        scatter=scatter,
    )


def axis_phase_columns(samples: int, bandwidth_per_reading: float) -> np.ndarray:
    """The discrete cosines of the row (N, K) a frequency axis made from the meter's own
    phase smoothed to ``bandwidth_per_reading`` (cycles per reading) follows: ``K = 2 N``
    times it (cosine ``m`` turns ``m / 2N`` cycles per reading), at most the largest of
    ``SMOOTH_ORDERS`` (beyond it they would change no test along the rows); (N, 0) for 0."""
    orders = min(int(2 * samples * max(bandwidth_per_reading, 0.0)), SMOOTH_ORDERS[-1])
    return discrete_cosines(samples, min(orders, samples - 1))


def off_axis_phase(residual: np.ndarray, tangent: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """The residual (N, n) less its least-squares fit by ``columns`` (N, K) along each
    reading's fringe tangent (N, n): what is left when a phase error smooth along the rows
    (the corrected axis's) is taken out; the residual itself for K = 0."""
    if columns.shape[1] == 0:
        return residual
    weight = np.einsum("ij,ij->i", tangent, tangent)
    gram = columns.T @ (columns * weight[:, None])
    along = columns.T @ np.einsum("ij,ij->i", residual, tangent)
    phase = columns @ linalg.solve(gram, along, assume_a="pos")
    return residual - tangent * phase[:, None]


def rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))
