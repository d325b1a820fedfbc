"""The wide-band model on its own sweep: the covariance of every fitted number and the
fit diagnostics on the band model.

:class:`BandChecksMixin` gives :class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator`
the parameter covariance (map coefficients, offsets and phase coefficients), the misfit
report of :mod:`~wavemeter.calibration.checks.misfit` on the band model (whose
``dispersion`` remedy is a higher phase or map order), the residual phase per FSR window and the
``diagnostics_["wideband"]`` record.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...exceptions import CalibrationWarning
from ...model.cone import wrap_phase_rad
from ...model.uncertainty import fit_parameter_covariance
from ...stats.nested_tests import TEST_P_VALUE
from ..checks.misfit import misfit_report
from ..models.band_reading import residual_phase_by_window
from ..models.wideband_fit import band_object_derivatives, band_objects

__all__ = ["BandChecksMixin"]


class BandChecksMixin:
    """The band model judged on its sweep (module docstring); the fit's context carries
    the sweep and whether offsets were fitted."""

    def _sweep_design(self, ctx) -> tuple[np.ndarray, np.ndarray]:
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

    def _set_covariance(self, ctx) -> None:
        objects, derivatives = self._sweep_design(ctx)
        covariance = fit_parameter_covariance(
            objects,
            derivatives,
            self._design_matrix(ctx.affine),
            self.port_noise_std_w_,
            weighted=False,
        )
        gauge = ctx.fit.gauge
        if gauge is not None:
            # the map's order-1 rotation was held at zero: the covariance on that plane,
            # ``C - C g (g' C g)^-1 g' C`` (``g`` the constraint's gradient)
            columns = objects.shape[1]
            gradient = np.zeros(covariance.shape[0])
            for port in range(self.n_ports_):
                gradient[port * columns + 3 : port * columns + 6] = gauge[port]
            along = covariance @ gradient
            covariance = covariance - np.outer(along, along) / float(gradient @ along)
        self.parameter_covariance_ = covariance

    def _misfit_report(self, ctx):
        """The fit diagnostics on the band model; a change with frequency the model left
        (``dispersion``) is remedied here by a higher phase order (a phase even in
        frequency) or map order (ports that change each in its own way)."""
        report = self._band_misfit_report(ctx)
        if "dispersion" not in report.causes:
            return report
        failed = {
            name
            for name in ("dispersion", "band_slope")
            if report.p_values.get(name) is not None and report.p_values[name] < TEST_P_VALUE
        }
        raise_orders = []
        if "dispersion" in failed or not failed:
            raise_orders.append(f"a higher phase_order (this fit has {self.phase_order_})")
        if "band_slope" in failed:
            raise_orders.append(f"a higher map_order (this fit has {self.map_order_})")
        remedy = (
            f"set {' and '.join(raise_orders)}, or sweep more FSRs so that cross-validation "
            "can choose the orders"
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

    def _band_misfit_report(self, ctx):
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
            axis_bandwidth_per_reading=ctx.sweep.axis_bandwidth_per_reading,
            method=self.method,
        )

    def _residual_phase_by_window(self, ctx, readings) -> list[dict]:
        """Retrieved minus model phase (rad) of the sweep's offset-corrected readings, by
        FSR window: what the fit left across the band."""
        frequency_hz = ctx.sweep.frequency_hz
        maps = self.band_model_.maps_at(frequency_hz)
        residual = wrap_phase_rad(
            self._retrieve(readings, maps) - self.band_model_.phase_rad(frequency_hz)
        )
        return residual_phase_by_window(frequency_hz, residual, self.span_hz_[0], self.fsr_hz_)

    def _band_record(self, ctx, residual_phase: list) -> dict:
        """``diagnostics_["wideband"]``: the orders and how they were chosen, the phase
        coefficients with their standard errors, the residual phase per FSR window."""
        return {
            "phase_order": self.phase_order_,
            "map_order": self.map_order_,
            "n_parameters": self.n_parameters_,
            "orders": ctx.orders.record(),
            "phase_coefficients_s": self.phase_coefficients_.tolist(),
            "phase_coefficients_std_s": self._phase_coefficients_std_s().tolist(),
            "residual_phase": residual_phase,
        }
