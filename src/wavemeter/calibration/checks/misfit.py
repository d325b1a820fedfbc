"""Fit diagnostics: does the calibration sweep follow the model, and if not, why.

:func:`misfit_report` takes a fitted sweep (readings in acquisition order, their known
frequencies, the fitted delay and map, or a wide-band model's per-reading maps with its
design and phase derivatives), measures the structure left in the residual, tests it
against the noise, and returns a :class:`MisfitReport`: per-port residual and model-free
noise, the tests' statistics and p-values, and one
:class:`~wavemeter.exceptions.CalibrationWarning` per failed check, the likely cause named
and what to do. This module owns the report and its assembly, and the detector-noise
bookkeeping the thermal model shares (:func:`detector_noise_w`,
:func:`phase_noise_variance_w2`). The tests on the residual are in :mod:`.residual_tests`,
the naming of causes with their warnings and remedies in :mod:`.misfit_causes`, the checks
of the arguments in :mod:`.misfit_inputs`, and the generic statistics (model-free noise,
projections, nested cosine tests) in :mod:`wavemeter.stats`. The theory (the model, the
noise without it, each test, how a cause is named, what cannot be seen) is in the docs'
fit-diagnostics page (``docs/theory/diagnostics.rst``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from ...exceptions import CalibrationWarning
from ...model.cone import cone_vectors
from ...stats.blocks import orthonormal_columns
from ...stats.model_free_noise import model_free_noise
from ...stats.nested_tests import ResidualTests
from ...stats.projection import RANK_TOLERANCE, Projector
from .axis_tests import axis_quantisation, axis_test
from .band_tests import band_tests
from .misfit_causes import (
    ill_conditioned_warning,
    misfit_warning,
    offset_warning,
    partial_span_warning,
    quantised_axis_warning,
    unequal_noise,
)
from .misfit_inputs import checked_design, checked_inputs, checked_phase_derivatives, checked_vector
from .residual_tests import (
    DISPERSION_MIN_SPAN_FSR,
    HARMONICS,
    SMOOTH_ORDERS,
    axis_phase_columns,
    harmonic_columns,
    images,
    lag1_autocorrelation,
    off_axis_phase,
    pinv_variance_ratio,
    rms,
    scatter_tests,
    smooth_scales,
    span_fsr,
    structure_tests,
    tangents,
)

__all__ = [
    "MisfitReport",
    "misfit_report",
    "detector_noise_w",
    "phase_noise_variance_w2",
    "MIN_MODEL_FREE_READINGS",
    "MIN_READINGS_PER_FSR",
    "NOISY_BASIS_TOLERANCE",
    "POOLED_NOISE_P_VALUE",
]

#: with phase noise in the model, a test column is left out when less than this fraction
#: of its norm lies outside the fitted columns (which then carry that noise)
NOISY_BASIS_TOLERANCE = 0.9
#: fewest readings, and fewest readings per fringe period, for the model-free noise
MIN_MODEL_FREE_READINGS = 16
MIN_READINGS_PER_FSR = 16
#: the tests whiten with one pooled noise unless the ports' differ at this significance
POOLED_NOISE_P_VALUE = 0.01
#: residual below this many float64 epsilons of the readings: an exact (noiseless) fit
ROUNDOFF_EPSILONS = 1e4
#: the p-values of :func:`~.band_tests.band_tests`, None when they are not made
BAND_P_VALUES = ("band", "band_slope", "band_remainder")


@dataclass(frozen=True)
class MisfitReport:
    """What the calibration residual shows, per port and for the sweep.

    Attributes
    ----------
    residual_rms_w : ndarray, shape (n,)
        Residual RMS per port (W), corrected for the fitted values.
    noise_std_w : ndarray, shape (n,)
        Noise per port (W): model-free (second differences) or, for a short or coarse
        sweep, the residual's (see ``noise_method``).
    noise_dof : float
        Degrees of freedom of each port's ``noise_std_w``.
    noise_method : {"second_difference", "residual"}
        How ``noise_std_w`` was estimated.
    noise_ratio : ndarray, shape (n,)
        ``residual_rms_w / noise_std_w``: 1 on average for in-model data.
    lag1_autocorrelation : ndarray, shape (n,)
        Lag-1 autocorrelation of each port's residual along the rows.
    harmonic_power : ndarray, shape (n,)
        Residual energy in harmonics 2 and 3 of the fringe phase over white noise's: 1 on
        average for in-model data.
    span_fsr : float
        Effective span of the sweep in FSRs (1 for a sweep of one FSR).
    condition_number : float
        2-norm condition number of the map (the largest over the readings' maps).
    pinv_variance_ratio : float
        Phase variance of the pseudo-inverse retrieval over the Cramer-Rao bound's, averaged
        over the sweep at equal port noise (1 for an ideal map).
    p_values : dict of str to float or None
        p-value of each test (``"power"``, ``"phase"``, ``"dispersion"``, ``"harmonics"``,
        ``"smooth"`` over their scales, Bonferroni-corrected; ``"power_scatter"``,
        ``"phase_scatter"``; on a sweep of several FSRs with smooth structure ``"band"``,
        ``"band_slope"``, ``"band_remainder"``; on a rounded axis ``"quantised_axis"``;
        ``"unequal_noise"``); None where the test was not made. A test fails below
        ``TEST_P_VALUE``.
    power_error_rms : float
        RMS over the readings of the relative source-power error, smooth in time, that
        remains in the residual (what the fit did not absorb of a drift).
    phase_error_rms_rad : float
        The same for a phase error (rad).
    offset_w, offset_std_w : ndarray, shape (n,), or None
        Fitted per-port offsets and their standard errors (W), when the caller fitted them.
    warnings : tuple of CalibrationWarning
        One per failed check, the most important first; ``.cause`` is one of ``CAUSES``.
    """

    residual_rms_w: np.ndarray
    noise_std_w: np.ndarray
    noise_dof: float
    noise_method: str
    noise_ratio: np.ndarray
    lag1_autocorrelation: np.ndarray
    harmonic_power: np.ndarray
    span_fsr: float
    condition_number: float
    pinv_variance_ratio: float
    p_values: dict
    power_error_rms: float
    phase_error_rms_rad: float
    offset_w: np.ndarray | None
    offset_std_w: np.ndarray | None
    warnings: tuple[CalibrationWarning, ...]

    @property
    def misfit(self) -> bool:
        """True when any check failed (``warnings`` is not empty)."""
        return bool(self.warnings)

    def misfit_noise(self) -> tuple[np.ndarray, float] | None:
        """The model-free noise per port (W) and its degrees of freedom, to weight and state
        uncertainties with, when a check failed (a misfit is then reported by its warning,
        not counted as noise); None when none failed or the estimate is not usable."""
        model_free = np.asarray(self.noise_std_w, dtype=float)
        if self.misfit and np.all(np.isfinite(model_free) & (model_free > 0)):
            return model_free, float(self.noise_dof)
        return None

    @property
    def causes(self) -> tuple[str, ...]:
        """The causes of ``warnings``, in order."""
        return tuple(note.cause for note in self.warnings)

    def to_dict(self) -> dict:
        """JSON-ready fields: floats (None where not finite), lists of floats, and the
        warnings as ``{"cause", "message", "remedy"}`` dicts."""

        def plain(value):
            if isinstance(value, np.ndarray):
                return [float(item) for item in value]
            # a singular map has no finite condition number: None keeps the file strict JSON
            return None if value is None or not np.isfinite(value) else float(value)

        return {
            "residual_rms_w": plain(self.residual_rms_w),
            "noise_std_w": plain(self.noise_std_w),
            "noise_dof": plain(self.noise_dof),
            "noise_method": self.noise_method,
            "noise_ratio": plain(self.noise_ratio),
            "lag1_autocorrelation": plain(self.lag1_autocorrelation),
            "harmonic_power": plain(self.harmonic_power),
            "span_fsr": plain(self.span_fsr),
            "condition_number": plain(self.condition_number),
            "pinv_variance_ratio": plain(self.pinv_variance_ratio),
            "p_values": {name: plain(value) for name, value in self.p_values.items()},
            "power_error_rms": plain(self.power_error_rms),
            "phase_error_rms_rad": plain(self.phase_error_rms_rad),
            "offset_w": plain(self.offset_w),
            "offset_std_w": plain(self.offset_std_w),
            "misfit": self.misfit,
            "warnings": [note.record() for note in self.warnings],
        }


def phase_noise_variance_w2(tangent_w, phase_noise_std_rad) -> np.ndarray:
    """Mean variance (W^2, per port) a phase scatter ``s_k`` (rad) adds to readings whose
    fringe tangent is ``P A u'(t_k)`` (``tangent_w``, (N, n), W/rad)."""
    return np.mean((tangent_w * np.asarray(phase_noise_std_rad)[..., None]) ** 2, axis=0)


def detector_noise_w(noise_w, extra_variance_w2) -> np.ndarray:
    """Detector noise (W, per port): a noise estimate less an expected extra variance,
    kept at least a tenth of the estimate."""
    noise = np.asarray(noise_w, dtype=float)
    return np.sqrt(np.maximum(noise**2 - extra_variance_w2, 0.01 * noise**2))


# ---------------------------------------------------------------------- the report
def misfit_report(
    powers,
    frequency_hz,
    center_hz: float,
    delay_s: float,
    map_,
    *,
    scale=None,
    offset_w=None,
    offset_std_w=None,
    dark_given: bool = False,
    weighted_retrieval: bool = False,
    phase_rad=None,
    phase_noise_std_rad=None,
    design=None,
    phase_derivatives=None,
    test_axis: bool = True,
    axis_bandwidth_per_reading: float = 0.0,
    method: str | None = None,
) -> MisfitReport:
    """Test a fitted calibration sweep against the model and name what departs from it.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Calibration readings (W), dark-subtracted, in acquisition order.
    frequency_hz : array_like, shape (N,)
        Known frequency of each reading (Hz).
    center_hz : float
        Phase origin ``f0`` (Hz).
    delay_s : float
        Fitted delay ``tau`` (s); the FSR is ``1 / delay_s``.
    map_ : array_like, shape (n, 3) or (N, n, 3)
        Fitted map ``A`` (W), or the map of each reading (``A(f_k)``, a map that changes with
        frequency): the images, fringe tangents, residual and scatter tests use each
        reading's own; the condition number reported is the largest over the readings.
    scale : None or array_like, shape (N,)
        Relative monitored source power per reading (mean 1), or None.
    offset_w, offset_std_w : None or array_like, shape (n,)
        Fitted per-port offsets (W, subtracted from the readings) and their standard
        errors (W); both or neither.
    dark_given : bool
        Dark readings were subtracted (fitted offsets then do not warn).
    weighted_retrieval : bool
        The retrieval weights the ports by their noise (``"ml"``): unequal noise and an
        ill-conditioned map cost it nothing, so neither warns.
    phase_rad : None or array_like, shape (N,)
        The model phase of each reading (rad) when it is not ``2 pi (f - f0) tau`` (the
        thermal model's, which moves with temperature); the delay's direction stays
        ``2 pi (f - f0)`` along the fringe.
    phase_noise_std_rad : None or array_like, shape (N,)
        Phase scatter (rad) the model expects of each reading besides the detector noise
        (a chip temperature known to ``s_T``: ``s_T`` times the thermal rate). The phase
        scatter test looks for scatter beyond it, and the noise reported (and tested for
        unequal ports) is the detector's: the model-free estimate less its share.
    design : None or array_like, shape (N, k)
        The columns every port's map row was fitted on, by linear least squares (the residual
        is orthogonal to them), with a column of ones when offsets were fitted. None: the cone
        objects ``m_k [cos t_k, sin t_k, sqrt 2]`` (and ones with ``offset_w``).
    phase_derivatives : None or array_like, shape (q, N)
        Derivatives ``dt_k / d theta_i`` (rad per unit) of the model phase by the ``q``
        nonlinear parameters shared by the ports (a phase polynomial's coefficients). None:
        the delay alone, ``2 pi (f - f0)``.
    test_axis : bool
        Test the frequency axis for rounding (``quantised_axis``). When it is rounded, the
        other causes are named on the readings moved back onto the recorded axis (a report
        made with ``test_axis=False``).
    axis_bandwidth_per_reading : float
        When the frequency axis was made from the meter's own phase smoothed along the rows
        (a reference cell's corrected axis), the frequency (cycles per reading) up to which
        it follows that phase's noise: the axis was fitted to the readings there, so a phase
        error smooth along the rows at those scales is the axis's, not a misfit. Its
        discrete cosines of the row (:func:`~.residual_tests.axis_phase_columns`) along the
        fringe tangent are directions of the fit, not tested. 0: an axis given.
    method : None or str
        The calibration method judged (its ``method``): a remedy never suggests it.

    Returns
    -------
    MisfitReport

    Raises
    ------
    InputError
        For arrays of the wrong shape or with non-finite values.
    """
    readings, frequency, center, delay, matrix, power, offsets, offset_std = checked_inputs(
        powers, frequency_hz, center_hz, delay_s, map_, scale, offset_w, offset_std_w
    )
    samples, ports = readings.shape
    names = [f"p{k + 1}" for k in range(ports)]
    # 2 pi (f - f0): the phase's derivative in the delay, and t = 2 pi (f - f0) tau
    frequency_rad = 2.0 * np.pi * (frequency - center)
    phase = (
        frequency_rad * delay
        if phase_rad is None
        else checked_vector("phase_rad", phase_rad, samples)
    )
    derivatives = (
        frequency_rad[None]
        if phase_derivatives is None
        else checked_phase_derivatives(phase_derivatives, samples)
    )
    axis = axis_phase_columns(samples, axis_bandwidth_per_reading)
    axis_phase = axis.shape[1] > 0
    derivatives = np.vstack([derivatives, axis.T])
    unit = cone_vectors(phase)
    objects = unit if power is None else unit * power[:, None]
    design_given = design
    if design is None:
        design = objects if offsets is None else np.column_stack([objects, np.ones(samples)])
    basis = orthonormal_columns(checked_design(design, samples))
    # (N, ...) arrays are let go as soon as they are used: on long sweeps each one held
    # costs more to map into memory than to compute
    del design
    image = images(matrix, objects)
    residual = np.subtract(readings, image)
    if offsets is not None:
        residual -= offsets

    residual_dof = max(samples - basis.shape[1] - derivatives.shape[0] / ports, 1.0)
    residual_squares = np.einsum("ij,ij->j", residual, residual)
    residual_rms = np.sqrt(residual_squares / residual_dof)
    span = span_fsr(phase)
    dense = samples >= MIN_READINGS_PER_FSR * max(span, 1.0)
    model_free = samples >= MIN_MODEL_FREE_READINGS and dense
    if model_free:
        noise, noise_dof = model_free_noise(residual, basis)
    else:
        noise, noise_dof = residual_rms, residual_dof
    largest = max(float(readings.max()), -float(readings.min()), np.finfo(float).tiny)
    floor = np.finfo(float).eps * largest
    noise = np.maximum(noise, floor)
    ratio = residual_rms / noise
    lag1 = lag1_autocorrelation(residual, residual_squares)
    exact_fit = bool(np.sqrt(residual_squares.sum() / residual.size) <= ROUNDOFF_EPSILONS * floor)

    tangent = tangents(matrix, unit, power)
    if phase_noise_std_rad is None:
        expected, extra_variance = 0.0, np.zeros(ports)
    else:
        expected = np.abs(checked_vector("phase_noise_std_rad", phase_noise_std_rad, samples))
        extra_variance = phase_noise_variance_w2(tangent, expected)
    detector = detector_noise_w(noise, extra_variance)
    # a variance less a known share keeps the estimate's absolute error: its degrees of
    # freedom shrink by the square of the share left (Satterthwaite)
    detector_dof = noise_dof * float(np.min(detector / noise)) ** 4
    noise_note, unequal_p = unequal_noise(detector, detector_dof, names)
    # whitening weights: one noise for all ports unless theirs differ
    # (``docs/theory/diagnostics.rst``, "The residual tests")
    pooled = unequal_p >= POOLED_NOISE_P_VALUE
    weight = np.full(ports, np.sqrt(np.mean(noise**2))) if pooled else noise
    scatter = scatter_tests(
        off_axis_phase(residual, tangent, axis),
        image,
        tangent,
        residual_dof,
        pooled,
        expected,
        axis.shape[1] * (1.0 - 1.0 / ports),
    )
    del axis
    variance_ratio = pinv_variance_ratio(matrix, image, tangent)
    # whitened in place from here on: the tests keep no other copy of these (N, n) arrays
    for values in (residual, image, tangent):
        values /= weight
    # the directions the nonlinear parameters move the images in, d_i,k a_t,k (N, n, q)
    projector = Projector(basis, tangent[:, :, None] * derivatives.T[:, None, :])
    del frequency_rad, derivatives
    # the fitted columns carry the model's phase noise, which the residual carries too: a
    # test column partly inside their span is left with that noise in its direction
    tolerance = NOISY_BASIS_TOLERANCE if np.any(expected > 0) else RANK_TOLERANCE
    tests = ResidualTests(residual, projector, residual_dof, tolerance, out=residual)
    harmonics = tests.columns(partial(harmonic_columns, unit, power))
    harmonic_test, harmonic_scores = tests.per_port(harmonics, (2 * len(HARMONICS),))
    del harmonics
    # relative to each port's own noise
    harmonic_power = harmonic_scores * (weight / noise) ** 2 / max(harmonic_test.dof // ports, 1)
    structure = structure_tests(
        tests, harmonic_test, image, tangent, frequency, center, span, scatter
    )
    band = None
    if span > DISPERSION_MIN_SPAN_FSR and structure.smooth_failed:
        # the fringe's radius, the image less its cone-axis part: a common second-order
        # change of the fringe phase moves the readings along it
        radial = images(matrix, objects * np.array([1.0, 1.0, 0.0]))
        radial /= weight
        scales = smooth_scales(samples, SMOOTH_ORDERS[-1])
        band = band_tests(
            tests,
            projector,
            residual_dof,
            objects,
            (image, tangent, radial),
            frequency,
            scales,
            scales[-1],
            matrix.ndim == 2,
        )
        del radial
    del objects, unit
    axis = axis_quantisation(frequency) if test_axis and not exact_fit else None
    quantised = None
    if axis is not None:
        quantised = axis_test(tests, axis, tangent, np.einsum("ij,ij->i", tangent, tangent), delay)
    p_values = {
        **structure.p_values(),
        **(band.p_values() if band is not None else dict.fromkeys(BAND_P_VALUES)),
        "quantised_axis": None if quantised is None else quantised.test.p_value,
        "unequal_noise": unequal_p,
    }
    if quantised is not None and quantised.follows:
        # the other causes are named on the readings moved back onto the recorded axis
        relative = 1.0 if power is None else power
        moved = cone_vectors(phase + quantised.phase_error_rad, relative)
        readings = readings - images(matrix, moved) + images(matrix, cone_vectors(phase, relative))
        del moved
        inner = misfit_report(
            readings,
            frequency,
            center,
            delay,
            matrix,
            scale=scale,
            offset_w=offset_w,
            offset_std_w=offset_std_w,
            dark_given=dark_given,
            weighted_retrieval=weighted_retrieval,
            phase_rad=phase_rad,
            phase_noise_std_rad=phase_noise_std_rad,
            design=design_given,
            phase_derivatives=phase_derivatives,
            test_axis=False,
            axis_bandwidth_per_reading=axis_bandwidth_per_reading,
            method=method,
        )
        notes = [quantised_axis_warning(axis, quantised, samples, delay), *inner.warnings]
    else:
        notes = []
        if not exact_fit:
            notes.append(
                misfit_warning(
                    structure,
                    band,
                    names,
                    ratio,
                    lag1,
                    harmonic_power,
                    span,
                    delay,
                    model_free,
                    method=method,
                    axis_phase=axis_phase,
                )
            )
        if offsets is not None and not dark_given:
            notes.append(offset_warning(offsets, offset_std, readings, names))
        notes.append(partial_span_warning(span, delay))
        if not (weighted_retrieval or exact_fit):
            notes.append(noise_note)
    condition = float(np.max(np.linalg.cond(matrix)))
    if not (weighted_retrieval or quantised is not None and quantised.follows):
        notes.append(ill_conditioned_warning(variance_ratio, condition))
    return MisfitReport(
        residual_rms_w=residual_rms,
        noise_std_w=detector,
        noise_dof=float(noise_dof),
        noise_method="second_difference" if model_free else "residual",
        noise_ratio=ratio,
        lag1_autocorrelation=lag1,
        harmonic_power=harmonic_power,
        span_fsr=span,
        condition_number=condition,
        pinv_variance_ratio=variance_ratio,
        p_values=p_values,
        power_error_rms=rms(structure.power_error),
        phase_error_rms_rad=rms(structure.phase_error_rad),
        offset_w=offsets,
        offset_std_w=offset_std,
        warnings=tuple(note for note in notes if note is not None),
    )
