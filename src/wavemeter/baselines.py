"""The baselines under their 0.1 name: ``wavemeter.baselines`` is
:mod:`wavemeter.calibration.methods.baselines`."""

from .calibration.methods.baselines import (
    ConventionalCalibrator,
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
    convergence_share,
    ellipse_phase,
    fit_ellipse,
    fit_plane_ellipse,
    plane_ellipse_phase,
)

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
