"""Calibration files: versioned JSON that :func:`load_calibration` checks before use.

Floats are written with Python's shortest round-trip representation, so a loaded
calibration predicts bit for bit what the saved one did.
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from ..atomic import atomic_path
from ..exceptions import FileFormatError
from ..validation import check_fitted
from .registry import calibrator_class, registered

if TYPE_CHECKING:
    from .base import BaseCalibrator

__all__ = ["save_calibration", "load_calibration", "FORMAT", "SCHEMA_VERSION"]

FORMAT = "wavemeter.calibration"
SCHEMA_VERSION = 1
UNITS = {"frequency": "Hz", "power": "W", "phase": "rad", "delay": "s"}


def _package_version() -> str:
    from .._version import __version__

    return __version__


def calibration_to_dict(calibrator: BaseCalibrator, metadata: dict | None = None) -> dict:
    """The JSON document of a fitted calibrator."""
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "wavemeter_version": _package_version(),
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "units": UNITS,
        **calibrator_fields(calibrator),
        "metadata": metadata or {},
    }


def calibrator_fields(calibrator: BaseCalibrator) -> dict:
    """Method, settings and learned values of a fitted calibrator, JSON-ready.

    The body of a calibration file without its header; a calibration set stores one per
    window. The method tag is the class's (an instance attribute of the same name, such as
    :class:`wavemeter.CalibrationSet`'s window method, does not replace it).
    """
    check_fitted(calibrator)
    return {
        "method": type(calibrator).method,
        "params": calibrator.get_params_for_file(),
        "fsr_hz": calibrator.fsr_hz_,
        "center_hz": calibrator.center_hz_,
        "span_hz": list(calibrator.span_hz_),
        "n_ports": calibrator.n_ports_,
        "port_names": list(calibrator.port_names_),
        "n_samples": calibrator.n_samples_,
        "calibration_rms_hz": calibrator.calibration_rms_hz_,
        "state": calibrator._state(),
    }


def save_calibration(calibrator: BaseCalibrator, path, metadata: dict | None = None) -> None:
    """Write a fitted calibrator to ``path`` as JSON, atomically.

    Parameters
    ----------
    calibrator : BaseCalibrator
        A fitted calibrator.
    path : str or Path
        Target file, conventionally ``*.wmcal.json``.
    metadata : dict, optional
        JSON-ready notes kept with the calibration (source file, units, ...).
    """
    document = calibration_to_dict(calibrator, metadata)
    text = json.dumps(document, indent=1, allow_nan=False)
    with atomic_path(path) as temporary:
        temporary.write_text(text + "\n", encoding="utf-8")


def _fail(path, problem: str) -> FileFormatError:
    return FileFormatError(f"{path}: {problem}")


def _number(document: dict, key: str, path) -> float:
    value = document.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(path, f"field {key!r} must be a finite number, got {value!r}")
    return float(value)


def calibration_from_dict(document, path="<calibration>") -> BaseCalibrator:
    """Rebuild a calibrator from its JSON document, checking format, version and fields."""
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise _fail(path, f"not a wavemeter calibration file (no format {FORMAT!r})")
    version = document.get("schema_version")
    if not isinstance(version, int) or not 1 <= version <= SCHEMA_VERSION:
        raise _fail(
            path,
            f"calibration schema_version {version!r} is not supported by wavemeter "
            f"{_package_version()} (reads 1..{SCHEMA_VERSION}); upgrade wavemeter",
        )
    return calibrator_from_fields(document, path)


def calibrator_from_fields(document: dict, path="<calibration>") -> BaseCalibrator:
    """Rebuild a fitted calibrator from the fields :func:`calibrator_fields` wrote.

    ``path`` names the source in error messages (a file, or a window of a set).
    """
    if not isinstance(document, dict):
        raise _fail(path, f"calibration fields must be an object, got {type(document).__name__}")
    method = document.get("method")
    cls = calibrator_class(method)
    if cls is None:
        raise _fail(path, f"unknown calibration method {method!r}; known: {sorted(registered())}")
    params = document.get("params")
    state = document.get("state")
    if not isinstance(params, dict) or not isinstance(state, dict):
        raise _fail(path, "fields 'params' and 'state' must be objects")
    try:
        calibrator = cls(**cls._params_from_file(params))
    except TypeError as exc:
        raise _fail(path, f"parameters do not fit method {method!r}: {exc}") from exc
    n_ports = document.get("n_ports")
    names = document.get("port_names")
    span = document.get("span_hz")
    if not isinstance(n_ports, int) or n_ports < 3:
        raise _fail(path, f"field 'n_ports' must be an integer >= 3, got {n_ports!r}")
    if not isinstance(names, list) or len(names) != n_ports:
        raise _fail(path, f"field 'port_names' must list {n_ports} names, got {names!r}")
    if not isinstance(span, list) or len(span) != 2:
        raise _fail(path, f"field 'span_hz' must be [low, high], got {span!r}")
    calibrator.fsr_hz_ = _number(document, "fsr_hz", path)
    calibrator.center_hz_ = _number(document, "center_hz", path)
    calibrator.span_hz_ = (float(span[0]), float(span[1]))
    calibrator.n_ports_ = n_ports
    calibrator.port_names_ = [str(name) for name in names]
    calibrator.n_samples_ = int(_number(document, "n_samples", path))
    calibrator.calibration_rms_hz_ = _number(document, "calibration_rms_hz", path)
    try:
        calibrator._set_state(state)
        calibrator._check_state()
    except (KeyError, TypeError, ValueError) as exc:
        raise _fail(path, f"invalid {method!r} calibration state: {exc}") from exc
    return calibrator


def load_calibration(path) -> BaseCalibrator:
    """Read a calibration file written by :meth:`save` and return the fitted calibrator.

    Raises
    ------
    FileFormatError
        When the file is missing, truncated, not JSON, of another format or version, or
        its content is inconsistent. The message names the file and what is wrong.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise FileFormatError(f"{path}: calibration file not found") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{path}: cannot read calibration file ({exc})") from exc
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(
            f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}); the file is corrupt or "
            "truncated: write it again with `wavemeter calibrate`"
        ) from exc
    return calibration_from_dict(document, path)
