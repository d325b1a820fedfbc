"""Reading through a calibration set: each reading by the window of its coarse frequency.

:class:`WindowReadingMixin` gives :class:`~wavemeter.calibration.methods.set.CalibrationSet`
its windows (which window covers a coarse frequency, the parts) and its reading: frequency,
phase, uncertainty, bound and flags each come from the window that covers the reading, the
frequency as that window's alias nearest the coarse value.
"""

from __future__ import annotations

import numpy as np

from ...model.cone import wrap_to_period
from ...validation import check_coarse_inside, check_fitted, check_per_reading
from ..contract.base import Part
from ..contract.records import ReadingInputs
from .set_checks import window_label

__all__ = ["WindowReadingMixin"]


class WindowReadingMixin:
    """Windows and per-window reading of a fitted calibration set.

    Expects the set's fitted attributes ``windows_``, ``window_edges_hz_``, ``span_hz_`` and
    ``fsr_hz_``.
    """

    # ------------------------------------------------------------------ windows
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
        coarse = check_per_reading("coarse_hz", coarse_hz, np.size(coarse_hz))
        low, high = self.covered_hz()
        check_coarse_inside(
            coarse,
            (coarse >= low) & (coarse <= high),
            f"outside the calibrated span {low / 1e12:.6f} to {high / 1e12:.6f} THz: no window "
            "has a map there",
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

    def parts(self) -> tuple[Part, ...]:
        """One part per window, low to high frequency."""
        check_fitted(self)
        edges = self.window_edges_hz_
        return tuple(
            Part(
                window_label(edges, index),
                "window",
                window,
                (float(edges[index]), float(edges[index + 1])),
            )
            for index, window in enumerate(self.windows_)
        )

    # ------------------------------------------------------------------ retrieval
    def _coverage(self, inputs: ReadingInputs):
        low, high = self.covered_hz()
        coarse = inputs.coarse_hz
        return (
            (coarse >= low) & (coarse <= high),
            f"outside the calibrated span {low / 1e12:.6f} to {high / 1e12:.6f} THz: no "
            "window has a map there",
        )

    def _frequency_hz(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """The window's frequency alias (modulo its FSR) nearest each coarse value."""

        def nearest_alias(window, rows, coarse_rows):
            fine = window.predict(rows)
            return coarse_rows + wrap_to_period(fine - coarse_rows, window.fsr_hz_)

        return self._per_window(readings, inputs.coarse_hz, nearest_alias)

    def _phase_rad(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """The phase (rad) of each reading in its window, zero at the window's centre."""
        return self._per_window(
            readings, inputs.coarse_hz, lambda window, rows, _: window.phase(rows)
        )

    def _frequency_std(self, readings, inputs: ReadingInputs, include_calibration: bool):
        """The standard deviation (Hz) of the window that reads each reading."""
        return self._per_window(
            readings,
            inputs.coarse_hz,
            lambda window, rows, _: window.frequency_std_hz(
                rows, include_calibration=include_calibration
            ),
        )

    def _crlb(self, readings, inputs: ReadingInputs, frequency_hz) -> np.ndarray:
        """The bound under the map and noise of each reading's window."""
        index = self.window_index(inputs.coarse_hz)
        result = np.empty(readings.shape[0])
        for window_number in np.unique(index):
            rows = index == window_number
            result[rows] = self.windows_[window_number].crlb_hz(
                readings[rows], frequency_hz=None if frequency_hz is None else frequency_hz[rows]
            )
        return result

    def _offsets_known(self) -> bool:
        return super()._offsets_known() or any(w._offsets_known() for w in self.windows_)

    def _model_flags(self, readings, inputs: ReadingInputs) -> np.ndarray:
        """Each window's own bits."""
        return self._per_window(
            readings, inputs.coarse_hz, lambda window, rows, _: window.flags(rows)
        ).astype(np.int64)
