"""Calibration files: versioned JSON that :func:`load_calibration` checks before use.

Floats are written with Python's shortest round-trip representation, so a loaded
calibration predicts bit for bit what the saved one did.

A file is untrusted input. Reading is bounded (at most ``MAX_FILE_BYTES``, nesting at most
``MAX_DEPTH`` deep, integers of at most ``MAX_INTEGER_DIGITS`` digits, so a device, a FIFO
or a crafted document cannot exhaust memory or the stack), and every number is checked
before the calibrator is rebuilt: finite, of the right shape and range (an FSR > 0 and
below an optical centre frequency, a span ``[low, high]``, a map of full rank, a delay equal
to ``1 / FSR``). Anything else is a :class:`~wavemeter.exceptions.FileFormatError` naming
the file and the field.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

import numpy as np

from ...atomic import atomic_path
from ...exceptions import FileFormatError, InputError, WavemeterError
from ...validation import MIN_SAMPLES, check_fitted
from .registry import calibrator_class, registered

__all__ = [
    "CENTER_RANGE_HZ",
    "CalibrationFile",
    "FORMAT",
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_INTEGER_DIGITS",
    "SCHEMA_VERSION",
    "calibration_from_dict",
    "calibration_to_dict",
    "calibrator_fields",
    "calibrator_from_fields",
    "load_calibration",
    "parse_calibration_text",
    "read_calibration_file",
    "save_calibration",
    "state_array",
    "state_float",
]


class FittedCalibrator(Protocol):
    """What a calibration file is written from and read into: a calibrator
    (:class:`wavemeter.calibration.contract.base.BaseCalibrator`, which calls this module to save
    itself; this module names it only through this protocol, so the two import one way)."""

    method: str
    fsr_hz_: float
    center_hz_: float

    def get_params_for_file(self) -> dict: ...

    def _absolute_state(self) -> dict | None: ...


FORMAT = "wavemeter.calibration"
#: 2 (wavemeter 0.3): the reading model (dark readings, fitted offsets, total power range),
#: per-port noise and the fit's parameter covariance; a reader of 1 would ignore the offsets.
#: Optional field ``absolute`` (after 0.7.1): a reference cell's axis correction and absolute
#: budget; a reader that ignores it predicts the same, so the version stays 2
SCHEMA_VERSION = 2
UNITS = {"frequency": "Hz", "power": "W", "phase": "rad", "delay": "s"}
#: largest calibration file read (a calibration set of 1,000 windows is about 2 MB)
MAX_FILE_BYTES = 64 * 2**20
#: deepest nesting of JSON arrays and objects (a calibration set file nests 6 deep)
MAX_DEPTH = 64
#: longest integer literal (the port and sample counts need a few digits)
MAX_INTEGER_DIGITS = 30
#: centre frequencies a calibration of light may have (Hz): 1 THz (300 um) to 3 PHz
#: (100 nm), wider than the band the column readers accept, so any optical fit loads
CENTER_RANGE_HZ = (1e12, 3e15)
#: relative mismatch allowed between a stored delay and 1 / FSR (rounding only)
DELAY_RTOL = 1e-9


def _package_version() -> str:
    from ..._version import __version__

    return __version__


# ---------------------------------------------------------------------------- writing
def calibration_to_dict(calibrator: FittedCalibrator, metadata: dict | None = None) -> dict:
    """The JSON document of a fitted calibrator."""
    if metadata is not None and not isinstance(metadata, dict):
        raise InputError(f"metadata must be a dict, got {type(metadata).__name__}")
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "wavemeter_version": _package_version(),
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "units": UNITS,
        **calibrator_fields(calibrator),
        "metadata": metadata or {},
    }


def calibrator_fields(calibrator: FittedCalibrator) -> dict:
    """Method, settings, learned values and diagnostics of a fitted calibrator, JSON-ready.

    The body of a calibration file without its header; a calibration set stores one per
    window. The method tag is the class's (an instance attribute of the same name, such as
    :class:`wavemeter.CalibrationSet`'s window method, does not replace it).
    """
    check_fitted(calibrator)
    # a reference cell's axis correction and budget, only where there was a cell
    absolute = calibrator._absolute_state()
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
        "reading_model": calibrator._reading_model_state(),
        "state": calibrator._state(),
        "diagnostics": calibrator.diagnostics_,
        **({} if absolute is None else {"absolute": absolute}),
    }


def save_calibration(calibrator: FittedCalibrator, path, metadata: dict | None = None) -> None:
    """Write a fitted calibrator to ``path`` as JSON, atomically.

    Parameters
    ----------
    calibrator : FittedCalibrator
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


# ---------------------------------------------------------------------------- checks
def _fail(path, problem: str) -> FileFormatError:
    return FileFormatError(f"{path}: {problem}")


def _is_real(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def state_float(
    state: dict,
    key: str,
    *,
    minimum: float | None = None,
    open_minimum: bool = False,
    maximum: float | None = None,
) -> float:
    """A finite number from a loaded state, within ``[minimum, maximum]`` when given.

    Raises
    ------
    InputError
        Naming the field, when it is missing, not a number, not finite or out of range.
    """
    if key not in state:
        raise InputError(f"field {key!r} is missing")
    value = state[key]
    if not _is_real(value) or not math.isfinite(value):
        raise InputError(f"field {key!r} must be a finite number, got {value!r:.80}")
    value = float(value)
    if minimum is not None and (value < minimum or (open_minimum and value == minimum)):
        relation = ">" if open_minimum else ">="
        raise InputError(f"field {key!r} must be {relation} {minimum:g}, got {value!r}")
    if maximum is not None and value > maximum:
        raise InputError(f"field {key!r} must be <= {maximum:g}, got {value!r}")
    return value


def state_array(state: dict, key: str, shape: tuple) -> np.ndarray:
    """A finite float array of ``shape`` (None: any length) from a loaded state.

    Raises
    ------
    InputError
        Naming the field, when it is missing, ragged, not numeric, of another shape or
        holds NaN or inf.
    """
    if key not in state:
        raise InputError(f"field {key!r} is missing")
    try:
        array = np.asarray(state[key])
    except (ValueError, TypeError) as exc:
        raise InputError(f"field {key!r} must be nested lists of numbers ({exc})") from exc
    if array.dtype.kind not in "iuf":
        raise InputError(f"field {key!r} must hold numbers only, got {array.dtype} values")
    matches = array.ndim == len(shape) and all(
        size is None or size == actual for size, actual in zip(shape, array.shape, strict=True)
    )
    if not matches or not np.all(np.isfinite(array)):
        sizes = " x ".join("any" if size is None else str(size) for size in shape)
        raise InputError(f"field {key!r} must be {sizes} finite numbers, got shape {array.shape}")
    return array.astype(float)


def _number(document: dict, key: str, path) -> float:
    value = document.get(key)
    if not _is_real(value) or not math.isfinite(value):
        raise _fail(path, f"field {key!r} must be a finite number, got {value!r:.80}")
    return float(value)


def _count(document: dict, key: str, path, minimum: int) -> int:
    value = document.get(key)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise _fail(path, f"field {key!r} must be an integer >= {minimum}, got {value!r:.80}")
    return value


def _frequencies(document: dict, path) -> tuple[float, float, tuple[float, float]]:
    """FSR, centre and span, checked against each other and the optical band."""
    fsr = _number(document, "fsr_hz", path)
    center = _number(document, "center_hz", path)
    span = document.get("span_hz")
    if not (
        isinstance(span, list)
        and len(span) == 2
        and all(_is_real(value) and math.isfinite(value) for value in span)
        and span[0] <= span[1]
    ):
        raise _fail(path, f"field 'span_hz' must be [low, high] in Hz, got {span!r:.80}")
    low, high = float(span[0]), float(span[1])
    lowest, highest = CENTER_RANGE_HZ
    if not lowest <= center <= highest:
        raise _fail(
            path,
            f"field 'center_hz' must be an optical frequency ({lowest:g} to {highest:g} Hz), "
            f"got {center!r}",
        )
    if not low <= center <= high:
        raise _fail(path, f"field 'center_hz' {center!r} must lie in span_hz [{low!r}, {high!r}]")
    if not 0 < fsr < center:
        raise _fail(path, f"field 'fsr_hz' must be > 0 and below the centre frequency, got {fsr!r}")
    return fsr, center, (low, high)


def _optional_object(document: dict, key: str, path) -> dict:
    value = document.get(key, {})
    if not isinstance(value, dict):
        raise _fail(path, f"field {key!r} must be an object, got {type(value).__name__}")
    return value


#: what a state may raise on wrong content (a missing key, a wrong type, a bad number)
_STATE_ERRORS = (KeyError, TypeError, ValueError, OverflowError, IndexError)


def calibrator_from_fields(document: dict, path="<calibration>") -> FittedCalibrator:
    """Rebuild a fitted calibrator from the fields :func:`calibrator_fields` wrote.

    ``path`` names the source in error messages (a file, or a window of a set).
    """
    if not isinstance(document, dict):
        raise _fail(path, f"calibration fields must be an object, got {type(document).__name__}")
    method = document.get("method")
    try:
        cls = calibrator_class(method)
    except WavemeterError as exc:  # a plug-in that names the tag but cannot be loaded
        raise _fail(path, str(exc)) from exc
    if cls is None:
        raise _fail(
            path, f"unknown calibration method {method!r:.80}; known: {sorted(registered())}"
        )
    params = document.get("params")
    state = document.get("state")
    if not isinstance(params, dict) or not isinstance(state, dict):
        raise _fail(path, "fields 'params' and 'state' must be objects")
    try:
        calibrator = cls(**cls._params_from_file(params))
        calibrator._check_params()
    except (TypeError, ValueError) as exc:
        raise _fail(path, f"parameters do not fit method {method!r}: {exc}") from exc
    n_ports = _count(document, "n_ports", path, 3)
    names = document.get("port_names")
    if (
        not isinstance(names, list)
        or len(names) != n_ports
        or not all(isinstance(name, str) for name in names)
    ):
        raise _fail(path, f"field 'port_names' must list {n_ports} names, got {names!r:.80}")
    fsr, center, span = _frequencies(document, path)
    rms = _number(document, "calibration_rms_hz", path)
    if rms < 0:
        raise _fail(path, f"field 'calibration_rms_hz' must be >= 0, got {rms!r}")
    calibrator.fsr_hz_ = fsr
    calibrator.center_hz_ = center
    calibrator.span_hz_ = span
    calibrator.n_ports_ = n_ports
    calibrator.port_names_ = list(names)
    calibrator.n_samples_ = _count(document, "n_samples", path, MIN_SAMPLES)
    calibrator.calibration_rms_hz_ = rms
    # files of 0.1 have no diagnostics
    calibrator.diagnostics_ = _optional_object(document, "diagnostics", path)
    try:
        # files of schema 1 have no reading model: no dark readings, offsets or power range
        calibrator._set_reading_model_state(_optional_object(document, "reading_model", path))
        calibrator._set_state(state)
        calibrator._check_state()
        calibrator._set_absolute_state(document.get("absolute"))
    except _STATE_ERRORS as exc:
        raise _fail(path, f"invalid {method!r} calibration state: {exc}") from exc
    if abs(calibrator.fsr_hz_ / fsr - 1.0) > DELAY_RTOL:
        raise _fail(
            path,
            f"field 'fsr_hz' {fsr!r} disagrees with the state's delay ({calibrator.fsr_hz_!r})",
        )
    return calibrator


def calibration_from_dict(document, path="<calibration>") -> FittedCalibrator:
    """Rebuild a calibrator from its JSON document, checking format, version and fields."""
    return _checked_document(document, path).calibrator


# ---------------------------------------------------------------------------- reading
@dataclass(frozen=True)
class CalibrationFile:
    """A checked calibration file: the calibrator and what the header says.

    Attributes
    ----------
    calibrator : FittedCalibrator
    metadata : dict
        The notes saved with it (source file, columns, units, ...), as read.
    wavemeter_version, created_utc : str or None
        Who wrote it and when, as read.
    schema_version : int
    """

    calibrator: FittedCalibrator
    metadata: dict
    wavemeter_version: str | None
    created_utc: str | None
    schema_version: int


def _checked_document(document, path) -> CalibrationFile:
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise _fail(path, f"not a wavemeter calibration file (no format {FORMAT!r})")
    version = document.get("schema_version")
    if (
        isinstance(version, bool)
        or not isinstance(version, int)
        or not 1 <= version <= SCHEMA_VERSION
    ):
        raise _fail(
            path,
            f"calibration schema_version {version!r:.40} is not supported by wavemeter "
            f"{_package_version()} (reads 1..{SCHEMA_VERSION}); upgrade wavemeter",
        )
    header = {}
    for key in ("wavemeter_version", "created_utc"):
        value = document.get(key)
        if value is not None and not isinstance(value, str):
            raise _fail(path, f"field {key!r} must be a string, got {type(value).__name__}")
        header[key] = value
    metadata = _optional_object(document, "metadata", path)
    return CalibrationFile(
        calibrator=calibrator_from_fields(document, path),
        metadata=metadata,
        schema_version=version,
        **header,
    )


def _max_depth(document) -> int:
    """Deepest nesting of arrays and objects in a parsed JSON document (iterative)."""
    deepest, stack = 0, [(document, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, depth)
            children = node.values() if isinstance(node, dict) else node
            stack.extend((child, depth + 1) for child in children)
    return deepest


class _LongInteger(ValueError):
    pass


def _parse_integer(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise _LongInteger(f"an integer of {len(text.lstrip('-'))} digits")
    return int(text)


def parse_calibration_text(text: str, path="<calibration>") -> CalibrationFile:
    """Parse and check the text of a calibration file (bounded depth and number size).

    Raises
    ------
    FileFormatError
        Naming ``path`` and what is wrong.
    """
    too_deep = _fail(
        path,
        f"JSON nested more than {MAX_DEPTH} deep (a calibration file nests at most "
        f"{MAX_DEPTH}): not a calibration file",
    )
    try:
        # the C parser raises RecursionError, safely, on documents nested ~1000 deep
        document = json.loads(text, parse_int=_parse_integer)
    except RecursionError as exc:
        raise too_deep from exc
    except _LongInteger as exc:
        raise _fail(
            path,
            f"holds {exc} (at most {MAX_INTEGER_DIGITS} allowed): not a calibration file",
        ) from exc
    except json.JSONDecodeError as exc:
        raise _fail(
            path,
            f"not valid JSON ({exc.msg} at line {exc.lineno}); the file is corrupt or "
            "truncated: write it again with `wavemeter calibrate`",
        ) from exc
    except ValueError as exc:
        raise _fail(path, f"not a calibration file ({type(exc).__name__})") from exc
    if _max_depth(document) > MAX_DEPTH:
        raise too_deep
    return _checked_document(document, path)


def read_calibration_file(path) -> CalibrationFile:
    """Read and check a calibration file; the calibrator with the file's header.

    At most ``MAX_FILE_BYTES`` are read, also from a device or a pipe.

    Raises
    ------
    FileFormatError
        When the file is missing, too large, truncated, not JSON, of another format or
        version, or its content is inconsistent. The message names the file and the field.
    """
    path = Path(path)
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError as exc:
        raise FileFormatError(f"{path}: calibration file not found") from exc
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot read calibration file ({exc})") from exc
    if len(data) > MAX_FILE_BYTES:
        raise _fail(
            path,
            f"larger than {MAX_FILE_BYTES // 2**20} MiB, far more than a calibration file holds: "
            "not a calibration file",
        )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path}: cannot read calibration file ({exc})") from exc
    return parse_calibration_text(text, path)


def load_calibration(path) -> FittedCalibrator:
    """Read a calibration file written by :meth:`save` and return the fitted calibrator.

    Raises
    ------
    FileFormatError
        When the file is missing, too large, truncated, not JSON, of another format or
        version, or its content is inconsistent. The message names the file and the field.
    """
    return read_calibration_file(path).calibrator
