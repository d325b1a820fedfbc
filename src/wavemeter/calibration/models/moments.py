"""The learned map's cost ``J(tau)`` from binned moments of the sweep: one pass over the data.

For a trial delay ``tau`` the learned fit (:mod:`wavemeter.calibration.models.linear_map`) needs
only the normal equations of the object vectors ``x_i = m_i [cos t_i, sin t_i, sqrt 2]``
(with a fourth entry 1 when affine), ``t_i = 2 pi (f_i - f0) tau``:
``Rxx = sum_i x_i x_i^T`` and ``Rxp = sum_i x_i p_i^T``, with ``sum_i |p_i|^2``. Writing
``cos t = (e^{it} + e^{-it}) / 2`` and ``sin t = (e^{it} - e^{-it}) / (2 i)``, every entry
is the real part of a combination of the sums

    Z_w(k, tau) = sum_i w_i exp(i k t_i),   k = -2..2,  Z_w(-k) = conj Z_w(k),

for the weights ``w = m^2`` (``Rxx``), ``w = m p_j`` (``Rxp``) and ``w = m`` (the offset
column); the delay derivative of the objects, ``D_i = dx_i / dtau = 2 pi (f_i - f0) m_i
[-sin t_i, cos t_i, 0]``, needs the same sums with one and two more factors ``(f_i - f0)``.

**Moments.** The frequencies are binned on an absolute grid of width ``d`` (bin ``b``
holds ``f`` with ``floor(f / d) = b``, centre ``c_b = (b + 1/2) d``; the same for every
chunk, so that chunks and separate accumulations merge by adding). Per bin the moments
``M_b[q, w] = sum_{i in b} w_i eta_i^q`` of the scaled offsets ``eta_i = (f_i - c_b) / h``,
``h = d / 2``, ``|eta_i| <= 1`` (to the rounding of ``f / d``), are accumulated for
``q = 0..Q+2``. With
``a_b = c_b - f0`` and ``theta = 2 pi tau``,

    Z_w(k, tau) = sum_b e^{i k theta a_b} sum_{q=0}^{Q} (i k theta h)^q / q! M_b[q, w]

and ``sum_i w_i (f_i - f0)^r e^{i k t_i}`` (``r = 1, 2``) follows from
``(f_i - f0)^r = sum_s C(r, s) a_b^(r-s) h^s eta_i^s``, i.e. from the moments shifted by
``s``. A delay costs ``O(bins Q)``, whatever the number of samples.

**Truncation bound.** With ``|k| <= 2``, ``|eta_i| <= 1`` and ``|tau| <= tau_max`` the
series is evaluated at ``|k theta h eta_i| <= rho = 2 pi tau_max d``; the neglected terms
of every bin are bounded by
``sum_i |w_i| rho^(Q+1) / (Q+1)! / (1 - rho / (Q+2))``; ``Q`` (:func:`taylor_order`) is the
smallest order that makes this factor at most the unit roundoff ``2^-53``, so the series is
exact to rounding for every ``|tau| <= max_delay_s``. The default bin width makes
``rho = TAYLOR_RADIUS`` (0.1) at ``max_delay_s``, i.e. ``d = 0.1 / (2 pi tau_max)``, about
1/63 of an FSR, and ``Q = 9``.

**Precision.** ``J = (sum |p|^2 - tr(Rxp^T Rxx^-1 Rxp)) / N`` cancels: its absolute error
is a few ``2^-53 sum |p|^2 / N``, i.e. ``1e-10`` to ``1e-9`` of ``J`` at Table 1 noise
(fringes 2000 times the noise).
That is ample for scanning and bracketing a minimum, but not for locating it to better
than about ``1e-8`` relative. The derivative ``J'(tau) = -2 tr(B^T (D^T P - D^T X B)) / N``
(``B = Rxx^-1 Rxp``, the envelope theorem: the map is profiled out) has no such
cancellation at its root, so :func:`search_moment_delay` scans and brackets with ``J``
(:func:`~wavemeter.calibration.models.delay_search.search_delay`, its contract unchanged) and then
finds the root of ``J'`` to the delay tolerance.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np
from scipy import linalg, optimize

from ...exceptions import InputError
from ...validation import check_frequency, check_monitor, check_positive, reading_array
from .delay_search import EDGE_POINTS, MIN_GRID_POINTS, DelaySearchResult, search_delay

__all__ = [
    "FringeMoments",
    "MIN_BIN_SAMPLES",
    "TAYLOR_RADIUS",
    "binning_pays",
    "largest_search_delay_s",
    "search_moment_delay",
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
#: cone columns of the object vector as combinations of ``e^{i k t}``, ``k = -1, 0, 1``
_CONE = np.array([[0.5, 0.0, 0.5], [0.5j, 0.0, -0.5j], [0.0, np.sqrt(2.0), 0.0]])
_HARMONICS = np.array([-1, 0, 1])
#: ``d / dtau`` of those columns, per unit of ``(f - f0)``: ``2 pi i k``
_CONE_SLOPE = _CONE * (2j * np.pi * _HARMONICS)


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


def _solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``gram^-1 rhs`` for a symmetric positive (semi)definite ``gram``, columns equilibrated
    (any monitor unit), rank-revealing (LAPACK ``gelsy``) like the direct fit."""
    norm = np.sqrt(np.diag(gram))
    norm[norm == 0] = 1.0
    solution, *_ = linalg.lstsq(
        gram / np.outer(norm, norm), rhs / norm[:, None], lapack_driver="gelsy", check_finite=False
    )
    return solution / norm[:, None]


class FringeMoments:
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
                f"center_hz must be a finite number (Hz), got {center_hz!r}",
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
                f"offset_powers must be 0, 1 or 2, got {offset_powers!r}",
                parameter="offset_powers",
            )
        if not abs(delay_s) <= self.max_delay_s:
            raise InputError(
                f"delay {delay_s!r} s is beyond the {self.max_delay_s:g} s these moments "
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

    def _normal(self, sums: np.ndarray, affine: bool) -> tuple[np.ndarray, np.ndarray]:
        """``Rxx`` (k, k) and ``Rxp`` (k, n) from :meth:`harmonic_sums` ``[0]``."""
        ports = self._ports
        gram = np.zeros((4, 4) if affine else (3, 3))
        cross = np.zeros((gram.shape[0], ports))
        gram[:3, :3] = _pair(_CONE, _CONE, sums[:, 0])
        cross[:3] = (_CONE @ sums[_HARMONICS + 2, 1 : ports + 1]).real
        if affine:
            gram[:3, 3] = gram[3, :3] = (_CONE @ sums[_HARMONICS + 2, ports + 1]).real
            gram[3, 3] = self._samples
            cross[3] = self._sum_powers
        return gram, cross

    def _slopes(self, sums: np.ndarray, affine: bool) -> tuple[np.ndarray, np.ndarray]:
        """``D^T X`` (k, k) and ``D^T P`` (k, n) from :meth:`harmonic_sums` ``[1]``."""
        ports = self._ports
        columns = 4 if affine else 3
        slope = np.zeros((columns, columns))
        cross = np.zeros((columns, ports))
        slope[:3, :3] = _pair(_CONE_SLOPE, _CONE, sums[:, 0])
        cross[:3] = (_CONE_SLOPE @ sums[_HARMONICS + 2, 1 : ports + 1]).real
        if affine:
            slope[:3, 3] = (_CONE_SLOPE @ sums[_HARMONICS + 2, ports + 1]).real
        return slope, cross

    def cost(self, delay_s: float, affine: bool = False) -> float:
        """Learned-map cost ``J = min_A mean ||p - A x||^2`` (W^2) at ``delay_s`` (s).

        Equals :func:`~wavemeter.calibration.models.linear_map.map_cost` to a few ``2^-53``
        ``sum |p|^2 / N``; clipped at 0 (rounding can make it negative on noiseless data).
        """
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], affine)
        solution = _solve(gram, cross)
        return max(float(self._power2 - np.einsum("ij,ij->", cross, solution)) / self._samples, 0.0)

    def cost_derivative(self, delay_s: float, affine: bool = False) -> float:
        """``dJ / dtau`` (W^2/s) at ``delay_s`` (s), the map profiled out (envelope theorem).

        ``-2 tr(B^T (D^T P - D^T X B)) / N`` with ``B = Rxx^-1 Rxp``; no cancellation at the
        minimum of ``J``, where it changes sign.
        """
        sums = self.harmonic_sums(delay_s, 1)
        gram, cross = self._normal(sums[0], affine)
        slope, slope_cross = self._slopes(sums[1], affine)
        solution = _solve(gram, cross)
        residual = slope_cross - slope @ solution
        return -2.0 * float(np.einsum("ij,ij->", solution, residual)) / self._samples

    def map_at(self, delay_s: float, affine: bool = False) -> np.ndarray:
        """Least-squares map ``A = Rxp^T Rxx^-1`` (n, 3), or (n, 4) with ``affine`` (W)."""
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], affine)
        return _solve(gram, cross).T

    def unfitted_cost(self, affine: bool = False) -> float:
        """Cost ``J`` (W^2) of the model with no fringe: the cone axis (and offsets) alone.

        As :func:`~wavemeter.calibration.models.linear_map.unfitted_cost`.
        """
        gram, cross = self._normal(self.harmonic_sums(0.0, 0)[0], affine)
        keep = [2, 3] if affine else [2]
        solution = _solve(gram[np.ix_(keep, keep)], cross[keep])
        return float(self._power2 - np.einsum("ij,ij->", cross[keep], solution)) / self._samples

    def object_gram(self, delay_s: float, affine: bool = False):
        """The object matrix ``X`` and its delay derivative ``D`` through their products.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        affine : bool
            With the column of ones (per-port offsets), whose derivative is 0.

        Returns
        -------
        xx, dx, dd : ndarray, shape (k, k)
            ``X^T X``, ``D^T X`` and ``D^T D`` (``k`` = 3, or 4 with ``affine``), in the
            units of the scale squared times 1, 1/s and 1/s^2.
        """
        sums = self.harmonic_sums(delay_s, 2)
        gram, _ = self._normal(sums[0], affine)
        slope, _ = self._slopes(sums[1], affine)
        curvature = np.zeros_like(gram)
        curvature[:3, :3] = _pair(_CONE_SLOPE, _CONE_SLOPE, sums[2][:, 0])
        return gram, slope, curvature

    def port_residual_w2(self, delay_s: float, map_: np.ndarray) -> np.ndarray:
        """Each port's summed squared residual ``sum_i (p_ij - A_j x_i)^2`` (W^2) under a map.

        ``sum p_j^2 - 2 A_j (Rxp)_j + A_j Rxx A_j^T``: it cancels like :meth:`cost` (an
        absolute error of a few ``2^-53 sum p_j^2``); clipped at 0.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        map_ : ndarray, shape (n, 3) or (n, 4)
            Map (W) for the scale as given; a fourth column makes it affine.

        Returns
        -------
        ndarray, shape (n,)
        """
        solution = np.asarray(map_, dtype=float).T
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], solution.shape[0] == 4)
        energy = (
            self._port_power2
            - 2.0 * np.einsum("ij,ij->j", solution, cross)
            + np.einsum("ij,ij->j", solution, gram @ solution)
        )
        return np.maximum(energy, 0.0)

    def delay_information(self, delay_s: float, map_: np.ndarray) -> float:
        """Gauss-Newton curvature ``G`` (W^2/s^2) of the summed squared residual in the delay.

        As :func:`~wavemeter.calibration.models.linear_map.delay_information`:
        ``G = ||(I - Pi_X) D A^T||_F^2 = tr(B^T D^T D B) - tr(V^T Rxx^-1 V)``, ``B = A^T``,
        ``V = X^T D B``.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        map_ : ndarray, shape (n, 3) or (n, 4)
            Map at that delay (W) for the scale as given; a fourth column makes it affine.
        """
        solution = np.asarray(map_, dtype=float).T
        gram, slope, curvature = self.object_gram(delay_s, solution.shape[0] == 4)
        projected = slope.T @ solution
        return float(
            np.einsum("ij,ij->", solution, curvature @ solution)
            - np.einsum("ij,ij->", projected, _solve(gram, projected))
        )


def _pair(left: np.ndarray, right: np.ndarray, sums: np.ndarray) -> np.ndarray:
    """``Re sum_{k1, k2} left[a, k1] right[b, k2] Z(k1 + k2)`` for ``Z(k)``, ``k = -2..2``."""
    hankel = sums[_HARMONICS[:, None] + _HARMONICS[None, :] + 2]
    return (left @ hankel @ right.T).real


def search_moment_delay(
    moments: FringeMoments,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    method: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> DelaySearchResult:
    """:func:`~wavemeter.calibration.models.delay_search.search_delay` on the moments' ``J``, then
    the root of ``J'`` between the best scan point's neighbours, inside the bracket.

    The scan, the edge descent, the refinement, the fringe-power check and the bracket
    decision are :func:`~wavemeter.calibration.models.delay_search.search_delay`'s. Its refined
    delay is precise to about ``1e-8`` only (``J`` cancels); ``J'`` changing sign between
    the scan neighbours of the best point (clipped to the closed bracket) is then solved
    by Brent's method to ``xtol`` (relative). Without a sign change there the refined
    delay stands.

    Parameters
    ----------
    moments : FringeMoments
        The sweep, accumulated to a ``max_delay_s`` of at least
        :func:`largest_search_delay_s`.
    fsr_hz, fsr_tolerance, method, xtol
        As for :func:`~wavemeter.calibration.models.delay_search.search_delay`.
    affine : bool
        Fit per-port offsets too.

    Returns
    -------
    DelaySearchResult
        ``delay_s`` the root, ``cost`` the moments' ``J`` there, ``evaluations`` counting
        the derivative evaluations too; the scan as :func:`search_delay` made it.
    """
    result = search_delay(
        lambda delay_s: moments.cost(delay_s, affine),
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        span_hz=moments.span_hz,
        method=method,
        xtol=xtol,
        unfitted_cost=moments.unfitted_cost(affine),
    )
    design_delay = 1.0 / fsr_hz
    best = int(np.argmin(result.grid_cost))
    u_lo = max(result.grid_delay_s[best - 1] / design_delay, 1.0 / (1.0 + fsr_tolerance))
    u_hi = min(result.grid_delay_s[best + 1] / design_delay, 1.0 / (1.0 - fsr_tolerance))

    def slope(u: float) -> float:
        return moments.cost_derivative(u * design_delay, affine)

    if not slope(u_lo) < 0.0 < slope(u_hi):
        return dataclasses.replace(result, evaluations=result.evaluations + 2)
    u_root, info = optimize.brentq(
        slope, u_lo, u_hi, xtol=xtol, rtol=4 * np.finfo(float).eps, full_output=True
    )
    delay = u_root * design_delay
    return dataclasses.replace(
        result,
        delay_s=delay,
        cost=moments.cost(delay, affine),
        evaluations=result.evaluations + 3 + info.function_calls,
    )
