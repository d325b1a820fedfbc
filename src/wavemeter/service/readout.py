"""Reading blocks of port powers out with a calibration: one row as fast as many.

:meth:`readout <wavemeter.calibration.BaseCalibrator.readout>` costs about the same per
call whatever the rows (its flags and uncertainty are worked out for the block);
:meth:`row_reader <wavemeter.calibration.BaseCalibrator.row_reader>` reads one row with
what stays the same worked out once. A :class:`CalibrationReader` reads blocks of up to
:data:`STREAM_ROWS` rows a row at a time and larger ones in one readout (measured for the
Table 1 learned calibration: one row 0.02-0.025 ms, 16 rows 0.33 ms, against 0.2-0.4 ms for
a readout of 1 to 64 rows); both give the same numbers. It is made once per calibration:
a reload makes a new one, so a block is always read by one calibration.
"""

from __future__ import annotations

import numpy as np

from ..calibration import ReadingFlag

__all__ = ["CalibrationReader", "STREAM_ROWS"]

#: blocks of at most this many rows are read a row at a time (a service that fell behind
#: reads what waits as one block: row by row it would cost more per row)
STREAM_ROWS = 16


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
        self._read_row = calibration.row_reader()

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
        read = self._read_row
        records = [
            read(
                powers_w[k],
                None if coarse is None else float(coarse[k]),
                None if temperature is None else float(temperature[k]),
            )
            for k in range(rows)
        ]
        frequency = np.array([record.frequency_hz for record in records], dtype=float)
        std = np.array([record.frequency_std_hz for record in records], dtype=float)
        flags = np.array([record.flags for record in records], dtype=np.int64)
        extras = {
            name: np.array([record.extras[name] for record in records], dtype=float)
            for name in self.extras
        }
        return frequency, std, flags, extras

    def unread(self, rows: int):
        """What :meth:`read` gives readings that cannot be read: NaN and ``INVALID``."""
        nan = np.full(rows, np.nan)
        flags = np.full(rows, int(ReadingFlag.INVALID), dtype=np.int64)
        return nan, nan.copy(), flags, {name: np.full(rows, np.nan) for name in self.extras}
