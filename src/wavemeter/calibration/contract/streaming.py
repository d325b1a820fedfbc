"""Live readout: readings read one at a time, as they arrive.

:meth:`StreamMixin.stream` turns an iterable of rows (possibly endless: a live source)
into one :class:`~wavemeter.calibration.contract.records.StreamReading` per row, with the
numbers :meth:`~wavemeter.calibration.contract.reading.ReadingMixin.readout` gives the row
alone; :meth:`StreamMixin.row_reader` gives the same for one reading at a time (what the
live service reads with). What stays the same from row to row is worked out once per
reader (``_row_reader`` around ``_stream_reader``; the learned family reads a usual row in
plain floats, the cascade in one light pass per stage).
"""

from __future__ import annotations

import itertools
import math
import numbers
import types
import warnings
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from ...exceptions import CalibrationWarning, InputError
from ...validation import check_fitted, check_per_reading, check_powers
from .flags import ReadingFlag
from .records import StreamReading

__all__ = ["INVALID_READING_CAUSE", "SCREEN_MARGIN", "StreamMixin"]

#: cause of the warning that a streamed reading could not be read
INVALID_READING_CAUSE = "invalid_reading"
#: relative margin below the ``OFF_MODEL`` threshold under which a streamed reading's distance
#: to the cone at its retrieved phase proves it on the model without the exact test (that
#: test's distance is exact to ~1e-13 relative, its root tolerance: far inside the margin)
SCREEN_MARGIN = 1e-6


class StreamMixin:
    """``stream``: one record per reading of an iterable (module docstring)."""

    def stream(self, rows, *, coarse_hz=None, temperature_k=None) -> Iterator[StreamReading]:
        """Read readings one at a time, as they arrive: one record out for each row in.

        Each row is read only when its record is asked for, so ``rows`` may be endless (a
        live source). The records hold the numbers :meth:`readout` gives for the row alone,
        to float64 rounding.

        Parameters
        ----------
        rows : iterable of array_like, each shape (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or iterable of float
            Per-reading inputs (Hz, K); required when named in ``requires``. One value for
            every row, or an iterable consumed in step with ``rows``, one value per row.

        Returns
        -------
        iterator of StreamReading
            One record per row, in order.

        Raises
        ------
        InputError
            At the call, for a missing required input or a single value that is not a
            finite number; while iterating, when an iterable of inputs ends before ``rows``.

        Warns
        -----
        CalibrationWarning
            Cause :data:`INVALID_READING_CAUSE`, once per stream, at the first row that
            cannot be read: not ``n`` numbers, a value that is not finite, no light, or a
            coarse frequency the calibration has no map for. Such a row gives NaN values
            and the flags that say why (``INVALID`` where it is no reading at all).
        """
        check_fitted(self)
        given = {"coarse_hz": coarse_hz, "temperature_k": temperature_k}
        # only whether each input is given matters to this check of the required ones
        self._reading_inputs(*(None if value is None else 0.0 for value in given.values()), 1)
        sources = {name: _input_source(name, value) for name, value in given.items()}
        if not isinstance(rows, Iterable):
            raise InputError(f"rows must be an iterable of readings, got {type(rows).__name__}")
        read_row = self._row_reader()

        def records() -> Iterator[StreamReading]:
            warned = False
            for index, row in enumerate(rows):
                inputs = {}
                for name, source in sources.items():
                    try:
                        inputs[name] = next(source)
                    except StopIteration:
                        raise InputError(
                            f"{name} ended at reading {index} (zero-based) while rows went on: "
                            "give one value per row"
                        ) from None
                record, reason = read_row(row, inputs)
                if reason is not None and not warned:
                    warned = True
                    warnings.warn(
                        CalibrationWarning(
                            f"reading {index} of the stream (zero-based) cannot be read: "
                            f"{reason}; it, and every later reading that cannot be read, gets "
                            "NaN values and the flags that say why (without another warning)",
                            cause=INVALID_READING_CAUSE,
                            remedy="check the readings' source: its port count and units, "
                            "that the light is on and the coarse frequency in the band",
                        ),
                        stacklevel=2,
                    )
                yield record

        return records()

    def row_reader(self) -> Callable[..., StreamReading]:
        """A reader of one reading at a time, what stays the same worked out now.

        ``read(powers, coarse_hz=None, temperature_k=None)`` gives the record of one
        reading: the numbers :meth:`readout` gives the reading alone (to float64 rounding;
        the flags bit for bit), extras and all; a reading that cannot be read gets NaN and
        the flags that say why, without a warning. It reads with the calibration as it is
        now: ask again after changing it. What :meth:`stream` and the live service read
        with.

        Returns
        -------
        callable
            ``read(powers, coarse_hz=None, temperature_k=None) -> StreamReading`` for
            ``powers`` of shape (n,) in the unit of the calibration sweep and the
            per-reading inputs as numbers (Hz, K).

        Raises
        ------
        InputError
            From ``read``, for a per-reading input the calibration requires that is None.
        """
        check_fitted(self)
        read_row = self._row_reader()
        required = tuple(sorted(self.requires))

        def read(powers, coarse_hz=None, temperature_k=None) -> StreamReading:
            inputs = {"coarse_hz": coarse_hz, "temperature_k": temperature_k}
            if required and any(inputs[name] is None for name in required):
                self._reading_inputs(coarse_hz, temperature_k, 1)  # raises, naming it
            return read_row(powers, inputs)[0]

        return read

    def _row_reader(self) -> Callable[[object, dict], tuple[StreamReading, str | None]]:
        """``read_row(row, inputs) -> (record, reason)``: one row and its per-reading inputs
        by name (None where not given) to its record, and why it cannot be read (None when
        it can). Built once per stream from :meth:`_stream_reader`; a calibrator with a
        faster way for the common reading (finite, lit, in its band) puts it in front."""
        ports = self.n_ports_
        read = self._stream_reader()
        nan = float("nan")
        unread_extras = types.MappingProxyType(dict.fromkeys(self.reading_outputs, nan))

        def unread(row, inputs: dict) -> StreamReading:
            flags = int(ReadingFlag.INVALID)
            try:  # the other bits, where flags can tell them (a NaN or inf cell, no light)
                powers = np.reshape(np.asarray(row, dtype=float), (1, ports))
                flags |= int(self.flags(powers, **inputs)[0])
            except (InputError, TypeError, ValueError):
                pass  # not n numbers, or inputs that are not numbers: INVALID alone
            return StreamReading(nan, nan, flags, unread_extras)

        def read_row(row, inputs: dict) -> tuple[StreamReading, str | None]:
            try:
                powers, checked = _checked_row(row, inputs, ports)
                record = read(powers, checked)
            except InputError as exc:
                return unread(row, inputs), str(exc)
            if math.isnan(record.frequency_hz):
                return record, "the calibration has no map for it"
            return record, None

        return read_row

    def _stream_reader(self) -> Callable[[np.ndarray, dict], StreamReading]:
        """How :meth:`stream` reads one reading; built once per stream.

        Returns
        -------
        callable
            ``read(powers, inputs) -> StreamReading`` for a finite reading ``powers`` (1, n)
            and its per-reading inputs by name (floats, or None where not given); it raises
            :class:`InputError` where the reading cannot be read at all (a dim reading that
            is read keeps its numbers and ``INVALID``, as in :meth:`readout`). Here:
            :meth:`readout` of the reading.
        """

        def read(powers: np.ndarray, inputs: dict) -> StreamReading:
            found = self.readout(powers, **{n: v for n, v in inputs.items() if v is not None})
            if found.flags[0] & ReadingFlag.INVALID and np.isnan(found.frequency_hz[0]):
                raise InputError("it is no reading (no light)")
            return StreamReading(
                float(found.frequency_hz[0]),
                float(found.frequency_std_hz[0]),
                int(found.flags[0]),
                {name: float(values[0]) for name, values in found.extras.items()},
            )

        return read

    def _stream_corrector(self) -> Callable[[np.ndarray], np.ndarray]:
        """For a stream: ``corrected(powers)`` of a finite reading (1, n) is the reading less
        its offsets; for a reading without light it raises the error ``predict`` raises."""
        ones = np.ones(self.n_ports_)
        offset = self._reading_offset_w()
        shift = bool(offset.any())

        def corrected(powers: np.ndarray) -> np.ndarray:
            if not (powers @ ones)[0] > 0:
                check_powers(powers)  # its error: the powers sum to zero or less
            return powers - offset if shift else powers

        return corrected


def _input_source(name: str, value):
    """An endless iterator of a per-reading input given once, or the iterator of many."""
    if value is None:
        return itertools.repeat(None)
    if isinstance(value, (numbers.Real, np.ndarray)) and np.ndim(value) == 0:
        return itertools.repeat(float(check_per_reading(name, value, 1)[0]))
    if isinstance(value, Iterable):
        return iter(value)
    raise InputError(
        f"{name} must be None, a number or an iterable of numbers (one per row), "
        f"got {type(value).__name__}"
    )


def _checked_row(row, inputs: dict, ports: int) -> tuple[np.ndarray, dict]:
    """A row as a finite reading (1, n) and its inputs as floats; raises what is wrong."""
    try:
        array = np.asarray(row, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"its port powers are not numbers: {row!r:.60}") from None
    try:
        inputs = {n: None if v is None else float(v) for n, v in inputs.items()}
    except (TypeError, ValueError):
        raise InputError(f"its inputs are not numbers: {inputs!r:.80}") from None
    if array.shape != (ports,):
        raise InputError(f"it has shape {array.shape}, not {ports} port powers")
    if not np.isfinite(array).all():
        raise InputError(f"a port power is NaN or inf: {array.tolist()}")
    bad = [n for n, v in inputs.items() if v is not None and not math.isfinite(v)]
    if bad:
        raise InputError(f"{' and '.join(bad)} is not a finite number")
    return array[np.newaxis], inputs
