"""The fit step that makes a calibration absolute with a reference cell recorded beside it.

:func:`checked_cell` validates the cell's inputs of ``fit`` (:class:`CellRecording`);
:func:`fit_on_reference` is the step, shared by every calibrator that offers the
``"reference_cell"`` capability: where the sweep's axis enters the fit, it

1. with a recorded axis: reads the meter's phase of the sweep from the powers alone
   (the reference-free cone, :func:`~wavemeter.calibration.models.self_calibration.
   sweep_phase_reference_free`; where it cannot identify the lines, the calibrator's
   phase after a fit on the recorded axis), finds, fits and identifies the cell's lines
   and corrects the axis (:func:`~wavemeter.reference.correct_sweep_axis`);
2. without one: self-calibrates the axis from the powers, the lines and the band
   (:func:`~wavemeter.calibration.models.self_calibration.self_calibrate`);

then fits the calibrator on the corrected axis and records ``axis_correction_`` and
``uncertainty_budget_`` (:func:`~wavemeter.reference.records.axis_records`). An
identification that is not unique is refused with the reason. Theory: the docs' theory
page on absolute accuracy.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...exceptions import CalibrationWarning, InputError, WavemeterError
from ...reference import ReferenceLines, correct_sweep_axis
from ...reference.records import axis_records
from ...validation import check_frequency, check_positive
from ..models.self_calibration import self_calibrate, sweep_phase_reference_free
from .sweep import checked_temperature

__all__ = [
    "CellRecording",
    "REFERENCE_KEYWORDS",
    "ReferenceCellMixin",
    "cell_inputs",
    "checked_cell",
    "fit_on_reference",
]

#: a phase drift the fit on the corrected axis sees is the correction's own error up to
#: this many times the axis budget's RMS
EXPLAINED_AXIS_RMS = 2.0
#: the causes such a drift is named by: smooth along the sweep, or smooth in frequency
EXPLAINED_CAUSES = ("phase_drift", "dispersion")
#: the keywords of ``fit`` that describe the reference cell
REFERENCE_KEYWORDS = (
    "reference_transmission",
    "reference_lines",
    "band_hz",
    "reference_pressure_pa",
    "reference_pressure_std_pa",
    "axis_error_hz",
)


@dataclass(frozen=True, eq=False)
class CellRecording:
    """A reference cell recorded beside the ports during the sweep.

    Attributes
    ----------
    transmission : ndarray, shape (N,)
        The cell channel, one reading per sweep reading (any unit linear in power).
    lines : ReferenceLines
        The cell's line table.
    band_hz : None or (float, float)
        The band the sweep covers (Hz): the lines are identified among the table's in it.
    pressure_pa : None or float
        The cell's pressure (Pa), for a table of zero-pressure centres with shifts.
    pressure_std_pa : float
        Its standard uncertainty (Pa).
    axis_error_hz : None or float
        Bound on the recorded axis's error (Hz): below a quarter of the line spacing the
        nearest table line identifies each line; None: the pattern of spacings does.
    """

    transmission: np.ndarray
    lines: ReferenceLines
    band_hz: tuple | None = None
    pressure_pa: float | None = None
    pressure_std_pa: float = 0.0
    axis_error_hz: float | None = None

    @property
    def pressure(self) -> dict:
        return {"pressure_pa": self.pressure_pa, "pressure_std_pa": self.pressure_std_pa}


def _band(band_hz) -> tuple[float, float] | None:
    if band_hz is None:
        return None
    try:
        low, high = (float(value) for value in band_hz)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"band_hz must be (low, high) in Hz, got {band_hz!r:.60}", parameter="band_hz"
        ) from exc
    if not (np.isfinite(low) and np.isfinite(high) and 0 < low < high):
        raise InputError(
            f"band_hz must be (low, high) with 0 < low < high (Hz), got ({low:.6g}, {high:.6g})",
            parameter="band_hz",
        )
    return low, high


def checked_cell(
    samples: int,
    reference_transmission=None,
    reference_lines=None,
    band_hz=None,
    reference_pressure_pa=None,
    reference_pressure_std_pa=0.0,
    axis_error_hz=None,
) -> CellRecording | None:
    """The reference-cell keywords of ``fit`` checked; None when no cell was given.

    Raises
    ------
    InputError
        Naming the keyword: a channel without a table or the reverse, a channel of another
        length than the sweep or not finite, a table that is not a ``ReferenceLines``, a
        band that is not ``(low, high)``, a pressure or axis error that is not > 0.
    """
    given = {
        "reference_transmission": reference_transmission,
        "reference_lines": reference_lines,
    }
    if reference_transmission is None and reference_lines is None:
        extras = {
            "band_hz": band_hz,
            "reference_pressure_pa": reference_pressure_pa,
            "axis_error_hz": axis_error_hz,
        }
        stray = [name for name, value in extras.items() if value is not None]
        if stray:
            raise InputError(
                f"{stray[0]} describes a reference cell, but no reference_transmission and "
                "reference_lines were given: give both, or leave it out",
                parameter=stray[0],
            )
        return None
    missing = [name for name, value in given.items() if value is None]
    if missing:
        raise InputError(
            "a reference cell needs its channel (reference_transmission, one reading per "
            f"sweep reading) and its line table (reference_lines); {missing[0]} is missing",
            parameter=missing[0],
        )
    if not isinstance(reference_lines, ReferenceLines):
        raise InputError(
            "reference_lines must be a wavemeter.ReferenceLines (ReferenceLines.read_csv), got "
            f"{type(reference_lines).__name__}",
            parameter="reference_lines",
        )
    try:
        channel = np.asarray(reference_transmission, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(
            "reference_transmission must be numbers, one per sweep reading",
            parameter="reference_transmission",
        ) from exc
    if channel.size != samples:
        raise InputError(
            f"reference_transmission must have one reading per sweep reading ({samples}), "
            f"got {channel.size}",
            parameter="reference_transmission",
        )
    bad = np.flatnonzero(~np.isfinite(channel))
    if bad.size:
        raise InputError(
            f"reference_transmission is NaN or inf at reading {int(bad[0])} (zero-based; "
            f"{bad.size} in all): the cell channel must be finite",
            parameter="reference_transmission",
        )
    if reference_pressure_pa is not None:
        check_positive("reference_pressure_pa", reference_pressure_pa)
    std = float(reference_pressure_std_pa)
    if not (np.isfinite(std) and std >= 0):
        raise InputError(
            f"reference_pressure_std_pa must be >= 0 (Pa), got {std:.6g}",
            parameter="reference_pressure_std_pa",
        )
    if axis_error_hz is not None:
        check_positive("axis_error_hz", axis_error_hz)
    return CellRecording(
        channel,
        reference_lines,
        _band(band_hz),
        None if reference_pressure_pa is None else float(reference_pressure_pa),
        std,
        None if axis_error_hz is None else float(axis_error_hz),
    )


def cell_inputs(samples: int, temperature_k, required_by: str | None) -> dict:
    """The per-reading inputs of the axis correction's phase (``temperature_k``, one per
    reading, checked), where given."""
    temperature = checked_temperature(temperature_k, samples, required_by)
    return {} if temperature is None else {"temperature_k": temperature}


class ReferenceCellMixin:
    """What a calibrator's ``fit`` needs to take a reference cell: the keywords checked
    against its capabilities, and the records of an earlier fit cleared."""

    def _checked_cell(self, samples: int, frequency_hz, **keywords) -> CellRecording | None:
        """The cell's keywords checked (:func:`checked_cell`); None without a cell.

        Raises
        ------
        InputError
            Besides :func:`checked_cell`'s: no ``frequency_hz`` and no cell; a cell given
            to a class without ``"reference_cell"`` among its capabilities.
        """
        cell = checked_cell(samples, **keywords)
        # a fit replaces what an earlier one recorded
        vars(self).pop("axis_correction_", None)
        vars(self).pop("uncertainty_budget_", None)
        if cell is None:
            if frequency_hz is None:
                raise InputError(
                    "frequency_hz is None: give the sweep's known frequencies (Hz), or a "
                    "reference cell (reference_transmission, reference_lines and band_hz) to "
                    "calibrate without them",
                    parameter="frequency_hz",
                )
            return None
        self._require_capability("reference_cell", "cannot take a reference cell in its fit")
        return cell

    def _fit_with_cell(
        self,
        raw: np.ndarray,
        frequency_hz,
        reference: dict,
        fit_on: Callable[[np.ndarray], list],
        *,
        fsr_tolerance: float,
        design_fsr_hz: float | None = None,
        **options,
    ) -> list:
        """``fit_on(frequency_hz)``, or with the cell the keywords ``reference`` describe,
        :func:`fit_on_reference` (``options``: its ``columns``, ``dark_w``, ``inputs``);
        the fit's warnings, not issued."""
        cell = self._checked_cell(raw.shape[0], frequency_hz, **reference)
        if cell is None:
            return fit_on(frequency_hz)
        design = float(self.fsr_hz) if design_fsr_hz is None else float(design_fsr_hz)
        return fit_on_reference(
            self,
            raw,
            frequency_hz,
            cell,
            fit_on,
            design_fsr_hz=design,
            fsr_tolerance=fsr_tolerance,
            **options,
        )


def fit_on_reference(
    calibrator,
    powers_w: np.ndarray,
    frequency_hz,
    cell: CellRecording,
    fit_on: Callable[[np.ndarray], list],
    *,
    design_fsr_hz: float,
    fsr_tolerance: float,
    columns=None,
    dark_w=None,
    inputs: dict | None = None,
) -> list:
    """Fit ``calibrator`` on its sweep's axis corrected with the cell (module docstring).

    Parameters
    ----------
    calibrator : BaseCalibrator
        Unfitted, or fitted on another sweep: it is fitted here.
    powers_w : ndarray, shape (N, n)
        The sweep's readings as ``fit`` got them (the calibrator subtracts ``dark_w``).
    frequency_hz : None or array_like, shape (N,)
        The recorded axis (Hz), or None to self-calibrate.
    cell : CellRecording
    fit_on : callable
        ``fit_on(frequency_hz, axis_bandwidth_per_reading=0.0) -> warnings``: fits the
        calibrator on an axis, returning the fit's warnings (not issued); the corrected
        axis comes with the bandwidth (cycles per reading) up to which it follows the
        meter's own phase noise, which its fit diagnostics do not count as a misfit
        (:attr:`~wavemeter.calibration.fitting.sweep.Sweep.axis_bandwidth_per_reading`).
    design_fsr_hz, fsr_tolerance : float
        The design FSR (Hz) of the interferometer whose phase makes the axis, and its
        relative tolerance.
    columns : None or sequence of int
        The ports of that interferometer (a cascade's finest stage); None: all.
    dark_w : None or ndarray, shape (n,)
        Dark readings (W), for the phase read from the powers alone.
    inputs : dict, optional
        Per-reading inputs of the calibrator's ``phase`` and ``frequency_std_hz`` besides
        ``coarse_hz`` (``temperature_k``).

    Returns
    -------
    list of CalibrationWarning
        The warnings of the fit on the corrected axis, not issued.

    Raises
    ------
    InputError
        Lines that cannot be found or identified uniquely (the reason), a phase that
        cannot be unwrapped along the sweep, too few lines for a correction.
    """
    inputs = dict(inputs or {})
    chosen = slice(None) if columns is None else list(columns)
    dark = 0.0 if dark_w is None else np.asarray(dark_w, dtype=float)[chosen]
    interferometer = powers_w[:, chosen] - dark
    recorded = None
    if frequency_hz is None:
        if cell.band_hz is None:
            raise InputError(
                "a sweep without a frequency axis needs band_hz, the band it covers (Hz), to "
                "identify the cell's lines by their spacings",
                parameter="band_hz",
            )
        axis = self_calibrate(
            interferometer,
            cell.transmission,
            cell.lines,
            cell.band_hz,
            fsr_hz=design_fsr_hz,
            fsr_tolerance=fsr_tolerance,
            **cell.pressure,
        ).axis
    else:
        recorded = check_frequency(frequency_hz, powers_w.shape[0])
        axis = _corrected_axis(calibrator, powers_w, recorded, cell, fit_on, interferometer, inputs)
    notes = fit_on(axis.frequency_hz, axis.phase_bandwidth_per_reading)
    record, budget = axis_records(
        axis,
        cell.transmission,
        _own_std(calibrator, powers_w, axis.frequency_hz, inputs),
        recorded_hz=recorded,
    )
    calibrator.axis_correction_ = record
    calibrator.uncertainty_budget_ = budget
    return _unexplained(calibrator, notes, budget.rms_hz()["axis"])


def _unexplained(calibrator, notes: list, axis_rms_hz: float) -> list:
    """The fit's warnings less a phase drift (:data:`EXPLAINED_CAUSES`: smooth in frequency,
    it reads as dispersion) the corrected axis explains: a phase
    error (``diagnostics_["fit"]``) within ``EXPLAINED_AXIS_RMS`` times the axis budget's
    RMS is the correction's own smooth error, stated in the budget. What was set aside is
    kept in ``diagnostics_["reference_cell"]``."""
    fit = (calibrator.diagnostics_ or {}).get("fit") or {}
    error_rad = fit.get("phase_error_rms_rad")
    if error_rad is None:
        return notes
    error_hz = float(error_rad) * float(calibrator.fsr_hz_) / (2.0 * np.pi)
    explained = error_hz <= EXPLAINED_AXIS_RMS * axis_rms_hz
    kept = [note for note in notes if not (explained and note.cause in EXPLAINED_CAUSES)]
    set_aside = [note.record() for note in notes if note not in kept]
    calibrator.diagnostics_ = {
        **calibrator.diagnostics_,
        "warnings": [note.record() for note in kept],
        "reference_cell": {
            "phase_error_rms_hz": error_hz,
            "axis_budget_rms_hz": axis_rms_hz,
            "explained_by_axis": set_aside,
        },
    }
    return kept


def _corrected_axis(calibrator, powers_w, recorded_hz, cell, fit_on, interferometer, inputs):
    """The recorded axis corrected. The meter's phase: the reference-free phase of the
    interferometer's powers alone (label-free: a map fitted on an axis off by a share of
    an FSR reads a phase distorted periodically in the fringe, which the lines, a fringe
    or more apart, cannot see); where that phase leaves the lines unidentified, the
    calibrator's after a fit on the recorded axis (its warnings dropped: that fit is
    replaced). Raises the reason of each refusal."""

    def corrected(phase_of):
        return correct_sweep_axis(
            powers_w,
            recorded_hz,
            cell.transmission,
            cell.lines,
            phase_of=phase_of,
            axis_error_hz=cell.axis_error_hz,
            band_hz=cell.band_hz,
            **cell.pressure,
        )

    try:
        return corrected(lambda powers: sweep_phase_reference_free(interferometer)[0])
    except InputError as exc:
        first = exc
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CalibrationWarning)
            fit_on(recorded_hz)
        return corrected(lambda powers: calibrator.phase(powers, coarse_hz=recorded_hz, **inputs))
    except WavemeterError as exc:
        raise InputError(
            f"the sweep's axis cannot be corrected: with the phase of the powers alone, "
            f"{first}; with the phase of a fit on the recorded axis, {exc}",
            parameter=first.parameter,
        ) from exc


def _own_std(calibrator, powers_w, frequency_hz, inputs) -> Callable:
    """``std(rows)``: the calibration's own standard deviation (Hz) of sweep readings; its
    RMS error on the sweep where it states none per reading."""

    def std(rows):
        if "frequency_std" not in calibrator.capabilities:
            return np.full(len(rows), float(calibrator.calibration_rms_hz_))
        given = {name: np.asarray(value)[rows] for name, value in inputs.items()}
        found = calibrator.frequency_std_hz(powers_w[rows], coarse_hz=frequency_hz[rows], **given)
        # a reading the calibration cannot read (none on its own sweep) keeps the RMS
        return np.where(np.isfinite(found), found, float(calibrator.calibration_rms_hz_))

    return std
