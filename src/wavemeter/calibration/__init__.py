"""Calibrators: the learned map, calibration sets, baselines, and their files.

Importing this package registers every calibrator class under its file tag
(:mod:`wavemeter.calibration.registry`).
"""

from .absolute import ReferenceFreeCalibrator, self_calibrate
from .base import BaseCalibrator
from .baselines import (
    ConventionalCalibrator,
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
)
from .cascade import CascadeCalibrator
from .files import load_calibration, save_calibration
from .flags import ReadingFlag
from .learned import Calibrator, predict_frequency_hz, retrieve_phase_rad
from .registry import registered
from .set import CalibrationSet
from .thermal import ThermalCalibrator
from .wideband import WidebandCalibrator

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
    "ReferenceFreeCalibrator",
    "load_calibration",
    "predict_frequency_hz",
    "registered",
    "retrieve_phase_rad",
    "save_calibration",
    "self_calibrate",
    "ThermalCalibrator",
    "WidebandCalibrator",
]
