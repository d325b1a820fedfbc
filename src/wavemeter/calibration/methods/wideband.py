"""One calibration across a band of many FSRs: a phase polynomial and a smooth map.

:class:`WidebandCalibrator` learns the wide-band model
(:mod:`~wavemeter.calibration.models.wideband_fit`, its orders chosen by
:mod:`~wavemeter.calibration.models.wideband_orders`) from one sweep, gaps of whole FSRs
allowed: the paper's delay on the central FSRs, the fit grown to the band, the orders by
cross-validation, the ports and the residual judged on the band model. It reads absolute
frequency from a reading and a coarse frequency within half an FSR
(:mod:`~wavemeter.calibration.methods.wideband_reading`). Theory: the docs' wide-band page.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...units import frequency_text
from ...validation import check_choice, check_positive
from ..contract.base import BaseCalibrator
from ..contract.summary import FitValue
from ..files import fields
from ..files.document import state_array, state_float
from ..fitting.steps import (
    SweepFitMixin,
    check_ports,
    diagnostics_record,
    fits_offsets,
    guard_design_fsr,
    rms,
)
from ..fitting.sweep import FitContext, Sweep
from ..models.band_reading import band_cone_distance, band_phase_rad
from ..models.learned_fit import RETRIEVALS, fit_learned_map, port_noise_std_w
from ..models.wideband_fit import BandModel, check_monotonic, fit_band, map_coefficients
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
from .wideband_checks import BandChecksMixin
from .wideband_reading import ORDER_MARGIN_FSR, BandReadingMixin
from .wideband_report import BAND_RECORD_RULES, PHASE_COEFFICIENT_NAMES, BandReportMixin

__all__ = ["MAX_PHASE_TERM", "ORDER_MARGIN_FSR", "WidebandCalibrator"]

#: largest phase coefficient a file may hold, in units of the phase a linear term gives half
#: the band (pi span / FSR): dispersion changes the FSR across a band by percents, not tenfold
MAX_PHASE_TERM = 10.0

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


class WidebandCalibrator(
    BandReadingMixin, BandReportMixin, BandChecksMixin, SweepFitMixin, BaseCalibrator
):
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
    port_noise_std_w_, noise_std_w_, noise_dof_, parameter_covariance_, off_model_basis_
        As for :class:`~wavemeter.calibration.methods.learned.Calibrator` (the sweep's cone
        distances each under the map at its frequency); the covariance holds the
        map coefficients (row-major over ports, then the design columns) and ``b``.
    diagnostics_ : dict
        As the learned calibrator's, plus ``"wideband"``: orders, how they were chosen
        (the cross-validation curve), the phase coefficients with standard errors and the
        residual phase per FSR window across the band.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> chip = wm.Interferometer.table1(ports=3, seed=7).with_spectral("sin", seed=3)  # dispersion
    >>> f_hz = chip.sweep_hz(2000, span_fsr=10)  # ten FSRs, 500 GHz
    >>> powers = chip.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> cal = wm.WidebandCalibrator(fsr_hz=50e9).fit(powers, f_hz)

    Dispersion bends the phase: cross-validation on held-out FSRs picks a quadratic phase
    and a map linear in frequency:

    >>> cal.phase_order_, cal.map_order_
    (2, 1)
    >>> test_hz = f_hz[50::400] + 1e8
    >>> test = chip.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> coarse_hz = test_hz + 5e9  # a coarse frequency within half an FSR picks the order
    >>> error_hz = cal.predict(test, coarse_hz=coarse_hz) - test_hz
    >>> print(np.abs(error_hz).max() < 100e6)
    True
    """

    method = "wideband"
    requires = frozenset({"coarse_hz"})
    comparison_misfits_expected = True
    capabilities = frozenset({"frequency_std", "crlb", "power_monitor"})
    diagnostics_rules = BAND_RECORD_RULES
    #: what each number of the file's state may hold (:mod:`~wavemeter.calibration.files.fields`)
    state_rules = fields.rule_table(
        {
            "phase_order": fields.FieldRule(
                "the phase polynomial's order", "", 1, MAX_PHASE_ORDER, integer=True
            ),
            "map_order": fields.FieldRule("the map's order", "", 0, MAX_MAP_ORDER, integer=True),
            "n_parameters": fields.FieldRule("the fitted parameters", "", 1, integer=True),
            "phase_coefficients_rad": fields.FieldRule(
                "a phase coefficient",
                "rad",
                high=MAX_PHASE_TERM,
                scale="band_phase_rad",
                magnitude=True,
            ),
            "map_coefficients": (
                fields.ScaleRule(
                    "the map's coefficients",
                    fields.largest_singular_value,
                    "the largest singular value of the map's mean over the band",
                ),
                fields.FieldRule(
                    "a map coefficient",
                    "W",
                    high=fields.SPREAD_RELATIVE,
                    scale="power_w",
                    magnitude=True,
                ),
            ),
            **fields.NOISE_MODEL_RULES,
            "parameter_covariance": fields.CovarianceRule(
                tail=(("a phase coefficient", "band_phase_rad", MAX_PHASE_TERM),),
                tail_repeats="phase_order",
            ),
        }
    )

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
        maps = self.band_model_.maps_at(sweep.frequency_hz)
        self._judge_distances(band_cone_distance(readings, maps, self.port_noise_std_w_))
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
            **self._off_model_state(),
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
        coefficients_rad = state_array(state, "phase_coefficients_rad", (phase_order,))
        linear = 2.0 * np.pi * self.half_span_hz_ / self.fsr_hz_  # the delay, in rad
        if not abs(coefficients_rad[0] / linear - 1.0) <= fields.DELAY_RTOL:
            raise InputError(
                "field 'phase_coefficients_rad' must start with the linear term 2 pi (half the "
                f"span) / fsr_hz = {linear!r} rad (the delay), got {coefficients_rad.tolist()}"
            )
        try:
            self._set_model(
                coefficients_rad, state_array(state, "map_coefficients", (map_order + 1, ports, 3))
            )
        except InputError as exc:  # the fit's wording: say which field
            raise InputError(
                f"field 'phase_coefficients_rad' must give a phase rising across the band: {exc}"
            ) from exc
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)
        self.residual_rms_ = state_float(state, "residual_rms_w", minimum=0.0)
        self.noise_std_w_ = state_float(state, "noise_std_w", minimum=0.0)
        self.port_noise_std_w_ = state_array(state, "port_noise_std_w", (ports,))
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
        if state.get("n_parameters") != self.n_parameters_:
            raise InputError(
                f"field 'n_parameters' must be {self.n_parameters_}, the parameters of the orders "
                f"and ports, got {fields.shown(state.get('n_parameters'))}"
            )
        self._set_off_model_state(state)
