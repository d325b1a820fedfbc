"""Reference lines of a gas cell and the maths that makes a sweep's axis absolute.

The line table (:class:`ReferenceLines`, read from a CSV the user supplies; no table of a
standard cell ships, see ``docs``), the line shape (Voigt absorption), finding and fitting
lines in a transmission record, identifying them with table lines, and the correction of a
sweep's frequency axis from the meter's own phase with its uncertainty budget. A model-level
package: it knows nothing of calibrators, files of readings or simulations.
"""

from .axis import BUDGET_TERMS, AxisCorrection, fit_axis_correction
from .identify import Identification, identify_lines
from .line_fit import FittedLines, find_absorption_lines, fit_absorption_lines, record_noise_std
from .lines import LINE_TABLE_COLUMNS, ReferenceLines
from .lineshape import doppler_sigma_hz, voigt_absorbance, voigt_fwhm_hz
from .sweep import (
    SweepAxis,
    axis_from_phase,
    correct_sweep_axis,
    smooth_sweep_phase,
    smoothing_bandwidth,
)

__all__ = [
    "AxisCorrection",
    "BUDGET_TERMS",
    "FittedLines",
    "Identification",
    "LINE_TABLE_COLUMNS",
    "ReferenceLines",
    "SweepAxis",
    "axis_from_phase",
    "correct_sweep_axis",
    "doppler_sigma_hz",
    "find_absorption_lines",
    "fit_absorption_lines",
    "fit_axis_correction",
    "identify_lines",
    "record_noise_std",
    "smooth_sweep_phase",
    "smoothing_bandwidth",
    "voigt_absorbance",
    "voigt_fwhm_hz",
]
