"""Tests of a wide sweep's residual against a device that changes with frequency.

Over several FSRs a misfit smooth along the rows may be a drift in time or a device that
changes with wavelength (group-delay dispersion, coupler and detector slopes): on a one-way
sweep the rows and the frequency move together, and only the shape of the residual tells
them apart. :func:`band_tests` measures, on the whitened residual of
:func:`~wavemeter.calibration.checks.misfit.misfit_report`, the structure a map polynomial
in frequency explains on every port (``band``), what of it no common change of the source
power or the fringe phase explains (``slope``: the ports change each in its own way, which
no drift does), and what smooth structure along the rows is left once the polynomial is
taken out (``remainder``). The tests and the naming rules are in
``docs/theory/diagnostics.rst`` (tests 8-10, "Naming the cause").
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import special

from ...stats.blocks import orthonormal_columns
from ...stats.nested_tests import ResidualTest, ResidualTests
from ...stats.projection import Projector

__all__ = ["BAND_DEGREES", "BandTests", "band_tests"]

#: Legendre degrees in frequency of the map polynomial tested on wide sweeps (1..BAND_DEGREES)
BAND_DEGREES = 4


@dataclass(frozen=True)
class BandTests:
    """What a polynomial in frequency explains of a wide sweep's residual.

    Attributes
    ----------
    band : ResidualTest
        A map polynomial in frequency on every port (``L_j(y) x_k``, ``j = 1..``
        ``BAND_DEGREES``) beyond the fit.
    slope : ResidualTest
        The same columns beyond a common change of the source power, the fringe phase and
        the fringe's radius polynomial in frequency (what no drift of power or phase
        explains: the ports change each in its own way).
    remainder : ResidualTest
        Smooth structure along the rows (discrete cosines on every port) beyond the fit and
        the map polynomial.
    single_map : bool
        The fit has one map for the whole sweep (not a map that changes with frequency).
    """

    band: ResidualTest
    slope: ResidualTest
    remainder: ResidualTest
    single_map: bool = True

    def p_values(self) -> dict:
        return {
            "band": self.band.p_value,
            "band_slope": self.slope.p_value,
            "band_remainder": self.remainder.p_value,
        }


def _legendre(y: np.ndarray) -> np.ndarray:
    """``L_j(y)`` (N, BAND_DEGREES) for ``j = 1..BAND_DEGREES``."""
    return np.column_stack([special.eval_legendre(j, y) for j in range(1, BAND_DEGREES + 1)])


def _map_columns(objects: np.ndarray, y: np.ndarray, rows: slice) -> np.ndarray:
    """``L_j(y_k) x_k`` (L, 3 BAND_DEGREES) of the readings ``rows``."""
    legendre = _legendre(y[rows])
    products = legendre[:, :, None] * objects[rows][:, None, :]
    return products.reshape(legendre.shape[0], 3 * BAND_DEGREES)


def band_tests(
    tests: ResidualTests,
    projector: Projector,
    residual_dof: float,
    objects: np.ndarray,
    directions: tuple[np.ndarray, ...],
    frequency: np.ndarray,
    orders: tuple[int, ...],
    cosines: int,
    single_map: bool,
) -> BandTests:
    """The tests of the module docstring.

    Parameters
    ----------
    tests : ResidualTests
        The tests of the report, on the whitened residual projected off the fit.
    projector : Projector
        What the fit absorbs (whitened).
    residual_dof : float
        Degrees of freedom of each port's residual.
    objects : ndarray, shape (N, 3)
        The cone objects ``m_k [cos t_k, sin t_k, sqrt 2]``.
    directions : tuple of ndarray, each shape (N, n)
        The whitened per-reading directions of a common change: the image ``a_P``, the
        fringe tangent ``a_t`` and the fringe's radius (the image less its cone-axis part).
    frequency : ndarray, shape (N,)
        Frequency of each reading (Hz).
    orders : tuple of int
        Numbers of discrete cosines the remainder is tested at (nested).
    cosines : int
        The largest of them.
    single_map : bool
        The fit has one map for the whole sweep.
    """
    middle = 0.5 * (frequency.max() + frequency.min())
    half = max(0.5 * float(np.ptp(frequency)), np.finfo(float).tiny)
    y = (frequency - middle) / half
    columns = partial(_map_columns, objects, y)
    count = 3 * BAND_DEGREES
    band, _ = tests.per_port(tests.columns(columns), (count,))

    legendre = _legendre(y)
    common = [
        legendre[:, None, :] * direction[:, :, None] for direction in directions
    ]  # (N, n, BAND_DEGREES) each
    coupled = np.concatenate([projector.coupled, *common], axis=2)
    common_tests = ResidualTests(
        tests.residual.copy(),
        Projector(projector.basis, coupled),
        residual_dof,
        tests.rank_tolerance,
    )
    del common, coupled
    slope, _ = common_tests.per_port(common_tests.columns(columns), (count,))
    del common_tests

    extended = orthonormal_columns(np.column_stack([projector.basis, columns(slice(None))]))
    added = extended.shape[1] - projector.basis.shape[1]
    beyond = ResidualTests(
        tests.residual.copy(),
        Projector(extended, projector.coupled),
        max(residual_dof - added, 1.0),
        tests.rank_tolerance,
    )
    remainder, _ = beyond.per_port(beyond.cosines(cosines), orders)
    return BandTests(band, slope, remainder, single_map)
