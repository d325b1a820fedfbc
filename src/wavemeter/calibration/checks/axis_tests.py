"""Test of a quantised frequency axis: recorded values rounded while the truth moves on.

A frequency or wavelength column rounded to a few digits (by a spreadsheet, an export
format) departs from the smooth sweep the laser made by up to half a rounding step, and
the residual phase follows those departures one for one: a sawtooth, one tooth per run of
equal values. :func:`axis_quantisation` describes the recorded axis (its distinct values,
the step between them, the coarsest decimal grid its frequencies or wavelengths lie on) and
its departure from a smooth sweep (a local quadratic along the rows); :func:`axis_test`
tests the whitened residual along the fringe tangent times that departure (one column
shared by the ports) and fits its coefficient, 1 when the residual follows the axis'
rounding. Readings truly taken at one frequency each (a stepped laser averaging several
readings per step) leave no such tooth. The test and its naming rule are in
``docs/theory/diagnostics.rst`` (test 11, "Naming the cause").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...stats.nested_tests import ResidualTest, ResidualTests
from ...units import SPEED_OF_LIGHT_M_S

__all__ = [
    "MIN_MEAN_RUN",
    "GRID_TOLERANCE",
    "GRID_PROBE",
    "SWEEP_DEGREE",
    "FOLLOW_RANGE",
    "AxisQuantisation",
    "AxisTest",
    "axis_quantisation",
    "axis_test",
]

#: readings per distinct recorded value, on average, from which an axis repeats its values
MIN_MEAN_RUN = 2.0
#: largest distance (in grid steps) of every recorded value from the grid it lies on
GRID_TOLERANCE = 1e-6
#: coefficients of the departure (1: the residual follows the rounding one for one) that
#: make the residual's structure the axis' rounding
FOLLOW_RANGE = (0.5, 1.5)
#: values checked on a grid before the whole axis is
GRID_PROBE = 64
#: degree of the polynomial in the row the laser's sweep is taken to be
SWEEP_DEGREE = 3


@dataclass(frozen=True)
class AxisQuantisation:
    """A recorded axis that repeats its values or lies on a decimal grid.

    Attributes
    ----------
    distinct : int
        Distinct recorded frequencies.
    step_hz : float
        Median step between consecutive distinct recorded values (Hz).
    grid : tuple of (str, float) or None
        ``("frequency", step_hz)`` or ``("wavelength", step_m)``: the coarsest decimal grid
        (a power of ten in Hz or in m) every recorded value lies on; None when there is none.
    departure_hz : ndarray, shape (N,)
        Each recorded frequency less a smooth sweep through them (Hz).
    """

    distinct: int
    step_hz: float
    grid: tuple[str, float] | None
    departure_hz: np.ndarray


@dataclass(frozen=True)
class AxisTest:
    """The residual along the axis' departure from a smooth sweep."""

    test: ResidualTest
    coefficient: float  # 1: the residual phase follows the departures one for one
    phase_error_rad: np.ndarray  # (N,) what the column explains

    @property
    def follows(self) -> bool:
        """The test failed and the residual follows the rounding (``FOLLOW_RANGE``)."""
        low, high = FOLLOW_RANGE
        return self.test.failed and low <= self.coefficient <= high


def _grid(values: np.ndarray, coarsest: float) -> float | None:
    """The coarsest power of ten, at most ``coarsest``, every value lies on within
    ``GRID_TOLERANCE`` of a step (None: none above the values' rounding)."""
    largest = float(np.max(np.abs(values)))
    if not largest > 0 or not coarsest > 0:
        return None
    finest = largest * 64 * np.finfo(float).eps / GRID_TOLERANCE

    def on_grid(part: np.ndarray, step: float) -> bool:
        ratio = part / step
        return bool(np.max(np.abs(ratio - np.round(ratio))) <= GRID_TOLERANCE)

    exponent = math.floor(math.log10(coarsest))
    while 10.0**exponent > finest:
        step = 10.0**exponent
        # a few values first: an axis off every grid (most) costs no pass over the sweep
        if on_grid(values[:GRID_PROBE], step) and on_grid(values, step):
            return step
        exponent -= 1
    return None


def _smooth_sweep(frequency: np.ndarray) -> np.ndarray:
    """A polynomial of degree ``SWEEP_DEGREE`` in the row through the recorded frequencies
    (least squares): the laser's sweep, which the rounding's steps and their slow beats
    depart from."""
    rows = np.linspace(-1.0, 1.0, frequency.size)
    middle = 0.5 * (frequency.max() + frequency.min())
    degree = min(SWEEP_DEGREE, frequency.size - 1)
    fit = np.polynomial.legendre.Legendre.fit(rows, frequency - middle, degree, domain=[-1, 1])
    return middle + fit(rows)


def axis_quantisation(frequency: np.ndarray) -> AxisQuantisation | None:
    """The quantisation of ``frequency`` (N,) (Hz, in acquisition order): repeated values
    (``MIN_MEAN_RUN`` readings per run on average) or a decimal grid in frequency or
    wavelength coarser than the values' rounding; None when it has neither."""
    samples = frequency.size
    steps = np.diff(frequency)
    moves = np.flatnonzero(steps != 0.0)
    runs = moves.size + 1
    span = float(np.ptp(frequency))
    grid = None
    for name, values in (("frequency", frequency), ("wavelength", SPEED_OF_LIGHT_M_S / frequency)):
        step = _grid(values, float(np.ptp(values)))
        if step is not None:
            grid = (name, step)
            break
    if (samples < MIN_MEAN_RUN * runs and grid is None) or not span > 0:
        return None
    departure = frequency - _smooth_sweep(frequency)
    return AxisQuantisation(
        distinct=int(np.unique(frequency).size),
        step_hz=float(np.median(np.abs(steps[moves]))),
        grid=grid,
        departure_hz=departure,
    )


def axis_test(
    tests: ResidualTests,
    axis: AxisQuantisation,
    tangent: np.ndarray,
    weight: np.ndarray,
    delay_s: float,
) -> AxisTest:
    """The test along ``-2 pi tau d_k a_t,k`` (``d`` the departure, ``tangent`` whitened
    (N, n), ``weight`` its squared norm per reading, ``delay_s`` the fitted delay): the
    residual a reading recorded ``d`` above its true frequency leaves."""
    phase = -2.0 * np.pi * delay_s * axis.departure_hz
    test, explained = tests.coupled(tests.columns(phase[:, None], tangent), tangent, (1,), weight)
    energy = float(phase @ phase)
    coefficient = float(explained @ phase) / energy if energy > 0 else 0.0
    return AxisTest(test, coefficient, explained)
