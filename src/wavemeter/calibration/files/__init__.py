"""Calibration files and the registry of the methods they name: versioned JSON checked
before use, and tag -> class (built in, or from the ``wavemeter.calibrators`` entry-point
group)."""

from .document import load_calibration, read_calibration_file, save_calibration
from .registry import calibrator_class, registered

__all__ = [
    "calibrator_class",
    "load_calibration",
    "read_calibration_file",
    "registered",
    "save_calibration",
]
