"""The learned calibration of the paper (Section II.C): closed-form map, 1-D delay search.

:class:`Calibrator` fits the map ``A`` in closed form for each trial delay and searches
only the delay (:mod:`~wavemeter.calibration.models.learned_fit`); it reads with the
pseudo-inverse and an arctangent, or the cone maximum likelihood
(:mod:`~wavemeter.calibration.methods.learned_reading`). Beyond the paper it subtracts
dark readings or fits per-port offsets, estimates each port's noise, states every
reading's uncertainty with the calibration's own, and fits a sweep too long for memory on
its binned moments with the checks on every k-th reading. Theory: the docs' theory pages
(the learned method, uncertainty per reading, large sweeps).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...model.cone import wrap_to_period
from ...model.uncertainty import fit_parameter_covariance
from ...validation import check_choice, check_fitted, check_positive
from ..checks.misfit import MisfitReport, misfit_report
from ..contract.base import BaseCalibrator
from ..contract.records import ReadingInputs
from ..contract.summary import FitValue
from ..files import fields
from ..files.state import state_array, state_float
from ..fitting.steps import (
    SweepFitMixin,
    check_ports,
    diagnostics_record,
    fits_offsets,
    guard_design_fsr,
    rms,
)
from ..fitting.sweep import FitContext, Sweep
from ..models.delay_search import SEARCH_METHODS
from ..models.learned_fit import RETRIEVALS, LearnedFit, fit_learned_map, port_noise_std_w
from ..models.linear_map import object_delay_derivative, object_vectors
from ..models.reanchor import check_reference_readings, fit_reanchor, reanchored_copy
from ..models.subsample import DIAGNOSTIC_SAMPLES
from .learned_chunks import LargeSweepMixin
from .learned_reading import LearnedReadingMixin
from .learned_report import LearnedReportMixin

__all__ = ["Calibrator", "LearnedContext"]


@dataclass(eq=False)
class LearnedContext(FitContext):
    """The learned fit's state: besides the common one, for a fit on the binned moments of
    a long sweep, rows whose products equal those of every reading's objects
    (:func:`~wavemeter.calibration.models.learned_fit.gram_objects`); None when the sweep
    in ``sweep`` is every reading."""

    gram: tuple | None = None


class Calibrator(
    LearnedReadingMixin, LearnedReportMixin, LargeSweepMixin, SweepFitMixin, BaseCalibrator
):
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
        Noise per port (W) used for weights and uncertainties: each port's own residual
        with at least ``PER_PORT_MIN_DOF`` degrees of freedom, else the pooled one; where
        the fit diagnostics find a misfit, their model-free estimate.
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
    off_model_basis_ : OffModelBasis or None
        The sweep's distances to the cone and what ``OFF_MODEL`` compares a reading's
        with: the detector noise or, where those distances show a model error, the
        residual the sweep's readings share at their phase (subtracted first) and the
        noise's distribution scaled to what remains
        (:mod:`~wavemeter.calibration.contract.off_model`). None for a file written by 0.7
        or older (the detector-noise test).
    diagnostics_ : dict
        The sweep's own FSR estimate, every port's fringe amplitude and significance, the
        fit diagnostics (:mod:`wavemeter.calibration.checks.misfit`), the readings they saw
        (``"diagnostic_samples"``) and the warnings the fit emitted (saved to file).

    Notes
    -----
    A sweep of more than ``diagnostic_samples`` readings (2^17), or one read in chunks
    (:meth:`fit_chunks`), is fitted on the binned moments of every reading: delay, map,
    ``cost_``, the noise, ``parameter_covariance_`` and ``delay_std_s_`` describe the fit
    on every reading (equal to those of the direct fit to ~1e-9, the cancellation of ``J``
    from sums). The check of the design FSR, the port health, the misfit report and
    ``calibration_rms_hz_`` are made on every k-th reading at that fit
    (:mod:`wavemeter.calibration.models.subsample`).

    Examples
    --------
    Calibrate a simulated 3x3 meter (Table 1's impairments) from a sweep of 200 readings
    over one FSR at 1 mW with 0.5 uW of detector noise:

    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> cal.map_.shape
    (3, 3)

    The delay search finds the device's FSR (its delay is 3 % off the 50 GHz design) to
    within 5 MHz:

    >>> print(f"fitted FSR {cal.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    fitted FSR 51.51 GHz, true 51.50 GHz

    On ten readings the sweep did not contain, the error is at the per-reading Cramer-Rao
    bound of this device (14 MHz, see :func:`~wavemeter.crlb_frequency_std`), which the stated
    standard deviation follows:

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> error_hz = cal.predict(test) - test_hz
    >>> print(f"RMS error {np.sqrt(np.mean(error_hz**2)) / 1e6:.0f} MHz")
    RMS error 17 MHz
    >>> print(f"stated std {np.median(cal.frequency_std_hz(test)) / 1e6:.0f} MHz")
    stated std 14 MHz
    """

    method = "learned"
    capabilities = frozenset(
        {"frequency_std", "crlb", "power_monitor", "reanchor", "fit_chunks", "reference_cell"}
    )
    #: nonlinear parameters after the map in ``parameter_covariance_`` (the delay)
    nonlinear_parameters: ClassVar[int] = 1
    #: most readings the checks and diagnostics see (:mod:`~wavemeter.calibration.models.subsample`)
    diagnostic_samples: ClassVar[int] = DIAGNOSTIC_SAMPLES
    #: what each number of the file's state may hold (:mod:`~wavemeter.calibration.files.fields`)
    state_rules = fields.rule_table(
        {
            "map": fields.MAP_RULE,
            "delay_s": fields.DELAY_RULE,
            "delay_std_s": fields.DELAY_STD_RULE,
            **fields.NOISE_MODEL_RULES,
            "parameter_covariance": fields.CovarianceRule(tail=(("the delay", "delay_s", 1.0),)),
        }
    )

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

    # ------------------------------------------------------------------ fitting
    def _fit_sweep(self, sweep: Sweep) -> list:
        """Every reading fitted and checked up to ``diagnostic_samples`` of them; beyond,
        the fit on the moments of every reading and the checks on every k-th."""
        if sweep.samples > self.diagnostic_samples and self.plain_delay_phase:
            return self._fit_on_moments(sweep)
        return self._fit_every_reading(sweep)

    #: the fit's state from step to step
    _context = LearnedContext

    def _fit_every_reading(self, sweep: Sweep) -> list:
        """The steps on every reading: check, learn, judge; the warnings, not yet issued."""
        ctx = self._context(sweep)
        guard_design_fsr(ctx, self.fsr_hz, self.fsr_tolerance)
        self._start_fit(sweep.span_hz, sweep.port_names, sweep.samples, sweep.dark_w)
        check_ports(ctx, self.center_hz_, range(sweep.ports), self.fringe_ports_needed)
        ctx.affine = fits_offsets(sweep)
        fit = fit_learned_map(
            sweep.powers_w,
            sweep.frequency_hz,
            self.center_hz_,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            scale=sweep.scale,
            search=self.search,
            xtol=self.xtol,
            affine=ctx.affine,
        )
        objects = object_vectors(
            sweep.frequency_hz, self.center_hz_, fit.delay_s, sweep.scale, ctx.affine
        )
        noise, self.noise_dof_ = port_noise_std_w(
            sweep.powers_w - objects @ fit.map_.T, fit.map_.shape[1]
        )
        self._take_fit(fit, fit.map_, noise, float(np.abs(sweep.powers_w).max()))
        self._set_covariance(ctx)
        self._take_power_range(sweep.powers_w)
        return self._judged(ctx)

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

    def _judged(self, ctx: LearnedContext) -> list:
        """The fit judged on the readings in ``ctx``: the RMS error on them, the misfit
        report (its model-free noise taken where it finds a misfit), their distances to
        the cone (``off_model_basis_``), ``diagnostics_``; every warning, in order."""
        sweep = ctx.sweep
        readings = sweep.powers_w - self.offset_w_
        inputs = ReadingInputs(temperature_k=sweep.temperature_k)
        error = wrap_to_period(
            self._frequency_hz(readings, inputs) - sweep.frequency_hz, self.fsr_hz_
        )
        self.calibration_rms_hz_ = rms(error)
        misfit = self._misfit_report(ctx)
        noise = misfit.misfit_noise()
        if noise is not None:  # weight and state uncertainties with the model-free noise
            self.port_noise_std_w_, self.noise_dof_ = noise
            self._set_covariance(ctx)
        distance = self._cone_distance(readings, self._ml_phase_rad(readings))
        self._judge_distances(distance, readings, self.map_, self._phase(readings))
        self.diagnostics_, notes = diagnostics_record(
            ctx, misfit, method=self._method_record(ctx), notes=self._fit_notes(ctx)
        )
        return notes

    def _method_record(self, ctx: LearnedContext) -> dict:
        """Method-specific entries of ``diagnostics_`` (none here)."""
        return {}

    def _fit_notes(self, ctx: LearnedContext) -> list:
        """Method-specific warnings of the fit (none here)."""
        return []

    # ------------------------------------------------------------------ the model on the sweep
    def _set_covariance(self, ctx: LearnedContext) -> None:
        """Covariance of map (and offsets) and the nonlinear parameters at the current
        per-port noise (the paper's fit is unweighted: the sandwich covariance holds for
        unequal noise)."""
        matrix = np.column_stack([self.map_, self.offset_w_]) if ctx.affine else self.map_
        objects, derivatives = self._sweep_objects(ctx)
        self.parameter_covariance_ = fit_parameter_covariance(
            objects,
            derivatives,
            matrix,
            self.port_noise_std_w_,
            weighted=False,
            noise_directions_w=self._sweep_noise_directions_w(ctx),
        )

    def _sweep_objects(self, ctx: LearnedContext) -> tuple[np.ndarray, np.ndarray]:
        """The sweep's object vectors (N, k) and their derivatives (q, N, k) by the
        nonlinear parameters (here the delay alone); for a fit on the moments, rows with
        their products."""
        if ctx.gram is not None:
            objects, derivative = ctx.gram
            return objects, derivative[None]
        sweep = ctx.sweep
        args = (sweep.frequency_hz, self.center_hz_, self.delay_s_, sweep.scale, ctx.affine)
        return object_vectors(*args), object_delay_derivative(*args)[None]

    def _misfit_report(self, ctx: LearnedContext) -> MisfitReport:
        """The sweep against this calibration's cone map (:mod:`~..checks.misfit`)."""
        sweep = ctx.sweep
        offsets = offset_std = None
        if ctx.affine:
            offsets = self.offset_w_
            variances = np.diag(self.parameter_covariance_)[: 4 * self.n_ports_]
            offset_std = np.sqrt(variances.reshape(self.n_ports_, 4)[:, 3])
        return misfit_report(
            sweep.powers_w,
            sweep.frequency_hz,
            self.center_hz_,
            self.delay_s_,
            self.map_,
            scale=sweep.scale,
            offset_w=offsets,
            offset_std_w=offset_std,
            dark_given=self.dark_w_ is not None,
            weighted_retrieval=self.retrieval == "ml",
            phase_rad=self._sweep_model_phase_rad(ctx),
            phase_noise_std_rad=self._sweep_phase_noise_rad(ctx),
            axis_bandwidth_per_reading=sweep.axis_bandwidth_per_reading,
            method=self.method,
        )

    def _sweep_model_phase_rad(self, ctx: LearnedContext) -> np.ndarray | None:
        """The model phase of each sweep reading when it is not ``2 pi (f - f0) tau``
        (None: it is)."""
        return None

    def _sweep_phase_noise_rad(self, ctx: LearnedContext) -> np.ndarray | None:
        """Phase scatter (rad) the model expects of each sweep reading besides the
        detector noise (None: none)."""
        return None

    def _sweep_noise_directions_w(self, ctx: LearnedContext) -> np.ndarray | None:
        """That scatter as noise of each sweep reading along one direction (N, n), W
        (None: none); see :func:`~wavemeter.model.uncertainty.fit_parameter_covariance`."""
        return None

    # ------------------------------------------------------------------ re-anchoring
    def reanchor(self, powers, frequency_hz, *, temperature_k=None) -> Calibrator:
        """A copy re-anchored to readings of reference lines of known frequency.

        The bias phase (and, when the lines pin it better than the sweep did, the delay) is
        corrected as :mod:`wavemeter.calibration.models.reanchor` describes; the phase of
        each reading is retrieved as :meth:`phase` does. This calibrator is untouched.

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
            ``delay_change_std_s``, ``lines_hz``, ``readings``, ``reference_check`` (how
            each line's readings scattered against the calibration's noise).

        Raises
        ------
        InputError
            Naming ``powers``, ``frequency_hz`` or ``temperature_k`` for readings or values
            that are missing, not finite or of the wrong shape; ``frequency_hz`` when the
            readings of a line scatter far beyond the calibration's noise (not readings of
            that line: :mod:`~wavemeter.calibration.models.reference_check`).

        Warns
        -----
        CalibrationWarning
            (cause ``"reference_scatter"``) When a line scatters more than the calibration's
            noise, short of that; the warning is kept in the copy's ``diagnostics_``.
        """
        check_fitted(self)
        raw, frequency, _ = check_reference_readings(
            powers, frequency_hz, self.n_ports_, temperature_k
        )
        readings = raw - self._reading_offset_w()
        phase = self._phase(readings)
        reading_std = self._frequency_std_at(readings, include_calibration=False)
        fit = fit_reanchor(
            phase,
            frequency,
            self.center_hz_,
            self.delay_s_,
            delay_std_s=self.delay_std_s_,
            reading_phase_std_rad=reading_std * (2.0 * np.pi / self.fsr_hz_),
            noise_dof=self.noise_dof_,
        )
        return reanchored_copy(self, fit)

    # ------------------------------------------------------------------ description and files
    def _fsr_std_hz(self) -> float | None:
        """``FSR^2 sigma_tau`` (Hz); None for a file of 0.1, which did not keep it."""
        return None if self.delay_std_s_ is None else self.fsr_hz_**2 * self.delay_std_s_

    def _summary_values(self) -> dict:
        return {
            "delay_s": FitValue(self.delay_s_, self.delay_std_s_, "s"),
            "noise_std_w": FitValue(self.noise_std_w_, None, "W"),
            "cost_w2": FitValue(self.cost_, None, "W^2", "cost J"),
        }

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
            **self._off_model_state(),
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
        else:
            # schema 1: one pooled noise, its degrees of freedom, no parameter covariance
            self.port_noise_std_w_ = np.full(ports, self.noise_std_w_)
            self.noise_dof_ = max(self.n_samples_ * ports - 3.0 * ports - 1.0, 3.0)
            self.parameter_covariance_ = None
        self._set_off_model_state(state)
