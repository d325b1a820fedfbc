"""Fitting a calibrator on a sweep read in chunks, in memory bounded by the chunk.

:func:`fit_sweep_chunks` gives each chunk's valid rows to the calibrator's ``fit_chunks``
(a calibrator with the ``"fit_chunks"`` capability) and drops them, whatever the file's
length; a :class:`RowSample` given to it keeps every k-th valid row on the way (k doubling
as the sweep outgrows it), for what is computed on the readings after the fit (the
Cramer-Rao bound of the sweep): every row of a sweep of up to ``limit`` rows.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np

from ..exceptions import InputError
from ..io import ReadingStream
from .sweeps import SweepRead

__all__ = ["RowSample", "fit_sweep_chunks", "SAMPLE_ROWS"]

#: rows a sample keeps at most (that of the learned calibrator's diagnostics)
SAMPLE_ROWS = 1 << 17


class RowSample:
    """Every k-th row of a sweep met in chunks: k = 1 until the sweep exceeds ``limit``
    rows, then doubled as often as it needs to keep at most ``limit``.

    Parameters
    ----------
    limit : int
        The most rows kept.

    Attributes
    ----------
    stride : int
        k: the sample holds the rows whose index (among the rows added) is a multiple.
    powers_w : ndarray, shape (M, n)
    frequency_hz : ndarray, shape (M,)
        The rows kept, in order (empty before any is added).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.jobs import RowSample
    >>> sample = RowSample(limit=4)
    >>> sample.add(np.ones((6, 3)), np.arange(6.0))  # 6 rows > 4: every 2nd kept
    >>> sample.stride, sample.frequency_hz
    (2, array([0., 2., 4.]))
    >>> sample.add(np.ones((4, 3)), np.arange(6.0, 10.0))  # 5 of 10 > 4: every 4th
    >>> sample.stride, sample.frequency_hz
    (4, array([0., 4., 8.]))
    """

    def __init__(self, limit: int = SAMPLE_ROWS):
        self.limit = limit
        self.stride = 1
        self._added = 0
        self._index: list[np.ndarray] = []
        self._powers: list[np.ndarray] = []
        self._frequency: list[np.ndarray] = []

    def add(self, powers_w: np.ndarray, frequency_hz: np.ndarray) -> None:
        """Add the next rows: readings (m, n) and their frequencies (m,)."""
        index = np.arange(self._added, self._added + len(frequency_hz))
        self._added += len(frequency_hz)
        keep = index % self.stride == 0
        self._index.append(index[keep])
        self._powers.append(np.array(powers_w[keep]))
        self._frequency.append(np.array(frequency_hz[keep]))
        while sum(map(len, self._index)) > self.limit:
            self.stride *= 2
            kept = [indices % self.stride == 0 for indices in self._index]
            self._index = [part[rows] for part, rows in zip(self._index, kept, strict=True)]
            self._powers = [part[rows] for part, rows in zip(self._powers, kept, strict=True)]
            self._frequency = [part[rows] for part, rows in zip(self._frequency, kept, strict=True)]

    @property
    def powers_w(self) -> np.ndarray:
        return np.concatenate(self._powers) if self._powers else np.empty((0, 0))

    @property
    def frequency_hz(self) -> np.ndarray:
        return np.concatenate(self._frequency) if self._frequency else np.empty(0)


def fit_sweep_chunks(
    calibrator,
    stream: ReadingStream,
    *,
    dark_w=None,
    progress: Callable | None = None,
    sample: RowSample | None = None,
) -> SweepRead:
    """Fit a calibrator on a sweep read in chunks, in memory bounded by the chunk.

    Each chunk's valid rows go to the calibrator's ``fit_chunks`` and are dropped: for
    the learned calibrator, the calibration is the one ``fit`` gives on the valid rows read
    whole (bit for bit up to ``diagnostic_samples`` readings, to rounding beyond).

    Parameters
    ----------
    calibrator : BaseCalibrator
        Unfitted, with ``"fit_chunks"`` among its capabilities.
    stream : ReadingStream
        The sweep, opened with :func:`~wavemeter.io.iter_readings` (``need_x=True``) and
        not yet iterated; its ``allow_invalid`` decides whether invalid rows are skipped.
    dark_w : None or array_like, shape (n,)
        Per-port dark readings (W), subtracted from every reading.
    progress : callable, optional
        ``progress(description, total, unit)`` returning a context manager that yields
        ``advance(steps)`` (as :func:`wavemeter.progress.progress_bar`), advanced in the
        units of the read. None: silent.
    sample : RowSample, optional
        Keeps every k-th valid row on the way.

    Returns
    -------
    SweepRead

    Raises
    ------
    InputError
        For a calibrator that cannot fit chunks, what the read refuses (invalid rows when
        not allowed, bad cells) and what ``fit_chunks`` refuses.
    EdgeMinimumError
        As ``fit``.

    Warns
    -----
    CalibrationWarning
        As ``fit``.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import iter_readings, write_table
    >>> from wavemeter.jobs import fit_sweep_chunks
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(2000)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> path = Path(tempfile.mkdtemp()) / "sweep.csv"
    >>> write_table(path, {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}})
    >>> chunked = wm.Calibrator(fsr_hz=50e9)
    >>> read = fit_sweep_chunks(chunked, iter_readings(path, need_x=True, chunk_rows=256))
    >>> read.n_rows
    2000
    >>> whole = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)  # the same calibration
    >>> abs(chunked.fsr_hz_ - whole.fsr_hz_) < 1e-9 * whole.fsr_hz_
    True
    """
    if "fit_chunks" not in calibrator.capabilities:
        raise InputError(
            f"a {calibrator.method_label} calibration is fitted on the whole sweep at once "
            "(no 'fit_chunks' among its capabilities)"
        )
    found: dict = {"temperature": [np.inf, -np.inf]}

    def chunks(advance):
        done = 0
        for table in stream:
            found.setdefault("x", (table.x_column, table.x_unit))
            valid = table.valid_only()
            if valid.temperature_k is not None and valid.n_rows:
                low, high = found["temperature"]
                found["temperature"] = [
                    min(low, float(valid.temperature_k.min())),
                    max(high, float(valid.temperature_k.max())),
                ]
            if sample is not None:
                sample.add(valid.powers_w, valid.x_hz)
            yield valid.x_hz, valid.powers_w, valid.monitor_w
            if advance is not None:
                advance(stream.progress - done)
            done = stream.progress

    total, unit = stream.progress_total
    bar = progress(f"calibrating on {stream.source}", total, unit) if progress else None
    with bar if bar is not None else contextlib.nullcontext() as advance:
        calibrator.fit_chunks(chunks(advance), list(stream.port_names), dark_w=dark_w)
    x_column, x_unit = found.get("x", (None, None))
    temperature = found["temperature"]
    return SweepRead(
        source=stream.source,
        x_column=x_column,
        x_unit=x_unit,
        port_names=tuple(stream.port_names),
        port_units=tuple(stream.port_units),
        monitor_column=stream.monitor_column,
        temperature_column=stream.temperature_column,
        n_rows=stream.rows - stream.invalid_rows,
        dropped_rows=stream.invalid_rows,
        invalid_examples=tuple(stream.invalid_examples),
        temperature_range_k=temperature if np.isfinite(temperature[0]) else None,
    )
