"""What a wide-band calibration declares for its report, from ``diagnostics_["wideband"]``.

The candidate orders scored by cross-validation (a table and a figure), the residual phase
across the band per FSR window (a figure and a sentence), and the names of the phase
coefficients.
"""

from __future__ import annotations

import numpy as np

from ..contract.figures import FigureData, Series
from ..contract.summary import Table

__all__ = [
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
