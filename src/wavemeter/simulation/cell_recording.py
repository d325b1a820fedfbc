"""A scenario's sweep as a laser records it, with a reference cell beside the ports.

:func:`cell_sweep` gives what :class:`~wavemeter.simulation.Scenario` writes for
``sweep_axis`` (a :data:`~wavemeter.simulation.SWEEP_PRESETS` key: the laser's recorded
axis, its true frequencies the meter sees) and ``reference_cell`` (a
:data:`~wavemeter.simulation.CELL_PRESETS` key, or a line table file: the cell channel).
A table file's lines are simulated with equal strengths and the ``"hcn-like"`` preset's
widths, pressure, temperature and noise. Its draws come from ``[seed, CELL_STREAM]``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..reference import ReferenceLines
from .reference_cell import CELL_PRESETS, ReferenceCell
from .sweep_axis import SWEEP_PRESETS, laser_sweep

__all__ = ["CELL_STREAM", "CellSweep", "TRUE_COLUMN", "CELL_COLUMN", "cell_sweep", "check_cell"]

#: stream of the seed the sweep axis and the cell are drawn from
CELL_STREAM = 5
#: the true frequency's column (Hz, for evaluation only: its name is no axis name)
TRUE_COLUMN = "simulated_true_frequency_hz"
#: the cell channel's column (transmission, relative to the baseline)
CELL_COLUMN = "cell_transmission"


@dataclass(frozen=True, eq=False)
class CellSweep:
    """The true and the recorded frequency of every sweep sample, and the cell channel.

    Attributes
    ----------
    true_hz, recorded_hz : ndarray, shape (N,)
        What the meter and the cell see, and what the laser's axis says (Hz).
    transmission : ndarray, shape (N,), or None
        The cell channel; None without a cell.
    cell : ReferenceCell or None
        The simulated cell (its lines, true centres and pressure).
    """

    true_hz: np.ndarray
    recorded_hz: np.ndarray
    transmission: np.ndarray | None
    cell: ReferenceCell | None


def check_cell(sweep_axis, reference_cell) -> tuple:
    """``sweep_axis`` a preset's name or None; ``reference_cell`` a preset's name, an
    existing line table file or None (a file's path as a string)."""
    if sweep_axis is not None and sweep_axis not in SWEEP_PRESETS:
        raise InputError(
            f"sweep_axis must be one of {', '.join(SWEEP_PRESETS)}, got {sweep_axis!r:.40}",
            parameter="sweep_axis",
        )
    if reference_cell is None or reference_cell in CELL_PRESETS:
        return sweep_axis, reference_cell
    if not isinstance(reference_cell, (str, Path)) or not Path(reference_cell).is_file():
        raise InputError(
            f"reference_cell must be one of {', '.join(CELL_PRESETS)} (a simulated band) or a "
            f"line table file, got {str(reference_cell)!r:.60}",
            parameter="reference_cell",
        )
    return sweep_axis, str(reference_cell)


def _cell(reference_cell: str, rng) -> ReferenceCell:
    if reference_cell in CELL_PRESETS:
        return ReferenceCell.simulated(reference_cell, rng=rng)
    lines = ReferenceLines.read_csv(reference_cell)
    like = ReferenceCell.simulated("hcn-like", rng=rng)
    count = len(lines)
    true = lines.center_hz + rng.normal(0.0, lines.std_hz)
    return replace(
        like,
        lines=lines,
        true_center_hz=true,
        area_hz=np.full(count, like.area_hz.max()),
        sigma_hz=np.full(count, float(np.median(like.sigma_hz))),
        gamma_hz=np.full(count, float(np.median(like.gamma_hz))),
    )


def cell_sweep(sweep_hz, seed: int, sweep_axis=None, reference_cell=None) -> CellSweep:
    """The sweep over the band of ``sweep_hz`` (its lowest to highest, ``sweep_hz.size``
    samples) as the laser preset ``sweep_axis`` records it (None: exactly), with the cell
    ``reference_cell`` (None: no cell) recorded at the true frequencies."""
    sweep_hz = np.asarray(sweep_hz, dtype=float)
    axis_rng, cell_rng, noise_rng = np.random.default_rng([seed, CELL_STREAM]).spawn(3)
    if sweep_axis is None:
        true_hz = recorded_hz = sweep_hz
    else:
        swept = laser_sweep(
            (sweep_hz.min(), sweep_hz.max()), sweep_hz.size, sweep_axis, rng=axis_rng
        )
        true_hz, recorded_hz = swept.true_hz, swept.recorded_hz
    if reference_cell is None:
        return CellSweep(true_hz, recorded_hz, None, None)
    cell = _cell(reference_cell, cell_rng)
    return CellSweep(true_hz, recorded_hz, cell.transmission(true_hz, rng=noise_rng), cell)
