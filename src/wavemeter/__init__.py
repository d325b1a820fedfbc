"""wavemeter: calibration and frequency retrieval for multi-port interferometric meters.

Port powers are a linear image ``p = A x`` of a vector ``x`` on a circular cone; the map is
learned in closed form from a calibration sweep, only the delay (FSR) is searched, and
phase comes back through a pseudo-inverse and an arctangent.

The public names below are loaded on first use, so ``import wavemeter`` (and the command
line's ``--help``) does not pay for numpy and scipy until they are needed.
"""

from __future__ import annotations

import importlib

from ._version import __version__

#: public name -> submodule that defines it
_WHERE = {
    "Calibrator": "calibration",
    "CalibrationSet": "calibration",
    "CascadeCalibrator": "calibration",
    "ConventionalCalibrator": "calibration",
    "EllipseCalibrator": "calibration",
    "ExtendedConventionalCalibrator": "calibration",
    "NonlinearFitCalibrator": "calibration",
    "PlaneEllipseCalibrator": "calibration",
    "ThermalCalibrator": "calibration",
    "WidebandCalibrator": "calibration",
    "load_calibration": "calibration",
    "save_calibration": "calibration",
    "predict_frequency_hz": "calibration",
    "retrieve_phase_rad": "calibration",
    "ReadingFlag": "calibration",
    "ReferenceFreeCalibrator": "calibration",
    "ReferenceLines": "reference",
    "Interferometer": "simulation",
    "CascadeInterferometer": "simulation",
    "cone_vectors": "model",
    "phase_to_frequency_hz": "model",
    "wrap_phase_rad": "model",
    "fourier_matrix": "model",
    "mmi_matrix": "model",
    "orthonormal_map": "model",
    "crlb_frequency_std": "model",
    "crlb_ideal_frequency_std": "model",
    "design_cascade": "model",
    "CascadeDesign": "model",
    "error_summary_hz": "model",
    "frequency_error_hz": "model",
    "write_report": "report",
    "WavemeterError": "exceptions",
    "InputError": "exceptions",
    "FileFormatError": "exceptions",
    "NotFittedError": "exceptions",
    "EdgeMinimumError": "exceptions",
    "CalibrationWarning": "exceptions",
    "InputNote": "exceptions",
}

#: subpackages reachable as attributes (``wm.model.cone``), loaded on first use
_SUBPACKAGES = (
    "analysis",
    "calibration",
    "fleet",
    "io",
    "jobs",
    "model",
    "reference",
    "report",
    "service",
    "simulation",
)

__all__ = sorted(_WHERE) + ["__version__"]


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'wavemeter' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public names and subpackages, and the module's dunder attributes."""
    dunders = {name for name in globals() if name.startswith("__") and name.endswith("__")}
    return sorted(dunders | set(__all__) | set(_SUBPACKAGES))
