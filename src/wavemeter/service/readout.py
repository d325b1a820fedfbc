"""Reading blocks of port powers out with a calibration: one row as fast as many.

:meth:`readout <wavemeter.calibration.BaseCalibrator.readout>` costs about a
millisecond per call whatever the rows (its flags and uncertainty are worked out for the
block), too slow for a live reading at a time; :meth:`stream
<wavemeter.calibration.BaseCalibrator.stream>` reads one row in a pass with what stays
the same worked out once. A :class:`CalibrationReader` uses ``stream`` for a few rows and
``readout`` for more; both give the same numbers. It is made once per calibration: a
reload makes a new one, so a block is always read by one calibration.
"""

from __future__ import annotations

import numpy as np

from ..calibration import ReadingFlag

__all__ = ["CalibrationReader", "STREAM_ROWS"]

#: blocks of at most this many rows are read a row at a time
STREAM_ROWS = 4


class _Latest:
    """An endless iterator of the value set last (a row handed to ``calibration.stream``)."""

    __slots__ = ("value",)

    def __init__(self):
        self.value = None

    def __iter__(self):
        return self

    def __next__(self):
        return self.value


class CalibrationReader:
    """Frequency, uncertainty, flags and extra outputs of blocks of readings.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration (any method: only what it declares is asked).
    """

    def __init__(self, calibration):
        self.calibration = calibration
        self.extras = tuple(calibration.reading_outputs)
        self.uses_temperature = "temperature_k" in calibration.requires
        self.uses_coarse = "coarse_hz" in calibration.requires
        self._powers = _Latest()
        self._temperature = _Latest() if self.uses_temperature else None
        self._coarse = _Latest() if self.uses_coarse else None
        self._records = None

    def read(self, powers_w, temperature_k=None, coarse_hz=None):
        """Read a block of valid readings.

        Parameters
        ----------
        powers_w : ndarray, shape (N, ports)
            Port powers in the calibration's unit.
        temperature_k, coarse_hz : ndarray, shape (N,), optional
            Per-reading inputs, where the calibration uses them.

        Returns
        -------
        (frequency_hz, frequency_std_hz, flags, extras)
            Arrays (N,) (flags int64) and a dict of name -> (N,) array.
        """
        rows = len(powers_w)
        temperature = temperature_k if self.uses_temperature else None
        coarse = coarse_hz if self.uses_coarse else None
        if rows > STREAM_ROWS:
            found = self.calibration.readout(powers_w, coarse_hz=coarse, temperature_k=temperature)
            flags = np.asarray(found.flags, dtype=np.int64)
            return found.frequency_hz, found.frequency_std_hz, flags, found.extras
        frequency = np.empty(rows)
        std = np.empty(rows)
        flags = np.empty(rows, dtype=np.int64)
        extras = {name: np.empty(rows) for name in self.extras}
        records = self._stream()
        for k in range(rows):
            self._powers.value = powers_w[k]
            if self._temperature is not None:
                self._temperature.value = float(temperature[k])
            if self._coarse is not None:
                self._coarse.value = float(coarse[k])
            record = next(records)
            frequency[k] = record.frequency_hz
            std[k] = record.frequency_std_hz
            flags[k] = record.flags
            for name in self.extras:
                extras[name][k] = record.extras[name]
        return frequency, std, flags, extras

    def _stream(self):
        if self._records is None:
            self._records = self.calibration.stream(
                self._powers, coarse_hz=self._coarse, temperature_k=self._temperature
            )
        return self._records

    def unread(self, rows: int):
        """What :meth:`read` gives readings that cannot be read: NaN and ``INVALID``."""
        nan = np.full(rows, np.nan)
        flags = np.full(rows, int(ReadingFlag.INVALID), dtype=np.int64)
        return nan, nan.copy(), flags, {name: np.full(rows, np.nan) for name in self.extras}
