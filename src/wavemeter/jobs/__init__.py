"""Jobs over files: measure a file of readings in bounded memory, make a record one
frequency series, calibrate a device file.

The command line runs these; they know files (``wavemeter.io``) and calibrations
(``wavemeter.calibration``), and nothing about the command line.
"""

from .calibrate import (
    DeviceResult,
    SweepRead,
    calibrate_device,
    calibrate_file,
    fit_sweep_chunks,
)
from .line_reader import LineReader
from .measure import MEASURE_CHUNK_ROWS, MeasureSummary, check_stream, measure_file
from .noise import NoiseSeries, measure_series
from .stream import (
    StreamHeader,
    StreamSummary,
    follow_lines,
    read_header,
    stream_lines,
)

__all__ = [
    "measure_file",
    "MeasureSummary",
    "MEASURE_CHUNK_ROWS",
    "stream_lines",
    "follow_lines",
    "read_header",
    "LineReader",
    "StreamHeader",
    "StreamSummary",
    "check_stream",
    "calibrate_file",
    "calibrate_device",
    "DeviceResult",
    "fit_sweep_chunks",
    "SweepRead",
    "measure_series",
    "NoiseSeries",
]
