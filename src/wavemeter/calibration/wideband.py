"""One calibration across a band of many FSRs: a phase polynomial and a smooth map.

:mod:`wavemeter.calibration.wideband_fit` holds the model ``p = m A(y) u(t(y))``,
``t(y) = sum b_i y^i``, ``A(y) = sum A_j L_j(y)`` (``y = (f - f0) / h`` across the band)
and its fit; :mod:`wavemeter.calibration.wideband_orders` chooses the orders.
:class:`WidebandCalibrator` learns it from one sweep (gaps of whole FSRs allowed) and
reads absolute frequency from a reading and a coarse frequency within half an FSR, and
says what it knows of each reading:

* **uncertainty**: :meth:`WidebandCalibrator.frequency_std_hz` is the delta method through
  the retrieval used with each reading's own map, plus the spread the covariance of every
  fitted number (map coefficients and phase coefficients) gives, with the Student factor
  of the noise estimate, as for :class:`~wavemeter.calibration.learned.Calibrator`;
* **flags**: ``OUTSIDE_SPAN`` for a frequency outside the calibrated band (by more than
  ``SPAN_MARGIN_STD`` standard deviations; a coarse value half an FSR beyond it has no
  map at all), ``ORDER_AMBIGUOUS`` where the frequency found lies more than
  ``ORDER_MARGIN_FSR`` of the local FSR from the coarse value (the order then rests on a
  coarse value that is itself that far off), ``OFF_MODEL`` as for the learned calibrator;
* the fit diagnostics of :mod:`wavemeter.calibration.misfit` on the band model.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from ..exceptions import CalibrationWarning, InputError
from ..model.cone import wrap_phase_rad
from ..model.uncertainty import fit_parameter_covariance, student_factor
from ..validation import (
    check_choice,
    check_coarse_inside,
    check_fitted,
    check_per_reading,
    check_positive,
)
from .base import BaseCalibrator
from .delay_search import frequency_text
from .diagnostics import port_health
from .files import state_array, state_float
from .flags import SPAN_MARGIN_STD, ReadingFlag
from .learned import AFFINE_MIN_POWER_SPREAD, RETRIEVALS, fit_learned_map, port_noise_std_w
from .misfit import misfit_report
from .summary import FitValue
from .wideband_fit import (
    BandModel,
    band_frequency_hz,
    band_object_derivatives,
    band_objects,
    check_monotonic,
    fit_band,
    map_coefficients,
)
from .wideband_orders import (
    MAX_MAP_ORDER,
    MAX_PHASE_ORDER,
    OrderSelection,
    highest_map_order,
    parameter_count,
    raise_orders,
    select_orders,
    window_count,
)
from .wideband_reading import (
    band_crlb_hz,
    band_frequency_variance_hz2,
    band_off_model,
    band_phase_rad,
    residual_phase_by_window,
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


class WidebandCalibrator(BaseCalibrator):
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
        :class:`~wavemeter.calibration.learned.Calibrator`.

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
        The model as :mod:`wavemeter.calibration.wideband_fit` evaluates it: the phase and
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
        As for :class:`~wavemeter.calibration.learned.Calibrator`; the covariance holds the
        map coefficients (row-major over ports, then the design columns) and ``b``.
    diagnostics_ : dict
        As the learned calibrator's, plus ``"wideband"``: orders, how they were chosen
        (the cross-validation curve), the phase coefficients with standard errors and the
        residual phase per FSR window across the band.
    """

    method = "wideband"
    requires = frozenset({"coarse_hz"})
    capabilities = frozenset({"frequency_std", "power_monitor"})

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
    def _check_sweep(self, powers, frequency_hz, scale, temperature_k):
        """The design FSR on the readings within one design FSR of the reading nearest the
        middle of the band (where the fit starts)."""
        middle = 0.5 * (frequency_hz.min() + frequency_hz.max())
        anchor = frequency_hz[np.argmin(np.abs(frequency_hz - middle))]
        distance = np.abs(frequency_hz - anchor)
        rows = distance <= float(self.fsr_hz)
        if np.count_nonzero(rows) < MIN_CENTRAL_READINGS:
            rows = distance <= np.sort(distance)[min(MIN_CENTRAL_READINGS, distance.size) - 1]
        self._central = rows
        return super()._check_sweep(
            powers[rows], frequency_hz[rows], None if scale is None else scale[rows], None
        )

    def _port_health(self, powers, frequency_hz, center_hz, delay_s, names, scale):
        """Fit the band model (the ports' fringes are seen through it), then every port's
        fringe at the fitted phases."""
        self._fit_band(powers, frequency_hz, center_hz, scale)
        return port_health(
            powers,
            frequency_hz,
            center_hz,
            delay_s,
            names,
            scale,
            phase_rad=self._band_fit.phase_rad,
        )

    def _fit_band(self, powers, frequency_hz, center_hz, scale) -> None:
        """The paper's delay on the central readings, the fit grown to the band, the
        orders, the final fit on every reading."""
        central = self._central
        del self._central
        affine = (
            scale is not None and self.dark_w_ is None and np.std(scale) >= AFFINE_MIN_POWER_SPREAD
        )
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
        self._orders = select_orders(
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
        self._orders, self._band_fit = raise_orders(
            self._orders,
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
        self._check_fsr(2.0 * np.pi * half / self._band_fit.coefficients_rad[0])
        self._sweep = (frequency_hz, scale, affine)

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

    def _fit(self, powers, frequency_hz, monitor):
        fit, orders = self._band_fit, self._orders
        del self._band_fit
        _, scale, affine = self._sweep
        ports = powers.shape[1]
        self.half_span_hz_ = 0.5 * (self.span_hz_[1] - self.span_hz_[0])
        self.phase_order_ = orders.phase_order
        self.map_order_ = orders.map_order
        coefficients, offsets = map_coefficients(fit.matrix, orders.map_order)
        self._set_model(fit.coefficients_rad, coefficients)
        self.offset_w_ = np.zeros(ports) if offsets is None else offsets
        self.n_parameters_ = parameter_count(ports, orders.phase_order, orders.map_order, affine)
        self.cost_ = fit.cost
        self.residual_rms_ = float(np.sqrt(fit.cost / ports))
        pooled_dof = max(powers.size - fit.matrix.size - orders.phase_order, 1)
        self.noise_std_w_ = float(np.sqrt(fit.cost * powers.shape[0] / pooled_dof))
        noise, self.noise_dof_ = port_noise_std_w(
            fit.residual_w, fit.matrix.shape[0], shared=orders.phase_order
        )
        # noiseless (simulated) sweeps: keep weights finite at the readings' rounding level
        self.port_noise_std_w_ = np.maximum(noise, np.finfo(float).eps * np.abs(powers).max())
        self._set_covariance()
        self._residual_phase = self._residual_phase_by_window(powers - self.offset_w_)

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

    def _sweep_design(self) -> tuple[np.ndarray, np.ndarray]:
        """The sweep's design columns (N, q) and their derivatives (P, N, q) by ``b``."""
        frequency_hz, scale, affine = self._sweep
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

    def _set_covariance(self) -> None:
        objects, derivatives = self._sweep_design()
        self.parameter_covariance_ = fit_parameter_covariance(
            objects,
            derivatives,
            self._design_matrix(self._sweep[2]),
            self.port_noise_std_w_,
            weighted=False,
        )

    def _misfit_report(self, powers, frequency_hz, scale, sweep_delay_s):
        """The fit diagnostics on the band model; a phase the polynomial left, even in
        frequency (``dispersion``), is remedied by a higher phase order here."""
        report = self._band_misfit_report(powers, frequency_hz, scale)
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

    def _band_misfit_report(self, powers, frequency_hz, scale):
        objects, _ = self._sweep_design()
        y = self.band_model_.normalized(frequency_hz)
        offsets = offset_std = None
        if self._sweep[2]:
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

    def _use_misfit_report(self, report) -> None:
        """With a misfit, weight and state uncertainties with the model-free noise."""
        noise = report.misfit_noise()
        if noise is not None:
            self.port_noise_std_w_, self.noise_dof_ = noise
            self._set_covariance()
        del self._sweep

    def _residual_phase_by_window(self, readings) -> list[dict]:
        """Retrieved minus model phase (rad) of the sweep's offset-corrected readings, by
        FSR window: what the fit left across the band."""
        frequency_hz = self._sweep[0]
        maps = self.band_model_.maps_at(frequency_hz)
        residual = wrap_phase_rad(
            self._retrieve(readings, maps) - self.band_model_.phase_rad(frequency_hz)
        )
        return residual_phase_by_window(frequency_hz, residual, self.span_hz_[0], self.fsr_hz_)

    def _sweep_error_hz(self, readings, frequency_hz, temperature_k):
        """Frequency error (Hz) of the sweep read back with its true frequencies as coarse
        values (absolute)."""
        return self._frequency_checked(readings, frequency_hz)[0] - frequency_hz

    def _method_diagnostics(self) -> dict:
        orders: OrderSelection = self._orders
        del self._orders
        std = np.sqrt(np.diag(self.parameter_covariance_)[-self.phase_order_ :])
        record = {
            "phase_order": self.phase_order_,
            "map_order": self.map_order_,
            "n_parameters": self.n_parameters_,
            "orders": orders.record(),
            "phase_coefficients_s": self.phase_coefficients_.tolist(),
            "phase_coefficients_std_s": (std * self._seconds_per_rad()).tolist(),
            "residual_phase": self._residual_phase,
        }
        del self._residual_phase
        return {"wideband": record}

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

    def _readings_and_coarse(self, powers, coarse_hz, temperature_k):
        readings, inputs = self._check_reading_data(powers, coarse_hz, temperature_k)
        coarse = inputs["coarse_hz"]
        low, high = self.span_hz_
        check_coarse_inside(
            coarse,
            self._coarse_inside(coarse),
            f"more than half an FSR outside the calibrated band {low / 1e12:.6f} to "
            f"{high / 1e12:.6f} THz: the calibration has no map there",
            parameter="coarse_hz",
        )
        return readings, coarse

    def predict(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Absolute source frequency (Hz) of each reading.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz : float or array_like, shape (N,)
            Approximate frequency of each reading (Hz) within half an FSR of the truth (the
            laser set point, a coarse meter): it picks the fringe order. Required.
        temperature_k : None, float or array_like, shape (N,)
            Accepted for the common prediction API; not used.

        Returns
        -------
        ndarray, shape (N,), Hz

        Raises
        ------
        InputError
            When ``coarse_hz`` is missing, of the wrong length, not finite, or more than
            half an FSR outside the calibrated band.
        """
        readings, coarse = self._readings_and_coarse(powers, coarse_hz, temperature_k)
        return self._frequency_checked(readings, coarse)[0]

    def phase(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Retrieved phase (rad) in (-pi, pi] under each reading's map; the model phase
        ``t(f)`` of the frequency :meth:`predict` returns, wrapped.

        Parameters and errors as for :meth:`predict`.

        Returns
        -------
        ndarray, shape (N,), rad
        """
        readings, coarse = self._readings_and_coarse(powers, coarse_hz, temperature_k)
        return self._frequency_checked(readings, coarse)[1]

    def model_phase_rad(self, frequency_hz) -> np.ndarray:
        """The model phase ``t(f)`` (rad, wrapped to (-pi, pi]) at frequencies (Hz): what
        :meth:`phase` returns for a reading at ``f`` without noise."""
        check_fitted(self)
        return wrap_phase_rad(self.band_model_.phase_rad(frequency_hz))

    def fsr_hz_at(self, frequency_hz) -> np.ndarray:
        """The local FSR ``2 pi / (dt / df)`` (Hz) at frequencies (Hz)."""
        check_fitted(self)
        return 2.0 * np.pi / self.band_model_.phase_slope_rad_per_hz(frequency_hz)

    def frequency_std_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, include_calibration=True
    ) -> np.ndarray:
        """Standard deviation (Hz) of each reading's frequency (module docstring).

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
        coarse_hz : float or array_like, shape (N,)
            As for :meth:`predict`; required.
        temperature_k : None
            Accepted for the common prediction API; not used.
        include_calibration : bool
            Add the calibration's own uncertainty (default) or give the reading noise only.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings, coarse = self._readings_and_coarse(powers, coarse_hz, temperature_k)
        read = self._frequency_checked(readings, coarse)
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

    def crlb_hz(self, powers, *, coarse_hz=None, temperature_k=None, phase_rad=None):
        """Cramer-Rao bound (Hz) of each reading under its map and the port noise.

        At the frequency :meth:`predict` returns, or, given ``phase_rad`` (the model phase
        ``t(f)`` of the frequency to evaluate at, wrapped; e.g. at the true frequency in an
        evaluation, with that frequency as ``coarse_hz``), at the frequency of that phase
        nearest the coarse value.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings, coarse = self._readings_and_coarse(powers, coarse_hz, temperature_k)
        if phase_rad is None:
            frequency, phase, _ = self._frequency_checked(readings, coarse)
        else:
            phase = check_per_reading("phase_rad", phase_rad, readings.shape[0])
            reference = self.band_model_.phase_rad(coarse)
            target = reference + wrap_phase_rad(phase - reference)
            frequency = self.band_model_.frequency_of_phase_hz(target, coarse)
        return band_crlb_hz(self.band_model_, readings, frequency, phase, self.port_noise_std_w_)

    def _model_flags(self, readings, coarse_hz, temperature_k) -> np.ndarray:
        """``OUTSIDE_SPAN`` (a frequency outside the band by more than ``SPAN_MARGIN_STD``
        standard deviations, or a coarse value half an FSR beyond it), ``ORDER_AMBIGUOUS``
        and ``OFF_MODEL`` (module docstring)."""
        flags = np.zeros(readings.shape[0], dtype=np.int64)
        inside = self._coarse_inside(coarse_hz)
        flags[~inside] |= ReadingFlag.OUTSIDE_SPAN
        if not inside.any():
            return flags
        rows, coarse = readings[inside], coarse_hz[inside]
        frequency, phase, maps = self._frequency_checked(rows, coarse)
        margin = SPAN_MARGIN_STD * self._frequency_std_of(rows, frequency, phase, maps)
        low, high = self.span_hz_
        bits = np.where(
            (frequency < low - margin) | (frequency > high + margin),
            np.int64(ReadingFlag.OUTSIDE_SPAN),
            np.int64(0),
        )
        local_fsr = 2.0 * np.pi / self.band_model_.phase_slope_rad_per_hz(frequency)
        bits[np.abs(frequency - coarse) > ORDER_MARGIN_FSR * local_fsr] |= (
            ReadingFlag.ORDER_AMBIGUOUS
        )
        off_model = band_off_model(rows, maps, self.port_noise_std_w_, self.noise_dof_)
        bits[off_model] |= ReadingFlag.OFF_MODEL
        flags[inside] |= bits
        return flags

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
            "phase_order": FitValue(float(self.phase_order_), None, ""),
            "map_order": FitValue(float(self.map_order_), None, ""),
            "n_parameters": FitValue(float(self.n_parameters_), None, ""),
            "noise_std_w": FitValue(self.noise_std_w_, None, "W"),
            "cost_w2": FitValue(self.cost_, None, "W^2"),
        }
        for order in range(2, self.phase_order_ + 1):
            values[f"phase_coefficient_{order}_s{order}"] = FitValue(
                float(self.phase_coefficients_[order - 1]), float(std[order - 1]), f"s^{order}"
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
