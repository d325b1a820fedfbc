"""Calibration files: versioned JSON that :func:`load_calibration` checks before use.

Floats are written with Python's shortest round-trip representation, so a loaded
calibration predicts bit for bit what the saved one did.

A file is untrusted input. Reading is bounded (at most ``MAX_FILE_BYTES``, nesting at most
``MAX_DEPTH`` deep, integers of at most ``MAX_INTEGER_DIGITS`` digits, so a device, a FIFO
or a crafted document cannot exhaust memory or the stack), and every number is checked
before the calibrator is rebuilt: the header's (an FSR of at least 1 kHz and below an
optical centre frequency, a span ``[low, high]`` of light), the state's by the rules its
class declares (:mod:`~wavemeter.calibration.files.fields`), then the model's (a map of full
rank, a delay equal to ``1 / FSR``). Anything else is a
:class:`~wavemeter.exceptions.FileFormatError` naming the file and the field.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

from ...atomic import atomic_path
from ...exceptions import FileFormatError, InputError, WavemeterError, shown
from ...validation import MIN_SAMPLES, check_fitted
from .fields import (
    CENTER_RANGE_HZ,
    DELAY_RTOL,
    MIN_FSR_HZ,
    check_fields,
    check_setting_types,
    header_scales,
)
from .registry import calibrator_class, registered
from .state import is_real

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

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> import tempfile
    >>> from pathlib import Path
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> path = Path(tempfile.mkdtemp()) / "chip.wmcal.json"
    >>> wm.save_calibration(cal, path, metadata={"chip": "W7-14"})
    >>> loaded = wm.load_calibration(path)
    >>> print(loaded.method, loaded.fsr_hz_ == cal.fsr_hz_)
    learned True
    """
    document = calibration_to_dict(calibrator, metadata)
    text = json.dumps(document, indent=1, allow_nan=False)
    with atomic_path(path) as temporary:
        temporary.write_text(text + "\n", encoding="utf-8")


# ---------------------------------------------------------------------------- checks
def _fail(path, problem: str) -> FileFormatError:
    return FileFormatError(f"{path}: {problem}")


def _number(document: dict, key: str, path) -> float:
    value = document.get(key)
    if not is_real(value) or not math.isfinite(value):
        raise _fail(
            path, f"field {key!r} must be a finite number, got {shown(value, as_in_file=True)}"
        )
    return float(value)


def _count(document: dict, key: str, path, minimum: int) -> int:
    value = document.get(key)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise _fail(
            path,
            f"field {key!r} must be an integer >= {minimum}, got {shown(value, as_in_file=True)}",
        )
    return value


def _frequencies(document: dict, path) -> tuple[float, float, tuple[float, float]]:
    """FSR, centre and span, checked against each other and the optical band."""
    fsr = _number(document, "fsr_hz", path)
    center = _number(document, "center_hz", path)
    span = document.get("span_hz")
    if not (
        isinstance(span, list)
        and len(span) == 2
        and all(is_real(value) and math.isfinite(value) for value in span)
        and span[0] <= span[1]
    ):
        raise _fail(
            path, f"field 'span_hz' must be [low, high] in Hz, got {shown(span, as_in_file=True)}"
        )
    low, high = float(span[0]), float(span[1])
    lowest, highest = CENTER_RANGE_HZ
    if not lowest <= center <= highest:
        raise _fail(
            path,
            f"field 'center_hz' must be an optical frequency ({lowest:g} to {highest:g} Hz), "
            f"got {shown(center, as_in_file=True)}",
        )
    if not low <= center <= high:
        raise _fail(
            path,
            f"field 'center_hz' {shown(center, as_in_file=True)} must lie in span_hz "
            f"{shown([low, high], as_in_file=True)}",
        )
    if not 0 < low or not high <= 2 * highest:
        raise _fail(
            path,
            f"field 'span_hz' must hold optical frequencies, got {shown(span, as_in_file=True)}",
        )
    if not MIN_FSR_HZ <= fsr < center:
        raise _fail(
            path,
            f"field 'fsr_hz' must be >= {MIN_FSR_HZ:g} Hz (a delay of at most 1 ms) and below "
            f"the centre frequency, got {shown(fsr, as_in_file=True)}",
        )
    return fsr, center, (low, high)


def _optional_object(document: dict, key: str, path) -> dict:
    value = document.get(key, {})
    if not isinstance(value, dict):
        raise _fail(path, f"field {key!r} must be an object, got {shown(value, as_in_file=True)}")
    return value


#: what a state may raise on wrong content (a missing key, a wrong type, a bad number)
_STATE_ERRORS = (KeyError, TypeError, ValueError, OverflowError, IndexError)


def calibrator_from_fields(document: dict, path="<calibration>") -> FittedCalibrator:
    """Rebuild a fitted calibrator from the fields :func:`calibrator_fields` wrote.

    ``path`` names the source in error messages (a file, or a window of a set).
    """
    if not isinstance(document, dict):
        raise _fail(
            path, f"calibration fields must be an object, got {shown(document, as_in_file=True)}"
        )
    method = document.get("method")
    try:
        cls = calibrator_class(method)
    except WavemeterError as exc:  # a plug-in that names the tag but cannot be loaded
        raise _fail(path, str(exc)) from exc
    if cls is None:
        raise _fail(
            path,
            f"unknown calibration method {shown(method, as_in_file=True)}; known: "
            f"{', '.join(sorted(registered()))}",
        )
    params = document.get("params")
    state = document.get("state")
    if not isinstance(params, dict) or not isinstance(state, dict):
        raise _fail(path, "fields 'params' and 'state' must be objects")
    try:
        settings = cls._params_from_file(params)
        check_setting_types(cls, settings)
        calibrator = cls(**settings)
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
        raise _fail(
            path,
            f"field 'port_names' must list {n_ports} names, got {shown(names, as_in_file=True)}",
        )
    fsr, center, span = _frequencies(document, path)
    rms = _number(document, "calibration_rms_hz", path)
    if not 0 <= rms <= center:
        raise _fail(
            path, f"field 'calibration_rms_hz' must be >= 0 and below the centre, got {rms!r}"
        )
    calibrator.fsr_hz_ = fsr
    calibrator.center_hz_ = center
    calibrator.span_hz_ = span
    calibrator.n_ports_ = n_ports
    calibrator.port_names_ = list(names)
    calibrator.n_samples_ = _count(document, "n_samples", path, MIN_SAMPLES)
    calibrator.calibration_rms_hz_ = rms
    # files of 0.1 have no diagnostics
    calibrator.diagnostics_ = _optional_object(document, "diagnostics", path)
    # files of schema 1 have no reading model: no dark readings, offsets or power range
    reading_model = _optional_object(document, "reading_model", path)
    try:
        scales = header_scales(fsr, center, span, n_ports, calibrator.n_samples_)
        check_fields(cls, scales, state, reading_model, calibrator.diagnostics_)
        calibrator._set_reading_model_state(reading_model)
        calibrator._set_state(state)
        calibrator._check_state()
        calibrator._set_absolute_state(document.get("absolute"))
    except _STATE_ERRORS as exc:
        raise _fail(path, f"invalid {method!r} calibration state: {exc}") from exc
    if abs(calibrator.fsr_hz_ / fsr - 1.0) > DELAY_RTOL:
        raise _fail(
            path,
            f"field 'fsr_hz' {shown(fsr, as_in_file=True)} disagrees with the state, whose "
            f"delay gives an FSR of {shown(calibrator.fsr_hz_)} Hz",
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
            f"calibration schema_version {shown(version, as_in_file=True)} is not supported by "
            f"wavemeter {_package_version()} (reads 1..{SCHEMA_VERSION}); upgrade wavemeter",
        )
    header = {}
    for key in ("wavemeter_version", "created_utc"):
        value = document.get(key)
        if value is not None and not isinstance(value, str):
            raise _fail(
                path, f"field {key!r} must be a string, got {shown(value, as_in_file=True)}"
            )
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

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> import tempfile
    >>> from pathlib import Path
    >>> path = Path(tempfile.mkdtemp()) / "chip.wmcal.json"
    >>> wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz).save(path)
    >>> cal = wm.load_calibration(path)  # the class comes from the file's method tag
    >>> print(cal.method, f"{cal.fsr_hz_ / 1e9:.2f} GHz")
    learned 51.51 GHz
    >>> print(abs(cal.predict(powers[:1])[0] - f_hz[0]) < 100e6)
    True
    """
    return read_calibration_file(path).calibrator
