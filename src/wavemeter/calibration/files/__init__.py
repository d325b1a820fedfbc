"""Calibration files and the registry of the methods they name: versioned JSON checked
before use (every number against the rules its class declares), and tag -> class (built
in, or from the ``wavemeter.calibrators`` entry-point group)."""

from .document import load_calibration, read_calibration_file, save_calibration
from .fields import declared_rules
from .registry import calibrator_class, registered

__all__ = [
    "calibrator_class",
    "declared_rules",
    "load_calibration",
    "read_calibration_file",
    "registered",
    "save_calibration",
]
