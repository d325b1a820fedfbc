"""Baseline calibrators: the methods people use today, with the Calibrator's API."""

from .conventional import ConventionalCalibrator

__all__ = ["ConventionalCalibrator"]
