"""One calibration per FSR-wide window of a sweep over many FSRs (paper Section IV, Fig. 8, 9).

A single map ``A`` is optimal for the span it was learned on; over a wide band the fringe
amplitudes and the bias drift slowly, so the paper calibrates one FSR at a time and applies
each map to readings of its own FSR. :class:`CalibrationSet` does that for a sweep over many
FSRs:

1. the global delay is fitted on the whole sweep (the most precise FSR there is, and the
   only fit that can tell the true delay from a side minimum of ``J``), and checked to
   explain the fringes;
2. the sweep is cut into contiguous windows of exactly one fitted FSR, centred on the sweep;
3. each window is calibrated on its own readings alone, refitting the delay within
   +-5 % of the global FSR: the paper's per-FSR protocol, which also follows a local FSR
   that drifts across the band (dispersion). A one-FSR window has no side minimum of ``J``
   in that bracket, and its delay costs only the ``3/N`` part of ``CRLB sqrt(1 + 3/N)``.

Retrieval needs a coarse frequency per reading (the laser set point, a coarse meter, the
previous reading), good to better than half an FSR: it picks the window, and of the
window's readings modulo the FSR it picks the alias nearest the coarse value.
"""

from __future__ import annotations

import numpy as np

from .base import BaseCalibrator
from .baselines import ConventionalCalibrator
from .calibration import RETRIEVALS, Calibrator
from .metrics import error_summary_hz, frequency_error_hz
from .persistence import calibrator_fields, calibrator_from_fields
from .validation import (
    MIN_SAMPLES,
    check_choice,
    check_fitted,
    check_frequency,
    check_monitor,
    check_positive,
    check_powers,
)

__all__ = ["CalibrationSet", "WINDOW_METHODS", "WINDOW_FSR_TOLERANCE"]

WINDOW_METHODS = ("learned", "conventional")
#: half width of each window's delay bracket about the global FSR (dispersion is far smaller)
WINDOW_FSR_TOLERANCE = 0.05


def _window_label(edges_hz: np.ndarray, index: int) -> str:
    return f"window {index} ({edges_hz[index] / 1e12:.6f} to {edges_hz[index + 1] / 1e12:.6f} THz)"


class CalibrationSet(BaseCalibrator):
    """A calibration per FSR-wide window of a sweep spanning many FSRs.

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz); the global delay search brackets it.
    fsr_tolerance : float
        Relative half width of the global FSR bracket, in (0, 1). Default 0.2.
    method : {"learned", "conventional"}
        Calibration of each window: the learned map (:class:`wavemeter.Calibrator`) or the
        conventional method (:class:`wavemeter.ConventionalCalibrator`).
    port_phases_rad : None or array_like, shape (n,)
        Nominal port phases (rad) for the conventional method: used by conventional
        windows and by the baseline of :meth:`adjacent_evaluation`. Default: equally
        spaced in port order.
    retrieval : {"pinv", "ml"}
        Phase retrieval of learned windows (see :class:`wavemeter.Calibrator`).

    Attributes
    ----------
    windows_ : list of BaseCalibrator
        One fitted calibrator per window, low to high frequency; each has its own
        ``span_hz_`` (the readings it was fitted on), ``center_hz_`` and ``fsr_hz_``.
    window_edges_hz_ : ndarray, shape (K + 1,)
        Window boundaries (Hz), exactly one global FSR apart, centred on the sweep.
    delay_s_ : float
        Global delay ``tau`` (s) fitted on the whole sweep.
    fsr_hz_ : float
        Global FSR ``1 / tau`` (Hz).
    center_hz_ : float
        Middle of the sweep (Hz).
    span_hz_ : (float, float)
        Lowest and highest sweep frequency (Hz).
    calibration_rms_hz_ : float
        RMS frequency error on the sweep itself, each reading given its true frequency as
        the coarse value (Hz).

    Notes
    -----
    The instance attribute ``method`` is the window method; the calibration-file tag of the
    class is ``CalibrationSet.method == "calibration_set"`` (read it from the class).
    """

    method = "calibration_set"

    def __init__(
        self,
        fsr_hz: float = 50e9,
        fsr_tolerance: float = 0.2,
        method: str = "learned",
        port_phases_rad=None,
        retrieval: str = "pinv",
    ):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.method = method
        self.port_phases_rad = port_phases_rad
        self.retrieval = retrieval

    def _check_params(self) -> None:
        super()._check_params()
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        check_choice("method", self.method, WINDOW_METHODS)
        check_choice("retrieval", self.retrieval, RETRIEVALS)
        if self.method != "learned" and self.retrieval != "pinv":
            raise ValueError(
                f"retrieval={self.retrieval!r} needs method='learned', got method={self.method!r}"
            )

    def _window_calibrator(self, fsr_hz: float) -> BaseCalibrator:
        if self.method == "learned":
            return Calibrator(
                fsr_hz=fsr_hz, fsr_tolerance=WINDOW_FSR_TOLERANCE, retrieval=self.retrieval
            )
        return self._conventional(fsr_hz)

    def _conventional(self, fsr_hz: float) -> ConventionalCalibrator:
        return ConventionalCalibrator(fsr_hz=fsr_hz, port_phases_rad=self.port_phases_rad)

    # ------------------------------------------------------------------ fitting
    def fit(self, powers, frequency_hz, power_monitor_w=None, port_names=None):
        """Fit the global delay, cut the sweep into one-FSR windows, calibrate each window.

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings (W, or any unit linear in power) over a sweep of at least about
            one FSR (it is cut into ``round(span / FSR)`` windows).
        frequency_hz : array_like, shape (N,)
            Known source frequency of each reading (Hz).
        power_monitor_w : None or array_like, shape (N,)
            Source-power monitor reading (W, or any unit linear in power).
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.

        Returns
        -------
        self

        Raises
        ------
        EdgeMinimumError
            When the global delay is not inside the FSR bracket (including a side minimum
            of ``J`` on a sweep of several FSRs), or a window's delay is not within
            +-5 % of the global one.
        ValueError
            When the sweep is shorter than half an FSR or a window holds too few readings;
            the message names the window.
        """
        self._check_params()
        whole = Calibrator(fsr_hz=self.fsr_hz, fsr_tolerance=self.fsr_tolerance).fit(
            powers, frequency_hz, power_monitor_w, port_names
        )
        powers = check_powers(powers, min_samples=MIN_SAMPLES)
        frequency = check_frequency(frequency_hz, powers.shape[0])
        monitor = check_monitor(power_monitor_w, powers.shape[0])
        fsr = whole.fsr_hz_
        low, high = whole.span_hz_
        count = round((high - low) / fsr)
        if count < 1:
            raise ValueError(
                f"the sweep spans {(high - low) / 1e9:.6g} GHz, less than half the fitted FSR "
                f"({fsr / 1e9:.6g} GHz): a calibration set needs a sweep over whole FSRs; use "
                "wavemeter.Calibrator for a single FSR"
            )
        edges = whole.center_hz_ + (np.arange(count + 1) - count / 2) * fsr
        position = np.floor((frequency - edges[0]) / fsr)
        windows = []
        for index in range(count):
            rows = position == index
            window = self._window_calibrator(fsr)
            try:
                window.fit(
                    powers[rows],
                    frequency[rows],
                    None if monitor is None else monitor[rows],
                    whole.port_names_,
                )
            except ValueError as exc:
                raise type(exc)(f"{_window_label(edges, index)}: {exc}") from exc
            windows.append(window)
        self.delay_s_ = whole.delay_s_
        self.fsr_hz_ = fsr
        self.center_hz_ = whole.center_hz_
        self.span_hz_ = whole.span_hz_
        self.n_ports_ = whole.n_ports_
        self.n_samples_ = whole.n_samples_
        self.port_names_ = whole.port_names_
        self.window_edges_hz_ = edges
        self.windows_ = windows
        error = frequency_error_hz(self._predict_readings(powers, frequency), frequency, fsr)
        self.calibration_rms_hz_ = float(np.sqrt(np.mean(error**2)))
        return self

    # ------------------------------------------------------------------ windows
    def _check_coarse(self, coarse_hz, samples: int) -> np.ndarray:
        if coarse_hz is None:
            raise ValueError(
                "coarse_hz is required: a CalibrationSet holds one map per FSR window and needs "
                "each reading's approximate frequency (Hz, within half an FSR, e.g. the laser "
                "set point) to pick the window; got None"
            )
        try:
            coarse = np.array(coarse_hz, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(
                f"coarse_hz must be a number or an array of numbers (Hz), got "
                f"{type(coarse_hz).__name__}"
            ) from exc
        if coarse.ndim == 0:
            coarse = np.full(samples, float(coarse))
        if coarse.shape != (samples,):
            raise ValueError(
                f"coarse_hz must be one value or one per reading ({samples}), got shape "
                f"{coarse.shape}"
            )
        if not np.all(np.isfinite(coarse)):
            raise ValueError("coarse_hz contains NaN or inf")
        return coarse

    def covered_hz(self) -> tuple[float, float]:
        """Lowest and highest coarse frequency (Hz) the set has a window for.

        The union of the windows and the calibration sweep: readings beyond the outer
        window edges but inside the sweep use the outer window.
        """
        check_fitted(self)
        edges = self.window_edges_hz_
        return min(float(edges[0]), self.span_hz_[0]), max(float(edges[-1]), self.span_hz_[1])

    def window_index(self, coarse_hz) -> np.ndarray:
        """Index into ``windows_`` of the window for each coarse frequency.

        Parameters
        ----------
        coarse_hz : float or array_like, shape (N,)
            Approximate frequency (Hz).

        Returns
        -------
        ndarray of int, shape (N,) (shape (1,) for a scalar)

        Raises
        ------
        ValueError
            When a coarse frequency lies outside :meth:`covered_hz`.
        """
        check_fitted(self)
        coarse = np.atleast_1d(self._check_coarse(coarse_hz, np.size(coarse_hz)))
        low, high = self.covered_hz()
        outside = (coarse < low) | (coarse > high)
        if outside.any():
            first = int(np.flatnonzero(outside)[0])
            raise ValueError(
                f"coarse_hz {coarse[first]!r} Hz (reading {first}, zero-based; "
                f"{int(outside.sum())} in all) is outside the calibrated span "
                f"{low / 1e12:.6f} to {high / 1e12:.6f} THz: no window has a map there; "
                "calibrate over a sweep that covers it"
            )
        position = np.floor((coarse - self.window_edges_hz_[0]) / self.fsr_hz_)
        return np.clip(position, 0, len(self.windows_) - 1).astype(int)

    def _per_window(self, readings: np.ndarray, coarse: np.ndarray, retrieve) -> np.ndarray:
        """``retrieve(window, readings, coarse)`` applied to each window's readings."""
        index = self.window_index(coarse)
        result = np.empty(readings.shape[0])
        for window_number in np.unique(index):
            rows = index == window_number
            result[rows] = retrieve(self.windows_[window_number], readings[rows], coarse[rows])
        return result

    # ------------------------------------------------------------------ retrieval
    def _predict_readings(self, readings: np.ndarray, coarse: np.ndarray) -> np.ndarray:
        def nearest_alias(window, rows, coarse_rows):
            fine = window.predict(rows)
            return coarse_rows + frequency_error_hz(fine, coarse_rows, window.fsr_hz_)

        return self._per_window(readings, coarse, nearest_alias)

    def predict(self, powers, coarse_hz=None) -> np.ndarray:
        """Source frequency (Hz) of each reading.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings.
        coarse_hz : float or array_like, shape (N,)
            Approximate frequency of each reading (Hz), within half an FSR of the truth
            (e.g. the laser set point). It picks the window, and the window's frequency
            alias (modulo its FSR) nearest to it is returned. Required.

        Returns
        -------
        ndarray, shape (N,), Hz

        Raises
        ------
        ValueError
            When ``coarse_hz`` is missing, of the wrong length, not finite, or outside
            :meth:`covered_hz`.
        """
        readings = self._check_readings(powers)
        return self._predict_readings(readings, self._check_coarse(coarse_hz, readings.shape[0]))

    def phase(self, powers, coarse_hz=None) -> np.ndarray:
        """Interferometer phase (rad) in (-pi, pi], zero at the ``center_hz_`` of each window.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
        coarse_hz : float or array_like, shape (N,)
            Approximate frequency (Hz) that picks the window; see :meth:`predict`.

        Returns
        -------
        ndarray, shape (N,), rad
        """
        readings = self._check_readings(powers)
        coarse = self._check_coarse(coarse_hz, readings.shape[0])
        return self._per_window(readings, coarse, lambda window, rows, _: window.phase(rows))

    # ------------------------------------------------------------------ evaluation
    def adjacent_evaluation(self, powers, frequency_hz) -> dict:
        """Each window's map on its own FSR and on the neighbouring FSRs (paper Fig. 9).

        For every window with readings in it and in at least one neighbour, the window's
        calibration retrieves the readings of its own window and of the adjacent windows
        (the frequency alias nearest the truth), and the conventional method does the
        same: it is fitted on the window's own readings of this data (its origin,
        direction and FSR) and applied to both.

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings over several windows (test data, or the sweep itself).
        frequency_hz : array_like, shape (N,)
            True frequency of each reading (Hz).

        Returns
        -------
        dict
            JSON-ready. ``"windows"``: one entry per evaluated window with ``window``
            (index), ``center_hz``, ``fsr_hz``, ``samples_own``, ``samples_adjacent`` and
            error summaries (``rms_hz``, ``max_hz``, ``p95_hz``, ``p99_hz``, Hz) ``own``,
            ``adjacent``, ``conventional_own``, ``conventional_adjacent``, plus
            ``degradation_rms`` (adjacent over own RMS). The same summaries over all
            evaluated windows at the top level, with ``method`` and ``windows_evaluated``.

        Raises
        ------
        ValueError
            When no window has at least 4 readings of its own and one in a neighbour.
        """
        readings = self._check_readings(powers)
        frequency = check_frequency(frequency_hz, readings.shape[0])
        position = np.floor((frequency - self.window_edges_hz_[0]) / self.fsr_hz_)
        pooled = {"own": [], "adjacent": [], "conventional_own": [], "conventional_adjacent": []}
        entries = []
        for index, window in enumerate(self.windows_):
            own = position == index
            neighbours = [k for k in (index - 1, index + 1) if 0 <= k < len(self.windows_)]
            adjacent = np.isin(position, neighbours)
            if own.sum() < MIN_SAMPLES or not adjacent.any():
                continue
            try:
                conventional = self._conventional(window.fsr_hz_).fit(readings[own], frequency[own])
            except ValueError as exc:
                raise type(exc)(
                    f"{_window_label(self.window_edges_hz_, index)}, conventional baseline: {exc}"
                ) from exc
            errors = {
                name: frequency_error_hz(
                    calibrator.predict(readings[rows]), frequency[rows], calibrator.fsr_hz_
                )
                for name, calibrator, rows in (
                    ("own", window, own),
                    ("adjacent", window, adjacent),
                    ("conventional_own", conventional, own),
                    ("conventional_adjacent", conventional, adjacent),
                )
            }
            for name, error in errors.items():
                pooled[name].append(error)
            summaries = {name: error_summary_hz(error) for name, error in errors.items()}
            entries.append(
                {
                    "window": index,
                    "center_hz": window.center_hz_,
                    "fsr_hz": window.fsr_hz_,
                    "samples_own": int(own.sum()),
                    "samples_adjacent": int(adjacent.sum()),
                    **summaries,
                    "degradation_rms": summaries["adjacent"]["rms_hz"] / summaries["own"]["rms_hz"],
                }
            )
        if not entries:
            raise ValueError(
                f"adjacent evaluation needs readings in a window (at least {MIN_SAMPLES}) and in "
                "a neighbouring window; the data given covers no such pair of the set's "
                f"{len(self.windows_)} windows"
            )
        totals = {name: error_summary_hz(np.concatenate(parts)) for name, parts in pooled.items()}
        return {
            "method": self.method,
            "windows_evaluated": len(entries),
            **totals,
            "degradation_rms": totals["adjacent"]["rms_hz"] / totals["own"]["rms_hz"],
            "windows": entries,
        }

    # ------------------------------------------------------------------ persistence
    def _state(self) -> dict:
        return {
            "delay_s": self.delay_s_,
            "window_edges_hz": self.window_edges_hz_.tolist(),
            "windows": [calibrator_fields(window) for window in self.windows_],
        }

    def _set_state(self, state: dict) -> None:
        edges = np.array(state["window_edges_hz"], dtype=float)
        documents = state["windows"]
        if (
            edges.ndim != 1
            or edges.size < 2
            or not np.all(np.isfinite(edges))
            or np.any(np.diff(edges) <= 0)
        ):
            raise ValueError("window_edges_hz must be at least 2 increasing finite frequencies")
        if not isinstance(documents, list) or len(documents) != edges.size - 1:
            raise ValueError(f"windows must list {edges.size - 1} calibrations, one per window")
        windows = [
            calibrator_from_fields(document, f"window {index}")
            for index, document in enumerate(documents)
        ]
        for index, window in enumerate(windows):
            if type(window).method not in WINDOW_METHODS or window.n_ports_ != self.n_ports_:
                raise ValueError(
                    f"window {index} must be a {' or '.join(WINDOW_METHODS)} calibration of "
                    f"{self.n_ports_} ports, got {type(window).method!r} with {window.n_ports_}"
                )
        self.delay_s_ = float(state["delay_s"])
        self.window_edges_hz_ = edges
        self.windows_ = windows
