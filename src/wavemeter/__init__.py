"""wavemeter: calibration and frequency retrieval for multi-port interferometric meters.

Port powers are a linear image ``p = A x`` of a vector ``x`` on a circular cone; the map is
learned in closed form from a calibration sweep, only the delay (FSR) is searched, and
phase comes back through a pseudo-inverse and an arctangent.
"""

from .baselines import (
    ConventionalCalibrator,
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
)
from .calibration import Calibrator, predict_frequency_hz, retrieve_phase_rad
from .calibration_set import CalibrationSet
from .cone import cone_vectors, phase_to_frequency_hz, wrap_phase_rad
from .couplers import fourier_matrix, mmi_matrix, orthonormal_map
from .delay_search import EdgeMinimumError
from .limits import crlb_frequency_std, crlb_ideal_frequency_std
from .metrics import error_summary_hz, frequency_error_hz
from .persistence import load_calibration, save_calibration
from .report import write_report
from .simulation import Interferometer
from .validation import NotFittedError

__version__ = "0.1.0"

__all__ = [
    "Calibrator",
    "CalibrationSet",
    "ConventionalCalibrator",
    "EllipseCalibrator",
    "ExtendedConventionalCalibrator",
    "NonlinearFitCalibrator",
    "PlaneEllipseCalibrator",
    "EdgeMinimumError",
    "Interferometer",
    "NotFittedError",
    "cone_vectors",
    "crlb_frequency_std",
    "crlb_ideal_frequency_std",
    "error_summary_hz",
    "fourier_matrix",
    "frequency_error_hz",
    "load_calibration",
    "mmi_matrix",
    "orthonormal_map",
    "phase_to_frequency_hz",
    "predict_frequency_hz",
    "retrieve_phase_rad",
    "save_calibration",
    "write_report",
    "wrap_phase_rad",
    "__version__",
]
