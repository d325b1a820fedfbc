"""Calibrators: the learned map and its forms, the baselines, their files and registry.

Importing this package registers every built-in calibrator under its file tag; other
packages add theirs through the ``wavemeter.calibrators`` entry-point group
(:mod:`wavemeter.calibration.files.registry`). A calibrator of your own subclasses
:class:`BaseCalibrator` (with :class:`SweepFitMixin` for the checked fit of a sweep): see
the user guide's page on writing a calibrator.
"""

from .contract.base import BaseCalibrator, Part
from .contract.figures import FigureData, FringePanel, Series
from .contract.flags import ReadingFlag
from .contract.records import ReadingInputs, Readout, StreamReading
from .contract.summary import Check, FitReport, FitValue, Table
from .files.document import load_calibration, save_calibration
from .files.registry import calibrator_class, registered
from .fitting.steps import SweepFitMixin
from .fitting.sweep import FitContext, Sweep
from .methods.baselines import (
    ConventionalCalibrator,
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
)
from .methods.cascade import CascadeCalibrator
from .methods.learned import Calibrator
from .methods.reference_free import ReferenceFreeCalibrator
from .methods.set import CalibrationSet
from .methods.thermal import ThermalCalibrator
from .methods.wideband import WidebandCalibrator
from .models.cone_fit import ConeFit, cone_phase_rad, fit_cone
from .models.learned_fit import predict_frequency_hz, retrieve_phase_rad
from .models.self_calibration import (
    SelfCalibration,
    self_calibrate,
    sweep_phase_reference_free,
)

__all__ = [
    "BaseCalibrator",
    "Calibrator",
    "CalibrationSet",
    "CascadeCalibrator",
    "Check",
    "ConventionalCalibrator",
    "EllipseCalibrator",
    "ExtendedConventionalCalibrator",
    "FigureData",
    "FitContext",
    "FitReport",
    "FitValue",
    "FringePanel",
    "NonlinearFitCalibrator",
    "Part",
    "PlaneEllipseCalibrator",
    "ReferenceFreeCalibrator",
    "SelfCalibration",
    "ConeFit",
    "cone_phase_rad",
    "fit_cone",
    "self_calibrate",
    "sweep_phase_reference_free",
    "ReadingFlag",
    "ReadingInputs",
    "Readout",
    "Series",
    "StreamReading",
    "Sweep",
    "SweepFitMixin",
    "Table",
    "ThermalCalibrator",
    "WidebandCalibrator",
    "calibrator_class",
    "load_calibration",
    "predict_frequency_hz",
    "registered",
    "retrieve_phase_rad",
    "save_calibration",
]
