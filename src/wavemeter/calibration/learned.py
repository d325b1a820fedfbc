"""The learned calibration of the paper (Section II.C): closed-form map, 1-D delay search.

For a trial delay ``tau`` the map ``A`` is a linear least-squares fit to the sweep
(:mod:`wavemeter.calibration.linear_map`, Eq. 20-23); ``tau`` minimises ``J(tau)``
(:mod:`wavemeter.calibration.delay_search`). Retrieval: ``x_hat = A+ p``,
``t = atan2(x_hat_2, x_hat_1)``, ``f = f0 + t / (2 pi tau)``.

The standard error of the delay follows from the curvature of ``J`` at its minimum and
the noise estimate ``s``: ``var(tau) = 2 s^2 / (N J''(tau))`` (Gauss-Newton, map profiled
out), and ``sigma_FSR = FSR^2 sigma_tau``.

Beyond the paper, for real hardware:

* **offsets**: dark readings given to ``fit`` are subtracted from every reading; when a
  power monitor shows the source power varying (relative spread ``>= AFFINE_MIN_POWER_SPREAD``)
  and no dark readings are given, per-port offsets are fitted as a fourth map column
  (:mod:`wavemeter.calibration.linear_map`) and subtracted too;
* **per-port noise**: each port's noise is estimated from its own residual when it has at
  least ``PER_PORT_MIN_DOF`` degrees of freedom (else the pooled estimate); the ``"ml"``
  retrieval weights ports by it; where the fit diagnostics find a misfit, the noise is their
  model-free estimate, so that misfit is reported by a warning, not counted as noise;
* **honest uncertainty**: :meth:`Calibrator.frequency_std_hz` is the standard deviation of
  the estimator used (delta method, :mod:`wavemeter.model.uncertainty`), with the noise
  inflated by the Student factor of its degrees of freedom, plus the spread the calibration's
  own parameter covariance gives;
* **large sweeps**: beyond ``DIAGNOSTIC_SAMPLES`` (2^17) readings, or read in chunks
  (:meth:`Calibrator.fit_chunks`, in memory bounded by the chunk), the delay, the map, the
  noise, the covariance and the delay's standard error come from one pass of binned
  moments over every reading (:mod:`wavemeter.calibration.moments`), and the checks and
  diagnostics see every k-th reading (:mod:`wavemeter.calibration.subsample`, which says
  why that many suffice); ``diagnostics_["diagnostic_samples"]`` says how many they saw.

The pure functions here and the :class:`Calibrator` methods compute the same numbers.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import linalg

from ..blas import one_blas_thread
from ..exceptions import InputError
from ..model.cone import cone_vectors, phase_to_frequency_hz
from ..model.kernels import (
    fused_ml_frequency_hz,
    fused_ml_phase_rad,
    fused_pinv_frequency_hz,
    fused_pinv_phase_rad,
)
from ..model.limits import crlb_frequency_std
from ..model.retrieval import source_power_ratio
from ..model.uncertainty import (
    calibration_variance_hz2,
    fit_parameter_covariance,
    map_frequency_gradient_hz,
    ml_phase_gradient,
    phase_std_rad,
    pinv_phase_gradient,
    student_factor,
)
from ..validation import (
    MIN_SAMPLES,
    check_choice,
    check_fitted,
    check_positive,
    reading_array,
)
from .base import (
    SCREEN_MARGIN,
    BaseCalibrator,
    StreamReading,
    checked_port_names,
    value_range,
)
from .delay_search import SEARCH_METHODS, DelaySearchResult
from .files import state_array, state_float
from .flags import ReadingFlag, off_model_threshold
from .fsr_guard import check_design_fsr
from .linear_map import (
    fit_map,
    map_cost,
    object_delay_derivative,
    object_vectors,
    unfitted_cost,
)
from .misfit import MisfitReport, misfit_report
from .moments import BLOCK_ROWS, FringeMoments, largest_search_delay_s, search_moment_delay
from .reanchor import check_reference_readings, fit_reanchor, reanchored_copy
from .subsample import DIAGNOSTIC_SAMPLES, CheckedChunks, SweepSample
from .summary import FitValue

RETRIEVALS = ("pinv", "ml")
#: relative spread of the monitored power above which per-port offsets are fitted
AFFINE_MIN_POWER_SPREAD = 0.02
#: residual degrees of freedom a port needs for a noise estimate of its own
PER_PORT_MIN_DOF = 30
#: most memory the binned moments of a large sweep may take (bytes): they grow with the span
#: in fringes (~80 bins per FSR, ~0.5 kB per bin for 3 ports), whatever the readings
MAX_MOMENT_BYTES = 64 << 20

__all__ = [
    "AFFINE_MIN_POWER_SPREAD",
    "Calibrator",
    "MAX_MOMENT_BYTES",
    "LearnedFit",
    "PER_PORT_MIN_DOF",
    "port_noise_std_w",
    "RETRIEVALS",
    "fit_learned_map",
    "fit_learned_map_chunks",
    "object_vectors",
    "fit_map",
    "map_cost",
    "unfitted_cost",
    "retrieve_phase_rad",
    "predict_frequency_hz",
]


def port_noise_std_w(
    residual: np.ndarray, columns: int, shared: int = 1
) -> tuple[np.ndarray, float]:
    """Per-port noise (W) from a fit residual, and its degrees of freedom.

    Each port's residual has ``N - k - q/n`` degrees of freedom (``k`` map columns per
    port, ``q`` nonlinear parameters shared by the ``n`` ports: the delay, or the thermal
    model's three). With at least ``PER_PORT_MIN_DOF`` of them each port gets its own
    estimate; otherwise every port gets the pooled one, on ``N n - n k - q`` degrees of
    freedom.

    Parameters
    ----------
    residual : ndarray, shape (N, n)
        Readings minus the fitted model (W).
    columns : int
        Map columns per port ``k`` (3, or 4 with offsets).
    shared : int
        Nonlinear parameters ``q`` shared by the ports (1: the delay).

    Returns
    -------
    noise_std_w : ndarray, shape (n,)
    dof : float
    """
    squares = np.einsum("ij,ij->j", residual, residual)
    return _port_noise(squares, residual.shape[0], columns, shared)


def _port_noise(squares: np.ndarray, samples: int, columns: int, shared: int):
    """:func:`port_noise_std_w` from each port's summed squared residual (n,), W^2."""
    ports = squares.size
    per_port_dof = samples - columns - shared / ports
    if per_port_dof >= PER_PORT_MIN_DOF:
        return np.sqrt(squares / per_port_dof), per_port_dof
    pooled_dof = max(samples * ports - ports * columns - float(shared), 1.0)
    return np.full(ports, np.sqrt(squares.sum() / pooled_dof)), pooled_dof


def retrieve_phase_rad(powers, map_pinv: np.ndarray) -> np.ndarray:
    """Phase ``atan2(x_hat_2, x_hat_1)`` (rad) of ``x_hat = A+ p`` for readings (N, n)."""
    readings = np.asarray(powers, dtype=float)
    # two matrix-vector products keep both quadratures contiguous for the arctangent
    return np.arctan2(readings @ map_pinv[1], readings @ map_pinv[0])


def predict_frequency_hz(powers, map_: np.ndarray, center_hz: float, fsr_hz: float) -> np.ndarray:
    """Frequency (Hz) of readings (N, n) under a map (n, 3): pinv, arctangent, FSR scale."""
    return phase_to_frequency_hz(retrieve_phase_rad(powers, linalg.pinv(map_)), center_hz, fsr_hz)


@dataclass(frozen=True)
class LearnedFit:
    """Outcome of :func:`fit_learned_map`.

    Attributes
    ----------
    delay_s : float
        Delay ``tau`` at the minimum of ``J`` (s).
    delay_std_s : float or None
        Its standard error (s): ``sqrt(s^2 / G)`` with ``s`` the noise estimate and ``G``
        the Gauss-Newton curvature (:func:`wavemeter.calibration.linear_map.delay_information`),
        i.e. ``var(tau) = 2 s^2 / (N J''(tau))``.
    map_ : ndarray, shape (n, 3) or (n, 4)
        Least-squares map at ``delay_s`` (W); with ``affine`` a fourth column of offsets.
    cost : float
        ``J`` at ``delay_s`` (W^2).
    noise_std_w : float
        Detector noise estimate (W): ``sqrt(N J / (N n - 3 n - 1))``, the residual corrected
        for the ``3 n + 1`` fitted values.
    search : DelaySearchResult
        Scan and refinement of ``J(tau)``.
    """

    delay_s: float
    delay_std_s: float | None
    map_: np.ndarray
    cost: float
    noise_std_w: float
    search: DelaySearchResult


def fit_learned_map(
    powers: np.ndarray,
    frequency_hz: np.ndarray,
    center_hz: float,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    scale=None,
    search: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> LearnedFit:
    """Search the delay minimising ``J`` and fit the map there (paper Section II.C).

    One pass accumulates the sweep's moments (:class:`~wavemeter.calibration.moments.
    FringeMoments`); the delay search runs on them
    (:func:`~wavemeter.calibration.moments.search_moment_delay`), so its time does not grow
    with ``N``; the map and ``J`` at the delay found are one direct least-squares fit.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated calibration readings (W).
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    center_hz : float
        Phase origin (Hz).
    fsr_hz, fsr_tolerance : float
        Design FSR (Hz) and the relative half width of the bracket searched.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    search : {"golden", "brent"}
        Refinement of the delay after the scan.
    xtol : float
        Relative tolerance on the delay.
    affine : bool
        Fit per-port offsets too (a fourth map column); needs a varying ``scale``.

    Returns
    -------
    LearnedFit
    """
    moments = FringeMoments(largest_search_delay_s(fsr_hz, fsr_tolerance), center_hz)
    result = search_moment_delay(
        moments.add(frequency_hz, powers, scale),
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        method=search,
        xtol=xtol,
        affine=affine,
    )
    objects = object_vectors(frequency_hz, center_hz, result.delay_s, scale, affine)
    matrix, cost_value = map_cost(objects, powers)
    return _learned_fit(moments, result, matrix, cost_value)


def fit_learned_map_chunks(
    chunks,
    center_hz: float,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    search: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> LearnedFit:
    """:func:`fit_learned_map` on a sweep read in chunks, in memory bounded by the chunk.

    Each chunk is binned into the sweep's moments
    (:class:`~wavemeter.calibration.moments.FringeMoments`) and dropped; everything else
    comes from them. Nothing else is checked (no FSR guard, port health or misfit report:
    those need the readings).

    Parameters
    ----------
    chunks : iterable of (frequency_hz, powers_w, scale)
        ``frequency_hz`` (N_c,) in Hz, ``powers_w`` (N_c, n) in W, ``scale`` (N_c,) the
        monitored source power in any linear unit or None (the same for every chunk); any
        order, any sizes.
    center_hz : float
        Phase origin (Hz), e.g. the middle of the sweep.
    fsr_hz, fsr_tolerance, search, xtol, affine
        As for :func:`fit_learned_map`.

    Returns
    -------
    LearnedFit
        ``delay_s`` as :func:`fit_learned_map` finds it (the same search on the same
        moments); ``map_`` the least-squares map from the moments' normal equations, for
        the monitored power relative to its mean over all chunks (as
        :class:`Calibrator` uses it); ``cost`` ``J`` from the moments, whose absolute error
        is a few ``2^-53 sum |p|^2 / N`` (about ``1e-9 J`` at Table 1 noise);
        ``noise_std_w`` and ``delay_std_s`` from these.

    Raises
    ------
    InputError
        For a malformed chunk, fewer than ``MIN_SAMPLES`` readings in all, or as
        :func:`fit_learned_map`.
    EdgeMinimumError
        As :func:`fit_learned_map`.
    """
    moments = FringeMoments(largest_search_delay_s(fsr_hz, fsr_tolerance), center_hz)
    for frequency, readings, monitor in chunks:
        moments.add(frequency, readings, monitor)
    if moments.samples < MIN_SAMPLES:
        raise InputError(f"need at least {MIN_SAMPLES} samples, got {moments.samples}")
    fit = _moment_fit(
        moments, fsr_hz=fsr_hz, fsr_tolerance=fsr_tolerance, search=search, xtol=xtol, affine=affine
    )
    return dataclasses.replace(fit, map_=_relative_map(fit.map_, moments.mean_scale))


def _moment_fit(
    moments: FringeMoments, *, fsr_hz, fsr_tolerance, search, xtol, affine
) -> LearnedFit:
    """The fit on the moments alone (settings as :func:`fit_learned_map` takes them): the
    search, the map from the normal equations (for the scale as the moments were given it)
    and ``J`` from the moments."""
    result = search_moment_delay(
        moments,
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        method=search,
        xtol=xtol,
        affine=affine,
    )
    return _learned_fit(moments, result, moments.map_at(result.delay_s, affine), result.cost)


def _relative_map(matrix: np.ndarray, mean_scale: float) -> np.ndarray:
    """A map for a monitor in any unit (n, k) as the map for the monitor relative to its mean."""
    relative = matrix.copy()
    relative[:, :3] *= mean_scale
    return relative


def _gram_objects(moments: FringeMoments, delay_s: float, affine: bool, mean_scale: float):
    """Stand-ins (2k, k) for the sweep's objects ``X`` and their delay derivative ``D``
    (for the monitor relative to its mean): the products ``X^T X``, ``X^T D``, ``D^T D``
    of every reading, from the moments, as those of ``2 k`` rows.

    The covariance of the fit (:func:`~wavemeter.model.uncertainty.fit_parameter_covariance`)
    depends on the sweep only through these products: any rows with the same Gram matrix
    give it. They are a square root of that matrix, taken from the eigenvectors of its
    correlation matrix (the entries differ by many decades in scale).
    """
    xx, dx, dd = moments.object_gram(delay_s, affine)
    columns = xx.shape[0]
    gram = np.block([[xx, dx.T], [dx, dd]])
    relative = np.ones(2 * columns)
    relative[:3] = relative[columns : columns + 3] = 1.0 / mean_scale
    gram *= np.outer(relative, relative)
    norm = np.sqrt(np.diag(gram))
    norm[norm == 0] = 1.0
    values, vectors = np.linalg.eigh(gram / np.outer(norm, norm))
    root = np.sqrt(np.clip(values, 0.0, None))[:, None] * vectors.T * norm
    return root[:, :columns], root[:, columns:]


def _learned_fit(
    moments: FringeMoments, result: DelaySearchResult, matrix: np.ndarray, cost_value: float
) -> LearnedFit:
    """The fit at the searched delay: noise from ``J``, the delay's standard error."""
    ports = matrix.shape[0]
    dof = max(moments.samples * ports - matrix.size - 1, 1)
    noise = float(np.sqrt(cost_value * moments.samples / dof))
    information = moments.delay_information(result.delay_s, matrix)
    return LearnedFit(
        delay_s=result.delay_s,
        delay_std_s=noise / np.sqrt(information) if information > 0 else None,
        map_=matrix,
        cost=cost_value,
        noise_std_w=noise,
        search=result,
    )


class Calibrator(BaseCalibrator):
    """Learned linear-map calibration of an n-port interferometric wavelength meter.

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz); the delay search brackets it.
    fsr_tolerance : float
        Relative half width of the FSR bracket, in (0, 1). Default 0.2 (+-20 %).
    search : {"golden", "brent"}
        Refinement of the delay after the scan: golden-section (paper) or bounded Brent.
    xtol : float
        Relative tolerance on the delay.
    retrieval : {"pinv", "ml"}
        Phase retrieval: the paper's pseudo-inverse and arctangent, or the cone-constrained
        maximum-likelihood phase weighted by each port's noise
        (:mod:`wavemeter.model.retrieval`, the exact global optimum), which reaches the
        Cramer-Rao bound also for ill-conditioned maps and unequal port noise.

    Attributes
    ----------
    map_ : ndarray, shape (n, 3)
        Learned map ``A`` (W): readings at the calibration's source power (or, with a
        monitor, per unit of the mean monitor reading) are ``A @ [cos t, sin t, sqrt 2]``.
    map_pinv_ : ndarray, shape (3, n)
        Moore-Penrose inverse of ``map_``.
    delay_s_ : float
        Fitted delay imbalance ``tau`` (s).
    delay_std_s_ : float or None
        Standard error of ``delay_s_`` (s); None when loaded from a file of version 0.1.
        The FSR's is ``fsr_hz_**2 * delay_std_s_`` (``summary()["fsr_hz"].stderr``).
    fsr_hz_ : float
        Calibrated FSR ``1 / tau`` (Hz).
    center_hz_ : float
        Phase origin (Hz): the middle of the calibration sweep.
    span_hz_ : (float, float)
        Lowest and highest calibration frequency (Hz).
    residual_rms_ : float
        RMS of the fit residual over all readings (W).
    noise_std_w_ : float
        Detector noise estimate (W): residual corrected for the ``3 n + 1`` fitted values
        (``4 n + 1`` with offsets), pooled over the ports.
    port_noise_std_w_ : ndarray, shape (n,)
        Noise per port (W) used for weights and uncertainties (see the module docstring).
    noise_dof_ : float
        Degrees of freedom of ``port_noise_std_w_``.
    offset_w_ : ndarray, shape (n,)
        Fitted per-port offsets (W), subtracted from every reading; zeros unless fitted.
    parameter_covariance_ : ndarray, shape (n k + 1, n k + 1)
        Covariance of the fitted map (row-major, ``k`` = 3 or 4 with offsets) and delay.
    cost_ : float
        ``J`` at the fitted delay (W^2).
    delay_search_ : DelaySearchResult
        Scan and refinement of ``J(tau)`` (not saved to file).
    calibration_rms_hz_ : float
        RMS frequency error on the calibration sweep itself (Hz).
    diagnostics_ : dict
        The sweep's own FSR estimate, every port's fringe amplitude and significance, the
        fit diagnostics (:mod:`wavemeter.calibration.misfit`), the readings they saw
        (``"diagnostic_samples"``) and the warnings the fit emitted (saved to file).

    Notes
    -----
    A sweep of more than ``diagnostic_samples`` readings (2^17), or one read in chunks
    (:meth:`fit_chunks`), is fitted on the binned moments of every reading: delay, map,
    ``cost_``, the noise, ``parameter_covariance_`` and ``delay_std_s_`` describe the fit
    on every reading (equal to those of the direct fit to ~1e-9, the cancellation of ``J``
    from sums). The check of the design FSR, the port health, the misfit report and
    ``calibration_rms_hz_`` are made on every k-th reading at that fit
    (:mod:`wavemeter.calibration.subsample`); where a misfit is found, the noise is the
    sample's model-free estimate, with its degrees of freedom. Subclasses that fit
    otherwise (the thermal calibrator) fit and diagnose every reading.
    """

    method = "learned"
    capabilities = frozenset({"frequency_std", "power_monitor"})
    #: nonlinear parameters after the map in ``parameter_covariance_`` (the delay)
    nonlinear_parameters: ClassVar[int] = 1
    #: the phase is the delay's alone, ``2 pi (f - center) delay``: predict runs the fused
    #: kernel, and a long sweep is fitted on its moments. A subclass that models the phase
    #: further (the thermal one) sets False: it predicts step by step and fits every reading
    plain_delay_phase: ClassVar[bool] = True
    #: most readings the checks and diagnostics see (:mod:`~wavemeter.calibration.subsample`)
    diagnostic_samples: ClassVar[int] = DIAGNOSTIC_SAMPLES
    #: while fitting on moments: stand-ins for the sweep's objects (:func:`_gram_objects`)
    _sweep_gram: ClassVar[tuple | None] = None

    def __init__(
        self,
        fsr_hz: float = 50e9,
        fsr_tolerance: float = 0.2,
        search: str = "golden",
        xtol: float = 1e-12,
        retrieval: str = "pinv",
    ):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.search = search
        self.xtol = xtol
        self.retrieval = retrieval

    def _check_params(self) -> None:
        super()._check_params()
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        check_choice("search", self.search, SEARCH_METHODS)
        check_positive("xtol", self.xtol, upper=1.0)
        check_choice("retrieval", self.retrieval, RETRIEVALS)

    def _fsr_tolerance(self) -> float:
        return self.fsr_tolerance

    def _fit(self, powers, frequency_hz, monitor):
        scale = None if monitor is None else monitor / monitor.mean()
        affine = (
            scale is not None and self.dark_w_ is None and np.std(scale) >= AFFINE_MIN_POWER_SPREAD
        )
        fit = fit_learned_map(
            powers,
            frequency_hz,
            self.center_hz_,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            scale=scale,
            search=self.search,
            xtol=self.xtol,
            affine=affine,
        )
        noise, self.noise_dof_ = port_noise_std_w(
            powers
            - object_vectors(frequency_hz, self.center_hz_, fit.delay_s, scale, affine)
            @ fit.map_.T,
            fit.map_.shape[1],
        )
        self._take_fit(fit, fit.map_, noise, float(np.abs(powers).max()))
        self._sweep = (frequency_hz, scale, affine)
        self._sweep_gram = None
        self._set_covariance()

    def _take_fit(self, fit: LearnedFit, matrix: np.ndarray, noise, largest_w: float) -> None:
        """The fitted values: the map (n, k) for the relative monitor, the per-port noise (W)
        floored at the rounding of the largest reading ``largest_w`` (W)."""
        ports = matrix.shape[0]
        self.delay_search_ = fit.search
        # noiseless (simulated) sweeps: keep weights finite at the readings' rounding level
        noise = np.maximum(noise, np.finfo(float).eps * largest_w)
        self.delay_s_ = fit.delay_s
        self.delay_std_s_ = fit.delay_std_s
        self.fsr_hz_ = 1.0 / fit.delay_s
        self.cost_ = fit.cost
        self.residual_rms_ = float(np.sqrt(fit.cost / ports))
        self.noise_std_w_ = fit.noise_std_w
        self.port_noise_std_w_ = noise
        self.offset_w_ = matrix[:, 3].copy() if matrix.shape[1] == 4 else np.zeros(ports)
        self._set_map(matrix[:, :3])

    # ------------------------------------------------------------------ large sweeps
    def fit_chunks(self, chunks, port_names=None, *, dark_w=None):
        """Learn the calibration from a sweep read in chunks, in memory bounded by the chunk.

        One pass: every chunk is checked, binned into the sweep's moments and sampled
        (every k-th reading), then dropped. A sweep of up to ``diagnostic_samples``
        readings is then fitted as :meth:`fit` fits it (the sample holds every reading: the
        same numbers, bit for bit); a longer one is fitted on the moments and diagnosed on
        the sample, as :meth:`fit` does with a long sweep given whole (the same numbers to
        rounding; see the class notes).

        Parameters
        ----------
        chunks : iterable of (frequency_hz, powers, power_monitor_w)
            In sweep order: ``frequency_hz`` (m,) Hz, ``powers`` (m, n) port readings (W or
            any unit linear in power), ``power_monitor_w`` (m,) or None, the same ``n`` and
            either always or never a monitor; any sizes, empty ones too.
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.
        dark_w : None or array_like, shape (n,)
            Per-port dark readings (W), subtracted from every reading, in fit and predict.

        Returns
        -------
        self

        Raises
        ------
        InputError
            As :meth:`fit`; a chunk's message names it and its first reading (zero-based).
            When the sweep spans so many fringes that its moments would take more than
            ``MAX_MOMENT_BYTES`` (the design FSR is then checked first), or for a subclass
            that fits every reading at once (the thermal calibrator: use :meth:`fit`).
        EdgeMinimumError
            As :meth:`fit`.

        Warns
        -----
        CalibrationWarning
            As :meth:`fit`.
        """
        self._check_params()
        if not self.plain_delay_phase:
            raise InputError(
                f"{type(self).__name__} fits every reading of its sweep at once: give the "
                "whole sweep to fit, not chunks to fit_chunks"
            )
        checked = CheckedChunks(chunks, dark_w)
        with one_blas_thread():
            moments, sample = self._accumulate(checked)
            if sample.samples < MIN_SAMPLES:
                raise InputError(f"need at least {MIN_SAMPLES} samples, got {sample.samples}")
            names = checked_port_names(port_names, sample.powers_w.shape[1])
            if sample.stride == 1:  # every reading kept: the sweep is in memory
                args = (sample.powers_w, sample.frequency_hz, sample.monitor_w, names, checked.dark)
                notes = super()._fit_sweep(*args, None)
            else:
                notes = self._fit_sampled(moments, sample, names, checked.dark, None)
        for note in notes:
            warnings.warn(note, stacklevel=2)
        return self

    def _fit_sweep(self, powers, frequency_hz, monitor, names, dark, temperature_k) -> list:
        """Every reading diagnosed up to ``diagnostic_samples`` of them; beyond, the fit on
        the moments and the checks on every k-th reading (:meth:`_fit_sampled`)."""
        if powers.shape[0] <= self.diagnostic_samples or not self.plain_delay_phase:
            return super()._fit_sweep(powers, frequency_hz, monitor, names, dark, temperature_k)
        blocks = (
            (
                frequency_hz[start : start + BLOCK_ROWS],
                powers[start : start + BLOCK_ROWS],
                None if monitor is None else monitor[start : start + BLOCK_ROWS],
            )
            for start in range(0, powers.shape[0], BLOCK_ROWS)
        )
        moments, sample = self._accumulate(blocks)
        return self._fit_sampled(moments, sample, names, dark, value_range(temperature_k))

    def _accumulate(self, chunks) -> tuple[FringeMoments | None, SweepSample]:
        """One pass over checked, dark-subtracted chunks: their moments (None once they
        outgrow ``MAX_MOMENT_BYTES``) and the sample."""
        moments = FringeMoments(largest_search_delay_s(self.fsr_hz, self.fsr_tolerance), 0.0)
        sample = SweepSample(self.diagnostic_samples)
        for frequency, powers, monitor in chunks:
            sample.add(frequency, powers, monitor)
            if moments is not None:
                moments.add(frequency, powers, monitor)
                if moments.nbytes > MAX_MOMENT_BYTES:
                    moments = None  # the check of the design FSR (on the sample) speaks first
        return moments, sample

    def _fit_sampled(self, moments, sample: SweepSample, names, dark, temperature_range) -> list:
        """Fit on the moments of every reading, check and diagnose on the sample; the
        warnings, not yet issued."""
        powers, frequency = sample.powers_w, sample.frequency_hz
        monitor = sample.monitor_w
        scale = None if monitor is None else monitor / sample.monitor_mean_w
        estimate = check_design_fsr(
            powers,
            frequency,
            fsr_hz=float(self.fsr_hz),
            fsr_tolerance=self.fsr_tolerance,
            scale=scale,
            step_hz=sample.median_step_hz(),
            span_hz=sample.span_hz,
        )
        if moments is None:
            raise InputError(
                f"the sweep spans {sample.span_hz / self.fsr_hz:.4g} FSRs of "
                f"{self.fsr_hz / 1e9:.6g} GHz: its binned moments would take more than "
                f"{MAX_MOMENT_BYTES >> 20} MiB; one map does not hold over so many FSRs: "
                "calibrate it per FSR (CalibrationSet) or with WidebandCalibrator",
                parameter="fsr_hz",
            )
        self._start_fit((sample.low_hz, sample.high_hz), names, sample.samples, dark)
        delay = 1.0 / self.fsr_hz if estimate is None else estimate.delay_s
        self._sweep_temperature_k = None
        health, notes = self._checked_port_health(powers, frequency, delay, scale)
        affine = (
            monitor is not None
            and dark is None
            and sample.monitor_relative_std >= AFFINE_MIN_POWER_SPREAD
        )
        moments.center_hz = self.center_hz_
        fit = _moment_fit(
            moments,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            search=self.search,
            xtol=self.xtol,
            affine=affine,
        )
        noise, self.noise_dof_ = _port_noise(
            moments.port_residual_w2(fit.delay_s, fit.map_), moments.samples, fit.map_.shape[1], 1
        )
        mean_scale = moments.mean_scale
        self._take_fit(fit, _relative_map(fit.map_, mean_scale), noise, sample.largest_w)
        self._sweep = (frequency, scale, affine)
        self._sweep_gram = _gram_objects(moments, fit.delay_s, affine, mean_scale)
        self._set_covariance()
        offsets = float(self.offset_w_.sum())
        low, high = sample.total_range_w
        self.total_power_range_w_ = (low - offsets, high - offsets)
        corrected = powers - self.offset_w_
        misfit = self._diagnose_fit(powers, corrected, frequency, scale, delay, None)
        return self._record_diagnostics(
            estimate,
            health,
            misfit,
            notes,
            temperature_range=temperature_range,
            diagnosed=powers.shape[0],
        )

    def _set_covariance(self) -> None:
        """Covariance of map (and offsets) and the nonlinear parameters at the current
        per-port noise."""
        affine = self._sweep[2]
        matrix = np.column_stack([self.map_, self.offset_w_]) if affine else self.map_
        objects, derivatives = self._sweep_objects()
        # the paper's fit is unweighted: the sandwich covariance holds for unequal noise
        self.parameter_covariance_ = fit_parameter_covariance(
            objects,
            derivatives,
            matrix,
            self.port_noise_std_w_,
            weighted=False,
            noise_directions_w=self._sweep_noise_directions_w(),
        )

    def _sweep_objects(self) -> tuple[np.ndarray, np.ndarray]:
        """The sweep's object vectors (N, k) and their derivatives (q, N, k) by the
        nonlinear parameters (here the delay alone); for a fit on the moments, rows with
        their products (:func:`_gram_objects`)."""
        if self._sweep_gram is not None:
            objects, derivative = self._sweep_gram
            return objects, derivative[None]
        frequency_hz, scale, affine = self._sweep
        args = (frequency_hz, self.center_hz_, self.delay_s_, scale, affine)
        return object_vectors(*args), object_delay_derivative(*args)[None]

    def _misfit_report(self, powers, frequency_hz, scale, sweep_delay_s) -> MisfitReport:
        offsets = self.offset_w_ if self._sweep[2] else None
        offset_std = None
        if offsets is not None:
            variances = np.diag(self.parameter_covariance_)[:-1].reshape(self.n_ports_, 4)
            offset_std = np.sqrt(variances[:, 3])
        return misfit_report(
            powers,
            frequency_hz,
            self.center_hz_,
            self.delay_s_,
            self.map_,
            scale=scale,
            offset_w=offsets,
            offset_std_w=offset_std,
            dark_given=self.dark_w_ is not None,
            weighted_retrieval=self.retrieval == "ml",
            phase_rad=self._sweep_model_phase_rad(),
            phase_noise_std_rad=self._sweep_phase_noise_rad(),
        )

    def _sweep_model_phase_rad(self) -> np.ndarray | None:
        """The model phase of each sweep reading when it is not ``2 pi (f - f0) tau``
        (None: it is)."""
        return None

    def _sweep_phase_noise_rad(self) -> np.ndarray | None:
        """Phase scatter (rad) the model expects of each sweep reading besides the
        detector noise (None: none)."""
        return None

    def _sweep_noise_directions_w(self) -> np.ndarray | None:
        """That scatter as noise of each sweep reading along one direction (N, n), W
        (None: none); see :func:`~wavemeter.model.uncertainty.fit_parameter_covariance`."""
        return None

    def _use_misfit_report(self, report: MisfitReport) -> None:
        """With a misfit, weight and state uncertainties with the model-free noise."""
        noise = report.misfit_noise()
        if noise is not None:
            self.port_noise_std_w_, self.noise_dof_ = noise
            self._set_covariance()
        del self._sweep
        vars(self).pop("_sweep_gram", None)  # a subclass's own fit sets none

    def _fsr_std_hz(self) -> float | None:
        """``FSR^2 sigma_tau`` (Hz); None for a file of 0.1, which did not keep it."""
        return None if self.delay_std_s_ is None else self.fsr_hz_**2 * self.delay_std_s_

    def _summary_values(self) -> dict:
        return {
            "delay_s": FitValue(self.delay_s_, self.delay_std_s_, "s"),
            "noise_std_w": FitValue(self.noise_std_w_, None, "W"),
            "cost_w2": FitValue(self.cost_, None, "W^2"),
        }

    def _set_map(self, matrix: np.ndarray) -> None:
        self.map_ = matrix
        self.map_pinv_ = linalg.pinv(matrix)

    def predict(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Source frequency (Hz) of each reading, within ``center_hz_ +- fsr_hz_/2``.

        The check of the readings, the offsets and the retrieval are one pass
        (:mod:`wavemeter.model.kernels`; numba on every core when installed): the numbers
        and errors of the steps taken one by one.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Accepted for the common prediction API; not needed by this calibrator.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        if not self.plain_delay_phase:  # the phase model has more than the delay: step by step
            return super().predict(powers, coarse_hz=coarse_hz, temperature_k=temperature_k)
        check_fitted(self)
        readings = reading_array(powers, ports=self.n_ports_)
        frequency = self._fused_frequency_hz(readings, self._reading_offset_w(), check=True)
        self._reading_inputs(coarse_hz, temperature_k, readings.shape[0])
        return frequency

    def _predict_checked(self, powers, temperature_k=None) -> np.ndarray:
        return self._fused_frequency_hz(powers, None, check=False)

    def _fused_frequency_hz(self, readings, offset_w, *, check: bool) -> np.ndarray:
        args = (self.center_hz_, self.fsr_hz_)
        if self.retrieval == "ml":
            noise = self.port_noise_std_w_
            return fused_ml_frequency_hz(
                readings, self.map_, *args, noise_std_w=noise, offset_w=offset_w, check=check
            )
        return fused_pinv_frequency_hz(
            readings, self.map_pinv_, *args, offset_w=offset_w, check=check
        )

    def _frequency_of_phase(self, phase_rad, temperature_k=None) -> np.ndarray:
        """Frequency (Hz) of readings whose retrieved phase is ``phase_rad`` (N,), as
        ``predict`` gives it (the same operations)."""
        return self.center_hz_ + phase_rad * self._hz_per_rad(temperature_k)

    def _phase(self, powers):
        if self.retrieval == "ml":
            return fused_ml_phase_rad(powers, self.map_, noise_std_w=self.port_noise_std_w_)
        return fused_pinv_phase_rad(powers, self.map_pinv_)

    def _phase_gradient(self, powers, phase) -> np.ndarray:
        """``dt / dp`` (N, n) of the retrieval used, at each reading."""
        if self.retrieval == "ml":
            power = source_power_ratio(powers, self.map_, phase, self.port_noise_std_w_)
            return ml_phase_gradient(self.map_, phase, power, self.port_noise_std_w_)
        return pinv_phase_gradient(powers, self.map_pinv_)

    def frequency_std_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, include_calibration=True
    ) -> np.ndarray:
        """Standard deviation (Hz) of each reading's frequency estimate.

        The delta method through the retrieval actually used (pseudo-inverse and arctangent,
        or the weighted maximum likelihood), with the per-port noise ``port_noise_std_w_``
        inflated by the Student factor of its ``noise_dof_``; with ``include_calibration``
        also the spread the fit's own parameter covariance gives
        (:mod:`wavemeter.model.uncertainty`). ``(estimate - true) / frequency_std_hz`` has
        unit standard deviation for in-model readings.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Accepted for the common prediction API; not needed by this calibrator.
        include_calibration : bool
            Add the calibration's own uncertainty (default) or give the reading noise only.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings, inputs = self._check_reading_data(powers, coarse_hz, temperature_k)
        return self._frequency_std_checked(readings, include_calibration, inputs["temperature_k"])

    def _frequency_std_checked(
        self, readings, include_calibration=True, temperature_k=None, phase_rad=None
    ) -> np.ndarray:
        """:meth:`frequency_std_hz` of checked, offset-corrected readings (N, n); their
        retrieved phase ``phase_rad`` (N,) when already known."""
        phase = self._phase(readings) if phase_rad is None else phase_rad
        gradient = self._phase_gradient(readings, phase)
        per_rad = self._hz_per_rad(temperature_k)
        variance = (phase_std_rad(gradient, self.port_noise_std_w_) * per_rad) ** 2
        if include_calibration and self.parameter_covariance_ is not None:
            power = source_power_ratio(readings, self.map_, phase, self.port_noise_std_w_)
            objects = cone_vectors(phase, power)
            if self._map_columns() == 4:
                objects = np.column_stack([objects, np.ones(objects.shape[0])])
            variance = variance + calibration_variance_hz2(
                map_frequency_gradient_hz(gradient, objects, per_rad),
                self._parameter_frequency_gradient_hz(phase, temperature_k),
                self.parameter_covariance_,
            )
        if self.noise_dof_ <= 2:
            # a noise estimated on 2 or fewer degrees of freedom bounds nothing
            return np.full(readings.shape[0], np.inf)
        # both parts scale with the estimated noise: one Student factor for its uncertainty
        variance = variance * student_factor(self.noise_dof_) ** 2
        return np.sqrt(variance + self._sensor_variance_hz2(phase, temperature_k))

    def _object_phase_rad(self, phase_rad, temperature_k=None):
        """The map's phase (rad) of a phase as :meth:`phase` returns it (the same here)."""
        return phase_rad

    def _map_columns(self) -> int:
        """Map columns ``k`` the parameter covariance holds: 3, or 4 with fitted offsets."""
        size = self.parameter_covariance_.shape[0] - self.nonlinear_parameters
        return size // self.n_ports_

    def _hz_per_rad(self, temperature_k=None):
        """``df / dt`` (Hz/rad): ``FSR / (2 pi)``."""
        return self.fsr_hz_ / (2.0 * np.pi)

    def _parameter_frequency_gradient_hz(self, phase_rad, temperature_k=None) -> np.ndarray:
        """``df / d theta`` (N, q) of readings of phase ``phase_rad`` for the nonlinear
        parameters (the delay: ``-t / (2 pi tau^2)``, Hz/s)."""
        return (-np.asarray(phase_rad) * self._hz_per_rad() / self.delay_s_)[:, None]

    def _sensor_variance_hz2(self, phase_rad, temperature_k=None):
        """Variance (Hz^2) from the per-reading inputs' own noise (none here)."""
        return 0.0

    def crlb_hz(self, powers, *, coarse_hz=None, temperature_k=None, phase_rad=None):
        """Cramer-Rao bound (Hz) of each reading under the calibrated map and port noise.

        Evaluated at the retrieved phase, or at ``phase_rad`` (rad, zero at ``center_hz_``;
        e.g. the true phase in an evaluation), and at the reading's own source power.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings, inputs = self._check_reading_data(powers, coarse_hz, temperature_k)
        if phase_rad is None:
            phase = self._phase(readings)
        else:
            phase = self._object_phase_rad(np.asarray(phase_rad, float), inputs["temperature_k"])
        power = source_power_ratio(readings, self.map_, phase, self.port_noise_std_w_)
        # the bound in phase (FSR 2 pi), in Hz at each reading's FSR
        phase_bound = crlb_frequency_std(self.map_, phase, power, self.port_noise_std_w_, 2 * np.pi)
        return phase_bound * self._hz_per_rad(inputs["temperature_k"])

    def reanchor(self, powers, frequency_hz, *, temperature_k=None) -> Calibrator:
        """A copy re-anchored to readings of reference lines of known frequency.

        The bias phase (and, when the lines pin it better than the sweep did, the delay) is
        corrected as :mod:`wavemeter.calibration.reanchor` describes; the phase of each
        reading is retrieved as :meth:`phase` does. This calibrator is untouched.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Readings of one or more reference lines (W, the unit of the calibration).
        frequency_hz : float or array_like, shape (N,)
            Known frequency of each reading (Hz); readings of equal frequency are one line.
        temperature_k : None, float or array_like, shape (N,)
            Accepted for the common API; not used by this calibrator.

        Returns
        -------
        Calibrator
            A deep copy with the corrected ``map_`` (and ``delay_s_``, ``fsr_hz_``,
            ``delay_std_s_``) and ``diagnostics_["reanchor"]``: ``phase_shift_rad``,
            ``phase_shift_std_rad``, ``delay_change_s`` (None when kept),
            ``delay_change_std_s``, ``lines_hz``, ``readings``.

        Raises
        ------
        InputError
            Naming ``powers``, ``frequency_hz`` or ``temperature_k`` for readings or values
            that are missing, not finite or of the wrong shape.
        """
        check_fitted(self)
        raw, frequency, _ = check_reference_readings(
            powers, frequency_hz, self.n_ports_, temperature_k
        )
        readings = raw - self._reading_offset_w()
        phase = self._phase(readings)
        reading_std = self._frequency_std_checked(readings, include_calibration=False)
        fit = fit_reanchor(
            phase,
            frequency,
            self.center_hz_,
            self.delay_s_,
            delay_std_s=self.delay_std_s_,
            reading_phase_std_rad=reading_std * (2.0 * np.pi / self.fsr_hz_),
        )
        return reanchored_copy(self, fit)

    def _span_margin_std_hz(self, readings, temperature_k=None):
        return self._frequency_std_checked(readings, temperature_k=temperature_k)

    def _cone_distance(self, readings, phase_rad) -> np.ndarray:
        """Weighted squared distance (N,) of each reading (offset-corrected) to the calibrated
        cone at ``phase_rad``, the source power fitted."""
        noise = self.port_noise_std_w_
        power = source_power_ratio(readings, self.map_, phase_rad, noise)
        residual = (readings - power[:, None] * (cone_vectors(phase_rad) @ self.map_.T)) / noise
        return np.einsum("ij,ij->i", residual, residual)

    def _off_model(self, readings):
        """Weighted squared distance of each reading to the calibrated cone (at the
        maximum-likelihood phase, the nearest point), tested."""
        phase = fused_ml_phase_rad(readings, self.map_, noise_std_w=self.port_noise_std_w_)
        distance = self._cone_distance(readings, phase)
        return distance > off_model_threshold(self.n_ports_, self.noise_dof_)

    def _stream_reader(self) -> Callable[[np.ndarray, dict], StreamReading]:
        """One pass over a reading (this class and the thermal one), for :meth:`stream`.

        ``predict``, ``frequency_std_hz`` and ``flags`` each check the calibration, the
        reading and its inputs, remove the offsets, and ``flags`` reads the frequency and its
        uncertainty again for the span test (the family's span margin is the reading's own
        ``frequency_std_hz``): here each is done once, and what does not change from reading
        to reading once per stream. The ``OFF_MODEL`` test is screened first: the reading's
        weighted squared distance to the calibrated cone at its retrieved phase (the source
        power fitted) is at least the distance at the maximum-likelihood phase that
        ``_off_model`` tests, so a reading whose distance there lies below the threshold by
        more than ``SCREEN_MARGIN`` (relative) is on the model; any other takes the test
        itself. The bits are those ``flags`` gives. The phase is retrieved once and gives the
        frequency, its uncertainty and the screen.
        """
        corrected = self._stream_corrector()
        partial = self._partial_span()
        on_model = off_model_threshold(self.n_ports_, self.noise_dof_) * (1.0 - SCREEN_MARGIN)
        invalid, off_model = int(ReadingFlag.INVALID), int(ReadingFlag.OFF_MODEL)

        def read(powers: np.ndarray, inputs: dict) -> StreamReading:
            readings = corrected(powers)
            given = {n: None if v is None else np.array([v]) for n, v in inputs.items()}
            temperature = given["temperature_k"]
            phase = self._phase(readings)  # once: the ML phase is the costly part
            frequency = self._frequency_of_phase(phase, temperature)
            std = self._frequency_std_checked(readings, True, temperature, phase_rad=phase)
            flags = self._light_flags(powers, readings)
            if not flags[0] & invalid:
                if partial:
                    flags |= self._span_flags(frequency, std)
                screened = self._cone_distance(readings, phase)[0]
                if screened > on_model and self._off_model(readings)[0]:
                    flags |= off_model
                flags |= self._input_flags(given["coarse_hz"], temperature)
            return StreamReading(float(frequency[0]), float(std[0]), int(flags[0]))

        return read

    def _state(self) -> dict:
        return {
            "map": self.map_.tolist(),
            "delay_s": self.delay_s_,
            "delay_std_s": self.delay_std_s_,
            "cost_w2": self.cost_,
            "residual_rms_w": self.residual_rms_,
            "noise_std_w": self.noise_std_w_,
            "port_noise_std_w": self.port_noise_std_w_.tolist(),
            "noise_dof": self.noise_dof_,
            "parameter_covariance": self.parameter_covariance_.tolist(),
        }

    def _set_state(self, state: dict) -> None:
        ports = self.n_ports_
        self._set_map(state_array(state, "map", (ports, 3)))
        self.delay_s_ = state_float(state, "delay_s", minimum=0.0, open_minimum=True)
        # files of 0.1 have no standard error of the delay
        self.delay_std_s_ = (
            state_float(state, "delay_std_s", minimum=0.0)
            if state.get("delay_std_s") is not None
            else None
        )
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)
        self.residual_rms_ = state_float(state, "residual_rms_w", minimum=0.0)
        self.noise_std_w_ = state_float(state, "noise_std_w", minimum=0.0)
        if "port_noise_std_w" in state:
            self.port_noise_std_w_ = state_array(state, "port_noise_std_w", (ports,))
            self.noise_dof_ = state_float(state, "noise_dof", minimum=2.0, open_minimum=True)
            self.parameter_covariance_ = state_array(state, "parameter_covariance", (None, None))
            size = self.parameter_covariance_.shape[0]
            sizes = (3 * ports + self.nonlinear_parameters, 4 * ports + self.nonlinear_parameters)
            if self.parameter_covariance_.shape != (size, size) or size not in sizes:
                raise ValueError(
                    f"field 'parameter_covariance' must be square of size {sizes[0]} or "
                    f"{sizes[1]}, got shape {self.parameter_covariance_.shape}"
                )
            if np.any(self.port_noise_std_w_ <= 0):
                raise ValueError("field 'port_noise_std_w' must hold positive numbers (W)")
        else:
            # schema 1: one pooled noise, its degrees of freedom, no parameter covariance
            self.port_noise_std_w_ = np.full(ports, self.noise_std_w_)
            self.noise_dof_ = max(self.n_samples_ * ports - 3.0 * ports - 1.0, 3.0)
            self.parameter_covariance_ = None
