"""The physics: object space on the cone, coupler matrices, phase retrieval and its limit."""

from .cone import (
    cone_vectors,
    delay_phase_rad,
    phase_to_frequency_hz,
    wrap_phase_rad,
    wrap_to_period,
)
from .couplers import fourier_matrix, mmi_matrix, orthonormal_map
from .limits import crlb_frequency_std, crlb_ideal_frequency_std
from .retrieval import cone_ml_phase_rad, source_power_ratio

__all__ = [
    "cone_vectors",
    "delay_phase_rad",
    "phase_to_frequency_hz",
    "wrap_phase_rad",
    "wrap_to_period",
    "fourier_matrix",
    "mmi_matrix",
    "orthonormal_map",
    "crlb_frequency_std",
    "crlb_ideal_frequency_std",
    "cone_ml_phase_rad",
    "source_power_ratio",
]
