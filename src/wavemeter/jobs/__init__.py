"""Jobs over files: measure a file of readings in bounded memory.

The command line runs these; they know files (``wavemeter.io``) and calibrations
(``wavemeter.calibration``), and nothing about the command line.
"""

from .measure import MEASURE_CHUNK_ROWS, MeasureSummary, measure_file

__all__ = ["measure_file", "MeasureSummary", "MEASURE_CHUNK_ROWS"]
