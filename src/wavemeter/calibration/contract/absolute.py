"""What every calibration says of its absolute accuracy, when a reference cell made it absolute.

A fit with a reference cell (:mod:`~wavemeter.calibration.fitting.reference`) leaves two
learned attributes, None otherwise: ``axis_correction_``
(:class:`~wavemeter.reference.records.AxisRecord`) and ``uncertainty_budget_``
(:class:`~wavemeter.reference.records.UncertaintyBudget`). :class:`AbsoluteMixin` gives
every calibrator what follows from them: the budget at each reading's frequency for
``frequency_std_hz(..., absolute=True)``, the file field ``absolute``, the summary's budget
table and the report's figures (the cell channel with the lines, the correction with its
uncertainty band, the budget over the band).
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...reference.records import CALIBRATION_TERM, AxisRecord, UncertaintyBudget
from .figures import FigureData, Series
from .summary import Table

__all__ = ["AbsoluteMixin"]


class AbsoluteMixin:
    """The absolute accuracy of a calibration made absolute by a reference cell."""

    #: how the sweep's axis was corrected; None for a fit without a reference cell
    axis_correction_: AxisRecord | None = None
    #: the absolute uncertainty budget by term over the band (Hz); None likewise
    uncertainty_budget_: UncertaintyBudget | None = None

    def _absolute_std_hz(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The axis budget (Hz) at frequencies (Hz): what ``absolute=True`` adds.

        Raises
        ------
        InputError
            For a calibration fitted without a reference cell.
        """
        if self.uncertainty_budget_ is None:
            raise InputError(
                "this calibration states no absolute uncertainty: it was fitted without a "
                "reference cell, so its absolute accuracy is that of the sweep's frequency "
                "axis; fit it with reference_transmission and reference_lines",
                parameter="absolute",
            )
        return self.uncertainty_budget_.axis_std_hz(frequency_hz)

    # ------------------------------------------------------------------ files
    def _absolute_state(self) -> dict | None:
        """The file field ``absolute`` (None: the file has none)."""
        if self.uncertainty_budget_ is None or self.axis_correction_ is None:
            return None
        return {
            "axis_correction": self.axis_correction_.to_dict(),
            "uncertainty_budget": self.uncertainty_budget_.to_dict(),
        }

    def _set_absolute_state(self, document) -> None:
        """Restore :meth:`_absolute_state` (None: a file without one, as every file of
        0.7.1 or older)."""
        if document is None:
            return
        if not isinstance(document, dict):
            raise InputError(f"field 'absolute' must be an object, got {type(document).__name__}")
        self.axis_correction_ = AxisRecord.from_dict(document.get("axis_correction"))
        self.uncertainty_budget_ = UncertaintyBudget.from_dict(document.get("uncertainty_budget"))

    # ------------------------------------------------------------------ description
    def _absolute_tables(self) -> tuple[Table, ...]:
        """The budget as a table of the summary (none without a reference cell)."""
        budget, record = self.uncertainty_budget_, self.axis_correction_
        if budget is None or record is None:
            return ()
        rms = budget.rms_hz()
        peak = {name: float(values.max()) for name, values in budget.terms_hz.items()}
        names = (*budget.axis_terms, CALIBRATION_TERM)
        rows = [(name, rms[name] / 1e6, peak[name] / 1e6) for name in names]
        rows.append(
            (
                "total",
                rms["total"] / 1e6,
                float(budget.at_hz(budget.frequency_hz)["total"].max()) / 1e6,
            )
        )
        how = (
            "the recorded axis corrected"
            if record.mode == "corrected"
            else "an axis made from the lines alone (self-calibration)"
        )
        return (
            Table(
                name="uncertainty_budget",
                title="absolute uncertainty budget",
                columns=("term", "RMS over the band [MHz]", "largest [MHz]"),
                rows=tuple(rows),
                text="\n  ".join(
                    [
                        f"{how} with {len(record.labels)} lines ({record.labels[0]} to "
                        f"{record.labels[-1]}), identified by {record.identification}; "
                        f"correction of Legendre order {record.order}, FSR from the lines "
                        f"{record.fsr_hz / 1e9:.6f} GHz; frequency_std_hz(absolute=True) "
                        "adds the axis terms at each reading's frequency to its own",
                        *(f"{name}: {budget.descriptions[name]}" for name in names),
                        "total: the terms in quadrature",
                        *self._explained_text(),
                    ]
                ),
            ),
        )

    def _explained_text(self) -> list[str]:
        """What the fit set aside as the corrected axis's own error, in words."""
        record = (getattr(self, "diagnostics_", None) or {}).get("reference_cell") or {}
        if not record.get("explained_by_axis"):
            return []
        return [
            f"the fit's phase drift of {record['phase_error_rms_hz'] / 1e6:.3g} MHz RMS is the "
            f"corrected axis's own error (axis budget {record['axis_budget_rms_hz'] / 1e6:.3g} "
            "MHz RMS): no warning"
        ]

    def _absolute_figures(self) -> tuple[FigureData, ...]:
        """The report's figures of the correction (none without a reference cell)."""
        record, budget = self.axis_correction_, self.uncertainty_budget_
        if record is None or budget is None:
            return ()
        origin = float(np.mean(record.frequency_hz))
        cell = FigureData(
            name="reference_cell",
            caption=(
                "The reference cell's channel over the sweep (the lowest and highest reading "
                "of each stretch, on the corrected axis), the identified lines' centres in "
                "the cell (table plus pressure shift) and their fitted centres."
            ),
            x_label="frequency",
            y_label="cell transmission",
            x_unit="Hz",
            x_origin=origin,
            series=(
                Series("channel, lowest", record.cell_frequency_hz, record.cell_low),
                Series("channel, highest", record.cell_frequency_hz, record.cell_high),
                Series(
                    "fitted centres",
                    record.line_fitted_hz,
                    np.interp(record.line_fitted_hz, record.cell_frequency_hz, record.cell_low),
                    style="points",
                    point_labels=record.labels,
                ),
                Series(
                    "table centres",
                    record.line_target_hz,
                    np.interp(record.line_target_hz, record.cell_frequency_hz, record.cell_high),
                    style="points",
                ),
            ),
            note=f"identified by {record.identification}: {record.detail}"[:200],
        )
        band = record.shift_std_hz
        if record.shift_hz is not None:
            centre, title, what = record.shift_hz, "axis_correction", "corrected less recorded"
        else:
            centre = np.zeros_like(band)
            title, what = "axis_uncertainty", "the self-calibrated axis about itself"
        correction = FigureData(
            name=title,
            caption=(
                f"The axis correction ({what}) with its standard uncertainty band (the axis "
                "terms of the budget in quadrature); the lines' residuals from the "
                "correction (fitted less table centre) as points."
            ),
            x_label="frequency",
            y_label="correction",
            x_unit="Hz",
            y_unit="Hz",
            x_origin=origin,
            series=(
                Series("correction", record.frequency_hz, centre),
                Series("+1 sigma", record.frequency_hz, centre + band),
                Series("-1 sigma", record.frequency_hz, centre - band),
                Series(
                    "line residuals",
                    record.line_target_hz,
                    np.interp(record.line_target_hz, record.frequency_hz, centre)
                    + record.line_fitted_hz
                    - record.line_target_hz,
                    style="points",
                ),
            ),
        )
        terms = FigureData(
            name="uncertainty_budget",
            caption="The absolute uncertainty budget's terms over the band (standard "
            "uncertainties; the total is their quadrature sum).",
            x_label="frequency",
            y_label="standard uncertainty",
            x_unit="Hz",
            y_unit="Hz",
            x_origin=origin,
            series=tuple(
                Series(name.replace("_", " "), budget.frequency_hz, values)
                for name, values in budget.at_hz(budget.frequency_hz).items()
                if name != "axis"
            ),
        )
        return cell, correction, terms
