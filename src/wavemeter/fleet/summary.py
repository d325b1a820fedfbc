"""The fleet's summary table: one row per device, written as CSV and as Parquet.

Columns, in order: ``device``, ``status`` (``ok``/``error``), ``resumed`` (1 when the
calibration was found from an earlier run), ``samples``, ``fsr_hz``, ``noise_std_w``,
``calibration_rms_hz``, ``crlb_rms_hz``, ``crlb_ratio``, ``warnings`` (causes of the
calibration warnings, separated by ``"; "``), ``error`` (the message of a failed device),
``die_x``, ``die_y`` (position on the wafer from the device name, NaN when it has none) and
``source`` (the sweep file). Numbers of a failed device are NaN. Both files hold the same
values: CSV floats are the shortest text that reads back to the same float64.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np

from ..io import write_table
from ..jobs.calibrate import DeviceResult

__all__ = [
    "SUMMARY_COLUMNS",
    "WARNING_SEPARATOR",
    "die_position",
    "summary_columns",
    "write_summary",
]

#: the summary's columns, in order
SUMMARY_COLUMNS = (
    "device",
    "status",
    "resumed",
    "samples",
    "fsr_hz",
    "noise_std_w",
    "calibration_rms_hz",
    "crlb_rms_hz",
    "crlb_ratio",
    "warnings",
    "error",
    "die_x",
    "die_y",
    "source",
)
#: between the causes of one device's calibration warnings
WARNING_SEPARATOR = "; "
#: a die position in a device name: ``x03_y12``, ``X-2Y5``, ``x3-y4``, not inside a word
_POSITION = re.compile(r"(?<![A-Za-z0-9])[xX](-?\d+)[_-]?[yY](-?\d+)(?![0-9])")


def die_position(device: str) -> tuple[int, int] | None:
    """The die's position on the wafer from its name (``die_x03_y12`` -> ``(3, 12)``).

    The first ``x<int>`` followed by ``y<int>`` (optionally one ``_`` or ``-`` between,
    either case, integers may be negative) that does not start inside a word; None when
    the name has none.

    Examples
    --------
    >>> from wavemeter.fleet import die_position
    >>> die_position("die_x03_y12"), die_position("W7-X-3Y12"), die_position("chip7")
    ((3, 12), (-3, 12), None)
    """
    found = _POSITION.search(device)
    return None if found is None else (int(found.group(1)), int(found.group(2)))


def summary_columns(rows: Sequence[DeviceResult]) -> dict[str, np.ndarray]:
    """The summary's columns (:data:`SUMMARY_COLUMNS`), one entry per device, in order."""
    positions = [die_position(row.device) or (math.nan, math.nan) for row in rows]
    return {
        "device": np.array([row.device for row in rows], dtype=str),
        "status": np.array([row.status for row in rows], dtype=str),
        "resumed": np.array([int(row.resumed) for row in rows], dtype=np.int64),
        "samples": np.array([row.samples for row in rows], dtype=np.int64),
        "fsr_hz": np.array([row.fsr_hz for row in rows], dtype=float),
        "noise_std_w": np.array([row.noise_std_w for row in rows], dtype=float),
        "calibration_rms_hz": np.array([row.calibration_rms_hz for row in rows], dtype=float),
        "crlb_rms_hz": np.array([row.crlb_rms_hz for row in rows], dtype=float),
        "crlb_ratio": np.array([row.crlb_ratio for row in rows], dtype=float),
        "warnings": np.array([WARNING_SEPARATOR.join(row.warnings) for row in rows], dtype=str),
        "error": np.array([row.error for row in rows], dtype=str),
        "die_x": np.array([position[0] for position in positions], dtype=float),
        "die_y": np.array([position[1] for position in positions], dtype=float),
        "source": np.array([row.source for row in rows], dtype=str),
    }


def write_summary(rows: Sequence[DeviceResult], csv_path, parquet_path) -> None:
    """Write the summary of ``rows`` to ``csv_path`` and ``parquet_path``, each atomically."""
    columns = summary_columns(rows)
    write_table(csv_path, columns, "csv")
    write_table(parquet_path, columns, "parquet")
