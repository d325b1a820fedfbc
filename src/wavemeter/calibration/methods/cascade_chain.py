"""How a cascade reads: every stage in turn, each handing its frequency to the next.

:class:`ChainReadingMixin` gives :class:`~wavemeter.calibration.methods.cascade.CascadeCalibrator`
its reading: the coarsest stage read with the band's middle as coarse value, each next
stage with the frequency before it, every stage's uncertainty in the readings' own noise
(plus the error its sweep showed beyond it), the probability of a wrong order at each
hand-over and the coarsest stage's edge, the flags, one reading of a stream in one light
pass per stage, and the warning that the readings are noisier than the sweep.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable

import numpy as np
from scipy import special

from ...exceptions import CalibrationWarning
from ...model.orders import handover_error_probability, wrap_error_probability
from ...units import frequency_text
from ...validation import check_fitted
from ..contract.flags import SPAN_MARGIN_STD, ReadingFlag, off_model_threshold, power_flags
from ..contract.records import ReadingInputs, Readout, StreamReading
from ..models.band_reading import band_cone_distance
from .cascade_reading import (
    CascadeReading,
    StageReader,
    chi2_median,
    distance_in_noise,
    noise_scale,
)

__all__ = ["ChainReadingMixin", "READING_NOISE_CAUSE"]

#: the cause of a warning that the readings are noisier than the calibration sweep
READING_NOISE_CAUSE = "reading_noise"
#: a hand-over residual beyond this many standard deviations is OFF_MODEL: the stages
#: disagree beyond their uncertainties (two-sided p-value ``OFF_MODEL_P_VALUE``, 1e-6)
DISAGREEMENT_STD = float(special.ndtri(1.0 - 0.5e-6))


def _stream_record(chain: CascadeReading) -> StreamReading:
    """What a stream gives for one reading read through the stages (with its flags)."""
    return StreamReading(
        float(chain.frequency_hz[-1, 0]),
        float(chain.std_hz[-1, 0]),
        int(chain.flags[0]),
        {"order_error_probability": float(chain.order_error_probability[0])},
    )


class ChainReadingMixin:
    """The reading side of a cascade (module docstring)."""

    reading_outputs = types.MappingProxyType({"order_error_probability": "1"})

    def _read(self, readings: np.ndarray) -> CascadeReading:
        """Read validated, offset-corrected readings through the stages (module docstring)."""
        samples = readings.shape[0]
        stages = len(self.stages_)
        frequency = np.empty((stages, samples))
        std = np.empty((stages, samples))
        phase = np.empty((stages, samples))
        distance = np.empty((stages, samples))
        scale = np.ones(stages)
        maps = []
        coarse = np.full(samples, self.center_hz_)
        for index, (stage, block) in enumerate(zip(self.stages_, self.stage_ports_, strict=True)):
            rows = readings[:, list(block)]
            frequency[index], phase[index], stage_maps = stage._frequency_checked(rows, coarse)
            maps.append(stage_maps)
            distance[index] = band_cone_distance(rows, stage_maps, stage.port_noise_std_w_)
            reference = self.cone_distance_median_[index]
            median = chi2_median(len(block) - 2, stage.noise_dof_)
            scale[index] = noise_scale(distance[index], reference, median)
            distance[index] = distance_in_noise(distance[index], reference, median, scale[index])
            std[index] = np.hypot(
                stage._frequency_std_of(
                    rows, frequency[index], phase[index], stage_maps, noise_scale=scale[index]
                ),
                self.model_error_hz_[index],
            )
            coarse = frequency[index]
        return self._joined(frequency, std, phase, maps, distance, scale)

    def _joined(self, frequency, std, phase, maps, distance, scale) -> CascadeReading:
        """The stages' readings (K, N), each with the probability that its order is wrong
        (the coarsest stage's edge, then each hand-over's) and the hand-overs' disagreement."""
        stages, samples = frequency.shape
        probability = np.empty((stages, samples))
        probability[0] = self._edge_probability(frequency[0], std[0])
        residual = frequency[:-1] - frequency[1:]
        spread = np.hypot(std[:-1], std[1:])
        # every hand-over at once: each at the finer stage's local FSR
        fsr = [stage.fsr_hz_at(f) for stage, f in zip(self.stages_[1:], frequency[1:], strict=True)]
        probability[1:] = handover_error_probability(residual, np.array(fsr), spread)
        with np.errstate(divide="ignore", invalid="ignore"):
            disagreement = np.abs(residual) / spread
        return CascadeReading(
            frequency, std, phase, maps, probability, disagreement, distance, scale
        )

    def _edge_probability(self, frequency_hz: np.ndarray, std_hz: np.ndarray) -> np.ndarray:
        """Probability that the coarsest stage's estimate wrapped past an end of the range
        its phase is unique over, the truth lying in the calibrated band: weighed in that
        stage's phase (rad), where the wrapped twin lies exactly one turn away."""
        model = self.stages_[0].band_model_
        phase = model.phase_rad(frequency_hz)
        phase_std = std_hz * model.phase_slope_rad_per_hz(frequency_hz)
        band = model.phase_rad(np.asarray(self.span_hz_, dtype=float))
        return wrap_error_probability(phase, phase_std, (band[0], band[1]), 2.0 * np.pi)

    def read(self, powers) -> CascadeReading:
        """Every stage's frequency, uncertainty and order probability for each reading, and
        the quality flags, in one pass.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings of every stage, in the unit of the calibration sweep (finite:
            :meth:`flags` takes readings with NaN).

        Returns
        -------
        CascadeReading
        """
        readings = self._corrected(powers)
        return self._flagged(self._read(readings), readings)

    def _flagged(self, chain: CascadeReading, readings: np.ndarray) -> CascadeReading:
        """The chain with the flags of its offset-corrected readings (N, n)."""
        flags = power_flags(readings.sum(axis=1), self.total_power_range_w_, self._offsets_known())
        return dataclasses.replace(chain, flags=flags | self._chain_flags(chain))

    def _stream_reader(self) -> Callable[[np.ndarray, dict], StreamReading]:
        """One reading through the stages for
        :meth:`~wavemeter.calibration.contract.base.BaseCalibrator.stream`: each stage in one light
        pass (:class:`~wavemeter.calibration.methods.cascade_reading.StageReader`), joined and
        flagged as :meth:`read` joins and flags them, to the numbers :meth:`read` gives
        (to rounding). With ``retrieval="ml"``, :meth:`read` itself."""
        if self.retrieval != "pinv":
            return lambda powers, inputs: _stream_record(self.read(powers))
        readers = [
            (np.array(block), StageReader(stage, error, median))
            for stage, block, error, median in zip(
                self.stages_,
                self.stage_ports_,
                self.model_error_hz_,
                self.cone_distance_median_,
                strict=True,
            )
        ]
        corrected = self._stream_corrector()
        unscaled = np.ones(len(readers))

        def read(powers: np.ndarray, inputs: dict) -> StreamReading:
            readings = corrected(powers)
            found = []
            coarse = self.center_hz_
            for block, reader in readers:
                found.append(reader.read(readings[0, block], coarse))
                coarse = found[-1][0]
            frequency, std, phase, maps, distance = zip(*found, strict=True)
            chain = self._joined(
                np.array(frequency)[:, None],
                np.array(std)[:, None],
                np.array(phase)[:, None],
                [stage_map[np.newaxis] for stage_map in maps],
                np.array(distance)[:, None],
                unscaled,
            )
            return _stream_record(self._flagged(chain, readings))

        return read

    def _frequency_hz(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """Absolute frequency (Hz) from the finest stage at the order the stages before it
        picked."""
        return self._read(readings).frequency_hz[-1]

    def _phase_rad(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """The finest stage's retrieved phase (rad)."""
        return self._read(readings).phase_rad[-1]

    def _frequency_std(self, readings, inputs: ReadingInputs, include_calibration: bool):
        """The finest stage's standard deviation (Hz), given the orders are right."""
        chain = self._read(readings)
        if include_calibration:
            return chain.std_hz[-1]
        rows = readings[:, list(self.stage_ports_[-1])]
        return self.stages_[-1]._frequency_std_of(
            rows, chain.frequency_hz[-1], chain.phase_rad[-1], chain.maps[-1], False
        )

    def _crlb(self, readings, inputs: ReadingInputs, frequency_hz) -> np.ndarray:
        """The finest stage's bound, at the frequency read (clipped to the band: the finest
        stage has no map beyond it) or at ``frequency_hz``."""
        if frequency_hz is None:
            low, high = self.span_hz_
            coarse = np.clip(self._read(readings).frequency_hz[-1], low, high)
        else:
            coarse = frequency_hz
        rows = readings[:, list(self.stage_ports_[-1])]
        return self.stages_[-1]._crlb(rows, ReadingInputs(coarse_hz=coarse), frequency_hz)

    def _model_flags(self, readings, inputs: ReadingInputs) -> np.ndarray:
        return self._chain_flags(self._read(readings))

    def _readout(self, readings, inputs: ReadingInputs) -> Readout:
        """One pass through the stages: the finest stage's frequency, uncertainty and phase,
        the flags and the probability of a wrong order; as the block's state, each stage's
        noise in these readings over the calibrated one (:meth:`readout_notes`)."""
        chain = self._read(readings)
        return Readout(
            chain.frequency_hz[-1],
            chain.std_hz[-1],
            self._chain_flags(chain),
            {"order_error_probability": chain.order_error_probability},
            chain.phase_rad[-1],
            {"noise_scale": chain.noise_scale},
        )

    def readout_notes(self, states) -> list:
        """The warning that the readings are noisier than the calibration sweep, from the
        largest noise scale of each stage over the blocks; none when none is."""
        scales = [state["noise_scale"] for state in states if "noise_scale" in state]
        if not scales:
            return []
        noise_scale = np.max(scales, axis=0)
        noisier = np.flatnonzero(noise_scale > 1.0)
        if noisier.size == 0:
            return []
        stages = ", ".join(
            f"{noise_scale[index]:.3g}x in stage {index + 1} "
            f"({frequency_text(self.stage_fsrs_hz_[index])})"
            for index in noisier
        )
        return [
            CalibrationWarning(
                f"the readings are noisier than the calibration sweep: their detector noise is "
                f"{stages} the calibrated one (estimated from the readings' distances to each "
                "stage's model); frequency_std_hz and order_error_probability follow the "
                "readings' noise, and wrong orders grow more likely with it",
                cause=READING_NOISE_CAUSE,
                remedy="lower the readings' noise (more power, averaging) or recalibrate in "
                "the conditions of use",
            )
        ]

    def order_error_probability(self, powers) -> np.ndarray:
        """Probability that some stage picked a wrong fringe order, per reading.

        From the stages' uncertainties and each hand-over's residual (module docstring);
        the mean over readings is the expected wrong-order rate.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)

        Returns
        -------
        ndarray, shape (N,), in [0, 1)
        """
        return self.read(powers).order_error_probability

    @property
    def noise_std_w_(self) -> float:
        """The finest stage's detector noise estimate (W), the cascade's precision."""
        check_fitted(self)
        return self.stages_[-1].noise_std_w_

    def model_phase_rad(self, frequency_hz) -> np.ndarray:
        """The finest stage's model phase (rad, wrapped) at frequencies (Hz)."""
        check_fitted(self)
        return self.stages_[-1].model_phase_rad(frequency_hz)

    def fsr_hz_at(self, frequency_hz) -> np.ndarray:
        """The finest stage's local FSR (Hz) at frequencies (Hz)."""
        check_fitted(self)
        return self.stages_[-1].fsr_hz_at(frequency_hz)

    def _chain_flags(self, chain: CascadeReading) -> np.ndarray:
        """``ORDER_AMBIGUOUS`` where the probability of a wrong order exceeds
        ``max_order_error``; ``OFF_MODEL`` where a stage's reading is off its cone (in the
        readings' noise) or a hand-over's residual exceeds ``DISAGREEMENT_STD`` standard
        deviations (the stages disagree); ``OUTSIDE_SPAN`` where a stage's frequency lies
        outside the band by more than ``SPAN_MARGIN_STD`` of its standard deviations."""
        flags = np.zeros(chain.frequency_hz.shape[1], dtype=np.int64)
        low, high = self.span_hz_
        for index, block in enumerate(self.stage_ports_):
            frequency, margin = chain.frequency_hz[index], SPAN_MARGIN_STD * chain.std_hz[index]
            flags[(frequency < low - margin) | (frequency > high + margin)] |= (
                ReadingFlag.OUTSIDE_SPAN
            )
            threshold = off_model_threshold(len(block), self.stages_[index].noise_dof_)
            flags[chain.cone_distance[index] > threshold] |= ReadingFlag.OFF_MODEL
        flags[np.any(chain.disagreement_std > DISAGREEMENT_STD, axis=0)] |= ReadingFlag.OFF_MODEL
        flags[chain.order_error_probability > self.max_order_error] |= ReadingFlag.ORDER_AMBIGUOUS
        return flags

    def _offsets_known(self) -> bool:
        return super()._offsets_known() or any(stage._offsets_known() for stage in self.stages_)
