"""The learned map's cost ``J(tau)`` from binned moments of the sweep: one pass over the data.

:class:`FringeMoments` bins the sweep's frequencies on an absolute grid and keeps, per bin,
the moments of the scaled offsets weighted by the monitored power and the readings; any
chunks, in any order, merge by adding. From them the normal equations of the learned fit,
``J``, its delay derivative, the map and the covariance's products come at any trial delay
in a time that does not grow with the number of readings, exact to rounding for every
delay searched (a Taylor series whose order bounds the truncation below ``2^-53``).
Theory (the moments, the truncation bound, the precision of ``J``): the docs' page on
large sweeps. The search on them: :mod:`~wavemeter.calibration.models.moment_search`.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ...exceptions import InputError, shown
from ...validation import check_frequency, check_monitor, check_positive, reading_array
from .delay_search import EDGE_POINTS, MIN_GRID_POINTS
from .moment_equations import MomentEquationsMixin

__all__ = [
    "FringeMoments",
    "MIN_BIN_SAMPLES",
    "TAYLOR_RADIUS",
    "binning_pays",
    "largest_search_delay_s",
    "taylor_order",
]

#: truncation error allowed per bin, relative to ``sum |w|``: the unit roundoff
TRUNCATION_TOLERANCE = 2.0**-53
#: ``rho = 2 pi tau d`` at the largest delay with the default bin width
TAYLOR_RADIUS = 0.1
#: largest ``rho`` allowed: beyond it the series' terms exceed its sum and lose digits
MAX_TAYLOR_RADIUS = 1.0
#: readings a bin must hold on average for the moments to pay (:func:`binning_pays`)
MIN_BIN_SAMPLES = 4
#: readings binned at a time (bounds the temporaries of :meth:`FringeMoments.add`)
BLOCK_ROWS = 1 << 16


def taylor_order(radius: float) -> int:
    """Smallest ``Q`` with ``radius^(Q+1) / (Q+1)! / (1 - radius / (Q+2)) <= 2^-53``.

    Parameters
    ----------
    radius : float
        Largest ``|k theta h|`` (rad) the series is evaluated at, in (0, 1].

    Returns
    -------
    int
    """
    order, term = 0, radius  # term = radius^(order+1) / (order+1)!
    while term / (1.0 - radius / (order + 2)) > TRUNCATION_TOLERANCE:
        order += 1
        term *= radius / (order + 1)
    return order


def largest_search_delay_s(fsr_hz: float, fsr_tolerance: float) -> float:
    """Largest delay (s) :func:`~wavemeter.calibration.models.delay_search.search_delay` evaluates.

    Its scan spacing is at most ``(u_hi - u_lo) / (MIN_GRID_POINTS - 1)`` in relative delay
    ``u`` whatever the span, and it goes at most ``EDGE_POINTS`` steps beyond ``u_hi``; the
    refinements stay between scan points.
    """
    fsr_hz = check_positive("fsr_hz", fsr_hz)
    fsr_tolerance = check_positive("fsr_tolerance", fsr_tolerance, upper=1.0)
    u_lo, u_hi = 1.0 / (1.0 + fsr_tolerance), 1.0 / (1.0 - fsr_tolerance)
    return (u_hi + EDGE_POINTS * (u_hi - u_lo) / (MIN_GRID_POINTS - 1)) / fsr_hz


def binning_pays(max_delay_s: float, span_hz: float, samples: int) -> bool:
    """Whether bins of the default width for ``max_delay_s`` (s) over ``span_hz`` (Hz) hold
    at least ``MIN_BIN_SAMPLES`` of ``samples`` readings on average.

    Fewer, and a delay evaluated from the moments costs about as much as a direct fit
    (bins of about one reading each), while accumulating them is one more.
    """
    bins = span_hz * 2.0 * np.pi * max_delay_s / TAYLOR_RADIUS + 1.0
    return samples >= MIN_BIN_SAMPLES * bins


def _runs(keys: np.ndarray) -> np.ndarray:
    """Start of each run of equal values in sorted ``keys``."""
    return np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1]]))


class FringeMoments(MomentEquationsMixin):
    """Binned Taylor moments of a calibration sweep: ``J(tau)``, ``J'(tau)`` and the map.

    Accumulate readings with :meth:`add` (any number of chunks, any order) or
    :meth:`merge`; then every delay ``|tau| <= max_delay_s`` is evaluated in ``O(bins)``
    time (see the module text for the derivation and the truncation bound).

    Parameters
    ----------
    max_delay_s : float
        Largest delay (s) to be evaluated, > 0; sets the bin width and the order.
    center_hz : float
        Phase origin ``f0`` (Hz).
    bin_width_hz : float, optional
        Bin width ``d`` (Hz); default ``TAYLOR_RADIUS / (2 pi max_delay_s)``. Accumulations
        with the same ``bin_width_hz`` and ``max_delay_s`` share their grid and merge.

    Attributes
    ----------
    center_hz : float
        The phase origin (Hz). The bins are absolute and the origin enters only when a delay
        is evaluated, so it may be set after the readings are added (the middle of a sweep
        read in chunks is known at its end).
    bin_width_hz : float
    order : int
        Taylor order ``Q`` (:func:`taylor_order` of ``2 pi max_delay_s bin_width_hz``);
        moments are kept to ``Q + 2``.

    Raises
    ------
    InputError
        For a ``max_delay_s`` or ``bin_width_hz`` that is not a finite number > 0, or whose
        ``2 pi max_delay_s bin_width_hz`` exceeds ``MAX_TAYLOR_RADIUS`` (1).
    """

    def __init__(self, max_delay_s: float, center_hz: float, *, bin_width_hz: float | None = None):
        self.max_delay_s = check_positive("max_delay_s", max_delay_s)
        if not (isinstance(center_hz, numbers.Real) and np.isfinite(center_hz)):
            raise InputError(
                f"center_hz must be a finite number (Hz), got {shown(center_hz)}",
                parameter="center_hz",
            )
        self.center_hz = float(center_hz)
        if bin_width_hz is None:
            bin_width_hz = TAYLOR_RADIUS / (2.0 * np.pi * self.max_delay_s)
        self.bin_width_hz = check_positive("bin_width_hz", bin_width_hz)
        radius = 2.0 * np.pi * self.max_delay_s * self.bin_width_hz
        if radius > MAX_TAYLOR_RADIUS:
            raise InputError(
                f"bin_width_hz={self.bin_width_hz:g} Hz is too wide for delays up to "
                f"{self.max_delay_s:g} s (2 pi tau d = {radius:.3g} > {MAX_TAYLOR_RADIUS:g}): "
                "leave it unset or narrow it",
                parameter="bin_width_hz",
            )
        self.order = taylor_order(radius)
        self._ports: int | None = None
        self._scaled: bool | None = None
        self._samples = 0
        self._power2 = 0.0
        self._port_power2 = np.zeros(0)
        self._sum_powers = np.zeros(0)
        self._sum_scale = 0.0
        self._low, self._high = np.inf, -np.inf
        self._bins = np.zeros(0, dtype=np.int64)
        self._moments = np.zeros((0, self.order + 3, 0))
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []

    # -- accumulation -------------------------------------------------------------------

    @property
    def samples(self) -> int:
        """Readings accumulated."""
        return self._samples

    @property
    def span_hz(self) -> float:
        """Frequency span of the readings accumulated (Hz), 0 before any."""
        return float(self._high - self._low) if self._samples else 0.0

    @property
    def nbytes(self) -> int:
        """Memory the moments hold (bytes): it grows with the occupied bins, i.e. with the
        span in fringes, not with the readings."""
        return self._moments.nbytes + sum(block.nbytes for _, block in self._pending)

    @property
    def mean_scale(self) -> float:
        """Mean of the ``scale`` given with the readings (1 when none was)."""
        return self._sum_scale / self._samples if self._scaled else 1.0

    def _check_layout(self, ports: int, scaled: bool) -> None:
        if self._ports is None:
            self._ports, self._scaled = ports, scaled
            self._sum_powers = np.zeros(ports)
            self._port_power2 = np.zeros(ports)
            self._moments = np.zeros((0, self.order + 3, ports + 2))
        elif (ports, scaled) != (self._ports, self._scaled):
            raise InputError(
                f"readings of {ports} ports {'with' if scaled else 'without'} a scale cannot "
                f"be added to moments of {self._ports} ports "
                f"{'with' if self._scaled else 'without'} one: give every chunk the same "
                "port columns and either always or never a power monitor",
                parameter="powers_w",
            )

    def add(self, frequency_hz, powers_w, scale=None) -> FringeMoments:
        """Accumulate a chunk of readings.

        Parameters
        ----------
        frequency_hz : array_like, shape (N,)
            Known frequencies (Hz), any order.
        powers_w : array_like, shape (N, n)
            Port readings (W or any linear unit), finite, ``n >= 3``.
        scale : None or array_like, shape (N,)
            Monitored source power per reading (any linear unit, > 0); the objects are
            ``scale_i [cos t_i, sin t_i, sqrt 2]``. Every chunk has one or none.

        Returns
        -------
        self

        Raises
        ------
        InputError
            For non-finite or mis-shaped inputs, or a chunk whose ports or scale do not
            match the earlier ones.
        """
        powers = reading_array(powers_w)
        if not np.all(np.isfinite(powers)):
            raise InputError(
                "port powers contain NaN or inf; drop those rows", parameter="powers_w"
            )
        frequency = check_frequency(frequency_hz, powers.shape[0])
        monitor = None if scale is None else check_monitor(scale, powers.shape[0])
        self._check_layout(powers.shape[1], monitor is not None)
        for start in range(0, powers.shape[0], BLOCK_ROWS):
            rows = slice(start, start + BLOCK_ROWS)
            self._add_block(
                frequency[rows], powers[rows], None if monitor is None else monitor[rows]
            )
        if sum(bins.size for bins, _ in self._pending) > max(self._bins.size, BLOCK_ROWS):
            self._consolidate()
        return self

    def _add_block(self, frequency: np.ndarray, powers: np.ndarray, scale) -> None:
        keys = np.floor(frequency / self.bin_width_hz).astype(np.int64)
        if np.any(keys[1:] < keys[:-1]):
            order = np.argsort(keys, kind="stable")
            keys, frequency, powers = keys[order], frequency[order], powers[order]
            scale = None if scale is None else scale[order]
        starts = _runs(keys)
        half = 0.5 * self.bin_width_hz
        eta = (frequency - (keys + 0.5) * self.bin_width_hz) / half
        ports = powers.shape[1]
        weights = np.empty((ports + 2, keys.size))  # a row per weight: contiguous runs
        if scale is None:
            weights[0] = 1.0
            weights[1:-1] = powers.T
            weights[-1] = 1.0
        else:
            np.multiply(scale, scale, out=weights[0])
            np.multiply(powers.T, scale, out=weights[1:-1])
            weights[-1] = scale
            self._sum_scale += float(scale.sum())
        moments = np.empty((starts.size, self.order + 3, ports + 2))  # (bin, q, weight)
        for power in range(self.order + 3):
            moments[:, power] = np.add.reduceat(weights, starts, axis=1).T
            if power < self.order + 2:
                weights *= eta
        self._pending.append((keys[starts], moments))
        self._samples += keys.size
        self._power2 += float(np.einsum("ij,ij->", powers, powers))
        self._port_power2 += np.einsum("ij,ij->j", powers, powers)
        self._sum_powers += powers.sum(axis=0)
        self._low = min(self._low, float(frequency.min()))
        self._high = max(self._high, float(frequency.max()))

    def _consolidate(self) -> tuple[np.ndarray, np.ndarray]:
        """Fold the pending blocks into one moment per occupied bin; (bins, moments)."""
        if self._pending:
            keys = np.concatenate([self._bins] + [bins for bins, _ in self._pending])
            moments = np.concatenate([self._moments] + [block for _, block in self._pending])
            order = np.argsort(keys, kind="stable")
            keys = keys[order]
            starts = _runs(keys)
            self._bins = keys[starts]
            self._moments = np.add.reduceat(moments[order], starts, axis=0)
            self._pending = []
        return self._bins, self._moments

    def merge(self, other: FringeMoments) -> FringeMoments:
        """Add the readings accumulated by ``other`` (same grid, ports and scale use).

        Returns
        -------
        self

        Raises
        ------
        InputError
            When the bin widths or orders differ, or the ports or scale use do.
        """
        if (other.bin_width_hz, other.order) != (self.bin_width_hz, self.order):
            raise InputError(
                f"moments on bins of {other.bin_width_hz:g} Hz to order {other.order} cannot "
                f"be merged into moments on bins of {self.bin_width_hz:g} Hz to order "
                f"{self.order}: build both with the same max_delay_s and bin_width_hz",
                parameter="other",
            )
        if other.samples == 0:
            return self
        self._check_layout(other._ports, other._scaled)
        bins, moments = other._consolidate()
        self._pending.append((bins.copy(), moments.copy()))
        self._samples += other._samples
        self._power2 += other._power2
        self._port_power2 += other._port_power2
        self._sum_powers += other._sum_powers
        self._sum_scale += other._sum_scale
        self._low, self._high = min(self._low, other._low), max(self._high, other._high)
        self._consolidate()
        return self

    # -- evaluation -----------------------------------------------------------------------

    def harmonic_sums(self, delay_s: float, offset_powers: int = 0) -> np.ndarray:
        """The sums ``Z[r, k + 2, w] = sum_i w_i (f_i - f0)^r exp(i k t_i)`` at a delay.

        Parameters
        ----------
        delay_s : float
            Delay ``tau`` (s), ``|tau| <= max_delay_s``; ``t_i = 2 pi (f_i - f0) tau``.
        offset_powers : int
            Largest power ``r`` of ``f_i - f0`` (Hz), 0 to 2.

        Returns
        -------
        ndarray of complex, shape (offset_powers + 1, 5, n + 2)
            ``k = -2..2``; weights ``w = (m^2, m p_1 .. m p_n, m)`` with ``m`` the scale
            (1 without): units ``Hz^r`` times those of the weight.

        Raises
        ------
        InputError
            Before any reading, or for a delay beyond ``max_delay_s``.
        """
        if self._samples == 0:
            raise InputError("no readings accumulated: add some first", parameter="moments")
        if offset_powers not in (0, 1, 2):
            raise InputError(
                f"offset_powers must be 0, 1 or 2, got {shown(offset_powers)}",
                parameter="offset_powers",
            )
        if not abs(delay_s) <= self.max_delay_s:
            raise InputError(
                f"delay {shown(delay_s)} s is beyond the {self.max_delay_s:g} s these moments "
                "were built for (their Taylor order would not reach rounding precision)",
                parameter="delay_s",
            )
        bins, moments = self._consolidate()
        order, half = self.order, 0.5 * self.bin_width_hz
        theta = 2.0 * np.pi * delay_s
        offset = (bins + 0.5) * self.bin_width_hz - self.center_hz  # a_b = c_b - f0
        harmonic = np.arange(3)
        angle = np.outer(harmonic, theta * offset)  # k theta a_b, (3, bins)
        scaled = offset ** np.arange(offset_powers + 1)[:, None]  # a_b^j, (R + 1, bins)
        rows = np.concatenate(
            [(scaled[:, None] * np.cos(angle)), (scaled[:, None] * np.sin(angle))]
        ).reshape(-1, bins.size)
        # one product over the bins: F[j, k, q, w] = sum_b a_b^j e^{i k theta a_b} M_b[q, w]
        folded = (rows @ moments.reshape(bins.size, -1)).reshape(
            2, offset_powers + 1, 3, order + 3, moments.shape[2]
        )
        folded = folded[0] + 1j * folded[1]
        series = np.ones((3, order + 1), dtype=complex)  # (i k theta h)^q / q!
        for q in range(1, order + 1):
            series[:, q] = series[:, q - 1] * (1j * harmonic * theta * half / q)
        sums = np.empty((offset_powers + 1, 5, moments.shape[2]), dtype=complex)
        for power in range(offset_powers + 1):
            # (f - f0)^r = sum_s C(r, s) a_b^(r-s) h^s eta^s: the moments shifted by s
            positive = sum(
                math.comb(power, s)
                * half**s
                * np.einsum("kq,kqw->kw", series, folded[power - s, :, s : s + order + 1])
                for s in range(power + 1)
            )
            sums[power, 2:] = positive
            sums[power, :2] = np.conj(positive[:0:-1])
        return sums
