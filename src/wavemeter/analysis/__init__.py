"""Figures of merit and evaluations of calibrations on readings of known frequency."""

from .evaluation import adjacent_evaluation
from .metrics import error_summary_hz, frequency_error_hz

__all__ = ["adjacent_evaluation", "error_summary_hz", "frequency_error_hz"]
