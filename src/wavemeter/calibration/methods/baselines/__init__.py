"""Baseline calibrators: the methods people use today, with the Calibrator's API.

Reference-free (label-free) fits for measured data: :func:`fit_ellipse` /
:func:`ellipse_phase` (two ports) and :func:`fit_plane_ellipse` /
:func:`plane_ellipse_phase` (n ports). Kleijn's fit's sensitivity to its starting point:
:func:`convergence_share`.
"""

from .conventional import ConventionalCalibrator
from .ellipse import EllipseCalibrator, ellipse_phase, fit_ellipse
from .extended_conventional import ExtendedConventionalCalibrator
from .nonlinear_fit import NonlinearFitCalibrator, convergence_share
from .plane_ellipse import PlaneEllipseCalibrator, fit_plane_ellipse, plane_ellipse_phase

__all__ = [
    "ConventionalCalibrator",
    "EllipseCalibrator",
    "ExtendedConventionalCalibrator",
    "NonlinearFitCalibrator",
    "PlaneEllipseCalibrator",
    "convergence_share",
    "ellipse_phase",
    "fit_ellipse",
    "fit_plane_ellipse",
    "plane_ellipse_phase",
]
