"""Fit diagnostics: does the calibration sweep follow the model, and if not, why.

After a fit, the residual of every reading (row order = acquisition order)

    r_k = p_k - d - A x_k,   x_k = m_k [cos t_k, sin t_k, sqrt 2],   t_k = 2 pi (f_k - f0) tau

(``d`` the fitted per-port offsets or 0, ``m_k`` the relative monitored power or 1) is white
Gaussian detector noise when the model holds, and carries structure when it does not. This
module measures that structure, tests it against the noise, names the likely cause and says
what to do, as :class:`~wavemeter.exceptions.CalibrationWarning` objects whose ``cause`` is
one of :data:`CAUSES` (:func:`misfit_report`).

A wide-band model has a map that changes with frequency and a phase polynomial: reading
``k`` has its own map ``A_k = A(f_k)`` (``sum_j A_j L_j(y_k)``, ``y = (f - f0) / h``) and phase
``t_k = sum_i b_i y_k^i``. Its map coefficients are linear least squares on the design
columns ``kron(L_j(y_k), x_k)`` (``c = 3 (J + 1)``, shared by the ports), its ``q`` phase
coefficients are shared by the ports; the caller passes the per-reading maps, the phases,
the design and the phase's derivatives ``dt_k / db_i``, and every statistic below takes
them in place of the one map, the ``3`` cone columns and the delay.

Noise without the model
-----------------------
Each port's noise ``s_j`` is estimated from the second differences of its residual along
the rows, ``e_k = r_{k+1} - 2 r_k + r_{k-1}``: white noise of variance ``s^2`` gives
``var(e) = 6 s^2``, while a misfit that changes slowly from reading to reading (a drift, or
a fringe-shaped error on a dense sweep) is suppressed by the double difference. The estimate
is ``s_j^2 = sum e^2 / T`` with ``T = trace(D (I - H) D')`` (``D`` the second-difference
operator, ``H`` the projector on the fitted columns; ``T ~ 6 (N - 2)``): unbiased for white
noise after the fit. Its degrees of freedom are ``nu = T^2 / trace((D (I - H) D')^2)``
(Satterthwaite, ``~ 0.51 N``), its relative standard error ``1 / sqrt(2 nu)``. A sweep of
fewer than ``MIN_MODEL_FREE_READINGS`` readings, or of fewer than ``MIN_READINGS_PER_FSR``
readings per fringe period, is too short or too coarse for it: there each port's residual
gives the noise and ``noise_method == "residual"`` says so.

Statistics reported per port
----------------------------
``residual_rms_w``: ``sqrt(sum r^2 / (N - c - q/n))`` (``c`` = 3 fitted columns, 4 with
offsets, or the rank of the design; ``q`` = 1 for the delay, shared by the ``n`` ports, or
the number of phase coefficients). ``noise_std_w``: above. ``noise_ratio``:
their ratio, 1 on average for in-model data. ``lag1_autocorrelation``: ``sum r_k r_{k+1} /
sum r_k^2``, about 0 (within ``1/sqrt(N)``) for white noise and near 1 for a slow drift.
``harmonic_power``: the residual energy in harmonics 2 and 3 of the fringe phase (the
columns ``m_k cos h t_k``, ``m_k sin h t_k`` with the fitted columns projected out) divided
by what white noise of the port's level puts there (``s_j^2`` per column): an F(4, nu)
variable for in-model data, 1 on average.

Tests
-----
The residual is whitened by the noise (``r_kj / s_j``; one pooled ``s`` for every port
unless the unequal-noise test below finds them different at ``POOLED_NOISE_P_VALUE``, so
that in-model sweeps are not tested with noisy weights). Each alternative is a set of
columns in the ``N n`` dimensional space of readings x ports, from which the directions the
fit absorbs are projected out: the map's columns on every port, the offsets, and for each
nonlinear parameter ``theta_i`` the direction ``(dt_k / d theta_i) a_t,k`` it moves the
readings in (``2 pi (f_k - f0) a_t,k`` for the delay; ``a_t`` below), these orthonormalised
jointly and left out where the others absorb them. The energy of the whitened residual along
the remaining columns is a score (Lagrange-multiplier) statistic: chi-square with as many
degrees of freedom ``k`` as independent columns when the model holds. Its p-value is that of
the lack-of-fit F test, the statistic per degree of freedom over the rest of the whitened
residual per degree of freedom, F(k, n d - k) with ``d = N - c - q/n`` (exact for white
noise of known port ratios; the model-free noise keeps the weights robust to the misfit
itself). *Smooth in time* means a combination of the first ``K`` discrete cosines of the row
index, ``b_m(k) = cos(pi m (k + 1/2) / N)``, ``m = 1..K``, tested at the nested scales ``K``
of ``SMOOTH_ORDERS`` (up to ``N / 4``; ``MAX_COUPLED_ORDER`` for the columns that couple the
ports), so that a slow drift and a thermostat cycling many times are both caught; a family's
p-value is its smallest over the scales times their number (Bonferroni). Columns are taken
in order, and one that the fit and the columns before it absorb (to ``RANK_TOLERANCE`` of
its norm: on a sweep of evenly spaced frequencies, the fringe's own ``cos t`` and ``sin t``
can span a discrete cosine) is left out, with no degree of freedom.

1. **power** (``power_drift``): columns ``b_m(k) a_P,k``, ``a_P,k = A x_k`` (the reading's
   own image, through its own map ``A_k`` in a wide-band model): a relative source-power
   error ``u(k)`` smooth in time.
2. **phase** (``phase_drift``): columns ``b_m(k) a_t,k``, ``a_t,k = m_k A [-sin t_k, cos t_k,
   0]`` (the fringe tangent): a phase error smooth in time.
3. **dispersion**: columns ``P_2(y_k) a_t,k`` and ``P_4(y_k) a_t,k`` (Legendre polynomials
   of ``y = (f - f0) / max |f - f0|``): a phase error even in ``f - f0``, as group-delay
   dispersion gives (``t = w tau + GDD w^2 / 2``). The odd part of a dispersion is a local
   change of the FSR that, in a one-way sweep, cannot be told from a drift (nor a drift of
   one cycle from a cubic phase), so it is left to ``phase_drift``. Only for sweeps over
   more than ``DISPERSION_MIN_SPAN_FSR`` FSRs. After a fitted phase polynomial of degree 2
   or more, ``P_2`` lies in the fitted directions and is left out: ``P_4`` tests what the
   polynomial left.
4. **harmonics** (``other_misfit``): harmonics 2 and 3 of the fringe phase on every port
   (a fringe that is not a sinusoid: detector nonlinearity, stray interference).
5. **smooth** (``other_misfit``): columns ``b_m(k)`` on every port, up to ``N / 4``: any
   residual that wanders in time (a background, a drifting dark level) and the reference
   for how much of it the causes above explain.
6. **power scatter** (``power_drift``) and 7. **phase scatter** (``phase_drift``): without
   any order in time. At every reading the residual is split (whitened by the ports'
   residual RMS, pooled as above) into its component along ``a_P``, its component along
   ``a_t`` orthogonal to that, and the rest (``n - 2`` directions). White detector noise
   puts the same energy in each direction, so ``(S_P / d) / (S_rest / (d (n - 2)))`` is
   F(d, d (n - 2)) (``d = N - c - q/n``), and likewise for ``S_t``; source-power noise from
   reading to reading (flicker, which the second differences count as noise on a short
   sweep) raises ``S_P``, phase jitter (an error of the known frequencies, laser frequency
   noise) ``S_t``.

Each test fails below ``TEST_P_VALUE`` (1e-6, one-sided ``z = 4.75``). With the
unequal-noise test below there are eight, so in-model sweeps warn with a probability below
``1e-5`` where the nulls hold; the approximations (estimated noise, a linearised delay,
Satterthwaite degrees of freedom) are checked by Monte Carlo in ``tests/test_misfit.py``
(p-values at the 5 % level) and ``benchmarks/misfit_false_alarms.py`` (false alarms over
hundreds of sweeps).

Naming the cause
----------------
The residual gets at most one of ``power_drift``, ``phase_drift``, ``dispersion`` and
``other_misfit``. When only the scatter tests fail, the cause is the one of them with the
larger excess energy. Otherwise the candidates are the power and phase families (when they
fail) and the harmonics, each with its excess energy (statistic minus degrees of freedom,
in units of the noise). If none explains ``EXPLAINED_FRACTION`` of the excess of the
smooth family, the cause is ``other_misfit``; else it is the candidate with the largest
excess ``E``, where those within ``TIE_FRACTION E + TIE_Z sqrt(E)`` of it (2 % or two
standard deviations of the noise in ``E``) are a tie, named in the order phase, power,
other. ``dispersion`` replaces ``phase_drift`` when its even polynomial (two columns)
explains the phase structure as well (a tie). Power and phase errors move a reading along
different image directions (``a_P`` and ``a_t``) and separate well on sweeps of several
FSRs; on a one-way sweep of about one FSR a drift is partly absorbed into the map
and the FSR, and a drift of one cycle leaves the same residual as power or as phase (the
message then says both).

What cannot be seen
-------------------
* A **linear temperature ramp over a one-way sweep** shifts the phase in proportion to
  ``f - f0``: exactly another FSR, absorbed by the delay fit and invisible here. Log the
  temperature and use a thermal calibration; a cycling thermostat, or a ramp over repeated
  or two-way sweeps, is not collinear with frequency and is detected (2).
* With a **map that changes with frequency**, a small phase error ``e(y)`` moves reading
  ``k`` by ``e(y_k) A_k R x_k`` (``R`` the quarter turn about the cone axis): a map of degree
  ``J`` absorbs it where ``e(y) A(y)`` is of degree ``J`` or less (``e`` of degree ``J - deg
  A``), and nearly so where ``A``'s coefficients of the highest degrees are small. Such an
  error is invisible here, and phase coefficients of those degrees are determined by the
  map's variation alone (with large standard errors).
* A **constant detector offset without a power monitor** is absorbed exactly by the map's
  cone-axis column (``sqrt 2`` for every reading) and leaves no residual. With a monitor
  that shows the power varying, the caller fits offsets ``d`` with standard errors; when no
  dark readings were given, a ``d`` beyond ``MIN_OFFSET_Z`` standard errors warns
  ``detector_offset``.

Checks of the map and the sweep
-------------------------------
* ``partial_span``: the effective span ``span_fsr = (ptp(t) + step) / 2 pi`` (``step`` the
  mean phase step between distinct frequencies, so ``N`` readings evenly over one FSR give
  1) below ``1 - SPAN_TOLERANCE``: the map is learned from part of the fringe and readings
  outside the span are extrapolated.
* ``unequal_noise``: the model-free port noises differ by more than ``UNEQUAL_NOISE_RATIO``
  and significantly (``s_max^2 / s_min^2`` against F(nu, nu), p-value times the
  ``n (n - 1)`` ordered pairs below ``TEST_P_VALUE``), and the retrieval does not weight
  the ports by their noise.
* ``ill_conditioned``: for the pseudo-inverse retrieval, the phase variance it gives at
  equal port noise, averaged over the sweep (each reading with its own map), exceeds the
  Cramer-Rao bound's by more than ``MAX_PINV_VARIANCE_RATIO`` (1.2^2); the cone maximum
  likelihood reaches the bound.

A sweep whose residual is at the rounding level of the readings (a noiseless simulation)
fits exactly: the residual and noise tests are not made.

The statistics (model-free noise, nested cosine tests) are computed by
:mod:`wavemeter.calibration.checks.residual_tests`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import linalg, special, stats

from ...exceptions import CalibrationWarning, InputError
from ...model.cone import cone_vectors
from ...model.retrieval import stacked_pinv
from .residual_tests import (
    RANK_TOLERANCE,
    TEST_P_VALUE,
    Projector,
    ResidualTest,
    ResidualTests,
    model_free_noise,
    orthonormal_columns,
    row_blocks,
)

__all__ = [
    "CAUSES",
    "detector_noise_w",
    "phase_noise_variance_w2",
    "DISPERSION_MIN_SPAN_FSR",
    "EXPLAINED_FRACTION",
    "MAX_COUPLED_ORDER",
    "MAX_PINV_VARIANCE_RATIO",
    "MIN_MODEL_FREE_READINGS",
    "MIN_OFFSET_Z",
    "MIN_READINGS_PER_FSR",
    "NOISY_BASIS_TOLERANCE",
    "MisfitReport",
    "POOLED_NOISE_P_VALUE",
    "SMOOTH_ORDERS",
    "SPAN_TOLERANCE",
    "TEST_P_VALUE",
    "TIE_FRACTION",
    "TIE_Z",
    "UNEQUAL_NOISE_RATIO",
    "misfit_report",
]

#: the causes a :class:`~wavemeter.exceptions.CalibrationWarning` of this module names
CAUSES = (
    "power_drift",
    "detector_offset",
    "phase_drift",
    "dispersion",
    "partial_span",
    "unequal_noise",
    "ill_conditioned",
    "other_misfit",
)
#: numbers of discrete cosines of the row index tested as "smooth in time"
SMOOTH_ORDERS = (3, 6, 12, 24, 48, 96, 192)
#: with phase noise in the model, a test column is left out when less than this fraction
#: of its norm lies outside the fitted columns (which then carry that noise)
NOISY_BASIS_TOLERANCE = 0.9
#: the largest of them for a drift of power or phase (their columns couple the ports)
MAX_COUPLED_ORDER = 96
#: fewest readings, and fewest readings per fringe period, for the model-free noise
MIN_MODEL_FREE_READINGS = 16
MIN_READINGS_PER_FSR = 16
#: share of the smooth structure a cause must explain to be named
EXPLAINED_FRACTION = 0.5
#: causes explaining within this fraction, and TIE_Z noise standard deviations, of the
#: best are a tie (named phase, power, other)
TIE_FRACTION = 0.02
TIE_Z = 2.0
#: dispersion is told from a phase drift only on sweeps longer than this (FSRs)
DISPERSION_MIN_SPAN_FSR = 1.5
#: significance (standard errors) of a fitted offset that warns
MIN_OFFSET_Z = 5.0
#: a sweep shorter than 1 - SPAN_TOLERANCE FSR is partial
SPAN_TOLERANCE = 0.05
#: port noises differing by more than this factor (and significantly) are unequal
UNEQUAL_NOISE_RATIO = 1.3
#: the tests whiten with one pooled noise unless the ports' differ at this significance
POOLED_NOISE_P_VALUE = 0.01
#: pseudo-inverse phase variance over the Cramer-Rao bound's that is ill-conditioned
MAX_PINV_VARIANCE_RATIO = 1.2**2
#: residual below this many float64 epsilons of the readings: an exact (noiseless) fit
ROUNDOFF_EPSILONS = 1e4
HARMONICS = (2, 3)

#: the first remedy of a misfit no cause explains on a sweep of several FSRs
WIDE_SWEEP_REMEDY = (
    "over a sweep of several FSRs the couplers and photodiodes change with the wavelength: "
    "calibrate the band with WidebandCalibrator (a map smooth in frequency), or per FSR "
    "(CalibrationSet)"
)

REMEDIES = {
    "power_drift": (
        "record the source power with a power monitor during the sweep (power_monitor_w), "
        "or stabilise the source"
    ),
    "detector_offset": (
        "pass dark readings taken with the source off (dark_w), so that the offsets are "
        "subtracted rather than fitted"
    ),
    "phase_drift": (
        "stabilise the chip temperature, or log it with every reading for a thermal "
        "calibration; a linear temperature ramp over a one-way sweep cannot be seen here "
        "(it is absorbed into the FSR)"
    ),
    "dispersion": (
        "calibrate the band with WidebandCalibrator (a phase polynomial and a map smooth in "
        "frequency, orders chosen by cross-validation), or per FSR (CalibrationSet)"
    ),
    "partial_span": "calibrate over at least one FSR",
    "unequal_noise": 'use the maximum-likelihood retrieval (retrieval="ml"), which weights '
    "the ports by their noise",
    "ill_conditioned": 'use the maximum-likelihood retrieval (retrieval="ml"), which reaches '
    "the Cramer-Rao bound for any map",
    "other_misfit": (
        "inspect the residual in the calibration diagnostics; check the detectors for "
        "nonlinearity or saturation and the setup for stray light, back-reflections or a "
        "wandering background"
    ),
}


@dataclass(frozen=True)
class MisfitReport:
    """What the calibration residual shows, per port and for the sweep.

    Attributes
    ----------
    residual_rms_w : ndarray, shape (n,)
        Residual RMS per port (W), corrected for the fitted values.
    noise_std_w : ndarray, shape (n,)
        Noise per port (W): model-free (second differences) or, for a short or coarse
        sweep, the residual's (see ``noise_method``).
    noise_dof : float
        Degrees of freedom of each port's ``noise_std_w``.
    noise_method : {"second_difference", "residual"}
        How ``noise_std_w`` was estimated.
    noise_ratio : ndarray, shape (n,)
        ``residual_rms_w / noise_std_w``: 1 on average for in-model data.
    lag1_autocorrelation : ndarray, shape (n,)
        Lag-1 autocorrelation of each port's residual along the rows.
    harmonic_power : ndarray, shape (n,)
        Residual energy in harmonics 2 and 3 of the fringe phase over white noise's: 1 on
        average for in-model data.
    span_fsr : float
        Effective span of the sweep in FSRs (1 for a sweep of one FSR).
    condition_number : float
        2-norm condition number of the map (the largest over the readings' maps).
    pinv_variance_ratio : float
        Phase variance of the pseudo-inverse retrieval over the Cramer-Rao bound's, averaged
        over the sweep at equal port noise (1 for an ideal map).
    p_values : dict of str to float or None
        p-value of each test (``"power"``, ``"phase"``, ``"dispersion"``, ``"harmonics"``,
        ``"smooth"`` over their scales, Bonferroni-corrected; ``"power_scatter"``,
        ``"phase_scatter"``, ``"unequal_noise"``); None where the test was not made. A test
        fails below ``TEST_P_VALUE``.
    power_error_rms : float
        RMS over the readings of the relative source-power error, smooth in time, that
        remains in the residual (what the fit did not absorb of a drift).
    phase_error_rms_rad : float
        The same for a phase error (rad).
    offset_w, offset_std_w : ndarray, shape (n,), or None
        Fitted per-port offsets and their standard errors (W), when the caller fitted them.
    warnings : tuple of CalibrationWarning
        One per failed check, the most important first; ``.cause`` is one of ``CAUSES``.
    """

    residual_rms_w: np.ndarray
    noise_std_w: np.ndarray
    noise_dof: float
    noise_method: str
    noise_ratio: np.ndarray
    lag1_autocorrelation: np.ndarray
    harmonic_power: np.ndarray
    span_fsr: float
    condition_number: float
    pinv_variance_ratio: float
    p_values: dict
    power_error_rms: float
    phase_error_rms_rad: float
    offset_w: np.ndarray | None
    offset_std_w: np.ndarray | None
    warnings: tuple[CalibrationWarning, ...]

    @property
    def misfit(self) -> bool:
        """True when any check failed (``warnings`` is not empty)."""
        return bool(self.warnings)

    def misfit_noise(self) -> tuple[np.ndarray, float] | None:
        """The model-free noise per port (W) and its degrees of freedom, to weight and state
        uncertainties with, when a check failed (a misfit is then reported by its warning,
        not counted as noise); None when none failed or the estimate is not usable."""
        model_free = np.asarray(self.noise_std_w, dtype=float)
        if self.misfit and np.all(np.isfinite(model_free) & (model_free > 0)):
            return model_free, float(self.noise_dof)
        return None

    @property
    def causes(self) -> tuple[str, ...]:
        """The causes of ``warnings``, in order."""
        return tuple(note.cause for note in self.warnings)

    def to_dict(self) -> dict:
        """JSON-ready fields: floats (None where not finite), lists of floats, and the
        warnings as ``{"cause", "message", "remedy"}`` dicts."""

        def plain(value):
            if isinstance(value, np.ndarray):
                return [float(item) for item in value]
            # a singular map has no finite condition number: None keeps the file strict JSON
            return None if value is None or not np.isfinite(value) else float(value)

        return {
            "residual_rms_w": plain(self.residual_rms_w),
            "noise_std_w": plain(self.noise_std_w),
            "noise_dof": plain(self.noise_dof),
            "noise_method": self.noise_method,
            "noise_ratio": plain(self.noise_ratio),
            "lag1_autocorrelation": plain(self.lag1_autocorrelation),
            "harmonic_power": plain(self.harmonic_power),
            "span_fsr": plain(self.span_fsr),
            "condition_number": plain(self.condition_number),
            "pinv_variance_ratio": plain(self.pinv_variance_ratio),
            "p_values": {name: plain(value) for name, value in self.p_values.items()},
            "power_error_rms": plain(self.power_error_rms),
            "phase_error_rms_rad": plain(self.phase_error_rms_rad),
            "offset_w": plain(self.offset_w),
            "offset_std_w": plain(self.offset_std_w),
            "misfit": self.misfit,
            "warnings": [note.record() for note in self.warnings],
        }


# ---------------------------------------------------------------------- inputs
def _vector(name: str, value, size: int) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise InputError(
            f"{name} must be {size} finite numbers, got shape {array.shape}", parameter=name
        )
    return array


def _check_inputs(powers, frequency_hz, center_hz, delay_s, map_, scale, offset_w, offset_std_w):
    readings = np.asarray(powers, dtype=float)
    if readings.ndim != 2 or readings.shape[0] < 4 or readings.shape[1] < 3:
        raise InputError(
            f"powers must have shape (N, n) with N >= 4 readings and n >= 3 ports, got "
            f"{readings.shape}",
            parameter="powers",
        )
    if not np.all(np.isfinite(readings)):
        raise InputError("powers must be finite numbers (W)", parameter="powers")
    samples, ports = readings.shape
    frequency = _vector("frequency_hz", frequency_hz, samples)
    for name, value in (("center_hz", center_hz), ("delay_s", delay_s)):
        if not np.isfinite(value):
            raise InputError(f"{name} must be a finite number, got {value!r}", parameter=name)
    if not delay_s > 0:
        raise InputError(f"delay_s must be > 0 (s), got {delay_s!r}", parameter="delay_s")
    matrix = np.asarray(map_, dtype=float)
    if matrix.shape not in ((ports, 3), (samples, ports, 3)) or not np.all(np.isfinite(matrix)):
        raise InputError(
            f"map_ must be {ports} x 3 finite numbers (one map) or {samples} x {ports} x 3 (the "
            f"map of each reading), got shape {matrix.shape}",
            parameter="map_",
        )
    power = None if scale is None else _vector("scale", scale, samples)
    if (offset_w is None) != (offset_std_w is None):
        raise InputError(
            "offset_w and offset_std_w must be given together (fitted offsets with their "
            "standard errors) or both be None",
            parameter="offset_std_w",
        )
    offsets = None if offset_w is None else _vector("offset_w", offset_w, ports)
    offset_std = None if offset_std_w is None else _vector("offset_std_w", offset_std_w, ports)
    if offset_std is not None and np.any(offset_std < 0):
        raise InputError("offset_std_w must be >= 0 (W)", parameter="offset_std_w")
    return readings, frequency, float(center_hz), float(delay_s), matrix, power, offsets, offset_std


def _fitted_columns(design, samples: int) -> np.ndarray:
    """The columns (N, k) each port's map row was fitted on, checked."""
    columns = np.asarray(design, dtype=float)
    if columns.ndim != 2 or columns.shape[0] != samples or not 1 <= columns.shape[1] < samples:
        raise InputError(
            f"design must have shape (N, k) with N = {samples} readings and 1 <= k < N fitted "
            f"columns, got {columns.shape}",
            parameter="design",
        )
    if not np.all(np.isfinite(columns)):
        raise InputError("design must be finite numbers", parameter="design")
    return columns


def _phase_derivatives(derivatives, samples: int) -> np.ndarray:
    """The derivatives (q, N) of the model phase by the shared nonlinear parameters, checked."""
    rows = np.asarray(derivatives, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != samples or rows.shape[0] < 1:
        raise InputError(
            f"phase_derivatives must have shape (q, N) with q >= 1 parameters and N = "
            f"{samples} readings, got {rows.shape}",
            parameter="phase_derivatives",
        )
    if not np.all(np.isfinite(rows)):
        raise InputError("phase_derivatives must be finite numbers", parameter="phase_derivatives")
    return rows


def _images(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``A x_k`` (N, n) of vectors (N, 3) through one map (n, 3) or each reading's (N, n, 3)."""
    if matrix.ndim == 2:
        return vectors @ matrix.T
    return np.einsum("kij,kj->ki", matrix, vectors)


def _tangents(matrix: np.ndarray, unit: np.ndarray, power) -> np.ndarray:
    """Fringe tangents ``m_k A [-sin t_k, cos t_k, 0]`` (N, n) from the unit objects (N, 3)
    ``[cos t_k, sin t_k, sqrt 2]`` and the relative power ``m_k`` (None: 1)."""
    if matrix.ndim == 2:
        tangent = unit[:, :2] @ np.array([matrix[:, 1], -matrix[:, 0]])
    else:
        tangent = matrix[:, :, 1] * unit[:, :1]
        tangent -= matrix[:, :, 0] * unit[:, 1:2]
    if power is not None:
        tangent *= power[:, None]
    return tangent


def _harmonic_columns(unit: np.ndarray, power, rows: slice) -> np.ndarray:
    """``m_k cos h t_k``, ``m_k sin h t_k`` for each order ``h`` of ``HARMONICS`` (L, 2 H) of
    the readings ``rows``, by angle addition from the unit objects' ``cos t_k``, ``sin t_k``."""
    unit = unit[rows]
    power = None if power is None else power[rows]
    cos, sin = unit[:, 0], unit[:, 1]
    columns = np.empty((unit.shape[0], 2 * len(HARMONICS)))
    harmonic_cos, harmonic_sin = cos, sin
    for order in range(2, max(HARMONICS) + 1):
        harmonic_cos, harmonic_sin = (
            harmonic_cos * cos - harmonic_sin * sin,
            harmonic_sin * cos + harmonic_cos * sin,
        )
        if order in HARMONICS:
            index = 2 * HARMONICS.index(order)
            columns[:, index], columns[:, index + 1] = harmonic_cos, harmonic_sin
    if power is not None:
        columns *= power[:, None]
    return columns


def _span_fsr(phase_rad: np.ndarray) -> float:
    steps = np.diff(phase_rad)
    if np.all(steps >= 0.0) or np.all(steps <= 0.0):
        # a one-way sweep: its distinct phases without sorting
        distinct = 1 + np.count_nonzero(steps)
        extent = abs(float(phase_rad[-1] - phase_rad[0]))
    else:
        values = np.unique(phase_rad)
        distinct, extent = values.size, float(values[-1] - values[0])
    if distinct < 2:
        return 0.0
    return (extent + extent / (distinct - 1)) / (2.0 * np.pi)


def _lag1(residual: np.ndarray, energy: np.ndarray) -> np.ndarray:
    """Lag-1 autocorrelation per port of the residual (N, n); ``energy`` (n,) its sums of
    squares."""
    lagged = np.einsum("ij,ij->j", residual[1:], residual[:-1])
    return np.divide(lagged, energy, out=np.zeros_like(energy), where=energy > 0)


def _pinv_variance_ratio(matrix, image, tangent) -> float:
    """Mean pseudo-inverse phase variance over the mean Cramer-Rao variance, unit noise, for
    one map (n, 3) or each reading's (N, n, 3), at the readings' images ``a_P`` and fringe
    tangents ``a_t`` (N, n) (their inverses from the normal equations, several times
    faster than SVDs: a stack with a map of rank < 3 raises InputError).

    With ``x = A+ a_P`` and ``A+`` rows ``g_1``, ``g_2``, the arctangent's gradient is
    ``(x_1 g_2 - x_2 g_1) / r^2`` (:func:`~wavemeter.model.uncertainty.pinv_phase_gradient`,
    ``r^2 = x_1^2 + x_2^2``), of squared norm ``(x_1^2 |g_2|^2 - 2 x_1 x_2 g_1 g_2 + x_2^2
    |g_1|^2) / r^4``; the bound's information is ``|a_t|^2 - (a_t a_P)^2 / |a_P|^2``
    (:func:`~wavemeter.model.limits.crlb_frequency_std`, the power a nuisance)."""
    inverse = linalg.pinv(matrix) if matrix.ndim == 2 else stacked_pinv(matrix)
    first, second = inverse[..., 0, :], inverse[..., 1, :]
    pinv_variance = bound_variance = 0.0
    for rows in row_blocks(image.shape[0]):
        images, tangents = image[rows], tangent[rows]
        # ports x readings: the sums over the ports run down contiguous readings
        image_rows, tangent_rows = np.ascontiguousarray(images.T), np.ascontiguousarray(tangents.T)
        if matrix.ndim == 2:
            x_1, x_2 = images @ first, images @ second
            gram = first @ first, first @ second, second @ second
        else:
            rows_1, rows_2 = first[rows], second[rows]
            x_1, x_2 = np.einsum("ij,ij->i", images, rows_1), np.einsum("ij,ij->i", images, rows_2)
            gram = [np.einsum("ij,ij->i", *pair) for pair in ((rows_1, rows_1), (rows_1, rows_2))]
            gram.append(np.einsum("ij,ij->i", rows_2, rows_2))
        radius2 = x_1**2 + x_2**2
        variance = x_1**2 * gram[2] - 2.0 * x_1 * x_2 * gram[1] + x_2**2 * gram[0]
        pinv_variance += float(np.sum(variance / radius2**2))
        along = np.einsum("ij,ij->j", image_rows, tangent_rows)
        information = np.einsum("ij,ij->j", tangent_rows, tangent_rows) - along**2 / np.einsum(
            "ij,ij->j", image_rows, image_rows
        )
        bound_variance += float(np.sum(1.0 / information))
    return pinv_variance / bound_variance


@dataclass(frozen=True)
class _Scatter:
    """Residual energy along each reading's power and phase directions against the rest."""

    power_p: float
    phase_p: float
    power_excess: float  # statistic minus degrees of freedom (whitened energy)
    phase_excess: float
    power_rms: float  # relative source-power noise, RMS over the readings
    phase_rms_rad: float

    @property
    def failed(self) -> bool:
        return min(self.power_p, self.phase_p) < TEST_P_VALUE


def _scatter(residual, image, tangent, dof: float, pooled: bool, phase_noise_rad) -> _Scatter:
    """Tests 6 and 7 (module docstring) on the residual (N, n) and the directions
    ``a_P`` (``image``) and ``a_t`` (``tangent``) of every reading (N, n); ``pooled``: one
    noise level for every port; ``phase_noise_rad`` (N,) the phase scatter the model
    expects besides the detector noise (0 for none).

    Per reading, with ``r``, ``a``, ``t`` whitened by the level: the component along ``a``
    is ``r a / |a|``, the one along the part of ``t`` orthogonal to ``a`` (of squared norm
    ``|t|^2 - (a t)^2 / |a|^2``) is ``(r t - (a t)(r a) / |a|^2) / |t - ...|``; these
    come from row products, block by block (each block whitened into ports x readings, the
    sums over the ports then run down contiguous readings)."""
    samples, ports = residual.shape
    level = np.einsum("ij,ij->j", residual, residual) / dof
    level = np.sqrt(np.full(ports, level.mean()) if pooled else level)
    inverse = (1.0 / np.maximum(level, np.finfo(float).tiny))[:, None]
    along_norm, across_norm, power, phase = np.empty((4, samples))
    energy = 0.0
    for rows in row_blocks(samples):
        whitened, along, across = np.empty((3, ports, rows.stop - rows.start))
        for values, out in zip((residual, image, tangent), (whitened, along, across), strict=True):
            np.multiply(values[rows].T, inverse, out=out)
        squares = np.einsum("ij,ij->j", along, along)
        cross = np.einsum("ij,ij->j", along, across)
        on_along = np.einsum("ij,ij->j", whitened, along)
        along_norm[rows] = np.sqrt(squares)
        power[rows] = on_along / along_norm[rows]
        across_norm[rows] = np.sqrt(np.einsum("ij,ij->j", across, across) - cross**2 / squares)
        on_across = np.einsum("ij,ij->j", whitened, across) - cross * on_along / squares
        phase[rows] = on_across / across_norm[rows]
        energy += np.einsum("ij,ij->", whitened, whitened)
    rest = float(energy - power @ power - phase @ phase)
    rest_dof = dof * (ports - 2)
    unit = max(rest / rest_dof, np.finfo(float).tiny)  # whitened variance per direction

    def test(component, norm, expected_rad=0.0):
        statistic = excess = 0.0
        for rows in row_blocks(samples):
            expected = expected_rad if np.ndim(expected_rad) == 0 else expected_rad[rows]
            variance = unit + (norm[rows] * expected) ** 2
            squares = component[rows] ** 2
            statistic += float(np.sum(squares / variance))
            excess += float(np.sum((squares - variance) / norm[rows] ** 2))
        return (
            float(stats.f.sf(statistic / dof, dof, rest_dof)),
            statistic - dof,
            float(np.sqrt(max(excess / samples, 0.0))),
        )

    power_p, power_excess, power_rms = test(power, along_norm)
    phase_p, phase_excess, phase_rms = test(phase, across_norm, phase_noise_rad)
    return _Scatter(power_p, phase_p, power_excess, phase_excess, power_rms, phase_rms)


@dataclass(frozen=True)
class _Structure:
    """The residual tests and the drifts they estimate."""

    power: ResidualTest
    power_error: np.ndarray  # relative source-power error (N,)
    phase: ResidualTest
    phase_error_rad: np.ndarray  # (N,)
    dispersion: ResidualTest | None
    dispersion_amplitude: Callable[[], np.ndarray] | None  # the dispersion's (N,), rad
    harmonics: ResidualTest
    smooth: ResidualTest
    scatter: _Scatter

    @property
    def dispersion_rad(self) -> np.ndarray:
        """The phase error even in ``f - f0`` left in the residual (N,), rad (computed when
        a warning states it)."""
        return self.dispersion_amplitude()

    def p_values(self) -> dict:
        return {
            "power": self.power.p_value,
            "phase": self.phase.p_value,
            "dispersion": None if self.dispersion is None else self.dispersion.p_value,
            "harmonics": self.harmonics.p_value,
            "smooth": self.smooth.p_value,
            "power_scatter": self.scatter.power_p,
            "phase_scatter": self.scatter.phase_p,
        }

    @property
    def smooth_failed(self) -> bool:
        """Whether a test of structure along the rows (1-5) failed."""
        tests = (self.power, self.phase, self.dispersion, self.harmonics, self.smooth)
        return any(test is not None and test.failed for test in tests)

    @property
    def failed(self) -> bool:
        return self.smooth_failed or self.scatter.failed


def _orders(samples: int, largest: int) -> tuple[int, ...]:
    """Scales of SMOOTH_ORDERS up to ``largest`` and a quarter of the readings."""
    top = max(min(samples // 4, largest), 1)
    return tuple(k for k in SMOOTH_ORDERS if k <= top) or (top,)


def _structure(tests, harmonic_test, image, tangent, frequency, center, span, scatter):
    """Tests 1-3 and 5 on the whitened residual (``image`` and ``tangent`` whitened too)."""
    samples = frequency.size
    orders = _orders(samples, MAX_COUPLED_ORDER)
    background = _orders(samples, SMOOTH_ORDERS[-1])
    # first: its columns are the largest set, while the fewest other arrays are held
    smooth, _ = tests.per_port(tests.cosines(background[-1]), background)
    image_weight, tangent_weight = (np.einsum("ij,ij->i", a, a) for a in (image, tangent))
    power, power_error = tests.coupled(
        tests.cosines(orders[-1], image, image_weight), image, orders, image_weight
    )
    phase, phase_error = tests.coupled(
        tests.cosines(orders[-1], tangent, tangent_weight), tangent, orders, tangent_weight
    )
    dispersion = dispersion_amplitude = None
    if span > DISPERSION_MIN_SPAN_FSR:
        largest = max(float(frequency.max() - center), float(center - frequency.min()))
        scale = max(largest, np.finfo(float).tiny)

        def even(rows):
            relative = (frequency[rows] - center) / scale
            return np.column_stack([special.eval_legendre(degree, relative) for degree in (2, 4)])

        dispersion, dispersion_amplitude = tests.coupled_test(
            tests.columns(even, tangent), tangent, (2,), tangent_weight
        )
    return _Structure(
        power=power,
        power_error=power_error,
        phase=phase,
        phase_error_rad=phase_error,
        dispersion=dispersion,
        dispersion_amplitude=dispersion_amplitude,
        harmonics=harmonic_test,
        smooth=smooth,
        scatter=scatter,
    )


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def _excess(test: ResidualTest | None) -> float:
    """Excess energy of a failed test, 0 for one that passed or was not made."""
    return test.excess if test is not None and test.failed else 0.0


def _cause(structure: _Structure) -> str:
    """The alternative that explains the residual best (module docstring)."""
    if not structure.smooth_failed:
        scatter = structure.scatter
        return "power_drift" if scatter.power_excess >= scatter.phase_excess else "phase_drift"
    phase, dispersion = _excess(structure.phase), _excess(structure.dispersion)
    explained = {  # in the order ties are named
        "phase_drift": max(phase, dispersion),
        "power_drift": _excess(structure.power),
        "other_misfit": structure.harmonics.excess,
    }
    best = max(explained.values())
    if best <= 0.0 or best < EXPLAINED_FRACTION * structure.smooth.excess:
        return "other_misfit"
    cause = next(name for name, value in explained.items() if _ties(value, best))
    if cause == "phase_drift" and dispersion > 0.0 and _ties(dispersion, phase):
        return "dispersion"
    return cause


def _ties(value: float, best: float) -> bool:
    """Whether ``value`` explains as much as ``best`` within the tolerance of a tie."""
    return best - value <= TIE_FRACTION * best + TIE_Z * np.sqrt(max(best, 0.0))


def _port_list(names, mask) -> str:
    return ", ".join(name for name, flag in zip(names, mask, strict=True) if flag)


def _warning(cause: str, seen: str, remedy: str | None = None) -> CalibrationWarning:
    remedy = REMEDIES[cause] if remedy is None else remedy
    return CalibrationWarning(f"{seen}; {remedy}", cause=cause, remedy=remedy)


def _power_clause(error: np.ndarray) -> str:
    return (
        f"a relative source-power error of {100 * _rms(error):.3g} % RMS "
        f"({100 * np.abs(error).max():.3g} % peak)"
    )


def _phase_clause(error: np.ndarray, delay_s: float) -> str:
    per_rad_mhz = 1e-6 / (2.0 * np.pi * delay_s)
    return (
        f"a phase error of {_rms(error):.3g} rad RMS ({_rms(error) * per_rad_mhz:.3g} MHz, "
        f"{np.abs(error).max():.3g} rad peak)"
    )


def _misfit_warning(structure, names, ratio, lag1, harmonic_power, span, delay, model_free):
    """The one warning that names the misfit, or None when every residual test passes."""
    if not structure.failed:
        return None
    cause = _cause(structure)
    residual = f"lag-1 autocorrelation of the residual up to {lag1.max():.2f}"
    if model_free:
        high = ratio >= min(ratio.max(), 1.0 + 0.5 * (ratio.max() - 1.0))
        residual = (
            f"residual up to {ratio.max():.3g}x the model-free noise "
            f"({_port_list(names, high)}), {residual}"
        )
    power, phase, scatter = structure.power, structure.phase, structure.scatter
    # a drift of power and one of phase that leave the same residual (a sweep of ~1 FSR)
    tie = _ties(power.excess, phase.excess)
    if not structure.smooth_failed:
        direction, error = (
            ("power", f"{100 * scatter.power_rms:.3g} % RMS of relative source-power noise")
            if cause == "power_drift"
            else ("phase", f"{scatter.phase_rms_rad:.3g} rad RMS of phase noise")
        )
        seen = (
            f"the readings scatter along the fringe's {direction} direction more than across "
            f"it: {error} from reading to reading, beyond the detector noise (p-value "
            f"{min(scatter.power_p, scatter.phase_p):.2g}; {residual})"
        )
    elif cause == "power_drift":
        seen = (
            f"the source power drifts along the sweep: {_power_clause(structure.power_error)} "
            f"remains in the residual after the fit ({residual}); without a power monitor "
            "part of a drift is absorbed into the map and the FSR"
        )
    elif cause == "phase_drift":
        seen = (
            f"the fringe phase drifts along the sweep: "
            f"{_phase_clause(structure.phase_error_rad, delay)} that is not a polynomial "
            f"in frequency remains in the residual ({residual})"
        )
        if tie and power.failed:
            seen += (
                f"; on this sweep {_power_clause(structure.power_error)} would leave the "
                "same residual: if the source power was not monitored, suspect it too"
            )
    elif cause == "dispersion":
        seen = (
            f"the fringe phase is not linear in frequency over the {span:.3g} FSR sweep: "
            f"{_phase_clause(structure.dispersion_rad, delay)} even in f - f0 remains in "
            f"the residual, as group-delay dispersion gives ({residual}); the FSR changes "
            "across the sweep"
        )
    else:
        seen = (
            f"the residual departs from white noise in a way no listed cause explains "
            f"({residual}; harmonics 2-3 of the fringe phase up to "
            f"{harmonic_power.max():.3g}x their noise level)"
        )
        if span > DISPERSION_MIN_SPAN_FSR:
            # over many FSRs the couplers and photodiodes change with the wavelength
            return _warning(cause, seen, f"{WIDE_SWEEP_REMEDY}; else {REMEDIES[cause]}")
    return _warning(cause, seen)


def _offset_warning(offsets, offset_std, readings, names):
    """``detector_offset`` when a fitted offset exceeds ``MIN_OFFSET_Z`` standard errors."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(offsets) / offset_std
    z = np.where(offset_std > 0, z, np.where(offsets != 0, np.inf, 0.0))
    significant = z > MIN_OFFSET_Z
    if not significant.any():
        return None
    mean = np.abs(readings.mean(axis=0))
    parts = [
        f"{names[j]} {offsets[j]:+.3g} W ({100 * offsets[j] / mean[j]:+.3g} % of its mean "
        f"reading, {z[j]:.3g} standard errors)"
        for j in np.flatnonzero(significant)
    ]
    return _warning(
        "detector_offset",
        f"the readings carry offsets independent of the source power: {'; '.join(parts)}; "
        "they were fitted from the power variation the monitor shows",
    )


def _unequal_noise(noise, dof, names):
    """``unequal_noise`` warning (or None) and the test's p-value."""
    ports = noise.size
    factor = float(noise.max() / noise.min())
    # two noise variances on nu degrees of freedom each: their ratio is F(nu, nu)
    p_value = float(min(1.0, ports * (ports - 1) * stats.f.sf(factor**2, dof, dof)))
    if factor <= UNEQUAL_NOISE_RATIO or p_value >= TEST_P_VALUE:
        return None, p_value
    levels = ", ".join(f"{name} {level:.3g} W" for name, level in zip(names, noise, strict=True))
    return (
        _warning(
            "unequal_noise",
            f"the ports' noise differs by a factor {factor:.3g} ({levels}; p-value "
            f"{p_value:.2g}): the pseudo-inverse retrieval weights them equally",
        ),
        p_value,
    )


def phase_noise_variance_w2(tangent_w, phase_noise_std_rad) -> np.ndarray:
    """Mean variance (W^2, per port) a phase scatter ``s_k`` (rad) adds to readings whose
    fringe tangent is ``P A u'(t_k)`` (``tangent_w``, (N, n), W/rad)."""
    return np.mean((tangent_w * np.asarray(phase_noise_std_rad)[..., None]) ** 2, axis=0)


def detector_noise_w(noise_w, extra_variance_w2) -> np.ndarray:
    """Detector noise (W, per port): a noise estimate less an expected extra variance,
    kept at least a tenth of the estimate."""
    noise = np.asarray(noise_w, dtype=float)
    return np.sqrt(np.maximum(noise**2 - extra_variance_w2, 0.01 * noise**2))


# ---------------------------------------------------------------------- the report
def misfit_report(
    powers,
    frequency_hz,
    center_hz: float,
    delay_s: float,
    map_,
    *,
    scale=None,
    offset_w=None,
    offset_std_w=None,
    dark_given: bool = False,
    weighted_retrieval: bool = False,
    phase_rad=None,
    phase_noise_std_rad=None,
    design=None,
    phase_derivatives=None,
) -> MisfitReport:
    """Test a fitted calibration sweep against the model and name what departs from it.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Calibration readings (W), dark-subtracted, in acquisition order.
    frequency_hz : array_like, shape (N,)
        Known frequency of each reading (Hz).
    center_hz : float
        Phase origin ``f0`` (Hz).
    delay_s : float
        Fitted delay ``tau`` (s); the FSR is ``1 / delay_s``.
    map_ : array_like, shape (n, 3) or (N, n, 3)
        Fitted map ``A`` (W), or the map of each reading (``A(f_k)``, a map that changes with
        frequency): the images, fringe tangents, residual and scatter tests use each
        reading's own; the condition number reported is the largest over the readings.
    scale : None or array_like, shape (N,)
        Relative monitored source power per reading (mean 1), or None.
    offset_w, offset_std_w : None or array_like, shape (n,)
        Fitted per-port offsets (W, subtracted from the readings) and their standard
        errors (W); both or neither.
    dark_given : bool
        Dark readings were subtracted (fitted offsets then do not warn).
    weighted_retrieval : bool
        The retrieval weights the ports by their noise (``"ml"``): unequal noise and an
        ill-conditioned map cost it nothing, so neither warns.
    phase_rad : None or array_like, shape (N,)
        The model phase of each reading (rad) when it is not ``2 pi (f - f0) tau`` (the
        thermal model's, which moves with temperature); the delay's direction stays
        ``2 pi (f - f0)`` along the fringe.
    phase_noise_std_rad : None or array_like, shape (N,)
        Phase scatter (rad) the model expects of each reading besides the detector noise
        (a chip temperature known to ``s_T``: ``s_T`` times the thermal rate). The phase
        scatter test looks for scatter beyond it, and the noise reported (and tested for
        unequal ports) is the detector's: the model-free estimate less its share.
    design : None or array_like, shape (N, k)
        The columns every port's map row was fitted on, by linear least squares (the residual
        is orthogonal to them), with a column of ones when offsets were fitted. None: the cone
        objects ``m_k [cos t_k, sin t_k, sqrt 2]`` (and ones with ``offset_w``).
    phase_derivatives : None or array_like, shape (q, N)
        Derivatives ``dt_k / d theta_i`` (rad per unit) of the model phase by the ``q``
        nonlinear parameters shared by the ports (a phase polynomial's coefficients). None:
        the delay alone, ``2 pi (f - f0)``.

    Returns
    -------
    MisfitReport

    Raises
    ------
    InputError
        For arrays of the wrong shape or with non-finite values.
    """
    readings, frequency, center, delay, matrix, power, offsets, offset_std = _check_inputs(
        powers, frequency_hz, center_hz, delay_s, map_, scale, offset_w, offset_std_w
    )
    samples, ports = readings.shape
    names = [f"p{k + 1}" for k in range(ports)]
    # 2 pi (f - f0): the phase's derivative in the delay, and t = 2 pi (f - f0) tau
    frequency_rad = 2.0 * np.pi * (frequency - center)
    phase = frequency_rad * delay if phase_rad is None else _vector("phase_rad", phase_rad, samples)
    derivatives = (
        frequency_rad[None]
        if phase_derivatives is None
        else _phase_derivatives(phase_derivatives, samples)
    )
    unit = cone_vectors(phase)
    objects = unit if power is None else unit * power[:, None]
    if design is None:
        design = objects if offsets is None else np.column_stack([objects, np.ones(samples)])
    basis = orthonormal_columns(_fitted_columns(design, samples))
    # (N, ...) arrays are let go as soon as they are used: on long sweeps each one held
    # costs more to map into memory than to compute
    del design
    image = _images(matrix, objects)
    del objects
    residual = np.subtract(readings, image)
    if offsets is not None:
        residual -= offsets

    residual_dof = max(samples - basis.shape[1] - derivatives.shape[0] / ports, 1.0)
    residual_squares = np.einsum("ij,ij->j", residual, residual)
    residual_rms = np.sqrt(residual_squares / residual_dof)
    span = _span_fsr(phase)
    del phase
    dense = samples >= MIN_READINGS_PER_FSR * max(span, 1.0)
    model_free = samples >= MIN_MODEL_FREE_READINGS and dense
    if model_free:
        noise, noise_dof = model_free_noise(residual, basis)
    else:
        noise, noise_dof = residual_rms, residual_dof
    largest = max(float(readings.max()), -float(readings.min()), np.finfo(float).tiny)
    floor = np.finfo(float).eps * largest
    noise = np.maximum(noise, floor)
    ratio = residual_rms / noise
    lag1 = _lag1(residual, residual_squares)
    exact_fit = bool(np.sqrt(residual_squares.sum() / residual.size) <= ROUNDOFF_EPSILONS * floor)

    tangent = _tangents(matrix, unit, power)
    if phase_noise_std_rad is None:
        expected, extra_variance = 0.0, np.zeros(ports)
    else:
        expected = np.abs(_vector("phase_noise_std_rad", phase_noise_std_rad, samples))
        extra_variance = phase_noise_variance_w2(tangent, expected)
    detector = detector_noise_w(noise, extra_variance)
    # a variance less a known share keeps the estimate's absolute error: its degrees of
    # freedom shrink by the square of the share left (Satterthwaite)
    detector_dof = noise_dof * float(np.min(detector / noise)) ** 4
    noise_note, unequal_p = _unequal_noise(detector, detector_dof, names)
    # whitening weights: one noise for all ports unless theirs differ (module docstring)
    pooled = unequal_p >= POOLED_NOISE_P_VALUE
    weight = np.full(ports, np.sqrt(np.mean(noise**2))) if pooled else noise
    scatter = _scatter(residual, image, tangent, residual_dof, pooled, expected)
    variance_ratio = _pinv_variance_ratio(matrix, image, tangent)
    # whitened in place from here on: the tests keep no other copy of these (N, n) arrays
    for values in (residual, image, tangent):
        values /= weight
    # the directions the nonlinear parameters move the images in, d_i,k a_t,k (N, n, q)
    projector = Projector(basis, tangent[:, :, None] * derivatives.T[:, None, :])
    del frequency_rad, derivatives
    # the fitted columns carry the model's phase noise, which the residual carries too: a
    # test column partly inside their span is left with that noise in its direction
    tolerance = NOISY_BASIS_TOLERANCE if np.any(expected > 0) else RANK_TOLERANCE
    tests = ResidualTests(residual, projector, residual_dof, tolerance, out=residual)
    harmonics = tests.columns(partial(_harmonic_columns, unit, power))
    harmonic_test, harmonic_scores = tests.per_port(harmonics, (2 * len(HARMONICS),))
    del unit, harmonics
    # relative to each port's own noise
    harmonic_power = harmonic_scores * (weight / noise) ** 2 / max(harmonic_test.dof // ports, 1)
    structure = _structure(tests, harmonic_test, image, tangent, frequency, center, span, scatter)

    notes = []
    if not exact_fit:
        notes.append(
            _misfit_warning(structure, names, ratio, lag1, harmonic_power, span, delay, model_free)
        )
    if offsets is not None and not dark_given:
        notes.append(_offset_warning(offsets, offset_std, readings, names))
    if span < 1.0 - SPAN_TOLERANCE:
        notes.append(
            _warning(
                "partial_span",
                f"the sweep covers {span:.3g} of the fitted FSR ({1e-9 / delay:.6g} GHz): the "
                "map is learned from part of the fringe and readings outside the span are "
                "extrapolated",
            )
        )
    if not (weighted_retrieval or exact_fit):
        notes.append(noise_note)
    condition = float(np.max(np.linalg.cond(matrix)))
    if variance_ratio > MAX_PINV_VARIANCE_RATIO and not weighted_retrieval:
        notes.append(
            _warning(
                "ill_conditioned",
                f"the pseudo-inverse retrieval's phase variance is {variance_ratio:.3g}x the "
                f"Cramer-Rao bound's over the sweep (allowed {MAX_PINV_VARIANCE_RATIO:.3g}x; "
                f"map condition number {condition:.3g})",
            )
        )
    return MisfitReport(
        residual_rms_w=residual_rms,
        noise_std_w=detector,
        noise_dof=float(noise_dof),
        noise_method="second_difference" if model_free else "residual",
        noise_ratio=ratio,
        lag1_autocorrelation=lag1,
        harmonic_power=harmonic_power,
        span_fsr=span,
        condition_number=condition,
        pinv_variance_ratio=variance_ratio,
        p_values={**structure.p_values(), "unequal_noise": unequal_p},
        power_error_rms=_rms(structure.power_error),
        phase_error_rms_rad=_rms(structure.phase_error_rad),
        offset_w=offsets,
        offset_std_w=offset_std,
        warnings=tuple(note for note in notes if note is not None),
    )
