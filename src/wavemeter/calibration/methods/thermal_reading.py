"""How a thermally compensated calibration reads: every reading at its chip temperature.

:class:`ThermalReadingMixin` corrects the retrieved phase ``t`` for the temperature,
``s = wrap(t - alpha dT)``, reads the frequency on the FSR at that temperature,
``f = f0 + s / (2 pi tau0 (1 + beta dT))``, adds the temperature sensor's noise times
``df/dT`` to the uncertainty, flags readings beyond the calibrated temperatures, and
re-anchors at the lines' temperature. Theory: the docs' thermal model page.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...exceptions import InputError
from ...model.cone import wrap_phase_rad
from ...validation import check_fitted
from ..contract.flags import temperature_flags
from ..contract.records import ReadingInputs
from ..models.reanchor import check_reference_readings, fit_reanchor, reanchored_copy

__all__ = ["ThermalReadingMixin"]


class ThermalReadingMixin:
    """The reading side of :class:`~wavemeter.calibration.methods.thermal.ThermalCalibrator`
    (module docstring), over the learned family's
    (:class:`~wavemeter.calibration.methods.learned_reading.LearnedReadingMixin`)."""

    def fsr_hz_at(self, temperature_k) -> np.ndarray:
        """The calibrated FSR ``1 / (tau0 (1 + beta (T - T0)))`` (Hz) at temperatures (K)."""
        check_fitted(self)
        return 2.0 * np.pi * self._hz_per_rad(np.asarray(temperature_k, dtype=float))

    def _temperature_offset_k(self, temperature_k) -> np.ndarray:
        return np.asarray(temperature_k, dtype=float) - self.reference_temperature_k_

    def _hz_per_rad(self, temperature_k=None):
        """``df / dt = 1 / (2 pi tau(T))`` (Hz/rad); at ``T0`` without temperatures."""
        if temperature_k is None:
            return self.fsr_hz_ / (2.0 * np.pi)
        stretch = 1.0 + self.thermal_delay_per_k_ * self._temperature_offset_k(temperature_k)
        return 1.0 / (2.0 * np.pi * self.delay_s_ * stretch)

    def _phase_rad(self, readings, inputs: ReadingInputs):
        return self._corrected_phase_rad(self._phase(readings), inputs.temperature_k)

    def _phase_shown_rad(self, phase_rad, temperature_k=None):
        return self._corrected_phase_rad(phase_rad, temperature_k)

    def _corrected_phase_rad(self, phase_rad, temperature_k):
        """``s = wrap(t - alpha dT)``: a retrieved phase corrected for the temperature."""
        offset = self._temperature_offset_k(temperature_k)
        return wrap_phase_rad(phase_rad - self.thermal_phase_rad_per_k_ * offset)

    def _object_phase_rad(self, phase_rad, temperature_k=None):
        """``t = s + alpha dT``: the map's phase of a temperature-corrected phase ``s``."""
        return phase_rad + self.thermal_phase_rad_per_k_ * self._temperature_offset_k(temperature_k)

    def _frequency_of_phase(self, phase_rad, temperature_k=None):
        """Frequency (Hz) of readings of retrieved phase ``phase_rad`` at ``temperature_k``:
        the phase corrected for the temperature, over ``df/dt``."""
        phase = self._corrected_phase_rad(phase_rad, temperature_k)
        return self.center_hz_ + phase * self._hz_per_rad(temperature_k)

    def _parameter_frequency_gradient_hz(self, phase_rad, temperature_k=None) -> np.ndarray:
        """``df / d(tau0, alpha, beta)`` (N, 3) with ``f - f0 = s / (2 pi tau0 (1 + beta dT))``,
        ``s = wrap(t - alpha dT)``."""
        offset = self._temperature_offset_k(temperature_k)
        phase = wrap_phase_rad(phase_rad - self.thermal_phase_rad_per_k_ * offset)
        per_rad = self._hz_per_rad(temperature_k)
        stretch = 1.0 + self.thermal_delay_per_k_ * offset
        return np.column_stack(
            [
                -phase * per_rad / self.delay_s_,
                -offset * per_rad,
                -phase * per_rad * offset / stretch,
            ]
        )

    def _sensor_variance_hz2(self, phase_rad, temperature_k=None):
        """``(temperature_std_k df/dT)^2``, ``df/dT = -(alpha + s beta / (1 + beta dT)) / (2 pi
        tau(T))``."""
        offset = self._temperature_offset_k(temperature_k)
        phase = wrap_phase_rad(phase_rad - self.thermal_phase_rad_per_k_ * offset)
        stretch = 1.0 + self.thermal_delay_per_k_ * offset
        rate = self.thermal_phase_rad_per_k_ + phase * self.thermal_delay_per_k_ / stretch
        return (self.temperature_std_k * rate * self._hz_per_rad(temperature_k)) ** 2

    def _temperature_flags(self, temperature_k) -> np.ndarray:
        return temperature_flags(
            temperature_k, self.temperature_range_k_, float(self.temperature_std_k)
        )

    def reanchor(self, powers, frequency_hz, *, temperature_k=None):
        """A copy re-anchored to readings of reference lines at known chip temperatures.

        The lines' phases are corrected to the reference temperature by the fitted rates
        and then treated as :meth:`Calibrator.reanchor` does: the bias phase moves (the
        map rotates) at every temperature; a delay change measured at the lines' mean
        temperature ``T`` becomes ``d tau0 = d tau(T) / (1 + beta (T - T0))``. The rates
        are kept. This calibrator is untouched.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Readings of one or more reference lines (W, the unit of the calibration).
        frequency_hz : float or array_like, shape (N,)
            Known frequency of each reading (Hz).
        temperature_k : float or array_like, shape (N,)
            Chip temperature of each reading (K); required.

        Returns
        -------
        ThermalCalibrator
            With ``diagnostics_["reanchor"]`` as :meth:`Calibrator.reanchor` records it,
            plus ``temperature_k`` (the lines' mean temperature).
        """
        check_fitted(self)
        raw, frequency, temperature = check_reference_readings(
            powers, frequency_hz, self.n_ports_, temperature_k
        )
        if temperature is None:
            raise InputError(
                "ThermalCalibrator.reanchor needs temperature_k (K) of the reference readings",
                parameter="temperature_k",
            )
        readings = raw - self._reading_offset_w()
        phase = self._corrected_phase_rad(self._phase(readings), temperature)
        per_rad = self._hz_per_rad(temperature)
        reading_std = self._frequency_std_at(
            readings, include_calibration=False, temperature_k=temperature
        )
        mean_temperature = float(temperature.mean())
        stretch = 1.0 + self.thermal_delay_per_k_ * (
            mean_temperature - self.reference_temperature_k_
        )
        fit = fit_reanchor(
            phase,
            frequency,
            self.center_hz_,
            self.delay_s_ * stretch,
            delay_std_s=self.delay_std_s_ * stretch,
            reading_phase_std_rad=reading_std / per_rad,
            noise_dof=self.noise_dof_,
        )
        if fit.delay_change_s is not None:
            fit = dataclasses.replace(
                fit,
                delay_change_s=fit.delay_change_s / stretch,
                delay_change_std_s=fit.delay_change_std_s / stretch,
                covariance=fit.covariance * np.outer([1.0, 1.0 / stretch], [1.0, 1.0 / stretch]),
            )
        return reanchored_copy(self, fit, {**fit.record(), "temperature_k": mean_temperature})
