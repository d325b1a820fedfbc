"""Identify the lines found in a record with the lines of a table, or refuse with the reason.

Two ways (:func:`identify_lines`):

- **nearest**: where the recorded axis is good to a quarter of the table's local spacing
  (the caller states its error bound), each found line is the nearest table line.
- **pattern**: otherwise, by the pattern of spacings. The found lines' positions (the
  meter's phase: linear in frequency up to a smooth dispersion) are mapped onto the table
  by every hypothesis that sends two neighbouring found lines to two table lines (one to
  three table lines apart, either direction); the map (a cubic in the position) is
  refitted on the lines it then explains. A hypothesis stands when every found line lies
  within a quarter of the local spacing of a distinct table line. The standing assignment
  of least chi-square (with the lines' stated frequency uncertainties, inflated by the
  best fit's reduced chi-square when above 1) is the identification when every other one
  is worse by at least ``DELTA_CHI2``; otherwise, or when none stands, it is refused with
  the reason, as is a best fit whose residuals exceed the stated uncertainty by far. Found
  lines map to consecutive table lines (unless ``allow_missing``: a missed line would look
  like a band's origin gap). A cubic map absorbs the slow change of a band's spacing, so a
  stretch of one branch fits assignments shifted by a line equally well: it takes a feature
  that fixes the lines' place (the gap at a band's origin, a band end inside ``band_hz``,
  or a known scale). Nothing is ever guessed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .lines import ReferenceLines

__all__ = ["Identification", "identify_lines", "QUARTER_SPACING"]

#: a found line must lie within this share of the local table spacing of its line
QUARTER_SPACING = 0.25
#: table lines a pair of neighbouring found lines may span (undetected lines between them)
MAX_PAIR_STEP = 3
#: refits of a hypothesis' map on the lines it explains
REFITS = 3
#: the identification's chi-square must beat every other standing assignment's by this
DELTA_CHI2 = 25.0
#: position-to-frequency map of a pattern hypothesis: polynomial order
PATTERN_ORDER = 3
#: default frequency uncertainty of a found line: this share of the median table spacing
DEFAULT_STD_SPACING = 1e-3
#: the identification's residuals may exceed the lines' stated uncertainty by this much
#: (reduced chi-square); beyond it the map or the lines are not what they should be
MAX_REDUCED_CHI2 = 25.0


@dataclass(frozen=True)
class Identification:
    """Which table line each found line is.

    Attributes
    ----------
    table_index : ndarray of int, shape (M,)
        Index into the table given to :func:`identify_lines` (its frequency order) of each
        found line, in the order the found lines were given.
    method : {"nearest", "pattern"}
    detail : str
        How the identification was made (for reports).
    """

    table_index: np.ndarray
    method: str
    detail: str


def _local_spacing(centers: np.ndarray) -> np.ndarray:
    if centers.size == 1:
        return np.array([np.inf])
    gaps = np.diff(centers)
    return np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])


def _nearest(values: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """Index of the nearest of sorted ``centers`` for each value."""
    right = np.clip(np.searchsorted(centers, values), 1, centers.size - 1)
    left = right - 1
    if centers.size == 1:
        return np.zeros(values.size, dtype=int)
    return np.where(values - centers[left] <= centers[right] - values, left, right)


def _explains(frequency: np.ndarray, centers: np.ndarray, spacing: np.ndarray):
    """Nearest table line of each predicted frequency when all lie within a quarter spacing
    of distinct lines; else None."""
    nearest = _nearest(frequency, centers)
    if np.unique(nearest).size != nearest.size:
        return None
    if np.any(np.abs(frequency - centers[nearest]) >= QUARTER_SPACING * spacing[nearest]):
        return None
    return nearest


def _pattern_assignments(
    x: np.ndarray, centers: np.ndarray, order: int, scale_range, allow_missing: bool
):
    """Every distinct standing assignment of positions ``x`` (increasing with frequency),
    with its residuals (Hz); consecutive table lines only unless ``allow_missing``."""
    spacing = _local_spacing(centers)
    count = x.size
    pairs = sorted({0, count // 2 - 1, count - 2} - {-1}) if count >= 2 else []
    found: dict[tuple, np.ndarray] = {}
    for i in pairs:
        for a in range(centers.size):
            for step in range(1, (MAX_PAIR_STEP if allow_missing else 1) + 1):
                b = a + step
                if b >= centers.size:
                    break
                slope = (centers[b] - centers[a]) / (x[i + 1] - x[i])
                if scale_range is not None and not scale_range[0] <= slope <= scale_range[1]:
                    continue
                assignment = _explains(centers[a] + slope * (x - x[i]), centers, spacing)
                for _ in range(REFITS):
                    if assignment is None:
                        break
                    degree = min(order, count - 1)
                    coefficients = np.polyfit(x - x.mean(), centers[assignment], degree)
                    predicted = np.polyval(coefficients, x - x.mean())
                    refit = _explains(predicted, centers, spacing)
                    if refit is not None and np.array_equal(refit, assignment):
                        if allow_missing or np.all(np.diff(assignment) == 1):
                            found[tuple(assignment)] = predicted - centers[assignment]
                        break
                    assignment = refit
    return found


def identify_lines(
    positions,
    lines: ReferenceLines,
    *,
    approx_hz=None,
    axis_error_hz: float | None = None,
    band_hz=None,
    direction: int | None = None,
    scale_range=None,
    pressure_pa: float | None = None,
    frequency_std_hz=None,
    allow_missing: bool = False,
    order: int = PATTERN_ORDER,
) -> Identification:
    """Identify found lines with table lines (module docstring), or refuse with the reason.

    Parameters
    ----------
    positions : array_like, shape (M,)
        Position of each found line in a coordinate monotonic and nearly linear in
        frequency (the meter's unwrapped phase, rad, or a frequency axis, Hz).
    lines : ReferenceLines
        The table.
    approx_hz : None or array_like, shape (M,)
        Frequency of each found line on the recorded axis (Hz), for the nearest match.
    axis_error_hz : None or float
        Bound on the recorded axis's error (Hz). The nearest match is used when it is below
        a quarter of the local spacing of every table line concerned and every found line
        then lies within it of its table line; otherwise the pattern decides.
    band_hz : None or (float, float)
        The band the sweep covers (Hz): only table lines inside are candidates.
    direction : None, +1 or -1
        +1 when the positions increase with frequency, -1 when they decrease; None: both
        are tried (a reference-free phase has no known direction).
    scale_range : None or (float, float)
        Bounds on ``|d frequency / d position|`` (Hz per position unit), when known (an FSR
        known to some tolerance).
    pressure_pa : None or float
        The cell's pressure (Pa): the lines are expected at the table's centres shifted to it
        (``ReferenceLines.centers_at``).
    frequency_std_hz : None, float or array_like, shape (M,)
        Standard uncertainty (Hz) of each found line's frequency as the map would give it
        (its centre fit and the table's); None: ``DEFAULT_STD_SPACING`` of the median table
        spacing.
    allow_missing : bool
        Whether table lines between found ones may have gone unfound. By default every line
        between the first and the last found one must be found: a missed line would look
        like the gap at a band's origin.
    order : int
        Polynomial order of the position-to-frequency map of a pattern hypothesis.

    Returns
    -------
    Identification

    Raises
    ------
    InputError
        When no assignment explains every found line, or more than one does (the message
        names the alternatives and what would fix the place of the lines).
    """
    x = np.asarray(positions, dtype=float).reshape(-1)
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise InputError("positions must be finite, one per found line, at least one")
    candidates = lines if band_hz is None else lines.within(band_hz)
    offset = (
        0 if band_hz is None else int(np.searchsorted(lines.center_hz, candidates.center_hz[0]))
    )
    centers = candidates.centers_at(pressure_pa)
    spacing = _local_spacing(centers)
    if x.size > centers.size:
        raise InputError(
            f"{x.size} lines were found but the table has {centers.size} lines in the band: "
            "a dip that is not a table line (another gas, a fringe) or a band too narrow",
            parameter="band_hz",
        )
    notes = []
    if approx_hz is not None and axis_error_hz is not None:
        approx = np.asarray(approx_hz, dtype=float).reshape(-1)
        if approx.shape != x.shape:
            raise InputError("approx_hz must have one frequency per found line")
        nearest = _nearest(approx, centers)
        bound = QUARTER_SPACING * spacing[nearest]
        distance = np.abs(approx - centers[nearest])
        if np.all(axis_error_hz < bound) and np.all(distance <= axis_error_hz):
            if np.unique(nearest).size == nearest.size:
                return Identification(
                    nearest + offset,
                    "nearest",
                    f"nearest table line on the recorded axis (stated error "
                    f"{axis_error_hz / 1e9:.4g} GHz, below a quarter of the local spacing, "
                    f"largest distance found {distance.max() / 1e9:.4g} GHz)",
                )
            notes.append("two found lines are nearest to one table line")
        elif np.any(axis_error_hz >= bound):
            notes.append(
                f"the recorded axis error {axis_error_hz / 1e9:.4g} GHz is not below a quarter "
                f"of the local spacing ({bound.min() / 1e9:.4g} GHz)"
            )
        else:
            worst = int(np.argmax(distance))
            notes.append(
                f"found line {worst} lies {distance[worst] / 1e9:.4g} GHz from its nearest table "
                f"line, beyond the stated axis error {axis_error_hz / 1e9:.4g} GHz"
            )
    if frequency_std_hz is None:
        sigma = np.full(x.size, DEFAULT_STD_SPACING * float(np.median(np.diff(centers))))
    else:
        sigma = np.broadcast_to(np.asarray(frequency_std_hz, dtype=float), x.shape)
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise InputError("frequency_std_hz must be finite and > 0 for every found line")
    directions = (1, -1) if direction is None else (int(direction),)
    results = {}
    for sign in directions:
        rank = np.argsort(sign * x)
        standing = _pattern_assignments(sign * x[rank], centers, order, scale_range, allow_missing)
        for assignment, residual in standing.items():
            table = np.empty(x.size, dtype=int)
            table[rank] = np.asarray(assignment)
            chi2 = float(np.sum((residual / sigma[rank]) ** 2))
            results[tuple(table)] = (sign, chi2, float(np.sqrt(np.mean(residual**2))))
    why = ("; ".join(notes) + "; ") if notes else ""
    if not results:
        raise InputError(
            f"{why}no assignment of the {x.size} lines found to the {centers.size} table lines "
            f"in the band puts every line within a quarter spacing of a distinct table line: a "
            "dip that is no table line, a line missed between others, or the wrong table or "
            "band",
            parameter="reference_lines",
        )
    ranked = sorted(results.items(), key=lambda item: item[1][1])
    best_table, (best_sign, best_chi2, best_rms) = ranked[0]
    dof = max(x.size - order - 1, 1)
    if best_chi2 / dof > MAX_REDUCED_CHI2:
        raise InputError(
            f"{why}the best assignment of the {x.size} lines found leaves residuals of "
            f"{best_rms / 1e6:.3g} MHz RMS, {np.sqrt(best_chi2 / dof):.3g} times the lines' "
            "uncertainty: a line missed between others (a missed line looks like a band's "
            "origin gap), a dip that is no table line, or a phase that is not smooth in "
            "frequency",
            parameter="reference_lines",
        )
    inflation = max(1.0, best_chi2 / dof)
    rivals = [item for item in ranked[1:] if (item[1][1] - best_chi2) / inflation < DELTA_CHI2]
    if rivals:
        shown = []
        for table, (sign, chi2, rms) in [ranked[0], *rivals][:3]:
            labels = [candidates.labels[k] for k in table]
            shown.append(
                f"[{labels[0]} .. {labels[-1]}, direction {sign:+d}, rms {rms / 1e6:.3g} MHz, "
                f"chi2 {chi2:.4g}]"
            )
        raise InputError(
            f"{why}the {x.size} lines found cannot be identified uniquely: {len(rivals) + 1} "
            f"assignments fit their spacings within chi2 {DELTA_CHI2:g}, e.g. "
            f"{' or '.join(shown)}. The band holds no feature that fixes the place of its "
            "lines (a band origin gap or a band end): sweep across one, or give a recorded "
            "axis good to a quarter of the spacing",
            parameter="reference_lines",
        )
    second = ranked[1][1][1] if len(ranked) > 1 else float("inf")
    return Identification(
        np.asarray(best_table) + offset,
        "pattern",
        f"{why}by the pattern of spacings (direction {best_sign:+d}, rms {best_rms / 1e6:.3g} "
        f"MHz with a polynomial map of order {order}; chi2 {best_chi2:.4g}, next assignment "
        f"{second:.4g})",
    )
