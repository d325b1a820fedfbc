"""The HTML calibration report, its figures, and the demo job."""

from .html import write_report

__all__ = ["write_report"]
