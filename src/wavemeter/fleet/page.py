"""The fleet's HTML page (``fleet.html``): counts, histograms, the wafer map, the failures.

Self-contained like the calibration report (figures embedded as base64 PNG, every text
escaped, no scripts): a table of counts and medians; histograms of the fitted FSR, the
detector noise estimate, the calibration RMS and its ratio to the Cramer-Rao bound (the
devices that calibrated); a wafer map when device names carry die positions
(``die_x03_y12``), each die coloured by its Cramer-Rao ratio and failed dies marked; the
calibration warnings by cause; and a table of the failed devices with their errors.
Matplotlib is imported only when the page is drawn.
"""

from __future__ import annotations

import html
from collections import Counter
from collections.abc import Sequence
from datetime import UTC, datetime

import numpy as np

from ..atomic import atomic_path
from ..jobs.calibrate import DeviceResult
from ..report.formatting import power_unit, significant
from ..report.html import DEFAULT_DPI, png_bytes
from ..report.page import PAGE_STYLE, figures_html, html_table
from ..report.plotting import REFERENCE_ZORDER, new_figure
from .summary import WARNING_SEPARATOR, die_position

__all__ = ["write_page", "FIGURE_CAPTIONS"]

FIGURE_CAPTIONS = {
    "fsr": "Fitted free spectral range of each device that calibrated.",
    "noise": "Detector noise standard deviation each calibration estimates from its residual.",
    "rms": "RMS frequency error of each calibration on its own sweep.",
    "crlb_ratio": "Calibration RMS over the RMS Cramer-Rao bound of the same readings: 1 is "
    "the physical limit (in-sample fits may fall a little below it).",
    "wafer": "Devices at their die positions (from their names), coloured by their ratio to "
    "the Cramer-Rao bound; failed devices are red crosses.",
}
#: height of the figures (in), the histograms and the wafer map
FIGURE_HEIGHT_IN = 3.0
WAFER_HEIGHT_IN = 6.0
#: failed devices listed on the page (all are in summary.csv)
MAX_FAILURES_LISTED = 200


def _histogram(values, scale: float, unit: str, title: str):
    """A histogram of ``values / scale`` with its median marked."""
    shown = np.asarray(values, dtype=float) / scale
    figure, (axes,) = new_figure(height_in=FIGURE_HEIGHT_IN)
    axes.hist(shown, bins="auto", color="tab:blue", alpha=0.7)
    median = float(np.median(shown))
    axes.axvline(
        median,
        color="black",
        linestyle="--",
        zorder=REFERENCE_ZORDER,
        label=f"median {significant(median)} {unit}".rstrip(),
    )
    axes.set_xlabel(f"{title} ({unit})" if unit else title)
    axes.set_ylabel("devices")
    axes.legend(fontsize="small")
    return figure


def _wafer_map(rows: Sequence[DeviceResult]):
    """Dies at their positions: calibrated ones coloured by Cramer-Rao ratio (by RMS when
    no device has a bound; grey where one has none), failed ones as red crosses; None when
    no device name carries a position."""
    from matplotlib import colormaps
    from matplotlib.ticker import MaxNLocator

    placed = [(row, die_position(row.device)) for row in rows]
    placed = [(row, position) for row, position in placed if position is not None]
    if not placed:
        return None
    figure, (axes,) = new_figure(height_in=WAFER_HEIGHT_IN)
    good = [(row, position) for row, position in placed if row.ok]
    bad = [position for row, position in placed if not row.ok]
    if good:
        x, y = np.array([position for _, position in good], dtype=float).T
        values = np.array([row.crlb_ratio for row, _ in good])
        label = "calibration RMS / CRLB"
        if not np.isfinite(values).any():
            values = np.array([row.calibration_rms_hz for row, _ in good]) / 1e6
            label = "calibration RMS (MHz)"
        cmap = colormaps["viridis"].with_extremes(bad="lightgrey")
        dots = axes.scatter(x, y, c=values, marker="s", s=60, cmap=cmap, label="calibrated")
        figure.colorbar(dots, ax=axes, label=label)
    if bad:
        x, y = np.array(bad, dtype=float).T
        axes.scatter(x, y, marker="x", s=60, color="tab:red", label="failed")
    axes.set_aspect("equal", adjustable="datalim")
    for axis in (axes.xaxis, axes.yaxis):
        axis.set_major_locator(MaxNLocator(integer=True))
    axes.set_xlabel("die x")
    axes.set_ylabel("die y")
    axes.legend(fontsize="small", loc="lower left", bbox_to_anchor=(0.0, 1.01), ncols=2)
    return figure


def _figures(rows: Sequence[DeviceResult]) -> dict:
    """The page's figures by name (those with something to show)."""
    good = [row for row in rows if row.ok]
    figures = {}
    fsr = np.array([row.fsr_hz for row in good])
    if fsr.size:
        figures["fsr"] = _histogram(fsr, 1e9, "GHz", "fitted FSR")
    noise = np.array([row.noise_std_w for row in good])
    noise = noise[np.isfinite(noise)]
    if noise.size:
        scale, unit = power_unit(noise)
        figures["noise"] = _histogram(noise, scale, unit, "detector noise std")
    rms = np.array([row.calibration_rms_hz for row in good])
    if rms.size:
        figures["rms"] = _histogram(rms, 1e6, "MHz", "calibration RMS")
    ratio = np.array([row.crlb_ratio for row in good])
    ratio = ratio[np.isfinite(ratio)]
    if ratio.size:
        figures["crlb_ratio"] = _histogram(ratio, 1.0, "", "calibration RMS / CRLB")
    wafer = _wafer_map(rows)
    if wafer is not None:
        figures["wafer"] = wafer
    return figures


def _median_text(values, scale: float, unit: str) -> str:
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    return "n/a" if finite.size == 0 else f"{significant(np.median(finite) / scale)} {unit}"


def _count_rows(rows: Sequence[DeviceResult]) -> list[list[str]]:
    good = [row for row in rows if row.ok]
    noise = [row.noise_std_w for row in good]
    scale, unit = power_unit(np.nan_to_num(noise))
    return [
        ["devices", str(len(rows))],
        ["calibrated", str(len(good))],
        ["of which resumed", str(sum(row.resumed for row in good))],
        ["failed", str(len(rows) - len(good))],
        ["with calibration warnings", str(sum(bool(row.warnings) for row in good))],
        ["median FSR", _median_text([row.fsr_hz for row in good], 1e9, "GHz")],
        ["median noise std", _median_text(noise, scale, unit)],
        [
            "median calibration RMS",
            _median_text([row.calibration_rms_hz for row in good], 1e6, "MHz"),
        ],
        ["median RMS / CRLB", _median_text([row.crlb_ratio for row in good], 1.0, "")],
    ]


def _warning_rows(rows: Sequence[DeviceResult]) -> list[list[str]]:
    causes = Counter(cause for row in rows for cause in row.warnings)
    return [[cause, str(count)] for cause, count in causes.most_common()]


def _failure_rows(rows: Sequence[DeviceResult]) -> list[list[str]]:
    return [[row.device, row.source, row.error] for row in rows if not row.ok][:MAX_FAILURES_LISTED]


def render_page(rows: Sequence[DeviceResult], images: dict[str, bytes]) -> str:
    """The complete HTML document of a fleet's ``rows`` with its figures (PNG by name)."""
    failed = len(rows) - sum(row.ok for row in rows)
    warnings = _warning_rows(rows)
    parts = [
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
        f"<title>wavemeter fleet</title><style>{PAGE_STYLE}</style></head><body>",
        "<h1>wavemeter fleet</h1>",
        html_table(None, _count_rows(rows)),
        figures_html(images, FIGURE_CAPTIONS),
    ]
    if "wafer" not in images:
        parts.append(
            '<p class="note">No wafer map: no device name carries a die position '
            "(such as die_x03_y12).</p>"
        )
    if warnings:
        parts += ["<h2>Calibration warnings</h2>", html_table(["cause", "devices"], warnings)]
    if failed:
        listed = min(failed, MAX_FAILURES_LISTED)
        parts += [
            f"<h2>Failed devices ({failed}{'' if listed == failed else f', first {listed}'})</h2>",
            html_table(["device", "file", "error"], _failure_rows(rows)),
        ]
    created = datetime.now(UTC).isoformat(timespec="seconds")
    parts.append(
        f"<footer>Written by wavemeter on {created}; every device's numbers are in "
        f"summary.csv and summary.parquet (warnings separated by "
        f"{html.escape(repr(WARNING_SEPARATOR))}).</footer></body></html>"
    )
    return "".join(parts)


def write_page(rows: Sequence[DeviceResult], path, *, dpi: int = DEFAULT_DPI) -> None:
    """Draw the figures of a fleet's ``rows`` and write the page to ``path``, atomically."""
    images = {name: png_bytes(figure, dpi) for name, figure in _figures(rows).items()}
    page = render_page(rows, images)
    with atomic_path(path) as temporary:
        temporary.write_text(page, encoding="utf-8")
