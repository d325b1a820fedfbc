"""Figures of merit and evaluations of calibrations on readings of known frequency, and
frequency-noise metrology of a laser from a meter's readings."""

from ..model.errors import error_summary_hz, frequency_error_hz
from .evaluation import crlb_per_reading_hz, evaluate_calibrations
from .noise import frequency_noise
from .noise_fit import beta_separation_line_hz2_per_hz
from .noise_result import FrequencyNoise
from .power_law import power_law_deviations, power_law_psd_hz2_per_hz

__all__ = [
    "crlb_per_reading_hz",
    "error_summary_hz",
    "evaluate_calibrations",
    "frequency_error_hz",
    "FrequencyNoise",
    "frequency_noise",
    "beta_separation_line_hz2_per_hz",
    "power_law_deviations",
    "power_law_psd_hz2_per_hz",
]
