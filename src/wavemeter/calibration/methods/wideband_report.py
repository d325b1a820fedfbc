"""What a wide-band calibration declares for its report, from ``diagnostics_["wideband"]``.

The candidate orders scored by cross-validation (a table and a figure), the residual phase
across the band per FSR window (a figure and a sentence), the names of the phase
coefficients, and :class:`BandReportMixin`: the comparison (the learned set per FSR), the
fringes and object samples under the band model.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..contract.figures import FigureData, Series
from ..contract.summary import Table
from ..files import fields
from ..files.registry import calibrator_class
from .figures import (
    FRINGE_HALF_WIDTH_FSR,
    band_fringe_panel,
    near,
    pseudo_inverse,
    unit_power_samples,
)

__all__ = [
    "BAND_RECORD_RULES",
    "BandReportMixin",
    "PHASE_COEFFICIENT_NAMES",
    "band_figures",
    "band_tables",
    "orders_text",
    "residual_phase_text",
]

#: names of the phase coefficients ``c_i`` (s^i), by order
PHASE_COEFFICIENT_NAMES = {
    1: "delay",
    2: "group-delay dispersion",
    3: "third-order dispersion",
    4: "fourth-order dispersion",
}


_number = fields.record_number
#: what the record the report presents (``diagnostics_["wideband"]``) holds, as a file's
#: diagnostics rules: a file whose record lacks them is refused on load, not in the report
BAND_RECORD_RULES = fields.rule_table(
    {
        "wideband": fields.RecordRule("the wide-band record", "object"),
        "wideband.orders": fields.RecordRule("how the orders were chosen", "object"),
        "wideband.orders.reason": fields.RecordRule("why", "text"),
        "wideband.orders.candidates": fields.RecordRule("the orders scored", "list"),
        "wideband.orders.candidates.*.phase_order": _number("a phase order", "", 1, integer=True),
        "wideband.orders.candidates.*.map_order": _number("a map order", "", 0, integer=True),
        "wideband.orders.candidates.*.parameters": _number(
            "a parameter count", "", 1, integer=True
        ),
        "wideband.orders.candidates.*.cv_rms_hz": _number("a held-out RMS", "Hz", 0.0),
        "wideband.orders.candidates.*.chosen": fields.RecordRule("the choice", "flag"),
        "wideband.residual_phase": fields.RecordRule(
            "the residual phase per FSR window", "list", min_items=1
        ),
        "wideband.residual_phase.*.center_hz": _number("a window's centre", "Hz", 0.0),
        "wideband.residual_phase.*.rms_rad": _number("a residual phase RMS", "rad", 0.0),
        "wideband.residual_phase.*.mean_rad": _number("a mean residual phase", "rad"),
        "wideband.residual_phase.*.readings": _number("a window's readings", "", 0, integer=True),
    }
)


def band_tables(record: dict) -> tuple[Table, ...]:
    """The candidate orders scored (none when the orders were given or too few FSRs)."""
    orders = record["orders"]
    candidates = orders["candidates"]
    if not candidates:
        return ()
    rows = tuple(
        (
            candidate["phase_order"],
            candidate["map_order"],
            candidate["parameters"],
            candidate["cv_rms_hz"] / 1e6,
            "chosen" if candidate["chosen"] else "",
        )
        for candidate in candidates
    )
    return (
        Table(
            "orders",
            "orders scored",
            ("phase order P", "map order J", "parameters", "held-out RMS (MHz)", "chosen"),
            rows,
            f"{orders['reason']}.",
        ),
    )


def orders_text(record: dict) -> str:
    """How the orders were chosen, where no candidates were scored (both given, or too
    few FSR windows); empty where the table of candidates says it."""
    orders = record["orders"]
    return "" if orders["candidates"] else f"orders not cross-validated: {orders['reason']}"


def residual_phase_text(record: dict) -> str:
    """The residual phase per FSR window in a sentence: its range and the worst window."""
    residual = record["residual_phase"]
    worst = max(residual, key=lambda row: row["rms_rad"])
    lowest = min(row["rms_rad"] for row in residual)
    return (
        f"residual phase RMS per FSR window {lowest * 1e3:.3g} to "
        f"{worst['rms_rad'] * 1e3:.3g} mrad over {len(residual)} windows; the largest in "
        f"the window at {worst['center_hz'] / 1e12:.6f} THz (mean "
        f"{worst['mean_rad'] * 1e3:.3g} mrad, {worst['readings']} readings)"
    )


def band_figures(record: dict, center_hz: float, noise_std_rad: float | None) -> tuple:
    """The cross-validation curve of the orders and the residual phase across the band,
    with the phase standard deviation of the detector noise (``noise_std_rad``) to judge
    the residual by."""
    orders = record["orders"]
    candidates = orders["candidates"]
    parameters = np.array([c["parameters"] for c in candidates], dtype=float)
    rms = np.array([c["cv_rms_hz"] for c in candidates], dtype=float)
    choice = FigureData(
        "cross_validation",
        "How the wide-band orders were chosen: the RMS frequency error on held-out FSR "
        "windows of each phase order P and map order J scored, against the number of "
        "fitted parameters; the chosen pair ringed.",
        "fitted parameters",
        "held-out RMS frequency error",
        "",
        "Hz",
        (
            Series(
                "candidate (P, J)",
                parameters,
                rms,
                "points",
                tuple(f"({c['phase_order']}, {c['map_order']})" for c in candidates),
                np.array([c["chosen"] for c in candidates], dtype=bool),
            ),
        ),
        note="" if candidates else f"no cross-validation: {orders['reason']}",
    )
    residual = record["residual_phase"]
    window_hz = np.array([row["center_hz"] for row in residual])
    series = [
        Series("RMS per FSR window", window_hz, np.array([r["rms_rad"] for r in residual])),
        Series("mean per FSR window", window_hz, np.array([r["mean_rad"] for r in residual])),
    ]
    if noise_std_rad is not None:
        series.append(
            Series("CRLB phase σ (RMS)", window_hz[:1], np.array([noise_std_rad]), "level")
        )
    phase = FigureData(
        "residual_phase",
        "Retrieved minus model phase of the calibration sweep across the band, RMS and mean "
        "per FSR window; the dashed line is the phase standard deviation the Cramer-Rao "
        "bound gives for the detector noise alone.",
        "frequency",
        "residual phase",
        "Hz",
        "rad",
        tuple(series),
        x_origin=center_hz,
    )
    return choice, phase


class BandReportMixin:
    """Report declarations of a wide-band calibration (module docstring)."""

    def summary(self):
        """The fit report, with the candidate orders scored and the residual phase."""
        report = super().summary()
        record = (self.diagnostics_ or {}).get("wideband")
        if not record:
            return report
        notes = [text for text in (orders_text(record), residual_phase_text(record)) if text]
        return dataclasses.replace(
            report,
            tables=(*report.tables, *band_tables(record)),
            notes=(*report.notes, *notes),
        )

    def comparison(self, port_phases_rad=None):
        """The learned calibration set per FSR with the same settings: the other way to
        cover a band (what one model of the band buys)."""
        window = calibrator_class("learned")(
            fsr_hz=self.fsr_hz, fsr_tolerance=self.fsr_tolerance, retrieval=self.retrieval
        )
        return calibrator_class("calibration_set")(self.fsr_hz, self.fsr_tolerance, window=window)

    def fringe_panels(self, frequency_hz, powers_w, monitor_w=None, temperature_k=None):
        """The sweep within ``FRINGE_HALF_WIDTH_FSR`` of the reading nearest the middle of
        the band (the sweep may have a gap there) under the band model."""
        frequency = np.asarray(frequency_hz, dtype=float)
        anchor = frequency[np.argmin(np.abs(frequency - self.center_hz_))]
        panel = band_fringe_panel(
            self.band_model_,
            frequency,
            np.asarray(powers_w, dtype=float),
            monitor_w=None if monitor_w is None else np.asarray(monitor_w, dtype=float),
            rows=near(frequency, anchor, self.fsr_hz_),
            noise_std_w=self.noise_std_w_,
            title=f"readings within {FRINGE_HALF_WIDTH_FSR:g} FSR of the one nearest the "
            "middle of the band",
        )
        return (panel,)

    def object_samples(self, powers_w, frequency_hz, temperature_k=None):
        """Each reading under the map at the frequency it is read at (the truth as its
        coarse frequency)."""
        truth = np.asarray(frequency_hz, dtype=float)
        powers = np.asarray(powers_w, dtype=float)
        frequency = self.predict(powers, coarse_hz=truth)
        inverses = pseudo_inverse(self.band_model_.maps_at(frequency))
        return unit_power_samples(inverses, powers, self.phase(powers, coarse_hz=truth))

    def report_figures(self, noise_std_hz=None):
        record = (self.diagnostics_ or {}).get("wideband")
        if not record:
            return ()
        noise_rad = None if noise_std_hz is None else 2.0 * np.pi * noise_std_hz / self.fsr_hz_
        return band_figures(record, self.center_hz_, noise_rad)
