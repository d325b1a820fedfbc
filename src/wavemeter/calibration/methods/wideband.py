"""One calibration across a band of many FSRs: a phase polynomial and a smooth map.

:mod:`wavemeter.calibration.models.wideband_fit` holds the model ``p = m A(y) u(t(y))``,
``t(y) = sum b_i y^i``, ``A(y) = sum A_j L_j(y)`` (``y = (f - f0) / h`` across the band)
and its fit; :mod:`wavemeter.calibration.models.wideband_orders` chooses the orders.
:class:`WidebandCalibrator` learns it from one sweep (gaps of whole FSRs allowed) and
reads absolute frequency from a reading and a coarse frequency within half an FSR, and
says what it knows of each reading:

* **uncertainty**: :meth:`WidebandCalibrator.frequency_std_hz` is the delta method through
  the retrieval used with each reading's own map, plus the spread the covariance of every
  fitted number (map coefficients and phase coefficients) gives, with the Student factor
  of the noise estimate, as for :class:`~wavemeter.calibration.methods.learned.Calibrator`;
* **flags**: ``OUTSIDE_SPAN`` for a frequency outside the calibrated band (by more than
  ``SPAN_MARGIN_STD`` standard deviations; a coarse value half an FSR beyond it has no
  map at all), ``ORDER_AMBIGUOUS`` where the frequency found lies more than
  ``ORDER_MARGIN_FSR`` of the local FSR from the coarse value (the order then rests on a
  coarse value that is itself that far off), ``OFF_MODEL`` as for the learned calibrator;
* the fit diagnostics of :mod:`wavemeter.calibration.checks.misfit` on the band model.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from ...exceptions import CalibrationWarning, InputError
from ...model.cone import wrap_phase_rad
from ...model.uncertainty import fit_parameter_covariance, student_factor
from ...validation import (
    check_choice,
    check_fitted,
    check_positive,
)
from ..checks.misfit import misfit_report
from ..contract.base import BaseCalibrator
from ..contract.flags import SPAN_MARGIN_STD, ReadingFlag
from ..contract.records import ReadingInputs, Readout
from ..contract.summary import FitValue
from ..files.document import state_array, state_float
from ..files.registry import calibrator_class
from ..fitting.steps import (
    SweepFitMixin,
    check_ports,
    diagnostics_record,
    fits_offsets,
    guard_design_fsr,
    rms,
)
from ..fitting.sweep import FitContext, Sweep
from ..models.delay_search import frequency_text
from ..models.learned_fit import RETRIEVALS, fit_learned_map, port_noise_std_w
from ..models.wideband_fit import (
    BandModel,
    band_frequency_hz,
    band_object_derivatives,
    band_objects,
    check_monotonic,
    fit_band,
    map_coefficients,
)
from ..models.wideband_orders import (
    MAX_MAP_ORDER,
    MAX_PHASE_ORDER,
    OrderSelection,
    highest_map_order,
    parameter_count,
    raise_orders,
    select_orders,
    window_count,
)
from .figures import (
    FRINGE_HALF_WIDTH_FSR,
    band_fringe_panel,
    near,
    pseudo_inverse,
    unit_power_samples,
)
from .wideband_reading import (
    band_crlb_hz,
    band_frequency_variance_hz2,
    band_off_model,
    band_phase_rad,
    residual_phase_by_window,
)
from .wideband_report import (
    PHASE_COEFFICIENT_NAMES,
    band_figures,
    band_tables,
    orders_text,
    residual_phase_text,
)

__all__ = ["ORDER_MARGIN_FSR", "WidebandCalibrator"]

#: the frequency found may lie this share of the local FSR from the coarse value unflagged
ORDER_MARGIN_FSR = 0.25
#: readings within one design FSR of the middle start the fit: at least this many
MIN_CENTRAL_READINGS = 16
#: phase order of the growth of the fit when the order is to be chosen
GROWTH_PHASE_ORDER = 2


def _order(name: str, value, lowest: int, highest: int) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int) or not lowest <= value <= highest:
        raise InputError(
            f"{name} must be None (chosen by cross-validation) or an integer from {lowest} to "
            f"{highest}; got {value!r}",
            parameter=name,
        )


@dataclass(eq=False)
class BandContext(FitContext):
    """The wide-band fit's state: the orders chosen and the final fit of the band model."""

    orders: OrderSelection | None = None
    fit: object = None


class WidebandCalibrator(SweepFitMixin, BaseCalibrator):
    """Learned calibration of a band of many FSRs (module docstring).

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz) at the middle of the band.
    fsr_tolerance : float
        Relative half width of the FSR bracket searched, in (0, 1).
    phase_order : None or int
        Order ``P`` of the phase polynomial (1: the paper's linear phase), 1 to
        ``MAX_PHASE_ORDER``; None: chosen by cross-validation on held-out FSRs.
    map_order : None or int
        Legendre order ``J`` of the map in frequency (0: one map), 0 to ``MAX_MAP_ORDER``;
        None: chosen by cross-validation.
    retrieval : {"pinv", "ml"}
        Phase retrieval under each reading's map, as for
        :class:`~wavemeter.calibration.methods.learned.Calibrator`.

    Attributes
    ----------
    phase_coefficients_ : ndarray, shape (P,)
        Taylor coefficients ``c_i`` (s^i) of the phase in angular detuning:
        ``t = sum_i c_i w^i / i!``, ``w = 2 pi (f - center_hz_)``: the delay ``c_1``
        (``delay_s_``), the group-delay dispersion ``c_2`` (s^2), ...
        A map of order ``J`` may rotate about the cone axis along the band, which is a
        phase term of order up to ``J``: those coefficients are told from the map only to
        second order (their standard errors in ``diagnostics_["wideband"]`` say how well);
        the frequencies read are not affected.
    phase_coefficients_rad_ : ndarray, shape (P,)
        The same as ``b_i`` (rad): ``t = sum_i b_i y^i``, ``y = (f - center_hz_) / h``.
    map_coefficients_ : ndarray, shape (J + 1, n, 3)
        Legendre coefficients ``A_j`` (W) of the map ``A(y) = sum_j A_j L_j(y)``.
    band_model_ : BandModel
        The model as :mod:`wavemeter.calibration.models.wideband_fit` evaluates it: the phase and
        the map at any frequency (``phase_rad``, ``maps_at``, ...).
    phase_order_, map_order_ : int
        ``P`` and ``J``.
    n_parameters_ : int
        Fitted numbers: ``3 n (J + 1)`` map coefficients, ``n`` offsets if fitted, ``P``.
    span_hz_ : (float, float)
        The calibrated band (Hz): lowest and highest sweep frequency.
    half_span_hz_ : float
        ``h`` (Hz), half the band.
    delay_s_, fsr_hz_ : float
        Delay ``c_1`` (s) and FSR ``1 / c_1`` (Hz) at ``center_hz_``; :meth:`fsr_hz_at`
        gives the local FSR.
    offset_w_ : ndarray, shape (n,)
        Fitted per-port offsets (W); zeros unless fitted.
    port_noise_std_w_, noise_std_w_, noise_dof_, parameter_covariance_
        As for :class:`~wavemeter.calibration.methods.learned.Calibrator`; the covariance holds the
        map coefficients (row-major over ports, then the design columns) and ``b``.
    diagnostics_ : dict
        As the learned calibrator's, plus ``"wideband"``: orders, how they were chosen
        (the cross-validation curve), the phase coefficients with standard errors and the
        residual phase per FSR window across the band.
    """

    method = "wideband"
    requires = frozenset({"coarse_hz"})
    comparison_misfits_expected = True
    capabilities = frozenset({"frequency_std", "crlb", "power_monitor"})

    def __init__(
        self,
        fsr_hz: float = 50e9,
        fsr_tolerance: float = 0.2,
        phase_order: int | None = None,
        map_order: int | None = None,
        retrieval: str = "pinv",
    ):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.phase_order = phase_order
        self.map_order = map_order
        self.retrieval = retrieval

    def _check_params(self) -> None:
        super()._check_params()
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        _order("phase_order", self.phase_order, 1, MAX_PHASE_ORDER)
        _order("map_order", self.map_order, 0, MAX_MAP_ORDER)
        check_choice("retrieval", self.retrieval, RETRIEVALS)

    def _fsr_tolerance(self) -> float:
        return self.fsr_tolerance

    def _requirement_reason(self) -> str:
        return (
            "a wide-band calibration reads the fringe order from each reading's approximate "
            "frequency (Hz, within half an FSR, e.g. the laser set point)"
        )

    # ------------------------------------------------------------------ fitting
    def _fit_sweep(self, sweep: Sweep) -> list:
        """The steps: the design FSR checked on the readings near the middle of the band
        (where the fit starts), the band model fitted (the ports' fringes are seen through
        it), the ports checked at its phases, the fit taken and judged on every reading;
        the warnings, not yet issued."""
        ctx = BandContext(sweep)
        central = self._central_rows(sweep.frequency_hz)
        guard_design_fsr(ctx, self.fsr_hz, self.fsr_tolerance, central)
        self._start_fit(sweep.span_hz, sweep.port_names, sweep.samples, sweep.dark_w)
        ctx.affine = fits_offsets(sweep)
        self._fit_band(ctx, central)
        check_ports(
            ctx,
            self.center_hz_,
            range(sweep.ports),
            self.fringe_ports_needed,
            phase_rad=ctx.fit.phase_rad,
        )
        self._take_band_fit(ctx)
        self._take_power_range(sweep.powers_w)
        readings = sweep.powers_w - self.offset_w_
        error = self._frequency_checked(readings, sweep.frequency_hz)[0] - sweep.frequency_hz
        self.calibration_rms_hz_ = rms(error)
        misfit = self._misfit_report(ctx)
        noise = misfit.misfit_noise()
        if noise is not None:  # weight and state uncertainties with the model-free noise
            self.port_noise_std_w_, self.noise_dof_ = noise
            self._set_covariance(ctx)
        record = self._band_record(ctx, self._residual_phase_by_window(ctx, readings))
        self.diagnostics_, notes = diagnostics_record(ctx, misfit, method={"wideband": record})
        return notes

    def _central_rows(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The readings within one design FSR of the reading nearest the middle of the band
        (at least ``MIN_CENTRAL_READINGS``)."""
        middle = 0.5 * (frequency_hz.min() + frequency_hz.max())
        anchor = frequency_hz[np.argmin(np.abs(frequency_hz - middle))]
        distance = np.abs(frequency_hz - anchor)
        rows = distance <= float(self.fsr_hz)
        if np.count_nonzero(rows) < MIN_CENTRAL_READINGS:
            rows = distance <= np.sort(distance)[min(MIN_CENTRAL_READINGS, distance.size) - 1]
        return rows

    def _fit_band(self, ctx: BandContext, central: np.ndarray) -> None:
        """The paper's delay on the central readings, the fit grown to the band, the
        orders, the final fit on every reading (into ``ctx``)."""
        sweep, center_hz, scale, affine = ctx.sweep, self.center_hz_, ctx.sweep.scale, ctx.affine
        powers, frequency_hz = sweep.powers_w, sweep.frequency_hz
        start = fit_learned_map(
            powers[central],
            frequency_hz[central],
            center_hz,
            fsr_hz=float(self.fsr_hz),
            fsr_tolerance=self.fsr_tolerance,
            scale=None if scale is None else scale[central],
            affine=affine,
        )
        half = 0.5 * float(np.ptp(frequency_hz))
        windows = window_count(frequency_hz, 1.0 / start.delay_s)
        if self.map_order is not None and self.map_order > highest_map_order(windows):
            raise InputError(
                f"map_order {self.map_order} needs readings in at least {self.map_order + 2} "
                f"FSR windows (a map of that order could rotate each of fewer windows as it "
                f"likes, which leaves the phase undetermined); the sweep has {windows}: "
                "give a lower map_order, or None to choose it",
                parameter="map_order",
            )
        radius = float(np.abs(frequency_hz[central] - center_hz).max())
        grown = fit_band(
            powers,
            frequency_hz,
            center_hz,
            half,
            start.delay_s,
            radius,
            phase_order=self.phase_order or GROWTH_PHASE_ORDER,
            scale=scale,
            affine=affine,
        )
        fsr = 2.0 * np.pi * half / grown[0]
        orders = select_orders(
            powers,
            frequency_hz,
            center_hz,
            half,
            grown,
            fsr,
            functools.partial(band_phase_rad, retrieval="pinv", noise_std_w=None),
            scale=scale,
            affine=affine,
            phase_order=self.phase_order,
            map_order=self.map_order,
        )
        ctx.orders, ctx.fit = raise_orders(
            orders,
            powers,
            frequency_hz,
            center_hz,
            half,
            grown,
            fsr,
            scale=scale,
            affine=affine,
            phase_fixed=self.phase_order is not None,
            map_fixed=self.map_order is not None,
        )
        self._check_fsr(2.0 * np.pi * half / ctx.fit.coefficients_rad[0])

    def _check_fsr(self, fsr_hz: float) -> None:
        """Refuse a fitted FSR outside the bracket searched (the fit lost the fringes)."""
        low = float(self.fsr_hz) * (1.0 - self.fsr_tolerance)
        high = float(self.fsr_hz) * (1.0 + self.fsr_tolerance)
        if not low <= fsr_hz <= high:
            raise InputError(
                f"the wide-band fit has an FSR of {frequency_text(fsr_hz)} at the middle of the "
                f"band, outside the bracket searched ({frequency_text(low)} to "
                f"{frequency_text(high)}): the fringes were not followed across the band; set "
                "fsr_hz closer to the chip's FSR, or sweep FSRs nearer to each other",
                parameter="fsr_hz",
            )

    def _take_band_fit(self, ctx: BandContext) -> None:
        """The fitted band model: orders, coefficients, offsets, noise, covariance."""
        fit, orders, powers = ctx.fit, ctx.orders, ctx.sweep.powers_w
        ports = powers.shape[1]
        self.half_span_hz_ = 0.5 * (self.span_hz_[1] - self.span_hz_[0])
        self.phase_order_ = orders.phase_order
        self.map_order_ = orders.map_order
        coefficients, offsets = map_coefficients(fit.matrix, orders.map_order)
        self._set_model(fit.coefficients_rad, coefficients)
        self.offset_w_ = np.zeros(ports) if offsets is None else offsets
        self.n_parameters_ = parameter_count(
            ports, orders.phase_order, orders.map_order, ctx.affine
        )
        self.cost_ = fit.cost
        self.residual_rms_ = float(np.sqrt(fit.cost / ports))
        pooled_dof = max(powers.size - fit.matrix.size - orders.phase_order, 1)
        self.noise_std_w_ = float(np.sqrt(fit.cost * powers.shape[0] / pooled_dof))
        noise, self.noise_dof_ = port_noise_std_w(
            fit.residual_w, fit.matrix.shape[0], shared=orders.phase_order
        )
        # noiseless (simulated) sweeps: keep weights finite at the readings' rounding level
        self.port_noise_std_w_ = np.maximum(noise, np.finfo(float).eps * np.abs(powers).max())
        self._set_covariance(ctx)

    def _set_model(self, coefficients_rad, map_coefficients_w) -> None:
        """The learned band model and the attributes derived from it; raises when the
        phase does not rise across the band."""
        self.band_model_ = BandModel(
            self.center_hz_,
            self.half_span_hz_,
            np.asarray(coefficients_rad, dtype=float),
            np.asarray(map_coefficients_w, dtype=float),
        )
        check_monotonic(self.band_model_)
        self.phase_coefficients_rad_ = self.band_model_.phase_coefficients_rad
        self.map_coefficients_ = self.band_model_.map_coefficients_w
        self.phase_coefficients_ = self.phase_coefficients_rad_ * self._seconds_per_rad()
        self.delay_s_ = float(self.phase_coefficients_[0])
        self.fsr_hz_ = 1.0 / self.delay_s_

    def _seconds_per_rad(self) -> np.ndarray:
        """``c_i / b_i = i! / (2 pi h)^i`` (s^i/rad): the Taylor coefficients in angular
        detuning from those in ``y``."""
        orders = np.arange(1, self.phase_coefficients_rad_.size + 1)
        factorials = np.array([math.factorial(order) for order in orders], dtype=float)
        return factorials / (2.0 * np.pi * self.half_span_hz_) ** orders

    def _affine(self) -> bool:
        """Offsets were fitted: the covariance holds a column of ones per port."""
        columns = (self.parameter_covariance_.shape[0] - self.phase_order_) // self.n_ports_
        return columns > 3 * (self.map_order_ + 1)

    def _sweep_design(self, ctx: BandContext) -> tuple[np.ndarray, np.ndarray]:
        """The sweep's design columns (N, q) and their derivatives (P, N, q) by ``b``."""
        frequency_hz, scale, affine = ctx.sweep.frequency_hz, ctx.sweep.scale, ctx.affine
        y = self.band_model_.normalized(frequency_hz)
        phase = self.band_model_.phase_rad(frequency_hz)
        objects = band_objects(y, phase, scale, self.map_order_, affine)
        derivatives = band_object_derivatives(
            y, phase, scale, self.map_order_, affine, self.phase_order_
        )
        return objects, derivatives

    def _design_matrix(self, affine: bool) -> np.ndarray:
        """The least-squares coefficients as a map (n, q): ``A_j`` blocks, then offsets."""
        blocks = self.map_coefficients_.transpose(0, 2, 1).reshape(-1, self.n_ports_)
        if affine:
            blocks = np.vstack([blocks, self.offset_w_])
        return blocks.T

    def _set_covariance(self, ctx: BandContext) -> None:
        objects, derivatives = self._sweep_design(ctx)
        self.parameter_covariance_ = fit_parameter_covariance(
            objects,
            derivatives,
            self._design_matrix(ctx.affine),
            self.port_noise_std_w_,
            weighted=False,
        )

    def _misfit_report(self, ctx: BandContext):
        """The fit diagnostics on the band model; a phase the polynomial left, even in
        frequency (``dispersion``), is remedied by a higher phase order here."""
        report = self._band_misfit_report(ctx)
        if "dispersion" not in report.causes:
            return report
        remedy = (
            f"set a higher phase_order (this fit has {self.phase_order_}), or sweep more FSRs "
            "so that cross-validation can choose the orders"
        )
        notes = tuple(
            CalibrationWarning(
                str(note).replace(note.remedy, remedy), cause=note.cause, remedy=remedy
            )
            if note.cause == "dispersion"
            else note
            for note in report.warnings
        )
        return dataclasses.replace(report, warnings=notes)

    def _band_misfit_report(self, ctx: BandContext):
        objects, _ = self._sweep_design(ctx)
        powers, frequency_hz, scale = ctx.sweep.powers_w, ctx.sweep.frequency_hz, ctx.sweep.scale
        y = self.band_model_.normalized(frequency_hz)
        offsets = offset_std = None
        if ctx.affine:
            columns = 3 * (self.map_order_ + 1) + 1
            variances = np.diag(self.parameter_covariance_)[: self.n_ports_ * columns]
            offsets = self.offset_w_
            offset_std = np.sqrt(variances.reshape(self.n_ports_, columns)[:, -1])
        return misfit_report(
            powers,
            frequency_hz,
            self.center_hz_,
            self.delay_s_,
            self.band_model_.maps_at(frequency_hz),
            scale=scale,
            offset_w=offsets,
            offset_std_w=offset_std,
            dark_given=self.dark_w_ is not None,
            weighted_retrieval=self.retrieval == "ml",
            phase_rad=self.band_model_.phase_rad(frequency_hz),
            design=objects,
            phase_derivatives=np.power.outer(y, np.arange(1, self.phase_order_ + 1)).T,
        )

    def _residual_phase_by_window(self, ctx: BandContext, readings) -> list[dict]:
        """Retrieved minus model phase (rad) of the sweep's offset-corrected readings, by
        FSR window: what the fit left across the band."""
        frequency_hz = ctx.sweep.frequency_hz
        maps = self.band_model_.maps_at(frequency_hz)
        residual = wrap_phase_rad(
            self._retrieve(readings, maps) - self.band_model_.phase_rad(frequency_hz)
        )
        return residual_phase_by_window(frequency_hz, residual, self.span_hz_[0], self.fsr_hz_)

    def _band_record(self, ctx: BandContext, residual_phase: list) -> dict:
        """``diagnostics_["wideband"]``: the orders and how they were chosen, the phase
        coefficients with their standard errors, the residual phase per FSR window."""
        std = np.sqrt(np.diag(self.parameter_covariance_)[-self.phase_order_ :])
        return {
            "phase_order": self.phase_order_,
            "map_order": self.map_order_,
            "n_parameters": self.n_parameters_,
            "orders": ctx.orders.record(),
            "phase_coefficients_s": self.phase_coefficients_.tolist(),
            "phase_coefficients_std_s": (std * self._seconds_per_rad()).tolist(),
            "residual_phase": residual_phase,
        }

    # ------------------------------------------------------------------ retrieval
    def _retrieve(self, readings, maps) -> np.ndarray:
        """Phase (rad) of each reading under its own map, by the retrieval set."""
        return band_phase_rad(readings, maps, self.retrieval, self.port_noise_std_w_)

    def _frequency_checked(self, readings, coarse_hz):
        """:func:`band_frequency_hz` of validated, offset-corrected readings."""
        return band_frequency_hz(self.band_model_, readings, coarse_hz, self._retrieve)

    def _coarse_inside(self, coarse_hz: np.ndarray) -> np.ndarray:
        """Whether each coarse frequency lies within half an FSR of the calibrated band."""
        low, high = self.span_hz_
        margin = 0.5 * self.fsr_hz_
        return (coarse_hz >= low - margin) & (coarse_hz <= high + margin)

    def _coverage(self, inputs: ReadingInputs):
        low, high = self.span_hz_
        return (
            self._coarse_inside(inputs.coarse_hz),
            f"more than half an FSR outside the calibrated band {low / 1e12:.6f} to "
            f"{high / 1e12:.6f} THz: the calibration has no map there",
        )

    def _frequency_hz(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """Absolute frequency (Hz): of the frequencies the reading's phase allows, the one
        nearest its coarse value."""
        return self._frequency_checked(readings, inputs.coarse_hz)[0]

    def _phase_rad(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """The retrieved phase under each reading's map: the model phase ``t(f)`` of the
        frequency found, wrapped."""
        return self._frequency_checked(readings, inputs.coarse_hz)[1]

    def model_phase_rad(self, frequency_hz) -> np.ndarray:
        """The model phase ``t(f)`` (rad, wrapped to (-pi, pi]) at frequencies (Hz): what
        :meth:`phase` returns for a reading at ``f`` without noise."""
        check_fitted(self)
        return wrap_phase_rad(self.band_model_.phase_rad(frequency_hz))

    def fsr_hz_at(self, frequency_hz) -> np.ndarray:
        """The local FSR ``2 pi / (dt / df)`` (Hz) at frequencies (Hz)."""
        check_fitted(self)
        return 2.0 * np.pi / self.band_model_.phase_slope_rad_per_hz(frequency_hz)

    def _frequency_std(self, readings, inputs: ReadingInputs, include_calibration: bool):
        """The delta method through the retrieval used with each reading's own map, plus the
        spread the covariance of every fitted number gives, with the Student factor."""
        read = self._frequency_checked(readings, inputs.coarse_hz)
        return self._frequency_std_of(readings, *read, include_calibration)

    def _frequency_std_of(
        self, readings, frequency, phase, maps, include_calibration=True, noise_scale=1.0
    ):
        """Standard deviation (Hz) of readings already read: their frequency (Hz), phase
        (rad) and maps, as :func:`band_frequency_hz` returns them; with a detector noise
        ``noise_scale`` times the calibrated one (the calibration's part unchanged)."""
        variance = band_frequency_variance_hz2(
            self.band_model_,
            readings,
            frequency,
            phase,
            maps,
            retrieval=self.retrieval,
            noise_std_w=noise_scale * self.port_noise_std_w_,
            covariance=self.parameter_covariance_ if include_calibration else None,
            affine=self._affine(),
        )
        if self.noise_dof_ <= 2:
            return np.full(readings.shape[0], np.inf)
        return np.sqrt(variance) * student_factor(self.noise_dof_)

    def _crlb(self, readings, inputs: ReadingInputs, frequency_hz) -> np.ndarray:
        """The bound under each reading's map and the port noise, at the frequency read or
        at ``frequency_hz`` (its model phase)."""
        if frequency_hz is None:
            frequency, phase, _ = self._frequency_checked(readings, inputs.coarse_hz)
        else:
            frequency, phase = frequency_hz, self.band_model_.phase_rad(frequency_hz)
        return band_crlb_hz(self.band_model_, readings, frequency, phase, self.port_noise_std_w_)

    def _model_flags(self, readings, inputs: ReadingInputs) -> np.ndarray:
        return self._readout(readings, inputs).flags

    def _readout(self, readings, inputs: ReadingInputs) -> Readout:
        """One reading of the band model gives the frequency, its standard deviation and the
        flags: ``OUTSIDE_SPAN`` (outside the band by more than ``SPAN_MARGIN_STD``
        standard deviations), ``ORDER_AMBIGUOUS`` (more than ``ORDER_MARGIN_FSR`` of the
        local FSR from the coarse value), ``OFF_MODEL``."""
        coarse = inputs.coarse_hz
        frequency, phase, maps = self._frequency_checked(readings, coarse)
        std = self._frequency_std_of(readings, frequency, phase, maps)
        margin = SPAN_MARGIN_STD * std
        low, high = self.span_hz_
        flags = np.where(
            (frequency < low - margin) | (frequency > high + margin),
            np.int64(ReadingFlag.OUTSIDE_SPAN),
            np.int64(0),
        )
        local_fsr = 2.0 * np.pi / self.band_model_.phase_slope_rad_per_hz(frequency)
        flags[np.abs(frequency - coarse) > ORDER_MARGIN_FSR * local_fsr] |= (
            ReadingFlag.ORDER_AMBIGUOUS
        )
        off_model = band_off_model(readings, maps, self.port_noise_std_w_, self.noise_dof_)
        flags[off_model] |= ReadingFlag.OFF_MODEL
        return Readout(frequency, std, flags, {}, phase)

    # ------------------------------------------------------------------ reporting
    def _fsr_std_hz(self) -> float | None:
        """``FSR^2 sigma(c_1)`` (Hz)."""
        std = float(np.sqrt(self.parameter_covariance_[-self.phase_order_, -self.phase_order_]))
        return self.fsr_hz_**2 * std * self._seconds_per_rad()[0]

    def _summary_values(self) -> dict:
        std = (
            np.sqrt(np.diag(self.parameter_covariance_)[-self.phase_order_ :])
            * self._seconds_per_rad()
        )
        values = {
            "delay_s": FitValue(self.delay_s_, float(std[0]), "s"),
            "phase_order": FitValue(float(self.phase_order_), None, "", "phase order P"),
            "map_order": FitValue(float(self.map_order_), None, "", "map order J"),
            "n_parameters": FitValue(float(self.n_parameters_), None, "", "fitted parameters"),
            "noise_std_w": FitValue(self.noise_std_w_, None, "W"),
            "cost_w2": FitValue(self.cost_, None, "W^2", "cost J"),
        }
        for order in range(2, self.phase_order_ + 1):
            values[f"phase_coefficient_{order}_s{order}"] = FitValue(
                float(self.phase_coefficients_[order - 1]),
                float(std[order - 1]),
                f"s^{order}",
                PHASE_COEFFICIENT_NAMES.get(order, f"phase coefficient c{order}"),
            )
        return values

    def summary(self):
        """The fit report, with the candidate orders scored and the residual phase."""
        report = super().summary()
        record = (self.diagnostics_ or {}).get("wideband")
        if not record:
            return report
        notes = [text for text in (orders_text(record), residual_phase_text(record)) if text]
        return dataclasses.replace(
            report,
            tables=(*report.tables, *band_tables(record)),
            notes=(*report.notes, *notes),
        )

    def comparison(self, port_phases_rad=None):
        """The learned calibration set per FSR with the same settings: the other way to
        cover a band (what one model of the band buys)."""
        window = calibrator_class("learned")(
            fsr_hz=self.fsr_hz, fsr_tolerance=self.fsr_tolerance, retrieval=self.retrieval
        )
        return calibrator_class("calibration_set")(self.fsr_hz, self.fsr_tolerance, window=window)

    def fringe_panels(self, frequency_hz, powers_w, monitor_w=None, temperature_k=None):
        """The sweep within ``FRINGE_HALF_WIDTH_FSR`` of the reading nearest the middle of
        the band (the sweep may have a gap there) under the band model."""
        frequency = np.asarray(frequency_hz, dtype=float)
        anchor = frequency[np.argmin(np.abs(frequency - self.center_hz_))]
        panel = band_fringe_panel(
            self.band_model_,
            frequency,
            np.asarray(powers_w, dtype=float),
            monitor_w=None if monitor_w is None else np.asarray(monitor_w, dtype=float),
            rows=near(frequency, anchor, self.fsr_hz_),
            noise_std_w=self.noise_std_w_,
            title=f"readings within {FRINGE_HALF_WIDTH_FSR:g} FSR of the one nearest the "
            "middle of the band",
        )
        return (panel,)

    def object_samples(self, powers_w, frequency_hz, temperature_k=None):
        """Each reading under the map at the frequency it is read at (the truth as its
        coarse frequency)."""
        truth = np.asarray(frequency_hz, dtype=float)
        powers = np.asarray(powers_w, dtype=float)
        frequency = self.predict(powers, coarse_hz=truth)
        inverses = pseudo_inverse(self.band_model_.maps_at(frequency))
        return unit_power_samples(inverses, powers, self.phase(powers, coarse_hz=truth))

    def report_figures(self, noise_std_hz=None):
        record = (self.diagnostics_ or {}).get("wideband")
        if not record:
            return ()
        noise_rad = None if noise_std_hz is None else 2.0 * np.pi * noise_std_hz / self.fsr_hz_
        return band_figures(record, self.center_hz_, noise_rad)

    # ------------------------------------------------------------------ files
    def _state(self) -> dict:
        return {
            "phase_order": self.phase_order_,
            "map_order": self.map_order_,
            "phase_coefficients_rad": self.phase_coefficients_rad_.tolist(),
            "map_coefficients": self.map_coefficients_.tolist(),
            "n_parameters": self.n_parameters_,
            "cost_w2": self.cost_,
            "residual_rms_w": self.residual_rms_,
            "noise_std_w": self.noise_std_w_,
            "port_noise_std_w": self.port_noise_std_w_.tolist(),
            "noise_dof": self.noise_dof_,
            "parameter_covariance": self.parameter_covariance_.tolist(),
        }

    def _set_state(self, state: dict) -> None:
        ports = self.n_ports_
        phase_order = int(state_float(state, "phase_order", minimum=1, maximum=MAX_PHASE_ORDER))
        map_order = int(state_float(state, "map_order", minimum=0, maximum=MAX_MAP_ORDER))
        if phase_order != state["phase_order"] or map_order != state["map_order"]:
            raise ValueError("fields 'phase_order' and 'map_order' must be integers")
        self.phase_order_, self.map_order_ = phase_order, map_order
        self.half_span_hz_ = 0.5 * (self.span_hz_[1] - self.span_hz_[0])
        if not self.half_span_hz_ > 0:
            raise ValueError("field 'span_hz' must have low < high for a wide-band calibration")
        self._set_model(
            state_array(state, "phase_coefficients_rad", (phase_order,)),
            state_array(state, "map_coefficients", (map_order + 1, ports, 3)),
        )
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)
        self.residual_rms_ = state_float(state, "residual_rms_w", minimum=0.0)
        self.noise_std_w_ = state_float(state, "noise_std_w", minimum=0.0)
        self.port_noise_std_w_ = state_array(state, "port_noise_std_w", (ports,))
        if np.any(self.port_noise_std_w_ <= 0):
            raise ValueError("field 'port_noise_std_w' must hold positive numbers (W)")
        self.noise_dof_ = state_float(state, "noise_dof", minimum=2.0, open_minimum=True)
        columns = 3 * (map_order + 1)
        self.parameter_covariance_ = state_array(state, "parameter_covariance", (None, None))
        sizes = (ports * columns + phase_order, ports * (columns + 1) + phase_order)
        size = self.parameter_covariance_.shape[0]
        if self.parameter_covariance_.shape != (size, size) or size not in sizes:
            raise ValueError(
                f"field 'parameter_covariance' must be square of size {sizes[0]} or {sizes[1]}, "
                f"got shape {self.parameter_covariance_.shape}"
            )
        self.n_parameters_ = parameter_count(ports, phase_order, map_order, self._affine())
