"""The physics: object space on the cone, coupler matrices, phase retrieval, its limit and
the uncertainty of a reading."""

from .cascade_design import design_cascade
from .cascade_result import CascadeDesign
from .cone import (
    cone_vectors,
    delay_phase_rad,
    phase_to_frequency_hz,
    wrap_phase_rad,
    wrap_to_period,
)
from .couplers import fourier_matrix, mmi_matrix, orthonormal_map
from .errors import error_summary_hz, frequency_error_hz
from .limits import check_noise_std, crlb_frequency_std, crlb_ideal_frequency_std
from .orders import (
    any_error_probability,
    edge_error_probability,
    handover_error_probability,
    handover_error_rate,
    wrap_error_probability,
)
from .retrieval import cone_ml_phase_rad, source_power_ratio
from .uncertainty import (
    calibration_frequency_variance_hz2,
    fit_parameter_covariance,
    ml_phase_gradient,
    phase_std_rad,
    pinv_phase_gradient,
    student_factor,
)

__all__ = [
    "cone_vectors",
    "delay_phase_rad",
    "phase_to_frequency_hz",
    "wrap_phase_rad",
    "wrap_to_period",
    "error_summary_hz",
    "frequency_error_hz",
    "fourier_matrix",
    "mmi_matrix",
    "orthonormal_map",
    "crlb_frequency_std",
    "crlb_ideal_frequency_std",
    "check_noise_std",
    "cone_ml_phase_rad",
    "source_power_ratio",
    "pinv_phase_gradient",
    "ml_phase_gradient",
    "phase_std_rad",
    "fit_parameter_covariance",
    "calibration_frequency_variance_hz2",
    "student_factor",
    "handover_error_probability",
    "handover_error_rate",
    "edge_error_probability",
    "any_error_probability",
    "wrap_error_probability",
    "CascadeDesign",
    "design_cascade",
]
