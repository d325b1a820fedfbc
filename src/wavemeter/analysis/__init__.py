"""Figures of merit and evaluations of calibrations on readings of known frequency."""

from .evaluation import adjacent_evaluation, crlb_per_reading_hz, evaluate_calibrations
from .metrics import error_summary_hz, frequency_error_hz

__all__ = [
    "adjacent_evaluation",
    "crlb_per_reading_hz",
    "error_summary_hz",
    "evaluate_calibrations",
    "frequency_error_hz",
]
