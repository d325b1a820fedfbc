"""How a cascade reads: every stage in turn, each handing its frequency to the next.

:class:`ChainReadingMixin` gives :class:`~wavemeter.calibration.methods.cascade.CascadeCalibrator`
its reading: the coarsest stage read with the band's middle as coarse value, each next
stage with the frequency before it, every stage's uncertainty in the readings' own noise
(plus the error its sweep showed beyond it), the probability of a wrong order at each
hand-over and the coarsest stage's edge, the flags, one reading of a stream in one light
pass per stage, and the warning that the readings are noisier than the sweep. The coarsest
stage's fringe covers nearly the whole band: a reading near an end of it may have a twin,
one turn of the phase away, that its map (which turns with the frequency) also reads as
itself; of the two the one nearer its map's cone is taken (:func:`twin_probability`).
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable

import numpy as np
from scipy import special

from ...exceptions import CalibrationWarning
from ...model.orders import (
    any_error_probability,
    handover_error_probability,
    wrap_error_probability,
)
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

__all__ = [
    "ChainReadingMixin",
    "READING_NOISE_CAUSE",
    "is_twin",
    "twin_probability",
    "twin_start_hz",
]

#: the cause of a warning that the readings are noisier than the calibration sweep
READING_NOISE_CAUSE = "reading_noise"
#: a hand-over residual beyond this many standard deviations is OFF_MODEL: the stages
#: disagree beyond their uncertainties (two-sided p-value ``OFF_MODEL_P_VALUE``, 1e-6)
DISAGREEMENT_STD = float(special.ndtri(1.0 - 0.5e-6))


def twin_start_hz(model, frequency_hz: np.ndarray, center_hz: float) -> np.ndarray:
    """Where the coarsest stage's twin of a reading lies: the frequency (Hz) whose model
    phase is one turn from that of ``frequency_hz`` (N,) (Hz), towards the other end of the
    band (from ``center_hz``, Hz)."""
    phase = model.phase_rad(frequency_hz)
    center = float(model.phase_rad(np.array([center_hz]))[0])
    return model.frequency_of_phase_hz(phase - 2.0 * np.pi * np.sign(phase - center), frequency_hz)


def is_twin(model, found_hz, twin_hz, center_hz: float) -> np.ndarray:
    """Whether each ``twin_hz`` (N,) (Hz) is another reading than ``found_hz`` (N,) (Hz)
    (their phases a turn apart, not the same fixed point found again) within the range
    the coarsest stage's phase is unique over (within half a turn of ``center_hz``)."""
    center = float(model.phase_rad(np.array([center_hz]))[0])
    twin = model.phase_rad(twin_hz)
    return (np.abs(twin - model.phase_rad(found_hz)) > np.pi) & (np.abs(twin - center) <= np.pi)


def twin_probability(distance, twin_distance) -> np.ndarray:
    """Probability that the coarsest stage took the wrong one of a reading and its twin.

    Each is a frequency whose map reads the reading at the phase the model has there;
    their cone distances (N,), in the readings' noise (a chi-square's, so half of one is
    minus a log-likelihood), weigh them: ``1 / (1 + exp((d_twin - d) / 2))`` for the one
    taken (the smaller distance); 0 where there is no twin (``twin_distance`` inf).
    """
    with np.errstate(over="ignore"):
        return special.expit(-0.5 * (np.asarray(twin_distance) - np.asarray(distance)))


#: the bits of :func:`power_flags`: all a dim reading's flags say (as ``readout`` says it)
_LIGHT_BITS = int(ReadingFlag.INVALID | ReadingFlag.POWER_RANGE)


def _stream_record(chain: CascadeReading) -> StreamReading:
    """What a stream gives for one reading read through the stages (with its flags; a dim
    reading's only that it is no reading to trust, as in ``readout``)."""
    flags = int(chain.flags[0])
    if flags & ReadingFlag.INVALID:
        flags &= _LIGHT_BITS
    return StreamReading(
        float(chain.frequency_hz[-1, 0]),
        float(chain.std_hz[-1, 0]),
        flags,
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
            distance[index] = band_cone_distance(rows, stage_maps, stage.port_noise_std_w_)
            if index == 0:
                twin_distance = self._take_twins(rows, frequency, phase, stage_maps, distance)
            maps.append(stage_maps)
            reference = self.cone_distance_median_[index]
            median = chi2_median(len(block) - 2, stage.noise_dof_)
            scale[index] = noise_scale(distance[index], reference, median)
            distance[index] = distance_in_noise(distance[index], reference, median, scale[index])
            if index == 0:
                twin_distance = distance_in_noise(twin_distance, reference, median, scale[0])
            std[index] = np.hypot(
                stage._frequency_std_of(
                    rows, frequency[index], phase[index], stage_maps, noise_scale=scale[index]
                ),
                self.model_error_hz_[index],
            )
            coarse = frequency[index]
        twins = twin_probability(distance[0], twin_distance)
        return self._joined(frequency, std, phase, maps, distance, scale, twins)

    def _take_twins(self, rows, frequency, phase, maps, distance) -> np.ndarray:
        """The coarsest stage's twins of its readings (module docstring): where a twin lies
        nearer its map's cone than the reading found from the band's middle, it replaces it
        (in ``frequency[0]``, ``phase[0]``, ``maps``, ``distance[0]``, in place). Returns the
        cone distance of the one not taken (N,) (inf where there is no twin)."""
        stage = self.stages_[0]
        model = stage.band_model_
        start = twin_start_hz(model, frequency[0], self.center_hz_)
        other = np.full(rows.shape[0], np.inf)
        tried = np.flatnonzero(stage._coarse_inside(start))
        if tried.size == 0:
            return other
        found, found_phase, found_maps = stage._frequency_checked(rows[tried], start[tried])
        twin = is_twin(model, frequency[0][tried], found, self.center_hz_)
        tried, found, found_phase, found_maps = (
            tried[twin],
            found[twin],
            found_phase[twin],
            found_maps[twin],
        )
        found_distance = band_cone_distance(rows[tried], found_maps, stage.port_noise_std_w_)
        other[tried] = found_distance
        nearer = found_distance < distance[0][tried]
        taken = tried[nearer]
        other[taken] = distance[0][taken]
        frequency[0][taken] = found[nearer]
        phase[0][taken] = found_phase[nearer]
        maps[taken] = found_maps[nearer]
        distance[0][taken] = found_distance[nearer]
        return other

    def _joined(self, frequency, std, phase, maps, distance, scale, twins) -> CascadeReading:
        """The stages' readings (K, N), each with the probability that its order is wrong
        (the coarsest stage's edge or twin, then each hand-over's) and the hand-overs'
        disagreement; ``twins`` (N,): :func:`twin_probability`."""
        stages, samples = frequency.shape
        probability = np.empty((stages, samples))
        probability[0] = any_error_probability(
            [self._edge_probability(frequency[0], std[0]), twins]
        )
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
            block, reader = readers[0]
            first, twins = self._stream_coarsest(reader, readings[0, block])
            found = [first]
            for block, reader in readers[1:]:
                found.append(reader.read(readings[0, block], found[-1][0]))
            frequency, std, phase, maps, distance = zip(*found, strict=True)
            chain = self._joined(
                np.array(frequency)[:, None],
                np.array(std)[:, None],
                np.array(phase)[:, None],
                [stage_map[np.newaxis] for stage_map in maps],
                np.array(distance)[:, None],
                unscaled,
                np.array([twins]),
            )
            return _stream_record(self._flagged(chain, readings))

        return read

    def _stream_coarsest(self, reader: StageReader, rows: np.ndarray) -> tuple:
        """The coarsest stage's reading of one offset-corrected reading ``rows`` (n,), as
        :meth:`_read` takes it with its twin (:meth:`_take_twins`): the
        :meth:`StageReader.read` taken and :func:`twin_probability`."""
        stage = self.stages_[0]
        model = stage.band_model_
        found = reader.read(rows, self.center_hz_)
        start = twin_start_hz(model, np.array([found[0]]), self.center_hz_)
        if not stage._coarse_inside(start)[0]:
            return found, 0.0
        twin = reader.read(rows, float(start[0]))
        if not is_twin(model, np.array([found[0]]), np.array([twin[0]]), self.center_hz_)[0]:
            return found, 0.0
        noise = stage.port_noise_std_w_
        distance, twin_distance = (
            float(reader.in_noise(band_cone_distance(rows[None], read[3][None], noise)[0]))
            for read in (found, twin)
        )
        if twin_distance < distance:
            found, distance, twin_distance = twin, twin_distance, distance
        return found, float(twin_probability(distance, twin_distance))

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
