"""Thermally compensated calibration: the learned calibrator on the thermal model.

:mod:`wavemeter.calibration.models.thermal_fit` holds the model ``p = A u(t)``, ``t = 2 pi (f - f0)
tau0 (1 + beta dT) + alpha dT``, and its fit. :class:`ThermalCalibrator` learns it from
sweeps at several temperatures (or a recording while the temperature changes), reads a
reading at its temperature, ``f = f0 + wrap(t_hat - alpha dT) / (2 pi tau0 (1 + beta dT))``,
and says what the temperatures could not tell:

* a bias rate resolved only modulo ``2 pi / step`` within less than a chip's fringes may
  move warns (cause ``"thermal_ambiguity"``); temperatures that cannot separate the rates
  are refused, and so is a fitted rate too imprecise: ``RATE_BUDGET_K`` kelvin away from
  ``T0`` its error may cost at most one reading's phase noise;
* **uncertainty**: :meth:`ThermalCalibrator.frequency_std_hz` adds to the learned
  calibrator's (noise and the parameter covariance, now of the map and all three of
  ``theta``) the temperature sensor's noise ``temperature_std_k`` times ``df / dT``;
* **the sensor's noise in the calibration temperatures** scatters each calibration
  reading's phase by ``temperature_std_k |dt/dT|`` along its fringe tangent. The parameter
  covariance holds it (a sandwich term), the detector noise is estimated without it, and
  the fit diagnostics expect it; where it holds ``SENSOR_SHARE_NOTED`` of a port's residual
  power, a ``temperature_noise`` warning says so, and that the fit diagnostics cannot test
  the fringe phase through it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...exceptions import CalibrationWarning, InputError
from ...units import frequency_text
from ...validation import check_choice, check_positive
from ..checks.misfit import detector_noise_w, phase_noise_variance_w2
from ..contract.base import BaseCalibrator
from ..contract.summary import FitValue
from ..files.document import state_array, state_float
from ..fitting.steps import check_ports, fits_offsets, guard_design_fsr
from ..fitting.sweep import Sweep
from ..models.learned_fit import RETRIEVALS, port_noise_std_w
from ..models.thermal_fit import (
    PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K,
    TemperatureLayout,
    fit_thermal_map,
    phase_derivatives,
    spread_error,
    temperature_layout,
    thermal_objects,
    thermal_phase_rad,
)
from .learned import Calibrator, LearnedContext
from .thermal_fields import THERMAL_DIAGNOSTICS_RULES, THERMAL_STATE_RULES
from .thermal_reading import ThermalReadingMixin

__all__ = ["RATE_BUDGET_K", "ThermalCalibrator", "ThermalContext"]

#: readings a temperature cluster needs for the check of the design FSR on it alone
MIN_CLUSTER_READINGS = 16
#: kelvin from the reference at which the bias rate's error may cost one reading's noise
RATE_BUDGET_K = 1.0
#: share of the calibration residual power the temperature sensor's noise may hold unnoted
SENSOR_SHARE_NOTED = 0.2
#: causes found by tests built on the model phase, not trusted when the sensor dominates
PHASE_TESTED_CAUSES = frozenset({"phase_drift", "dispersion", "other_misfit", "unequal_noise"})


@dataclass(eq=False)
class ThermalContext(LearnedContext):
    """The thermal fit's state: the temperatures' layout and the fitted thermal model."""

    layout: TemperatureLayout | None = None
    fit: object = None


class ThermalCalibrator(ThermalReadingMixin, Calibrator):
    """Learned calibration that follows the chip temperature (module docstring).

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz) at the calibration temperatures.
    fsr_tolerance : float
        Relative half width of the FSR bracket searched, in (0, 1).
    retrieval : {"pinv", "ml"}
        Phase retrieval, as for :class:`~wavemeter.calibration.methods.learned.Calibrator`.
    temperature_std_k : float
        Standard deviation of the chip temperature sensor (K), default 1 mK: it separates
        temperature clusters, sets the smallest spread the fit accepts and adds
        ``temperature_std_k |df / dT|`` to every reading's uncertainty.

    Attributes
    ----------
    thermal_phase_rad_per_k_ : float
        Bias phase rate ``alpha`` (rad/K) at ``center_hz_``; fringes move by
        ``alpha fsr_hz_ / (2 pi)`` Hz per kelvin, to lower frequency when positive.
    thermal_delay_per_k_ : float
        Relative delay rate ``beta`` (1/K).
    reference_temperature_k_ : float
        ``T0`` (K): the mean calibration temperature; ``delay_s_`` and ``fsr_hz_`` hold there.
    temperature_range_k_ : (float, float)
        Lowest and highest calibration temperature (K).
    parameter_covariance_ : ndarray, shape (n k + 3, n k + 3)
        Covariance of the map (row-major, ``k`` = 3 or 4 with offsets), ``delay_s_``,
        ``thermal_phase_rad_per_k_`` and ``thermal_delay_per_k_``.
    diagnostics_ : dict
        As the learned calibrator's, plus ``"thermal"``: the rates with their standard
        errors, the fringe shift (Hz/K), the temperature clusters, the smallest step, the
        unambiguous and searched bias-rate ranges and the effective spread.

    The other attributes are those of :class:`~wavemeter.calibration.methods.learned.Calibrator`.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> chip = wm.Interferometer.table1(ports=3, seed=7).with_thermal("sin")  # silicon nitride
    >>> temperatures_k = np.repeat([293.0, 294.0, 295.0], 200)  # three sweeps, 1 K apart
    >>> f_hz = np.tile(chip.sweep_hz(200), 3)
    >>> powers = chip.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1, temperature_k=temperatures_k)
    >>> cal = wm.ThermalCalibrator(fsr_hz=50e9).fit(powers, f_hz, temperature_k=temperatures_k)

    The fitted bias rate gives the fringe shift per kelvin the simulated chip has:

    >>> shift = cal.thermal_phase_rad_per_k_ * cal.fsr_hz_ / (2 * np.pi)
    >>> true = chip.thermal_phase_rad_per_k * chip.true_fsr_hz / (2 * np.pi)
    >>> print(f"fringes move {shift / 1e9:.2f} GHz/K (true {true / 1e9:.2f} GHz/K)")
    fringes move 2.60 GHz/K (true 2.60 GHz/K)

    A reading 1 K beyond the calibrated range is still read within 50 MHz:

    >>> test = chip.powers(f_hz[:5], power_w=1e-3, rng=2, temperature_k=296.0)
    >>> error_hz = cal.predict(test, temperature_k=296.0) - f_hz[:5]
    >>> print(np.abs(error_hz).max() < 50e6)
    True
    """

    method = "thermal"
    requires = frozenset({"temperature_k"})
    comparison_misfits_expected = True
    #: every reading of the sweep is fitted at once, with its temperature: no fit in chunks
    capabilities = frozenset({"frequency_std", "crlb", "power_monitor", "reanchor"})
    nonlinear_parameters: ClassVar[int] = 3
    #: the phase follows the temperature too: predicted step by step
    plain_delay_phase: ClassVar[bool] = False
    #: what each number of the file may hold (:mod:`~wavemeter.calibration.files.fields`)
    state_rules = THERMAL_STATE_RULES
    diagnostics_rules = THERMAL_DIAGNOSTICS_RULES

    def __init__(
        self,
        fsr_hz: float = 50e9,
        fsr_tolerance: float = 0.2,
        retrieval: str = "pinv",
        temperature_std_k: float = 1e-3,
    ):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.retrieval = retrieval
        self.temperature_std_k = temperature_std_k

    def _check_params(self) -> None:
        BaseCalibrator._check_params(self)
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        check_choice("retrieval", self.retrieval, RETRIEVALS)
        check_positive("temperature_std_k", self.temperature_std_k)

    def _requirement_reason(self) -> str:
        return "its fringes move with the chip temperature"

    # ------------------------------------------------------------------ fitting
    def _fit_every_reading(self, sweep: Sweep) -> list:
        """The steps: the temperatures laid out, the design FSR checked on the largest
        temperature cluster (whose fringes do not move), the thermal model fitted (the
        ports' fringes are only seen through it), the ports checked at its phases, the fit
        taken and judged; the warnings, not yet issued."""
        ctx = ThermalContext(sweep)
        ctx.layout = temperature_layout(
            sweep.frequency_hz,
            sweep.temperature_k,
            sensor_std_k=float(self.temperature_std_k),
            fsr_hz=float(self.fsr_hz),
        )
        rows = ctx.layout.largest_cluster
        if np.count_nonzero(rows) < MIN_CLUSTER_READINGS:
            rows = np.ones_like(rows)
        guard_design_fsr(ctx, self.fsr_hz, self.fsr_tolerance, rows)
        self._start_fit(sweep.span_hz, sweep.port_names, sweep.samples, sweep.dark_w)
        ctx.affine = fits_offsets(sweep)
        ctx.fit = fit_thermal_map(
            sweep.powers_w,
            sweep.frequency_hz,
            sweep.temperature_k,
            self.center_hz_,
            ctx.layout,
            fsr_hz=float(self.fsr_hz),
            fsr_tolerance=self.fsr_tolerance,
            scale=sweep.scale,
            affine=ctx.affine,
        )
        check_ports(
            ctx,
            self.center_hz_,
            range(sweep.ports),
            self.fringe_ports_needed,
            phase_rad=ctx.fit.phase_rad,
        )
        self._take_thermal_fit(ctx)
        self._check_rate_precision(ctx)
        self._take_power_range(sweep.powers_w)
        return self._judged(ctx)

    def _take_thermal_fit(self, ctx: ThermalContext) -> None:
        """The fitted model: rates, map, offsets, the detector noise without the sensor's
        share, the covariance and the delay's standard error from it."""
        fit, layout, sweep = ctx.fit, ctx.layout, ctx.sweep
        powers = sweep.powers_w
        delay, phase_rate, delay_rate = (float(value) for value in fit.theta)
        self.delay_s_ = delay
        self.fsr_hz_ = 1.0 / delay
        self.thermal_phase_rad_per_k_ = phase_rate
        self.thermal_delay_per_k_ = delay_rate
        self.reference_temperature_k_ = layout.reference_k
        self.temperature_range_k_ = layout.range_k
        self.cost_ = fit.cost
        ports = powers.shape[1]
        noise, self.noise_dof_ = port_noise_std_w(
            fit.residual_w, fit.map_.shape[1], shared=self.nonlinear_parameters
        )
        self._set_map(fit.map_[:, :3])
        noise = detector_noise_w(noise, self._sensor_variance_w2(ctx))
        self.port_noise_std_w_ = np.maximum(noise, np.finfo(float).eps * np.abs(powers).max())
        pooled_dof = max(powers.size - fit.map_.size - self.nonlinear_parameters, 1)
        self.noise_std_w_ = float(np.sqrt(fit.cost * powers.shape[0] / pooled_dof))
        self.residual_rms_ = float(np.sqrt(fit.cost / ports))
        self.offset_w_ = fit.map_[:, 3].copy() if ctx.affine else np.zeros(ports)
        self._set_covariance(ctx)
        self.delay_std_s_ = float(np.sqrt(self.parameter_covariance_[-3, -3]))

    # ------------------------------------------------------------------ report
    def comparison(self, port_phases_rad=None):
        """The plain learned calibration with the same settings, fitted without the
        temperature: what following the temperature buys."""
        return Calibrator(
            fsr_hz=self.fsr_hz, fsr_tolerance=self.fsr_tolerance, retrieval=self.retrieval
        )

    def _drawn_frequency_hz(self, frequency_hz, temperature_k):
        """Each reading at the frequency whose phase at the reference temperature is its
        model phase at its own."""
        phase = thermal_phase_rad(
            frequency_hz,
            temperature_k,
            self.center_hz_,
            self.reference_temperature_k_,
            *self._theta(),
        )
        title = (
            "readings at the frequency with their model phase at the reference temperature "
            f"{self.reference_temperature_k_:.6g} K"
        )
        return self.center_hz_ + phase / (2.0 * np.pi * self.delay_s_), title

    def _check_rate_precision(self, ctx: ThermalContext) -> None:
        """Refuse a bias rate too uncertain: ``RATE_BUDGET_K`` from ``T0`` its error may
        cost one reading's phase noise (the median over the sweep)."""
        powers, layout = ctx.sweep.powers_w, ctx.layout
        rate_std = float(np.sqrt(self.parameter_covariance_[-2, -2]))
        reading_std = self._frequency_std_at(
            powers - self.offset_w_,
            include_calibration=False,
            temperature_k=np.full(powers.shape[0], layout.reference_k),
        )
        phase_std = float(np.median(reading_std)) / self._hz_per_rad()
        if rate_std * RATE_BUDGET_K > phase_std:
            needed = layout.effective_spread_k * rate_std * RATE_BUDGET_K / phase_std
            raise spread_error(
                layout.spread_k,
                layout.effective_spread_k,
                needed,
                f"the bias rate would be known to +-{rate_std:.3g} rad/K: "
                f"{RATE_BUDGET_K:g} K from the reference temperature that costs more than a "
                f"reading's noise ({phase_std:.3g} rad)",
            )

    def _sweep_phase_noise_rad(self, ctx: ThermalContext) -> np.ndarray:
        """Phase scatter (rad) the sensor noise gives each sweep reading:
        ``temperature_std_k |dt/dT|``, ``dt/dT = alpha + 2 pi (f - f0) tau0 beta``."""
        frequency_hz = ctx.sweep.frequency_hz
        rate = self.thermal_phase_rad_per_k_ + (
            2.0
            * np.pi
            * (frequency_hz - self.center_hz_)
            * self.delay_s_
            * self.thermal_delay_per_k_
        )
        return self.temperature_std_k * np.abs(rate)

    def _sweep_noise_directions_w(self, ctx: ThermalContext) -> np.ndarray:
        """The sensor's noise on each sweep reading (N, n), W: its phase scatter times the
        fringe tangent ``m_k A u'(t_k)``."""
        scale = ctx.sweep.scale
        phase = self._sweep_model_phase_rad(ctx)
        tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=1)
        power = 1.0 if scale is None else scale[:, None]
        return tangent @ self.map_.T * power * self._sweep_phase_noise_rad(ctx)[:, None]

    def _sensor_variance_w2(self, ctx: ThermalContext) -> np.ndarray:
        """Mean variance (W^2, per port) the sensor noise adds to the sweep readings."""
        return phase_noise_variance_w2(self._sweep_noise_directions_w(ctx), 1.0)

    def _misfit_report(self, ctx: ThermalContext):
        """The learned calibrator's report (which expects the sensor's phase scatter), and a
        ``temperature_noise`` warning when the sensor's expected share of a port's residual
        power is ``SENSOR_SHARE_NOTED`` or more (above 1: declared noisier than it is).

        At such a share the tests of the fringe phase are not to be trusted: they are built
        on the model phase, which carries the sensor noise the residual carries too (errors
        in variables). Their warnings (``PHASE_TESTED_CAUSES``) give way to this one, which
        says so; their p-values stay in the report.
        """
        report = super()._misfit_report(ctx)
        residual = np.square(np.asarray(report.residual_rms_w, dtype=float))
        share = self._sensor_variance_w2(ctx) / np.maximum(residual, np.finfo(float).tiny)
        if share.max() < SENSOR_SHARE_NOTED:
            return report
        kept = [note for note in report.warnings if note.cause not in PHASE_TESTED_CAUSES]
        return dataclasses.replace(report, warnings=(*kept, self._sensor_note(share)))

    def _sensor_note(self, share: np.ndarray) -> CalibrationWarning:
        port = int(np.argmax(share))
        rate = (
            f"{self.temperature_std_k:g} K x the bias rate "
            f"{abs(self.thermal_phase_rad_per_k_):.3g} rad/K"
        )
        if share[port] >= 1.0:
            remedy = "give temperature_std_k the sensor's true noise (K)"
            return CalibrationWarning(
                f"the declared temperature sensor noise ({rate}) would scatter the phase of the "
                f"calibration readings more than the residual of port {self.port_names_[port]} "
                f"shows: the sensor is quieter than temperature_std_k says, and the stated "
                f"uncertainties are too large; {remedy}",
                cause="temperature_noise",
                remedy=remedy,
            )
        remedy = (
            "average the temperature readings (a quieter sensor, or a slower one if the "
            "chip's temperature changes slowly), or give temperature_std_k the sensor's "
            "true noise"
        )
        return CalibrationWarning(
            f"the temperature sensor's noise ({rate}) scatters the phase of the calibration "
            f"readings: {100 * share[port]:.3g} % of the residual power of port "
            f"{self.port_names_[port]}; the detector noise is estimated without it and the "
            "uncertainties include it, but it costs the calibration precision, and the fit "
            "diagnostics cannot test the fringe phase through it (a phase drift, dispersion "
            f"or other misfit would go unseen); {remedy}",
            cause="temperature_noise",
            remedy=remedy,
        )

    def _sweep_objects(self, ctx: ThermalContext):
        """Object vectors (N, k) and their derivatives (3, N, k) at the fitted parameters."""
        sweep = ctx.sweep
        derivatives = phase_derivatives(
            sweep.frequency_hz,
            sweep.temperature_k,
            self.center_hz_,
            self.reference_temperature_k_,
            self._theta(),
        )
        return thermal_objects(
            self._sweep_model_phase_rad(ctx), sweep.scale, ctx.affine, derivatives
        )

    def _sweep_model_phase_rad(self, ctx: ThermalContext) -> np.ndarray:
        sweep = ctx.sweep
        return thermal_phase_rad(
            sweep.frequency_hz,
            sweep.temperature_k,
            self.center_hz_,
            self.reference_temperature_k_,
            *self._theta(),
        )

    def _theta(self) -> tuple[float, float, float]:
        return (self.delay_s_, self.thermal_phase_rad_per_k_, self.thermal_delay_per_k_)

    def _fit_notes(self, ctx: ThermalContext) -> list:
        layout = ctx.layout
        if layout.unambiguous_rad_per_k is None:
            return []
        if layout.unambiguous_rad_per_k >= layout.plausible_rad_per_k:
            return []
        shift = layout.unambiguous_rad_per_k * self.fsr_hz_ / (2.0 * np.pi)
        needed = np.pi / layout.plausible_rad_per_k
        remedy = (
            f"add a sweep at a temperature within {needed:.3g} K of another, so that fringe "
            f"shifts up to {frequency_text(PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K)}/K are resolved"
        )
        return [
            CalibrationWarning(
                f"the calibration temperatures are at least {layout.smallest_step_k:.3g} K "
                "apart: the bias rate is resolved only within "
                f"+-{layout.unambiguous_rad_per_k:.3g} rad/K (fringe shifts up to "
                f"{frequency_text(shift)}/K), less than a chip's "
                f"fringes may move (up to {frequency_text(PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K)}/K); "
                f"the fitted {self.thermal_phase_rad_per_k_:.4g} rad/K may be an alias; {remedy}",
                cause="thermal_ambiguity",
                remedy=remedy,
            )
        ]

    def _method_record(self, ctx: ThermalContext) -> dict:
        layout = ctx.layout
        std = np.sqrt(np.diag(self.parameter_covariance_)[-3:])
        shift = self._fringe_shift()
        return {
            "thermal": {
                "thermal_phase_rad_per_k": self.thermal_phase_rad_per_k_,
                "thermal_phase_std_rad_per_k": float(std[1]),
                "thermal_delay_per_k": self.thermal_delay_per_k_,
                "thermal_delay_std_per_k": float(std[2]),
                "fringe_shift_hz_per_k": shift.value,
                "fringe_shift_std_hz_per_k": shift.stderr,
                **layout.record(),
            }
        }

    def _fringe_shift(self) -> FitValue:
        """The fringe shift ``alpha / (2 pi tau0)`` (Hz/K) with its standard error from the
        covariance of ``tau0`` and ``alpha``."""
        per_rad = self.fsr_hz_ / (2.0 * np.pi)
        shift = self.thermal_phase_rad_per_k_ * per_rad
        gradient = np.array([-shift / self.delay_s_, per_rad])
        block = self.parameter_covariance_[-3:-1, -3:-1]
        return FitValue(shift, float(np.sqrt(gradient @ block @ gradient)), "Hz/K")

    # ------------------------------------------------------------------ reporting and files
    def _summary_values(self) -> dict:
        std = np.sqrt(np.diag(self.parameter_covariance_)[-3:])
        shift = self._fringe_shift()
        return {
            **super()._summary_values(),
            "thermal_phase_rad_per_k": FitValue(
                self.thermal_phase_rad_per_k_, std[1], "rad/K", "bias phase rate"
            ),
            "fringe_shift_hz_per_k": FitValue(
                shift.value, shift.stderr, shift.unit, "fringe shift (to lower frequency)"
            ),
            "thermal_delay_per_k": FitValue(self.thermal_delay_per_k_, std[2], "1/K", "delay rate"),
            "reference_temperature_k": FitValue(
                self.reference_temperature_k_, None, "K", "reference temperature"
            ),
        }

    def summary(self):
        """The fit report (:meth:`BaseCalibrator.summary`), with the calibrated
        temperatures and the bias rates they resolve."""
        report = super().summary()
        thermal = (self.diagnostics_ or {}).get("thermal", {})
        low, high = self.temperature_range_k_
        clusters = ", ".join(f"{value:.4g}" for value in thermal.get("temperatures_k") or ())
        unambiguous = thermal.get("unambiguous_phase_rate_rad_per_k")
        resolved = (
            "continuous temperatures: no alias"
            if unambiguous is None
            else f"bias rate unambiguous within +-{unambiguous:.3g} rad/K"
        )
        where = f" (clusters at {clusters} K; {resolved})" if clusters else f" ({resolved})"
        note = f"calibrated temperatures {low:.6g} to {high:.6g} K{where}"
        return dataclasses.replace(report, notes=(*report.notes, note))

    def _state(self) -> dict:
        return {
            **super()._state(),
            "thermal_phase_rad_per_k": self.thermal_phase_rad_per_k_,
            "thermal_delay_per_k": self.thermal_delay_per_k_,
            "reference_temperature_k": self.reference_temperature_k_,
            "temperature_range_k": list(self.temperature_range_k_),
        }

    def _set_state(self, state: dict) -> None:
        if "parameter_covariance" not in state or "port_noise_std_w" not in state:
            raise InputError(
                "a thermal calibration file must hold 'port_noise_std_w' and 'parameter_covariance'"
            )
        super()._set_state(state)
        self.thermal_phase_rad_per_k_ = state_float(state, "thermal_phase_rad_per_k")
        self.thermal_delay_per_k_ = state_float(state, "thermal_delay_per_k")
        self.reference_temperature_k_ = state_float(state, "reference_temperature_k")
        low, high = state_array(state, "temperature_range_k", (2,))
        if not low <= high:
            raise InputError(
                f"field 'temperature_range_k' must be [low, high] (K), got "
                f"{[float(low), float(high)]}"
            )
        self.temperature_range_k_ = (float(low), float(high))
