"""How a wide-band calibration reads: each reading under its own map, its fringe order
from its coarse frequency.

:class:`BandReadingMixin` retrieves the phase under the map at the reading's frequency
(pseudo-inverse or cone maximum likelihood), the frequency of that phase nearest the
coarse value, the standard deviation by the delta method with every fitted number's
covariance, the Cramer-Rao bound, and the flags (``OUTSIDE_SPAN``, ``ORDER_AMBIGUOUS``,
``OFF_MODEL`` against the threshold of :mod:`~wavemeter.calibration.contract.off_model`);
a coarse value more than half an FSR outside the band has no map.
"""

from __future__ import annotations

import numpy as np

from ...model.cone import wrap_phase_rad
from ...model.uncertainty import student_factor
from ...validation import check_fitted
from ..contract.flags import SPAN_MARGIN_STD, ReadingFlag
from ..contract.off_model import OffModelMixin
from ..contract.records import ReadingInputs, Readout
from ..models.band_reading import (
    band_crlb_hz,
    band_frequency_variance_hz2,
    band_off_model,
    band_phase_rad,
)
from ..models.wideband_fit import band_frequency_hz

__all__ = ["ORDER_MARGIN_FSR", "BandReadingMixin"]

#: the frequency found may lie this share of the local FSR from the coarse value unflagged
ORDER_MARGIN_FSR = 0.25


class BandReadingMixin(OffModelMixin):
    """The reading side of :class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator`
    (module docstring)."""

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
        off_model = band_off_model(
            readings, maps, self.port_noise_std_w_, self._off_model_threshold()
        )
        flags[off_model] |= ReadingFlag.OFF_MODEL
        return Readout(frequency, std, flags, {}, phase)
