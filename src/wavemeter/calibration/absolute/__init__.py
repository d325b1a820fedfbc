"""Absolute calibration without a calibrated laser: the reference-free cone and
self-calibration from a reference cell.

:mod:`.cone_fit` learns the cone of readings from the powers alone; :mod:`.reference_free`
is the calibrator built on it; :mod:`.self_calibration` turns a sweep with no frequency axis
and a cell's lines into an absolute axis. The axis correction of a recorded sweep, which
needs no calibration code, is :func:`wavemeter.reference.correct_sweep_axis`.
"""

from .cone_fit import ConeFit, cone_phase_rad, fit_cone
from .reference_free import ReferenceFreeCalibrator
from .self_calibration import SelfCalibration, self_calibrate, sweep_phase_reference_free

__all__ = [
    "ConeFit",
    "ReferenceFreeCalibrator",
    "SelfCalibration",
    "cone_phase_rad",
    "fit_cone",
    "self_calibrate",
    "sweep_phase_reference_free",
]
