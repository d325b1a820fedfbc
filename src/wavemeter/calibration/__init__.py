"""Calibrators: the learned map, calibration sets, baselines, and their files.

Importing this package registers every calibrator class under its file tag
(:mod:`wavemeter.calibration.files.registry`).
"""

from .contract.base import BaseCalibrator
from .contract.flags import ReadingFlag
from .files.document import load_calibration, save_calibration
from .files.registry import registered
from .methods.baselines import (
    ConventionalCalibrator,
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
)
from .methods.cascade import CascadeCalibrator
from .methods.learned import Calibrator
from .methods.set import CalibrationSet
from .methods.thermal import ThermalCalibrator
from .methods.wideband import WidebandCalibrator
from .models.learned_fit import predict_frequency_hz, retrieve_phase_rad

__all__ = [
    "BaseCalibrator",
    "Calibrator",
    "CalibrationSet",
    "CascadeCalibrator",
    "ConventionalCalibrator",
    "EllipseCalibrator",
    "ExtendedConventionalCalibrator",
    "NonlinearFitCalibrator",
    "PlaneEllipseCalibrator",
    "ReadingFlag",
    "load_calibration",
    "predict_frequency_hz",
    "registered",
    "retrieve_phase_rad",
    "save_calibration",
    "ThermalCalibrator",
    "WidebandCalibrator",
]
