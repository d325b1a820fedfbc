"""Absolute frequency from a cascade of interferometers of decreasing FSR, with order confidence.

One source feeds several stages (an on-chip cascade such as 5 THz / 500 GHz / 50 GHz over
the C band, or the etalons of a commercial meter); a reading holds every stage's ports.
:class:`CascadeCalibrator` calibrates each stage from one sweep over the band with the
wide-band model, checks the hand-overs on the sweep
(:mod:`~wavemeter.calibration.methods.cascade_handover`) and reads absolute frequency with
no coarse input, each reading with the probability of a wrong fringe order
(:mod:`~wavemeter.calibration.methods.cascade_chain`). Theory: the docs' cascade page.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ...exceptions import CalibrationWarning, InputError, recorded_calibration_warnings
from ...units import frequency_text
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
from ..contract.summary import FitValue
from ..files import fields
from ..fitting.reference import ReferenceCellMixin
from ..models.band_reading import band_cone_distance
from .cascade_chain import ChainReadingMixin
from .cascade_handover import HandoverChecksMixin, handover_rules, stage_label
from .cascade_params import design_fsrs_hz, stage_columns
from .cascade_report import CASCADE_RECORD_RULES, cascade_tables, order_error_check
from .cascade_state import CascadeStateMixin
from .learned import RETRIEVALS
from .wideband import WidebandCalibrator

__all__ = ["CascadeCalibrator", "DEFAULT_FSRS_HZ"]

#: the issue's C-band cascade (Hz, coarsest first)
DEFAULT_FSRS_HZ = (5e12, 500e9, 50e9)


class CascadeCalibrator(
    CascadeStateMixin, ChainReadingMixin, HandoverChecksMixin, ReferenceCellMixin, BaseCalibrator
):
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

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> meter = wm.CascadeInterferometer.table1(fsrs_hz=(500e9, 50e9), seed=2)  # 2 stages
    >>> band_hz = np.linspace(193.2e12, 193.5e12, 2000)  # one sweep over a 300 GHz band
    >>> powers = meter.powers(band_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> powers.shape
    (2000, 6)
    >>> cal = wm.CascadeCalibrator(fsr_hz=(500e9, 50e9)).fit(powers, band_hz)

    The stages' fitted FSRs (the coarse stage's delay is off its 500 GHz design):

    >>> print([f"{fsr / 1e9:.0f} GHz" for fsr in cal.stage_fsrs_hz_])
    ['514 GHz', '50 GHz']

    Readings are absolute with no coarse input, each with its probability of a wrong order:

    >>> test_hz = np.array([193.25e12, 193.4e12])
    >>> test = meter.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> reading = cal.readout(test)
    >>> print(np.abs(reading.frequency_hz - test_hz) < 5 * reading.frequency_std_hz)
    [ True  True]
    >>> print(reading.extras["order_error_probability"] < 1e-6)
    [ True  True]
    """

    method = "cascade"
    absolute_frequency = True
    capabilities = frozenset({"frequency_std", "crlb", "power_monitor", "reference_cell"})
    #: the stages' numbers are checked as each stage's file (:func:`calibrator_from_fields`)
    state_rules = fields.rule_table(
        {
            "stage_ports.*": fields.FieldRule(
                "a port's index", "", 0, 1, scale="last_port", integer=True
            ),
            "edge_margin_std": fields.FieldRule(
                "the smallest margin to the band's edges",
                "std",
                -fields.MAX_MARGIN_STD,
                fields.MAX_MARGIN_STD,
            ),
            # a chi-square median (0.45 for 3 ports) times the square of a noise scale
            # within 1e-6 to 1e3
            "cone_distance_median": fields.FieldRule(
                "a stage's median distance from its cone", "", 1e-12, 1e6
            ),
            "model_error_hz": fields.FieldRule(
                "a stage's error beyond its uncertainty", "Hz", 0.0, 1.0, scale="band_hz"
            ),
            **handover_rules("handovers"),
        }
    )
    diagnostics_rules = CASCADE_RECORD_RULES

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
        return design_fsrs_hz(self.fsr_hz)

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
        return stage_columns(self.stage_ports, len(self._design_fsrs_hz()), ports)

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
        **cell,
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
        **cell
            A reference cell recorded beside the ports (``reference_transmission``,
            ``reference_lines``, ``band_hz``, ``reference_pressure_pa``,
            ``reference_pressure_std_pa``, ``axis_error_hz``), as :meth:`Calibrator.fit
            <wavemeter.Calibrator.fit>` takes it; the finest stage's phase corrects the
            axis (``frequency_hz`` None: makes it).

        Returns
        -------
        self

        Raises
        ------
        InputError
            For readings or settings that are wrong (the stage named); with
            ``parameter="fsr_hz"`` when the coarsest stage's FSR does not exceed the band
            or it read the sweep a fringe away more often than it predicts, or a hand-over's
            wrong-order rate at the sweep's noise exceeds ``max_order_error`` (the message
            names the stages and the largest usable FSR ratio).

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
        columns = self._stage_columns(raw.shape[1])

        def fit_on(axis_hz, axis_bandwidth_per_reading=0.0):
            # the stages are fitted by their public fit, on an axis as given: the corrected
            # axis's bandwidth does not reach their fit diagnostics
            del axis_bandwidth_per_reading
            return self._fit_stages(
                raw, axis_hz, power_monitor_w, port_names, dark_w, temperature_k
            )

        notes = self._fit_with_cell(
            raw,
            frequency_hz,
            cell,
            fit_on,
            fsr_tolerance=self.fsr_tolerance,
            design_fsr_hz=self._design_fsrs_hz()[-1],
            columns=columns[-1],
            dark_w=dark_w,
        )
        for note in notes:
            warnings.warn(note, stacklevel=2)
        return self

    def _fit_stages(self, raw, frequency_hz, power_monitor_w, port_names, dark_w, temperature_k):
        """Every stage fitted and the hand-overs checked (the steps of :meth:`fit`); the
        warnings."""
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
            label = stage_label(index, fsr)
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
        return notes

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
                f"{stage_label(0, float(self._design_fsrs_hz()[0]))}: its fitted FSR "
                f"{frequency_text(coarsest.fsr_hz_)} does not exceed the band swept "
                f"({frequency_text(high - low)}, {turn:.3g} of its fringe): frequencies one "
                "FSR apart give it the same reading and no stage can tell them apart; sweep "
                "and measure a band narrower than that FSR, or add a coarser stage",
                parameter="fsr_hz",
            )

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
            Part(stage_label(index, design[index]), "stage", stage, tuple(stage.span_hz_))
            for index, stage in enumerate(self.stages_)
        )
