"""Absolute frequency from a cascade of interferometers of decreasing FSR, with order confidence.

One source feeds several stages (an on-chip cascade such as 5 THz / 500 GHz / 50 GHz over
the C band, or the etalons of a commercial meter); a reading holds every stage's ports.
:class:`CascadeCalibrator` calibrates each stage from one sweep over the band with the
wide-band model (:class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator`: a phase
polynomial and a map smooth in frequency, which is the paper's model on a stage whose FSR
exceeds the band) and reads a frequency without any coarse input:

1. the coarsest stage's phase is unique over the band: read with the band's middle as the
   coarse value, it gives the frequency;
2. every further stage is read with the stage before it as the coarse value: of its
   frequencies modulo its FSR it takes the one nearest that estimate (the fringe order);
3. the finest stage's frequency is the answer, its uncertainty that of the finest stage
   (given the orders are right).

Each stage's uncertainty is its wide-band calibration's, in the readings' own noise
(:func:`noise_scale`, measured against the sweep), plus any error the sweep showed beyond
it (``model_error_hz_``).

A wrong order is a gross error of a whole FSR, so each reading says how likely one is
(:meth:`CascadeCalibrator.order_error_probability`, :mod:`wavemeter.model.orders`): at a
hand-over the residual ``r`` (coarse estimate minus fine one) has the standard deviation
``s`` of both stages' uncertainties, and the posterior probability of another order is
``sum_{m != 0} w_m / sum_m w_m``, ``w_m = exp(-(r - m F)^2 / (2 s^2))``; at the coarsest
stage, it is the probability that the reading lies past an end of the range its phase is
unique over. The probabilities of the stages combine as ``1 - prod (1 - p_k)``.

The fit checks the hand-overs on the sweep itself: a hand-over whose expected wrong-order
rate at the sweep's noise exceeds ``max_order_error`` is refused (the message names the
stages and the largest FSR ratio the noise allows), and wrong orders seen on the sweep
beyond what the rates predict raise a warning.
"""

from __future__ import annotations

import dataclasses
import math
import types
import warnings
from collections.abc import Callable

import numpy as np
from scipy import special, stats

from ...exceptions import CalibrationWarning, InputError, recorded_calibration_warnings
from ...model.orders import handover_error_probability, handover_error_rate, wrap_error_probability
from ...validation import (
    MIN_SAMPLES,
    check_choice,
    check_dark,
    check_fitted,
    check_frequency,
    check_monitor,
    check_positive,
    check_powers,
)
from ..contract.base import BaseCalibrator, Part
from ..contract.flags import SPAN_MARGIN_STD, ReadingFlag, off_model_threshold, power_flags
from ..contract.records import ReadingInputs, Readout, StreamReading
from ..contract.summary import FitValue
from ..files.document import calibrator_fields, calibrator_from_fields, state_array, state_float
from ..models.delay_search import frequency_text
from .cascade_reading import (
    NOISE_P_VALUE,
    CascadeReading,
    StageReader,
    chi2_median,
    distance_in_noise,
    noise_scale,
)
from .cascade_report import cascade_tables, order_error_check
from .learned import RETRIEVALS
from .wideband import WidebandCalibrator
from .wideband_reading import band_cone_distance

__all__ = ["CascadeCalibrator", "HANDOVER_CAUSE", "READING_NOISE_CAUSE"]

#: the cause of a warning that the readings are noisier than the calibration sweep
READING_NOISE_CAUSE = "reading_noise"
#: the cause of a warning that the sweep saw more wrong orders than the rates predict
HANDOVER_CAUSE = "order_handover"
HANDOVER_REMEDY = (
    "look for steps in the sweep (a mode hop of the laser, a wavelength reference that "
    "slipped, a stage that drifted) and re-record it"
)
#: misfit causes whose residual a map changing with wavelength also leaves on a stage
#: swept over less than its FSR
SWEEP_MISFIT_CAUSES = ("power_drift", "detector_offset", "phase_drift", "other_misfit")
#: p-value below which the wrong orders seen on the sweep contradict the predicted ones
HANDOVER_P_VALUE = 1e-6
#: a hand-over residual beyond this many standard deviations is OFF_MODEL: the stages
#: disagree beyond their uncertainties (two-sided p-value ``OFF_MODEL_P_VALUE``, 1e-6)
DISAGREEMENT_STD = float(special.ndtri(1.0 - 0.5e-6))
#: the issue's C-band cascade (Hz, coarsest first)
DEFAULT_FSRS_HZ = (5e12, 500e9, 50e9)


def _stream_record(chain: CascadeReading) -> StreamReading:
    """What a stream gives for one reading read through the stages (with its flags)."""
    return StreamReading(
        float(chain.frequency_hz[-1, 0]),
        float(chain.std_hz[-1, 0]),
        int(chain.flags[0]),
        {"order_error_probability": float(chain.order_error_probability[0])},
    )


def _stage_label(index: int, fsr_hz: float) -> str:
    return f"stage {index + 1} ({frequency_text(fsr_hz)})"


class CascadeCalibrator(BaseCalibrator):
    """Absolute frequency from interferometer stages of decreasing FSR (module docstring).

    Parameters
    ----------
    fsr_hz : sequence of float
        Design FSR of each stage (Hz), coarsest first, strictly decreasing; at least two.
        The coarsest must exceed the band (its phase is then unique there).
    stage_ports : None or sequence of sequences of int
        The reading columns (zero-based) of each stage, every column in exactly one stage;
        None: consecutive blocks of equal size.
    retrieval : {"pinv", "ml"}
        Phase retrieval of every stage, as for
        :class:`~wavemeter.calibration.methods.learned.Calibrator`.
    max_order_error : float
        Probability of a wrong order above which a reading is flagged ``ORDER_AMBIGUOUS``,
        and the wrong-order rate per reading above which a hand-over is refused at fit
        time; in (0, 1).
    fsr_tolerance : float
        Relative half width of each stage's FSR bracket, in (0, 1).

    Attributes
    ----------
    stages_ : list of WidebandCalibrator
        One fitted calibration per stage, coarsest first, each on its own columns.
    stage_ports_ : tuple of tuple of int
        The columns of each stage.
    stage_fsrs_hz_ : ndarray, shape (K,)
        Each stage's fitted FSR at ``center_hz_`` (Hz).
    fsr_hz_ : float
        The finest stage's FSR (Hz).
    handovers_ : list of dict
        Per hand-over (stage ``k`` to ``k + 1``), JSON-ready: ``ratio`` (fitted FSRs),
        ``median_std_hz`` (of the residual over the sweep), ``margin_std`` (half the fine
        FSR over that std: the typical reading's margin), ``worst_margin_std``,
        ``largest_usable_ratio`` (the ratio at which the sweep's noise would make the rate
        ``max_order_error``), ``predicted_rate`` (mean expected wrong-order rate over the
        sweep), ``expected_wrong`` and ``wrong_on_sweep`` (counts on the sweep).
    model_error_hz_ : ndarray, shape (K,)
        Each stage's error on the sweep beyond its uncertainty (Hz, 0 where none is
        significant; estimated robustly), added to its readings' std in quadrature (a
        coarsest stage whose model misses the chip's wavelength slopes has some).
    cone_distance_median_ : ndarray, shape (K,)
        Each stage's median cone distance over the sweep: readings whose distances lie
        above it more often than chance carry more noise than the sweep
        (:func:`noise_scale`).
    edge_margin_std_ : float
        Distance (in the coarsest stage's standard deviations at the band ends, the
        smaller end) from the band to the ends of the range that stage's phase is unique
        over.
    calibration_rms_hz_ : float
        RMS absolute error of the sweep read through the cascade (Hz).
    diagnostics_ : dict
        ``"cascade"``: stages (FSR, orders, RMS, z-score spread on the sweep), hand-overs
        and the edge margin; ``"warnings"``: every stage's warnings, named by stage.
    """

    method = "cascade"
    absolute_frequency = True
    capabilities = frozenset({"frequency_std", "crlb", "power_monitor"})
    reading_outputs = types.MappingProxyType({"order_error_probability": "1"})

    def __init__(
        self,
        fsr_hz=DEFAULT_FSRS_HZ,
        stage_ports=None,
        retrieval: str = "pinv",
        max_order_error: float = 1e-6,
        fsr_tolerance: float = 0.2,
    ):
        self.fsr_hz = fsr_hz
        self.stage_ports = stage_ports
        self.retrieval = retrieval
        self.max_order_error = max_order_error
        self.fsr_tolerance = fsr_tolerance

    # ------------------------------------------------------------------ parameters
    def _design_fsrs_hz(self) -> tuple[float, ...]:
        values = self.fsr_hz
        if isinstance(values, (str, bytes)) or np.ndim(values) != 1 or len(values) < 2:
            raise InputError(
                "fsr_hz must be the design FSRs of two or more stages (Hz, coarsest first), "
                f"got {values!r}",
                parameter="fsr_hz",
            )
        try:
            fsrs = tuple(check_positive("fsr_hz", value) for value in values)
        except InputError as exc:
            raise InputError(str(exc), parameter="fsr_hz") from exc
        if any(fine >= coarse for coarse, fine in zip(fsrs[:-1], fsrs[1:], strict=True)):
            raise InputError(
                f"fsr_hz must decrease from stage to stage (coarsest first), got {list(fsrs)}",
                parameter="fsr_hz",
            )
        return fsrs

    def _check_params(self) -> None:
        self._design_fsrs_hz()
        check_choice("retrieval", self.retrieval, RETRIEVALS)
        check_positive("max_order_error", self.max_order_error, upper=1.0)
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        if self.stage_ports is not None:
            self._stage_columns(None)

    def _stage_columns(self, ports: int | None) -> tuple[tuple[int, ...], ...]:
        """The columns of each stage, checked against ``ports`` columns (None: the setting
        alone)."""
        stages = len(self._design_fsrs_hz())
        if self.stage_ports is None:
            if ports is None:
                return ()
            if ports % stages or ports // stages < 3:
                raise InputError(
                    f"the readings have {ports} columns, which do not split into {stages} "
                    "stages of 3 or more ports each: give stage_ports (the columns of each "
                    "stage)",
                    parameter="stage_ports",
                )
            size = ports // stages
            return tuple(tuple(range(k * size, (k + 1) * size)) for k in range(stages))
        given = self.stage_ports
        wrong = (
            f"stage_ports must list, for each of the {stages} stages, 3 or more column "
            f"indices (zero-based), got {given!r}"
        )
        if isinstance(given, (str, bytes)) or len(given) != stages:
            raise InputError(wrong, parameter="stage_ports")
        columns = []
        for block in given:
            if isinstance(block, (str, bytes)) or np.ndim(block) != 1 or len(block) < 3:
                raise InputError(wrong, parameter="stage_ports")
            if not all(
                isinstance(index, (int, np.integer)) and not isinstance(index, bool) and index >= 0
                for index in block
            ):
                raise InputError(wrong, parameter="stage_ports")
            columns.append(tuple(int(index) for index in block))
        flat = [index for block in columns for index in block]
        if len(set(flat)) != len(flat):
            raise InputError(
                f"stage_ports must give each column to one stage only, got {given!r}",
                parameter="stage_ports",
            )
        if ports is not None and sorted(flat) != list(range(ports)):
            missing = sorted(set(range(ports)) - set(flat))
            beyond = sorted(set(flat) - set(range(ports)))
            raise InputError(
                f"stage_ports must use every one of the {ports} columns once"
                + (f"; columns {missing} belong to no stage" if missing else "")
                + (f"; columns {beyond} do not exist" if beyond else "")
                + ": give each column to a stage, or leave it out of the readings",
                parameter="stage_ports",
            )
        return tuple(columns)

    def get_params_for_file(self) -> dict:
        params = super().get_params_for_file()
        if self.stage_ports is not None:
            params["stage_ports"] = [[int(index) for index in block] for block in self.stage_ports]
        return params

    @classmethod
    def _params_from_file(cls, params: dict) -> dict:
        params = dict(params)
        if isinstance(params.get("fsr_hz"), list):
            params["fsr_hz"] = tuple(params["fsr_hz"])
        if isinstance(params.get("stage_ports"), list):
            params["stage_ports"] = tuple(
                tuple(block) if isinstance(block, list) else block
                for block in params["stage_ports"]
            )
        return params

    def _stage_calibrator(self, fsr_hz: float) -> WidebandCalibrator:
        return WidebandCalibrator(
            fsr_hz=fsr_hz, fsr_tolerance=self.fsr_tolerance, retrieval=self.retrieval
        )

    # ------------------------------------------------------------------ fitting
    def fit(
        self,
        powers,
        frequency_hz,
        power_monitor_w=None,
        port_names=None,
        *,
        dark_w=None,
        temperature_k=None,
    ):
        """Calibrate every stage from one sweep over the band and check the hand-overs.

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings of every stage (W, or any unit linear in power), the columns
            of each stage as ``stage_ports`` says.
        frequency_hz : array_like, shape (N,)
            Known source frequency of each reading (Hz), over the band to be measured
            (narrower than the coarsest FSR).
        power_monitor_w : None or array_like, shape (N,)
            Source-power monitor reading (W, or any unit linear in power).
        port_names : None or sequence of str, length n
            Names of the columns.
        dark_w : None or array_like, shape (n,)
            Per-column dark readings (W), subtracted from every reading.
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature of each reading (K): its range is kept in the diagnostics.

        Returns
        -------
        self

        Raises
        ------
        InputError
            For readings or settings that are wrong (the stage named); with
            ``parameter="fsr_hz"`` when the coarsest stage's FSR does not exceed the band
            or a hand-over's wrong-order rate at the sweep's noise exceeds
            ``max_order_error`` (the message names the stages and the largest usable FSR
            ratio).

        Warns
        -----
        CalibrationWarning
            Each stage's (named by stage; the coarsest stage's ``"partial_span"`` is left
            out: its FSR exceeds the band by design; its misfits say what they cost in a
            cascade, ``SWEEP_MISFIT_CAUSES``), and cause ``"order_handover"`` when
            the sweep saw more wrong orders than the rates predict.
        """
        self._check_params()
        raw = check_powers(powers, min_samples=MIN_SAMPLES)
        frequency = check_frequency(frequency_hz, raw.shape[0])
        monitor = check_monitor(power_monitor_w, raw.shape[0])
        ports = raw.shape[1]
        dark = check_dark(dark_w, ports)
        columns = self._stage_columns(ports)
        names = [f"p{k + 1}" for k in range(ports)] if port_names is None else list(port_names)
        if len(names) != ports or not all(isinstance(name, str) for name in names):
            raise InputError(f"port_names must be {ports} strings, got {port_names!r}")
        design = self._design_fsrs_hz()
        stages, notes = [], []
        for index, (fsr, block) in enumerate(zip(design, columns, strict=True)):
            label = _stage_label(index, fsr)
            stage = self._stage_calibrator(fsr)
            try:
                with recorded_calibration_warnings() as caught:
                    stage.fit(
                        raw[:, block],
                        frequency,
                        monitor,
                        [names[column] for column in block],
                        dark_w=None if dark is None else dark[list(block)],
                        temperature_k=temperature_k,
                    )
            except InputError as exc:
                raise type(exc)(f"{label}: {exc}", parameter=exc.parameter) from exc
            notes += [
                CalibrationWarning(f"{label}: {note}", cause=note.cause, remedy=note.remedy)
                for note in caught
                if not (index == 0 and note.cause == "partial_span")
            ]
            stages.append(stage)
        self.stages_ = stages
        self.stage_ports_ = columns
        self.stage_fsrs_hz_ = np.array([stage.fsr_hz_ for stage in stages])
        self.fsr_hz_ = float(self.stage_fsrs_hz_[-1])
        self.center_hz_ = stages[0].center_hz_
        self.span_hz_ = stages[0].span_hz_
        self.n_ports_ = ports
        self.n_samples_ = raw.shape[0]
        self.port_names_ = names
        self.dark_w_ = dark
        self.offset_w_ = self._stage_offsets_w()
        corrected = raw - self._reading_offset_w()
        total = corrected.sum(axis=1)
        self.total_power_range_w_ = (float(total.min()), float(total.max()))
        self._check_coarsest_stage()
        self.cone_distance_median_ = np.array(
            [
                np.median(
                    band_cone_distance(
                        corrected[:, list(block)],
                        stage.band_model_.maps_at(frequency),
                        stage.port_noise_std_w_,
                    )
                )
                for stage, block in zip(stages, columns, strict=True)
            ]
        )
        self.model_error_hz_ = np.zeros(len(stages))
        self.model_error_hz_ = self._model_error_hz(self._read(corrected), frequency)
        chain = self._read(corrected)
        self.calibration_rms_hz_ = float(
            np.sqrt(np.mean((chain.frequency_hz[-1] - frequency) ** 2))
        )
        self.handovers_ = self._handovers(chain, frequency)
        self.edge_margin_std_ = self._edge_margin_std(chain, frequency)
        notes = [self._coarsest_context(note) for note in notes] + self._handover_notes()
        self.diagnostics_ = {
            "temperature_range_k": stages[0].diagnostics_.get("temperature_range_k"),
            "cascade": {
                "stages": self._stage_records(chain, frequency),
                "handovers": self.handovers_,
                "edge_margin_std": self.edge_margin_std_,
            },
            "warnings": [note.record() for note in notes],
        }
        for note in notes:
            warnings.warn(note, stacklevel=2)
        return self

    def _stage_offsets_w(self) -> np.ndarray:
        """Every column's fitted offset (W), from the stage that reads it."""
        offsets = np.zeros(self.n_ports_)
        for stage, block in zip(self.stages_, self.stage_ports_, strict=True):
            offsets[list(block)] = stage.offset_w_
        return offsets

    def _check_coarsest_stage(self) -> None:
        """Refuse a coarsest stage whose phase repeats within the band."""
        coarsest = self.stages_[0]
        low, high = self.span_hz_
        phase = coarsest.band_model_.phase_rad(np.array([low, high, self.center_hz_]))
        turn = float(phase[1] - phase[0]) / (2.0 * np.pi)
        if turn >= 1.0:
            raise InputError(
                f"{_stage_label(0, float(self._design_fsrs_hz()[0]))}: its fitted FSR "
                f"{frequency_text(coarsest.fsr_hz_)} does not exceed the band swept "
                f"({frequency_text(high - low)}, {turn:.3g} of its fringe): frequencies one "
                "FSR apart give it the same reading and no stage can tell them apart; sweep "
                "and measure a band narrower than that FSR, or add a coarser stage",
                parameter="fsr_hz",
            )

    def _handovers(self, chain: CascadeReading, frequency_hz: np.ndarray) -> list[dict]:
        """Every hand-over's record on the sweep (``handovers_``); refuses a hand-over whose
        expected wrong-order rate exceeds ``max_order_error``."""
        records = []
        design = self._design_fsrs_hz()
        required = math.sqrt(2.0) * float(special.erfcinv(self.max_order_error))
        for index in range(1, len(self.stages_)):
            coarse, fine = self.stages_[index - 1], self.stages_[index]
            fsr = fine.fsr_hz_at(chain.frequency_hz[index])
            std = np.hypot(chain.std_hz[index - 1], chain.std_hz[index])
            rate = handover_error_rate(fsr, std)
            # phase std (rad) of both stages: the ratio at which the margin is `required`
            coarse_phase = np.median(chain.std_hz[index - 1] * 2.0 * np.pi / coarse.fsr_hz_)
            fine_phase = np.median(chain.std_hz[index] * 2.0 * np.pi / fine.fsr_hz_)
            usable = math.sqrt(max((np.pi / required) ** 2 - fine_phase**2, 0.0)) / coarse_phase
            ratio = coarse.fsr_hz_ / fine.fsr_hz_
            # the order this hand-over took against the one the recorded frequency has,
            # each stage's error taken within its own order
            before = self._within_order_error_hz(chain, frequency_hz, index - 1)
            after = self._within_order_error_hz(chain, frequency_hz, index)
            wrong = np.round((before - after) / fsr) != 0
            record = {
                "from_stage": index,
                "to_stage": index + 1,
                "ratio": float(ratio),
                "median_std_hz": float(np.median(std)),
                "margin_std": float(np.median(0.5 * fsr / std)),
                "worst_margin_std": float(np.min(0.5 * fsr / std)),
                "largest_usable_ratio": float(usable),
                "predicted_rate": float(np.mean(rate)),
                "expected_wrong": float(np.sum(chain.error_probability[index])),
                "wrong_on_sweep": int(np.count_nonzero(wrong)),
            }
            if record["predicted_rate"] > self.max_order_error:
                raise InputError(
                    f"{_stage_label(index - 1, design[index - 1])} cannot pick the fringe order "
                    f"of {_stage_label(index, design[index])}: its frequency noise on the sweep "
                    f"({frequency_text(record['median_std_hz'])} with the finer stage's, "
                    f"median) is {2.0 * record['median_std_hz'] / float(np.median(fsr)):.3g} "
                    "of the finer stage's half FSR, a wrong order for "
                    f"{record['predicted_rate']:.3g} of the readings (max_order_error "
                    f"{self.max_order_error:g}); at this noise the largest usable FSR ratio "
                    f"is {usable:.3g} and these stages have {ratio:.3g}: lower the noise "
                    "(more power per stage, averaged readings) or add a stage between them",
                    parameter="fsr_hz",
                )
            records.append(record)
        return records

    def _within_order_error_hz(
        self, chain: CascadeReading, frequency_hz: np.ndarray, index: int
    ) -> np.ndarray:
        """Stage ``index``'s error (Hz) against the recorded frequencies, within its order
        (the coarsest stage's as it is)."""
        error = chain.frequency_hz[index] - frequency_hz
        if index == 0:
            return error
        fsr = self.stages_[index].fsr_hz_at(frequency_hz)
        return error - fsr * np.round(error / fsr)

    def _edge_margin_std(self, chain: CascadeReading, frequency_hz: np.ndarray) -> float:
        """The coarsest stage's unique range beyond the band, in that stage's standard
        deviations of the sweep readings at the band's ends (the smaller end)."""
        ends = np.array([np.argmin(frequency_hz), np.argmax(frequency_hz)])
        model = self.stages_[0].band_model_
        end_hz = frequency_hz[ends]
        offset = model.phase_rad(end_hz) - model.phase_rad(np.array([self.center_hz_]))
        distance = (np.pi - np.abs(offset)) / model.phase_slope_rad_per_hz(end_hz)
        return float(np.min(distance / chain.std_hz[0][ends]))

    def _coarsest_context(self, note: CalibrationWarning) -> CalibrationWarning:
        """A misfit of the coarsest stage, with what it means in a cascade: the stage's
        band is narrower than its FSR, where a map changing with wavelength cannot be told
        from the phase, and its uncertainties (the model-free noise) carry the misfit into
        the hand-over margin, not into the answer."""
        label = _stage_label(0, self._design_fsrs_hz()[0])
        if note.cause not in SWEEP_MISFIT_CAUSES or not str(note).startswith(f"{label}:"):
            return note
        margin = self.handovers_[0]["margin_std"]
        context = (
            "in a cascade the coarsest stage covers less than one of its FSRs, where a map "
            "changing with wavelength (coupler and detector slopes, which over a sweep look "
            "like a drift) cannot be told from the phase and leaves a residual of this kind: "
            "the stage's uncertainties include it, so it costs hand-over margin (now "
            f"{margin:.3g} standard deviations to stage 2), not the finest stage's accuracy"
        )
        return CalibrationWarning(
            f"{note}; {context}", cause=note.cause, remedy=f"{note.remedy}; {context}"
        )

    def _handover_notes(self) -> list[CalibrationWarning]:
        """A warning per hand-over where the sweep saw improbably many wrong orders."""
        notes = []
        for record in self.handovers_:
            seen, expected = record["wrong_on_sweep"], record["expected_wrong"]
            if seen and stats.poisson.sf(seen - 1, expected) < HANDOVER_P_VALUE:
                notes.append(
                    CalibrationWarning(
                        f"stage {record['from_stage']} handed stage {record['to_stage']} "
                        f"another fringe order than the recorded frequency has on {seen} sweep "
                        f"readings, where the stages' uncertainties predict {expected:.3g}: "
                        "those readings are not where the sweep says, or the stages disagree "
                        f"beyond their noise; {HANDOVER_REMEDY}",
                        cause=HANDOVER_CAUSE,
                        remedy=HANDOVER_REMEDY,
                    )
                )
        return notes

    def _model_error_hz(self, chain: CascadeReading, frequency_hz: np.ndarray) -> np.ndarray:
        """Each stage's error (Hz) on the sweep beyond its uncertainty, where significant.

        A stage whose model misses part of the chip (the coarsest stage over less than its
        FSR) reads the sweep with errors its ``std`` does not explain. Robustly, so that a
        few bad sweep readings do not count: when more z-scores than chance lie beyond
        the normal quartile ``Q`` (binomial at ``NOISE_P_VALUE``), their spread ``r =
        median |z| / Q`` gives the excess ``sqrt(r^2 - 1) rms(std)``, added to every
        reading's std in quadrature.
        """
        quartile = float(special.ndtri(0.75))
        excess = np.zeros(len(self.stages_))
        for index in range(len(self.stages_)):
            error = self._within_order_error_hz(chain, frequency_hz, index)
            std = chain.std_hz[index]
            z = np.abs(error / std)
            beyond = int(np.count_nonzero(z > quartile))
            if stats.binom.sf(beyond - 1, z.size, 0.5) < NOISE_P_VALUE:
                spread = float(np.median(z)) / quartile
                excess[index] = math.sqrt(max(spread**2 - 1.0, 0.0) * np.mean(std**2))
        return excess

    def _stage_records(self, chain: CascadeReading, frequency_hz: np.ndarray) -> list[dict]:
        records = []
        for index, stage in enumerate(self.stages_):
            error = chain.frequency_hz[index] - frequency_hz
            if index == 0:
                z = error / chain.std_hz[index]
            else:
                # modulo the stage's FSR: its precision, whatever order it was handed
                fsr = stage.fsr_hz_at(chain.frequency_hz[index])
                z = (error - fsr * np.round(error / fsr)) / chain.std_hz[index]
            records.append(
                {
                    "stage": index + 1,
                    "ports": [self.port_names_[column] for column in self.stage_ports_[index]],
                    "fsr_hz": float(stage.fsr_hz_),
                    "phase_order": stage.phase_order_,
                    "map_order": stage.map_order_,
                    "rms_hz": float(np.sqrt(np.mean(error**2))),
                    "median_std_hz": float(np.median(chain.std_hz[index])),
                    "z_std": float(np.std(z)),
                }
            )
        return records

    # ------------------------------------------------------------------ reading
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

    # ------------------------------------------------------------------ reporting
    def _fsr_std_hz(self) -> float | None:
        return self.stages_[-1]._fsr_std_hz()

    def _design_fsr_hz(self) -> float:
        """The finest stage's design FSR (Hz), as ``fsr_hz_`` is the finest stage's."""
        return self._design_fsrs_hz()[-1]

    def _summary_values(self) -> dict:
        values = {
            f"stage_{index + 1}_fsr_hz": FitValue(
                float(stage.fsr_hz_), stage._fsr_std_hz(), "Hz", f"stage {index + 1} FSR"
            )
            for index, stage in enumerate(self.stages_)
        }
        for record in self.handovers_:
            stages = f"{record['from_stage']}_{record['to_stage']}"
            values[f"handover_{stages}_margin_std"] = FitValue(
                record["margin_std"],
                None,
                "",
                f"hand-over {record['from_stage']} to {record['to_stage']} margin (std)",
            )
        values["edge_margin_std"] = FitValue(self.edge_margin_std_, None, "", "edge margin (std)")
        values["noise_std_w"] = FitValue(
            float(self.stages_[-1].noise_std_w_), None, "W", "noise estimate (finest stage)"
        )
        return values

    def summary(self):
        """The fit report, with the tables of the stages and the hand-overs."""
        report = super().summary()
        record = (self.diagnostics_ or {}).get("cascade")
        if not record:
            return report
        tables = cascade_tables(record, self._design_fsrs_hz(), self.max_order_error)
        return dataclasses.replace(report, tables=(*report.tables, *tables))

    def comparison(self, port_phases_rad=None):
        raise InputError(
            "a cascade calibration has no other method to fit on its sweep for comparison: "
            "no other method reads absolute frequency from the readings of its stages; "
            "evaluate it alone, or beside another calibration file",
            parameter="comparison",
        )

    def _finest(self, powers_w) -> tuple:
        """The finest stage and the readings of its columns."""
        columns = list(self.stage_ports_[-1])
        return self.stages_[-1], np.asarray(powers_w, dtype=float)[:, columns]

    def fringe_panels(self, frequency_hz, powers_w, monitor_w=None, temperature_k=None):
        """The finest stage's fringes (the stage the answer comes from), on its columns."""
        stage, readings = self._finest(powers_w)
        label = f"stage {len(self.stages_)}"
        return tuple(
            dataclasses.replace(
                panel, title=f"{label}: {panel.title}", port_names=tuple(stage.port_names_)
            )
            for panel in stage.fringe_panels(frequency_hz, readings, monitor_w, temperature_k)
        )

    def object_samples(self, powers_w, frequency_hz, temperature_k=None):
        """The finest stage's samples, each reading under its map at the truth."""
        stage, readings = self._finest(powers_w)
        return stage.object_samples(readings, frequency_hz)

    def evaluation_checks(self, powers_w, frequency_hz):
        """The wrong fringe orders of the readings, seen against predicted and flagged."""
        return (order_error_check(self, powers_w, frequency_hz),)

    def parts(self) -> tuple[Part, ...]:
        """One part per stage, coarsest first."""
        check_fitted(self)
        design = self._design_fsrs_hz()
        return tuple(
            Part(_stage_label(index, design[index]), "stage", stage, tuple(stage.span_hz_))
            for index, stage in enumerate(self.stages_)
        )

    # ------------------------------------------------------------------ persistence
    def _state(self) -> dict:
        return {
            "stage_ports": [list(block) for block in self.stage_ports_],
            "stages": [calibrator_fields(stage) for stage in self.stages_],
            "handovers": self.handovers_,
            "edge_margin_std": self.edge_margin_std_,
            "cone_distance_median": self.cone_distance_median_.tolist(),
            "model_error_hz": self.model_error_hz_.tolist(),
        }

    def _set_state(self, state: dict) -> None:
        design = self._design_fsrs_hz()
        documents = state.get("stages")
        if not isinstance(documents, list) or len(documents) != len(design):
            raise InputError(f"field 'stages' must list {len(design)} stage calibrations")
        blocks = state.get("stage_ports")
        if not isinstance(blocks, list):
            raise InputError("field 'stage_ports' must list the columns of each stage")
        saved, self.stage_ports = (
            self.stage_ports,
            tuple(tuple(block) if isinstance(block, list) else block for block in blocks),
        )
        try:
            columns = self._stage_columns(self.n_ports_)
        finally:
            self.stage_ports = saved
        stages = [
            calibrator_from_fields(document, f"stage {index + 1}")
            for index, document in enumerate(documents)
        ]
        for index, (stage, block) in enumerate(zip(stages, columns, strict=True)):
            if not isinstance(stage, WidebandCalibrator) or stage.n_ports_ != len(block):
                raise InputError(
                    f"stage {index + 1} must be a 'wideband' calibration of {len(block)} ports, "
                    f"got {type(stage).method!r} with {stage.n_ports_}"
                )
        handovers = state.get("handovers")
        if not isinstance(handovers, list) or len(handovers) != len(design) - 1:
            raise InputError(f"field 'handovers' must list {len(design) - 1} hand-overs")
        self.stages_ = stages
        self.stage_ports_ = columns
        self.stage_fsrs_hz_ = np.array([stage.fsr_hz_ for stage in stages])
        self.fsr_hz_ = float(self.stage_fsrs_hz_[-1])
        self.handovers_ = handovers
        self.edge_margin_std_ = state_float(state, "edge_margin_std")
        self.cone_distance_median_ = state_array(state, "cone_distance_median", (len(design),))
        if np.any(self.cone_distance_median_ <= 0):
            raise InputError("field 'cone_distance_median' must hold positive numbers")
        self.model_error_hz_ = state_array(state, "model_error_hz", (len(design),))
        if np.any(self.model_error_hz_ < 0):
            raise InputError("field 'model_error_hz' must hold numbers >= 0 (Hz)")
