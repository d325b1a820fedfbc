"""What a calibration keeps of its axis correction: the budget and the correction's record.

:class:`UncertaintyBudget` is the absolute uncertainty budget of a calibration fitted on a
corrected (or self-calibrated) axis: each term's standard uncertainty (Hz) on a grid of
the sweep's frequencies, with what it is. :class:`AxisRecord` is what a report shows of
the correction: the lines (table and fitted centres), the correction against the recorded
axis with its uncertainty, the cell channel's envelope. Both are plain numbers, written to
and read from a calibration file (``to_dict`` / ``from_dict``, every number checked).
:func:`axis_records` makes both from a :class:`~wavemeter.reference.SweepAxis`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .axis import BUDGET_TERMS
from .sweep import SweepAxis

__all__ = [
    "AXIS_RECORD_MODES",
    "AxisRecord",
    "BUDGET_GRID_POINTS",
    "CALIBRATION_TERM",
    "CELL_ENVELOPE_BINS",
    "UncertaintyBudget",
    "axis_records",
]

#: the budget's term for the calibration's own uncertainty (the others: BUDGET_TERMS)
CALIBRATION_TERM = "calibration"
CALIBRATION_DESCRIPTION = (
    "the calibration's own standard deviation of a reading (detector noise and the fitted "
    "parameters' covariance) at the sweep's readings; a reading's own is computed when it "
    "is read"
)
#: sweep samples the budget keeps, evenly in frequency order
BUDGET_GRID_POINTS = 256
#: bins of the cell channel's envelope a report draws
CELL_ENVELOPE_BINS = 1024
#: how an axis was made absolute: a recorded axis corrected, or none (self-calibration)
AXIS_RECORD_MODES = ("corrected", "self-calibrated")


def _array(values, name: str, shape=None) -> np.ndarray:
    """A finite float array (``shape``: its length, or None for any), else InputError."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"field {name!r} must hold numbers ({exc})") from exc
    if array.ndim != 1 or (shape is not None and array.size != shape):
        expected = "a list" if shape is None else f"{shape} numbers"
        raise InputError(f"field {name!r} must be {expected}, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InputError(f"field {name!r} must hold finite numbers")
    return array


def _text(values, name: str) -> str:
    if not isinstance(values, str):
        raise InputError(f"field {name!r} must be text, got {type(values).__name__}")
    return values


def _object(document, name: str) -> dict:
    if not isinstance(document, dict):
        raise InputError(f"field {name!r} must be an object, got {type(document).__name__}")
    return document


@dataclass(frozen=True, eq=False)
class UncertaintyBudget:
    """A calibration's absolute uncertainty budget, by term, over its band.

    Attributes
    ----------
    frequency_hz : ndarray, shape (K,)
        Increasing frequencies of the sweep (Hz) at which the terms are kept.
    terms_hz : dict of str to ndarray, shape (K,)
        Each term's standard uncertainty there (Hz): the axis terms
        (:data:`~wavemeter.reference.BUDGET_TERMS`) and ``"calibration"``.
    descriptions : dict of str to str
        What each term is and how it was computed.
    """

    frequency_hz: np.ndarray
    terms_hz: dict
    descriptions: dict

    def __post_init__(self):
        names = (*BUDGET_TERMS, CALIBRATION_TERM)
        if set(self.terms_hz) != set(names) or set(self.descriptions) != set(names):
            raise InputError(f"a budget has the terms {', '.join(names)}")
        grid = _array(self.frequency_hz, "frequency_hz")
        if grid.size < 2 or np.any(np.diff(grid) < 0):
            raise InputError("field 'frequency_hz' must be at least 2 increasing frequencies")
        terms = {}
        for name in names:
            terms[name] = _array(self.terms_hz[name], name, grid.size)
            if np.any(terms[name] < 0):
                raise InputError(f"field {name!r} must hold standard uncertainties >= 0 (Hz)")
        object.__setattr__(self, "frequency_hz", grid)
        object.__setattr__(self, "terms_hz", terms)
        object.__setattr__(self, "descriptions", {n: str(self.descriptions[n]) for n in names})

    @property
    def axis_terms(self) -> tuple:
        """The terms of the axis correction (all but the calibration's own)."""
        return tuple(BUDGET_TERMS)

    def at_hz(self, frequency_hz) -> dict:
        """Each term (Hz) at frequencies (Hz), interpolated over the grid (constant
        beyond it), plus ``"axis"`` (the axis terms in quadrature) and ``"total"`` (all
        terms in quadrature); each of the input's shape."""
        frequency = np.asarray(frequency_hz, dtype=float)
        found = {
            name: np.interp(frequency, self.frequency_hz, values)
            for name, values in self.terms_hz.items()
        }
        found["axis"] = np.sqrt(sum(found[name] ** 2 for name in self.axis_terms))
        found["total"] = np.hypot(found["axis"], found[CALIBRATION_TERM])
        return found

    def axis_std_hz(self, frequency_hz) -> np.ndarray:
        """The axis correction's standard uncertainty (Hz) at frequencies (Hz)."""
        return self.at_hz(frequency_hz)["axis"]

    def rms_hz(self) -> dict:
        """Each term's RMS over the band (Hz), with ``"axis"`` and ``"total"``."""
        return {
            name: float(np.sqrt(np.mean(np.square(values))))
            for name, values in self.at_hz(self.frequency_hz).items()
        }

    def to_dict(self) -> dict:
        return {
            "frequency_hz": self.frequency_hz.tolist(),
            "terms_hz": {name: values.tolist() for name, values in self.terms_hz.items()},
            "descriptions": dict(self.descriptions),
        }

    @classmethod
    def from_dict(cls, document) -> UncertaintyBudget:
        """The budget of a file (:meth:`to_dict`); InputError naming a wrong field."""
        document = _object(document, "uncertainty_budget")
        terms = _object(document.get("terms_hz"), "terms_hz")
        descriptions = _object(document.get("descriptions"), "descriptions")
        for name, text in descriptions.items():
            _text(text, name)
        return cls(document.get("frequency_hz"), dict(terms), dict(descriptions))


@dataclass(frozen=True, eq=False)
class AxisRecord:
    """What a report shows of a sweep's axis correction (module docstring).

    Attributes
    ----------
    mode : {"corrected", "self-calibrated"}
        A recorded axis corrected, or an axis made from the lines alone.
    identification, detail : str
        How the lines were identified (``"nearest"`` or ``"pattern"``) and its account.
    order : int
        Legendre order of the correction ``f = g(phi)``.
    fsr_hz : float
        The meter's FSR at the middle of the lines from the correction (Hz).
    labels : tuple of str
        The identified lines, in frequency order.
    line_target_hz : ndarray, shape (M,)
        Each line's centre in the cell: the table's plus its pressure shift (Hz).
    line_fitted_hz : ndarray, shape (M,)
        Each fitted centre on the corrected axis (Hz).
    line_fitted_std_hz : ndarray, shape (M,)
        Its standard error from the line fit (Hz).
    frequency_hz : ndarray, shape (K,)
        Corrected frequencies of sweep samples (Hz), increasing.
    shift_hz : ndarray, shape (K,), or None
        Corrected less recorded axis there (Hz); None without a recorded axis.
    shift_std_hz : ndarray, shape (K,)
        The correction's standard uncertainty there (Hz): the axis terms in quadrature.
    cell_frequency_hz, cell_low, cell_high : ndarray, shape (B,)
        The cell channel's envelope: bin centres (Hz, corrected axis), the lowest and the
        highest reading of each bin (the channel's unit).
    """

    mode: str
    identification: str
    detail: str
    order: int
    fsr_hz: float
    labels: tuple
    line_target_hz: np.ndarray
    line_fitted_hz: np.ndarray
    line_fitted_std_hz: np.ndarray
    frequency_hz: np.ndarray
    shift_hz: np.ndarray | None
    shift_std_hz: np.ndarray
    cell_frequency_hz: np.ndarray
    cell_low: np.ndarray
    cell_high: np.ndarray

    _LINES = ("line_target_hz", "line_fitted_hz", "line_fitted_std_hz")
    _GRID = ("frequency_hz", "shift_std_hz")
    _CELL = ("cell_frequency_hz", "cell_low", "cell_high")

    def __post_init__(self):
        if self.mode not in AXIS_RECORD_MODES:
            raise InputError(f"field 'mode' must be one of {AXIS_RECORD_MODES}, got {self.mode!r}")
        labels = tuple(self.labels)
        if not all(isinstance(label, str) for label in labels) or len(labels) < 2:
            raise InputError("field 'labels' must name at least 2 lines")
        object.__setattr__(self, "labels", labels)
        for name in self._LINES:
            object.__setattr__(self, name, _array(getattr(self, name), name, len(labels)))
        size = _array(self.frequency_hz, "frequency_hz").size
        for name in self._GRID:
            object.__setattr__(self, name, _array(getattr(self, name), name, size))
        if self.shift_hz is not None:
            object.__setattr__(self, "shift_hz", _array(self.shift_hz, "shift_hz", size))
        bins = _array(self.cell_frequency_hz, "cell_frequency_hz").size
        for name in self._CELL:
            object.__setattr__(self, name, _array(getattr(self, name), name, bins))
        if not (isinstance(self.order, int) and self.order >= 1):
            raise InputError(f"field 'order' must be an integer >= 1, got {self.order!r}")
        if not (np.isfinite(self.fsr_hz) and self.fsr_hz > 0):
            raise InputError(f"field 'fsr_hz' must be > 0 (Hz), got {self.fsr_hz!r}")

    def to_dict(self) -> dict:
        arrays = (*self._LINES, *self._GRID, *self._CELL)
        return {
            "mode": self.mode,
            "identification": self.identification,
            "detail": self.detail,
            "order": self.order,
            "fsr_hz": float(self.fsr_hz),
            "labels": list(self.labels),
            **{name: getattr(self, name).tolist() for name in arrays},
            "shift_hz": None if self.shift_hz is None else self.shift_hz.tolist(),
        }

    @classmethod
    def from_dict(cls, document) -> AxisRecord:
        """The record of a file (:meth:`to_dict`); InputError naming a wrong field."""
        document = _object(document, "axis_correction")
        labels = document.get("labels")
        if not isinstance(labels, list):
            raise InputError("field 'labels' must be a list of line names")
        order = document.get("order")
        fsr = document.get("fsr_hz")
        if isinstance(fsr, bool) or not isinstance(fsr, (int, float)):
            raise InputError(f"field 'fsr_hz' must be a number, got {fsr!r:.40}")
        arrays = {name: document.get(name) for name in (*cls._LINES, *cls._GRID, *cls._CELL)}
        return cls(
            mode=_text(document.get("mode"), "mode"),
            identification=_text(document.get("identification"), "identification"),
            detail=_text(document.get("detail"), "detail"),
            order=order if isinstance(order, int) and not isinstance(order, bool) else -1,
            fsr_hz=float(fsr),
            labels=tuple(labels),
            shift_hz=document.get("shift_hz"),
            **arrays,
        )


def _grid_rows(frequency_hz: np.ndarray, points: int) -> np.ndarray:
    """Indices of ``points`` samples evenly spread in frequency order (each once)."""
    order = np.argsort(frequency_hz, kind="stable")
    picks = np.unique(np.round(np.linspace(0, order.size - 1, points)).astype(int))
    return order[picks]


def _envelope(frequency_hz: np.ndarray, record: np.ndarray, bins: int):
    """Bin centres (Hz) and the lowest and highest reading of each non-empty bin."""
    edges = np.linspace(frequency_hz.min(), frequency_hz.max(), bins + 1)
    which = np.clip(np.searchsorted(edges, frequency_hz, side="right") - 1, 0, bins - 1)
    low = np.full(bins, np.inf)
    high = np.full(bins, -np.inf)
    np.minimum.at(low, which, record)
    np.maximum.at(high, which, record)
    kept = np.isfinite(low)
    return 0.5 * (edges[:-1] + edges[1:])[kept], low[kept], high[kept]


def axis_records(
    axis: SweepAxis,
    transmission,
    calibration_std_hz,
    *,
    recorded_hz=None,
    points: int = BUDGET_GRID_POINTS,
    bins: int = CELL_ENVELOPE_BINS,
) -> tuple[AxisRecord, UncertaintyBudget]:
    """The record of a correction and the budget of a calibration fitted on its axis.

    Parameters
    ----------
    axis : SweepAxis
        The corrected (or self-calibrated) axis.
    transmission : array_like, shape (N,)
        The cell channel, one reading per sample.
    calibration_std_hz : callable
        ``calibration_std_hz(rows) -> (len(rows),)``: the calibration's own standard
        deviation (Hz) of the sweep readings at those sample indices.
    recorded_hz : None or array_like, shape (N,)
        The recorded axis (Hz), when there was one.
    points, bins : int
        Samples the budget keeps; bins of the cell channel's envelope.

    Returns
    -------
    AxisRecord, UncertaintyBudget
    """
    frequency = axis.frequency_hz
    rows = _grid_rows(frequency, points)
    grid = frequency[rows]
    budget = axis.budget_hz()
    terms = {name: budget[name][rows] for name in BUDGET_TERMS}
    terms[CALIBRATION_TERM] = np.asarray(calibration_std_hz(rows), dtype=float)
    descriptions = {**BUDGET_TERMS, CALIBRATION_TERM: CALIBRATION_DESCRIPTION}
    correction = axis.correction
    lines_hz = correction.frequency_hz(correction.line_phase_rad)
    slope = np.abs(correction.slope_hz_per_rad(correction.line_phase_rad))
    cell = _envelope(frequency, np.asarray(transmission, dtype=float).reshape(-1), bins)
    shift = None
    if recorded_hz is not None:
        shift = grid - np.asarray(recorded_hz, dtype=float).reshape(-1)[rows]
    order = np.argsort(lines_hz)
    record = AxisRecord(
        mode="corrected" if recorded_hz is not None else "self-calibrated",
        identification=axis.identification.method,
        detail=axis.identification.detail,
        order=int(correction.order),
        fsr_hz=axis.fsr_hz,
        labels=tuple(np.asarray(correction.labels, dtype=object)[order]),
        line_target_hz=correction.line_target_hz[order],
        line_fitted_hz=lines_hz[order],
        line_fitted_std_hz=(slope * axis.lines.center_std)[order],
        frequency_hz=grid,
        shift_hz=shift,
        shift_std_hz=budget["total"][rows],
        cell_frequency_hz=cell[0],
        cell_low=cell[1],
        cell_high=cell[2],
    )
    return record, UncertaintyBudget(grid, terms, descriptions)
