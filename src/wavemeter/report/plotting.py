"""Figure scaffolding of the report: Agg canvas, colours, layers, legends outside the data.

Matplotlib is imported only inside these functions, so importing the report does not
import it. Layers: data markers are small and semi-transparent at ``DATA_ZORDER``; fitted
lines above them; references (Cramer-Rao band, noise band, ideal line, correct circle) on
top at ``REFERENCE_ZORDER``, so a reference is never hidden by the data it judges.
"""

from __future__ import annotations

__all__ = [
    "new_figure",
    "method_color",
    "port_color",
    "thin",
    "legend_outside",
    "figure_legend_outside",
    "plain_ticks",
    "offset_label",
    "FIGURE_WIDTH_IN",
    "FIGURE_HEIGHT_IN",
    "MARKER_SIZE",
    "MARKER_ALPHA",
    "DATA_ZORDER",
    "FIT_ZORDER",
    "REFERENCE_ZORDER",
    "REFERENCE_ALPHA",
]

#: line colour of each method, so a method looks the same in every figure
METHOD_COLORS = {
    "learned": "tab:blue",
    "conventional": "tab:red",
    "thermal": "tab:purple",
    "wideband": "tab:green",
}
OTHER_COLORS = ("tab:green", "tab:orange", "tab:brown", "tab:pink")
FIGURE_WIDTH_IN = 9.0
FIGURE_HEIGHT_IN = 4.0
MARKER_SIZE = 2.5
MARKER_ALPHA = 0.35
MAX_MARKERS = 6000
DATA_ZORDER = 2.0
FIT_ZORDER = 3.0
REFERENCE_ZORDER = 4.0
#: opacity of reference bands drawn over the data
REFERENCE_ALPHA = 0.3
LEGEND_FONT = "small"
FIGURE_LEGEND_COLUMNS = 6
LEGEND_MARKER_SCALE = 2.0


def new_figure(rows: int = 1, height_in: float = FIGURE_HEIGHT_IN, height_ratios=None):
    """A figure with ``rows`` stacked axes sharing x, on an Agg canvas, constrained layout."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(FIGURE_WIDTH_IN, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(
        rows, 1, sharex=True, squeeze=False, gridspec_kw={"height_ratios": height_ratios}
    )[:, 0]
    return figure, axes


def method_color(name: str, order: int) -> str:
    """Colour of a method by its first word (``"learned per FSR"`` -> learned's)."""
    return METHOD_COLORS.get(name.split()[0], OTHER_COLORS[order % len(OTHER_COLORS)])


def port_color(port: int) -> str:
    return f"C{port % 10}"


def thin(count: int, most: int = MAX_MARKERS) -> slice:
    """Every k-th point so that at most ``most`` markers are drawn."""
    return slice(None, None, max(1, -(-count // most)))


def legend_outside(axes, handles=None, labels=None):
    """The axes' legend to the right of its data area (constrained layout makes room)."""
    if handles is None:
        handles, labels = axes.get_legend_handles_labels()
    legend = axes.legend(
        handles,
        labels,
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize=LEGEND_FONT,
        markerscale=LEGEND_MARKER_SCALE,
    )
    _opaque(legend)
    return legend


def _opaque(legend) -> None:
    """Legend keys of semi-transparent markers drawn opaque, so their colour reads."""
    for handle in legend.legend_handles:
        if hasattr(handle, "get_marker") and handle.get_marker() not in (None, "None", ""):
            handle.set_alpha(1.0)


def figure_legend_outside(figure, handles, labels):
    """A legend for the whole figure, in rows below all axes (constrained layout makes room)."""
    columns = min(len(labels), FIGURE_LEGEND_COLUMNS)
    legend = figure.legend(
        handles,
        labels,
        loc="outside lower center",
        fontsize=LEGEND_FONT,
        ncols=columns,
        markerscale=LEGEND_MARKER_SCALE,
    )
    _opaque(legend)
    return legend


def plain_ticks(axes) -> None:
    """Tick labels as plain numbers in the axis unit: no offset, no ``1e-3`` multiplier."""
    axes.ticklabel_format(axis="y", style="plain", useOffset=False)


def offset_label(center_hz: float) -> str:
    return f"frequency offset from {center_hz / 1e12:.6f} THz (GHz)"
