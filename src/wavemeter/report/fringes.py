"""Port fringes with the fitted model and the fit residual: paper Fig. 4b / 7a, per window.

Each panel shows the port readings (small semi-transparent markers), the fitted fringes
(lines above them) and, underneath, the residual of each port (reading minus fit) in the
same power unit with the detector noise estimate as a +-1 sigma band drawn over it: a fit
is good when the residuals fill the band and show no structure. A calibration set gets
one such pair per window, as small multiples on common axes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..calibration.contract.figures import FringePanel
from .formatting import port_label, power_unit, scientific
from .plotting import (
    DATA_ZORDER,
    FIGURE_HEIGHT_IN,
    FIGURE_WIDTH_IN,
    FIT_ZORDER,
    MARKER_ALPHA,
    MARKER_SIZE,
    REFERENCE_ALPHA,
    REFERENCE_ZORDER,
    figure_legend_outside,
    legend_outside,
    new_figure,
    offset_label,
    plain_ticks,
    port_color,
    thin,
)

__all__ = ["plot_fringes", "plot_panels", "plot_window_fringes", "NOISE_BAND_LABEL"]

#: panels' height ratio: fringes over residuals
HEIGHT_RATIOS = (3.0, 1.6)
GRID_COLUMNS = 3
GRID_ROW_HEIGHT_IN = 3.2
NOISE_BAND_LABEL = "noise estimate ±1σ"
#: readings drawn per port over the fitted fringes, few enough for the lines to show
FRINGE_MARKERS = 250


def _legend_entries(port_names: Sequence[str], model_label: str, noise: bool):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [
        Line2D([], [], color=port_color(port), marker="o", markersize=2, linestyle="-")
        for port in range(len(port_names))
    ]
    labels = [port_label(name) for name in port_names]
    handles += [
        Line2D([], [], color="0.35", marker="o", markersize=MARKER_SIZE, linestyle="none"),
        Line2D([], [], color="0.35", linestyle="-"),
    ]
    labels += ["readings (markers)", f"{model_label} fit (lines)"]
    if noise:
        handles.append(Patch(facecolor="0.45", alpha=REFERENCE_ALPHA, edgecolor="0.2"))
        labels.append(NOISE_BAND_LABEL)
    return handles, labels


def _draw_panel(top, bottom, panel: FringePanel, scale: float) -> None:
    """Readings, fit and residuals of one panel on a (fringes, residual) pair of axes."""
    offset = (np.asarray(panel.frequency_hz) - panel.center_hz) / 1e9
    model_offset = (np.asarray(panel.model_frequency_hz) - panel.center_hz) / 1e9
    residual = (np.asarray(panel.powers_w) - np.asarray(panel.fitted_w)) / scale
    step, sparse = thin(offset.size), thin(offset.size, FRINGE_MARKERS)
    for port in range(panel.powers_w.shape[1]):
        color = port_color(port)
        marks = {"markersize": MARKER_SIZE, "alpha": MARKER_ALPHA, "zorder": DATA_ZORDER}
        top.plot(offset[sparse], panel.powers_w[sparse, port] / scale, "o", color=color, **marks)
        top.plot(
            model_offset,
            panel.model_powers_w[:, port] / scale,
            "-",
            color=color,
            linewidth=1.2,
            zorder=FIT_ZORDER,
        )
        bottom.plot(offset[step], residual[step, port], "o", color=color, **marks)
    bottom.axhline(0.0, color="black", linewidth=0.6, zorder=FIT_ZORDER)
    if panel.noise_std_w is not None:
        sigma = panel.noise_std_w / scale
        bottom.axhspan(
            -sigma, sigma, facecolor="0.45", alpha=REFERENCE_ALPHA, zorder=REFERENCE_ZORDER
        )
        for level in (-sigma, sigma):
            bottom.axhline(level, color="0.2", linewidth=0.7, zorder=REFERENCE_ZORDER)
    plain_ticks(top)
    plain_ticks(bottom)
    if panel.title:
        top.set_title(panel.title, fontsize="medium")


def _power_scale(panels: Sequence[FringePanel]) -> tuple[float, str]:
    return power_unit(np.concatenate([np.ravel(panel.powers_w) for panel in panels]))


def plot_fringes(panel: FringePanel, port_names: Sequence[str], model_label: str = "learned"):
    """Fringes with the fitted model over the residual per port: paper Fig. 4b / 7a.

    Parameters
    ----------
    panel : FringePanel
    port_names : sequence of str, length n
        Port column names; their unit suffix is dropped in the legend.
    model_label : str
        Name of the method the model belongs to.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: fringes (top) and residuals (bottom), in the same power unit.
    """
    scale, unit = _power_scale([panel])
    figure, (top, bottom) = new_figure(
        rows=2, height_in=FIGURE_HEIGHT_IN * 1.5, height_ratios=HEIGHT_RATIOS
    )
    _draw_panel(top, bottom, panel, scale)
    top.set_ylabel(f"port power ({unit})")
    bottom.set_ylabel(f"residual ({unit})")
    bottom.set_xlabel(offset_label(panel.center_hz))
    title = "Port fringes, fitted model and residual"
    if panel.noise_std_w is not None:
        title += f" (noise {scientific(panel.noise_std_w)} W)"
    if panel.title:  # what the panel's frequencies are (a thermal model's), on a line below
        title += f"\n{panel.title}"
    top.set_title(title)
    legend_outside(top, *_legend_entries(port_names, model_label, panel.noise_std_w is not None))
    return figure


def _common_limits(axes_list) -> None:
    low = min(axes.get_ylim()[0] for axes in axes_list)
    high = max(axes.get_ylim()[1] for axes in axes_list)
    for axes in axes_list:
        axes.set_ylim(low, high)


def plot_window_fringes(
    panels: Sequence[FringePanel], port_names: Sequence[str], model_label: str = "learned"
):
    """Every window of a calibration set as small multiples: fringes over residuals.

    All fringe panels share one power scale and limits, all residual panels another, so
    windows compare at a glance; each panel's x axis is the offset from its window centre
    (in its title).

    Parameters
    ----------
    panels : sequence of FringePanel
        One per window, in frequency order.
    port_names : sequence of str, length n
    model_label : str
        Name of the method the models belong to.

    Returns
    -------
    matplotlib.figure.Figure
        ``2 K`` axes, fringes and residual of each window in turn.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    count = len(panels)
    columns = min(count, GRID_COLUMNS)
    rows = math.ceil(count / columns)
    figure = Figure(
        figsize=(FIGURE_WIDTH_IN, GRID_ROW_HEIGHT_IN * rows + 0.4), layout="constrained"
    )
    FigureCanvasAgg(figure)
    scale, unit = _power_scale(panels)
    grid = figure.add_gridspec(2 * rows, columns, height_ratios=HEIGHT_RATIOS * rows)
    tops, bottoms = [], []
    for index, panel in enumerate(panels):
        row, column = divmod(index, columns)
        top = figure.add_subplot(grid[2 * row, column])
        bottom = figure.add_subplot(grid[2 * row + 1, column], sharex=top)
        top.tick_params(labelbottom=False)
        _draw_panel(top, bottom, panel, scale)
        bottom.set_xlabel("offset (GHz)")
        if column == 0:
            top.set_ylabel(f"port power ({unit})")
            bottom.set_ylabel(f"residual ({unit})")
        tops.append(top)
        bottoms.append(bottom)
    _common_limits(tops)
    _common_limits(bottoms)
    for index in range(count):
        if index % columns:
            tops[index].tick_params(labelleft=False)
            bottoms[index].tick_params(labelleft=False)
    noise = any(panel.noise_std_w is not None for panel in panels)
    figure_legend_outside(figure, *_legend_entries(port_names, model_label, noise))
    figure.suptitle(f"Port fringes, fitted model and residual of each of the {count} windows")
    return figure


def plot_panels(
    panels: Sequence[FringePanel], port_names: Sequence[str], model_label: str = "learned"
):
    """The fringe panels a calibration declares: one as :func:`plot_fringes`, several as
    small multiples (:func:`plot_window_fringes`). A panel that names its own ports (a
    cascade's stage) is drawn with those."""
    names = panels[0].port_names or tuple(port_names)
    if len(panels) == 1:
        return plot_fringes(panels[0], names, model_label)
    return plot_window_fringes(panels, names, model_label)
