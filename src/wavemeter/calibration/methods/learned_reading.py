"""How the learned family reads: retrieval, uncertainty, bound and flags of one cone map.

:class:`LearnedReadingMixin` is the reading side of
:class:`~wavemeter.calibration.methods.learned.Calibrator` and its thermal subclass: the
paper's pseudo-inverse and arctangent (or the cone maximum likelihood), the standard
deviation of that estimator by the delta method (:mod:`wavemeter.model.uncertainty`), the
Cramer-Rao bound under the calibrated map, the ``OFF_MODEL`` test (its threshold from
:mod:`~wavemeter.calibration.contract.off_model`), and one pass per
reading for ``readout`` and ``stream``. A subclass whose phase follows more than the
delay (the thermal one) changes ``_hz_per_rad``, ``_phase_rad``, ``_frequency_of_phase``,
``_object_phase_rad`` and the gradient and sensor terms.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import linalg

from ...exceptions import InputError
from ...model.cone import cone_vectors, wrap_phase_rad
from ...model.kernels import (
    fused_ml_frequency_hz,
    fused_ml_phase_rad,
    fused_pinv_frequency_hz,
    fused_pinv_phase_rad,
)
from ...model.limits import crlb_frequency_std
from ...model.retrieval import source_power_ratio
from ...model.uncertainty import (
    calibration_variance_hz2,
    map_frequency_gradient_hz,
    ml_phase_gradient,
    phase_std_rad,
    pinv_phase_gradient,
    student_factor,
)
from ...validation import check_choice, check_fitted, reading_array
from ..contract.flags import ReadingFlag
from ..contract.off_model import OffModelMixin
from ..contract.reading import ERRORS
from ..contract.records import ReadingInputs, Readout, StreamReading
from ..contract.streaming import SCREEN_MARGIN
from .learned_row import pinv_row_reader

__all__ = ["LearnedReadingMixin"]


class LearnedReadingMixin(OffModelMixin):
    """Reading with one cone map (module docstring)."""

    #: the phase is the delay's alone, ``2 pi (f - center) delay``: predict runs the fused
    #: kernel. A subclass that models the phase further (the thermal one) sets False.
    plain_delay_phase = True

    def _set_map(self, matrix: np.ndarray) -> None:
        self.map_ = matrix
        self.map_pinv_ = linalg.pinv(matrix)

    # ------------------------------------------------------------------ frequency and phase
    def predict(self, powers, *, coarse_hz=None, temperature_k=None, errors="coerce"):
        """Source frequency (Hz) of each reading, within ``center_hz_ +- fsr_hz_/2``.

        The check of the readings, the offsets and the retrieval are one pass
        (:mod:`wavemeter.model.kernels`; numba on every core when installed): the numbers
        of the steps taken one by one. Parameters, returns and errors as for
        :meth:`~wavemeter.calibration.contract.reading.ReadingMixin.predict`.
        """
        if not self.plain_delay_phase:  # the phase model has more than the delay
            return super().predict(
                powers, coarse_hz=coarse_hz, temperature_k=temperature_k, errors=errors
            )
        check_fitted(self)
        check_choice("errors", errors, ERRORS)
        readings = reading_array(powers, ports=self.n_ports_)
        self._reading_inputs(coarse_hz, temperature_k, readings.shape[0], finite=False)
        try:
            return self._fused_frequency_hz(readings, self._reading_offset_w(), check=True)
        except InputError:
            if errors == "raise":
                raise
        # some readings cannot be read: each is read on its own
        return super().predict(
            powers, coarse_hz=coarse_hz, temperature_k=temperature_k, errors=errors
        )

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

    def _frequency_hz(self, readings, inputs: ReadingInputs) -> np.ndarray:
        if self.plain_delay_phase:
            return self._fused_frequency_hz(readings, None, check=False)
        return self._frequency_of_phase(self._phase(readings), inputs.temperature_k)

    def _frequency_of_phase(self, phase_rad, temperature_k=None) -> np.ndarray:
        """Frequency (Hz) of readings whose retrieved phase is ``phase_rad`` (N,), as
        ``predict`` gives it (the same operations)."""
        return self.center_hz_ + phase_rad * self._hz_per_rad(temperature_k)

    def _phase(self, readings):
        if self.retrieval == "ml":
            return fused_ml_phase_rad(readings, self.map_, noise_std_w=self.port_noise_std_w_)
        return fused_pinv_phase_rad(readings, self.map_pinv_)

    def _phase_shown_rad(self, phase_rad, temperature_k=None):
        """The phase :meth:`phase` gives of readings whose map phase is ``phase_rad``."""
        return phase_rad

    def _object_phase_rad(self, phase_rad, temperature_k=None):
        """The map's phase (rad) of a phase as :meth:`phase` returns it (the same here)."""
        return phase_rad

    def _hz_per_rad(self, temperature_k=None):
        """``df / dt`` (Hz/rad): ``FSR / (2 pi)``."""
        return self.fsr_hz_ / (2.0 * np.pi)

    # ------------------------------------------------------------------ uncertainty
    def _phase_gradient(self, readings, phase) -> np.ndarray:
        """``dt / dp`` (N, n) of the retrieval used, at each reading."""
        if self.retrieval == "ml":
            power = source_power_ratio(readings, self.map_, phase, self.port_noise_std_w_)
            return ml_phase_gradient(self.map_, phase, power, self.port_noise_std_w_)
        return pinv_phase_gradient(readings, self.map_pinv_)

    def _frequency_std(self, readings, inputs: ReadingInputs, include_calibration: bool):
        """The standard deviation of the estimator used (delta method, through the pinv or
        the weighted maximum likelihood), the per-port noise inflated by the Student factor
        of ``noise_dof_``; with ``include_calibration`` also the spread the fit's own
        parameter covariance gives."""
        return self._frequency_std_at(readings, include_calibration, inputs.temperature_k)

    def _frequency_std_at(
        self, readings, include_calibration=True, temperature_k=None, phase_rad=None
    ) -> np.ndarray:
        """:meth:`_frequency_std` of offset-corrected readings (N, n); their retrieved
        phase ``phase_rad`` (N,) when already known."""
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

    def _map_columns(self) -> int:
        """Map columns ``k`` the parameter covariance holds: 3, or 4 with fitted offsets."""
        size = self.parameter_covariance_.shape[0] - self.nonlinear_parameters
        return size // self.n_ports_

    def _parameter_frequency_gradient_hz(self, phase_rad, temperature_k=None) -> np.ndarray:
        """``df / d theta`` (N, q) of readings of phase ``phase_rad`` for the nonlinear
        parameters (the delay: ``-t / (2 pi tau^2)``, Hz/s)."""
        return (-np.asarray(phase_rad) * self._hz_per_rad() / self.delay_s_)[:, None]

    def _sensor_variance_hz2(self, phase_rad, temperature_k=None):
        """Variance (Hz^2) from the per-reading inputs' own noise (none here)."""
        return 0.0

    def _crlb(self, readings, inputs: ReadingInputs, frequency_hz) -> np.ndarray:
        """The bound at the retrieved phase, or at the model phase of ``frequency_hz``, and
        at the reading's own source power, in Hz at each reading's FSR."""
        temperature = inputs.temperature_k
        if frequency_hz is None:
            phase = self._phase(readings)
        else:
            corrected = wrap_phase_rad(
                (frequency_hz - self.center_hz_) / self._hz_per_rad(temperature)
            )
            phase = self._object_phase_rad(corrected, temperature)
        power = source_power_ratio(readings, self.map_, phase, self.port_noise_std_w_)
        phase_bound = crlb_frequency_std(self.map_, phase, power, self.port_noise_std_w_, 2 * np.pi)
        return phase_bound * self._hz_per_rad(temperature)

    # ------------------------------------------------------------------ flags
    def _cone_distance(self, readings, phase_rad) -> np.ndarray:
        """Weighted squared distance (N,) of each reading (offset-corrected) to the calibrated
        cone at ``phase_rad``, the source power fitted."""
        noise = self.port_noise_std_w_
        power = source_power_ratio(readings, self.map_, phase_rad, noise)
        residual = (readings - power[:, None] * (cone_vectors(phase_rad) @ self.map_.T)) / noise
        return np.einsum("ij,ij->i", residual, residual)

    def _ml_phase_rad(self, readings) -> np.ndarray:
        """The maximum-likelihood phase (N,) of offset-corrected readings: the cone's point
        nearest each."""
        return fused_ml_phase_rad(readings, self.map_, noise_std_w=self.port_noise_std_w_)

    def _off_model(self, readings, inputs: ReadingInputs):
        """Each reading's distance to the calibrated cone, tested against the threshold
        (:class:`~wavemeter.calibration.contract.off_model.OffModelMixin`); where the
        sweep's readings share a learned residual, what remains of the reading's residual
        at its retrieved phase once that is subtracted."""
        if self._off_model_learned():
            return self._off_model_remaining(readings, self.map_, self._phase(readings))
        return self._cone_distance(readings, self._ml_phase_rad(readings)) > (
            self._off_model_threshold()
        )

    def _screened_off_model(self, readings, phase_rad) -> np.ndarray:
        """:meth:`_off_model` of readings whose retrieved phase is ``phase_rad``: the
        distance at that phase is at least the one at the maximum-likelihood phase, so a
        reading below the threshold there by more than ``SCREEN_MARGIN`` (relative) is on
        the model; the others take the test itself. With a learned residual the test is
        at the retrieved phase itself: no screen."""
        if self._off_model_learned():
            return self._off_model_remaining(readings, self.map_, phase_rad)
        threshold = self._off_model_threshold()
        suspect = self._cone_distance(readings, phase_rad) > threshold * (1.0 - SCREEN_MARGIN)
        off = np.zeros(readings.shape[0], dtype=bool)
        if suspect.any():
            off[suspect] = self._off_model(readings[suspect], None)
        return off

    def _temperature_flags(self, temperature_k) -> np.ndarray | int:
        """``TEMPERATURE_RANGE`` bits (none here; the thermal calibration has them)."""
        return 0

    def _model_flags(self, readings, inputs: ReadingInputs) -> np.ndarray:
        return self._readout(readings, inputs).flags

    # ------------------------------------------------------------------ one pass
    def _readout(self, readings, inputs: ReadingInputs) -> Readout:
        """The phase retrieved once gives the frequency, its uncertainty (the span margin
        too) and the ``OFF_MODEL`` screen."""
        temperature = inputs.temperature_k
        phase = self._phase(readings)
        frequency = self._frequency_of_phase(phase, temperature)
        std = self._frequency_std_at(readings, True, temperature, phase_rad=phase)
        flags = np.zeros(readings.shape[0], dtype=np.int64)
        if self._partial_span():
            flags |= self._span_flags(frequency, std)
        flags[self._screened_off_model(readings, phase)] |= ReadingFlag.OFF_MODEL
        flags |= self._temperature_flags(temperature)
        return Readout(frequency, std, flags, {}, self._phase_shown_rad(phase, temperature))

    def _stream_reader(self) -> Callable[[np.ndarray, dict], StreamReading]:
        """One pass over a reading for :meth:`stream`: what stays the same from reading to
        reading is worked out once per stream, each reading's phase once (:meth:`_readout`
        on one reading, without the checks ``readout`` makes of a block)."""
        corrected = self._stream_corrector()
        invalid = int(ReadingFlag.INVALID)

        def read(powers: np.ndarray, inputs: dict) -> StreamReading:
            readings = corrected(powers)
            flags = int(self._light_flags(powers, readings)[0])
            temperature = inputs.get("temperature_k")
            given = ReadingInputs(None, None if temperature is None else np.array([temperature]))
            found = self._readout(readings, given)
            if not flags & invalid:
                flags |= int(found.flags[0])
            return StreamReading(
                float(found.frequency_hz[0]), float(found.frequency_std_hz[0]), flags
            )

        return read

    def _row_reader(self):
        """One reading for :meth:`row_reader` and :meth:`stream`: with the pseudo-inverse
        and a delay-only phase, in plain floats (:func:`.learned_row.pinv_row_reader`)
        before the generic path."""
        generic = super()._row_reader()
        if self.retrieval != "pinv" or not self.plain_delay_phase:
            return generic
        return pinv_row_reader(self, generic)
