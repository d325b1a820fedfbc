"""Jobs over files: calibrate a device from its sweep, measure a file of readings in bounded
memory, stream a live readout, make a record one frequency series; and the one set of
checks of readings against a calibration they share.

The command line and the fleet run these; they know files (``wavemeter.io``) and
calibrations (``wavemeter.calibration``, asked what they declare), and nothing about the
command line.
"""

from .calibrate import CalibrationRefused, DeviceResult, calibrate_device, calibrate_file
from .calibrator import CalibrateOptions, build_calibrator, method_settings
from .chunks import RowSample, fit_sweep_chunks
from .line_reader import LineReader
from .measure import MEASURE_CHUNK_ROWS, MeasureSummary, ReadingsRefused, measure_file
from .noise import NoiseSeries, measure_series
from .readings import check_ports, check_reading_options, check_readings
from .stream import StreamSummary, follow_lines, stream_lines
from .stream_header import StreamHeader, read_header
from .sweeps import SweepRead, SweepsRead

__all__ = [
    "CalibrateOptions",
    "build_calibrator",
    "method_settings",
    "calibrate_file",
    "calibrate_device",
    "CalibrationRefused",
    "DeviceResult",
    "fit_sweep_chunks",
    "RowSample",
    "SweepRead",
    "SweepsRead",
    "measure_file",
    "MeasureSummary",
    "ReadingsRefused",
    "MEASURE_CHUNK_ROWS",
    "stream_lines",
    "follow_lines",
    "read_header",
    "LineReader",
    "StreamHeader",
    "StreamSummary",
    "measure_series",
    "NoiseSeries",
    "check_reading_options",
    "check_readings",
    "check_ports",
]
