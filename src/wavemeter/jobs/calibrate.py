"""Calibrating one device from its sweep file: the job a fleet runs once per device.

:func:`calibrate_file` reads a sweep file, fits the calibrator its options name (a
registered tag), optionally saves the calibration atomically, and returns a
:class:`DeviceResult` with the numbers a fleet's summary shows: the fitted FSR, the
detector noise, the RMS frequency error on the sweep and its ratio to the Cramer-Rao
bound. :func:`calibrate_device` does the same for a fleet: bad input
(:class:`~wavemeter.exceptions.WavemeterError`, ``OSError``) becomes a result with
``status="error"`` and the message, so that one broken file does not stop the others.

The options are a documented subset of ``wavemeter calibrate``'s (``method``, ``fsr_hz``,
``fsr_tolerance``, ``retrieval``, the columns, ``drop_invalid`` and the calibrator's own
settings by name): no dark readings, no per-FSR sets, no thermal sweeps at several
temperatures. The calibration's metadata keep the columns, the options
(``calibrate_options``) and the RMS bound (``crlb_rms_hz``), so that :func:`saved_result`
rebuilds the same result from the saved file alone.

:func:`fit_sweep_chunks` fits a learned calibration on a sweep file read in chunks
(:meth:`~wavemeter.calibration.Calibrator.fit_chunks`), in memory bounded by the chunk:
what ``wavemeter calibrate`` does for the learned method.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import InputError, WavemeterError, recorded_calibration_warnings
from ..io import ColumnRequest, ReadingStream, read_table
from .measure import about_file

__all__ = [
    "DeviceResult",
    "SweepRead",
    "calibrate_file",
    "calibrate_device",
    "fit_sweep_chunks",
    "build_calibrator",
    "calibrate_options",
    "saved_result",
    "OK",
    "ERROR",
]

#: status of a device calibrated (or found calibrated), and of one that failed
OK = "ok"
ERROR = "error"
#: Python records warnings process-wide (not per thread): fits in threads of one process
#: record their warnings one at a time, so that each records its own
_WARNINGS_LOCK = threading.Lock()


@dataclass(frozen=True)
class DeviceResult:
    """What calibrating one device gave: its numbers, or why it failed.

    Attributes
    ----------
    device : str
        The device's name: its sweep file's stem.
    source : str
        The sweep file.
    status : {"ok", "error"}
        Calibrated, or failed (``error`` says why).
    fsr_hz : float
        Fitted free spectral range (Hz); NaN when failed.
    noise_std_w : float
        Detector noise standard deviation the fit estimates (W): ``noise_std_w_``, else the
        mean of ``port_noise_std_w_``; NaN for a method that estimates none.
    calibration_rms_hz : float
        RMS frequency error of the calibration on its own sweep (Hz), modulo the FSR.
    crlb_rms_hz : float
        RMS over the sweep's readings of the Cramer-Rao bound (Hz) under the calibrated map
        and noise; NaN for a method without one (``crlb_hz``).
    crlb_ratio : float
        ``calibration_rms_hz / crlb_rms_hz``: 1 at the physical limit (in-sample, a little
        below 1 for few readings); NaN without a bound.
    samples : int
        Sweep readings the calibration was fitted on.
    warnings : tuple of str
        Causes of the fit's calibration warnings (``diagnostics_["warnings"]``), each once,
        in order.
    error : str
        The error message of a failed device; empty otherwise.
    resumed : bool
        The result was read from a calibration saved by an earlier run.
    calibration : BaseCalibrator or None
        The fitted calibration (not compared, not shown).
    metadata : dict
        What the calibration file keeps besides the calibration (not compared).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.jobs import calibrate_device
    >>> result = calibrate_device(folder / "sweep.csv", device="chip-07")
    >>> result.device, result.status, result.warnings
    ('chip-07', 'ok', ())

    The RMS error on the sweep is at the Cramer-Rao bound of the readings:

    >>> rms_mhz, bound_mhz = result.calibration_rms_hz / 1e6, result.crlb_rms_hz / 1e6
    >>> print(f"{rms_mhz:.1f} MHz, bound {bound_mhz:.1f} MHz")
    13.5 MHz, bound 13.5 MHz
    """

    device: str
    source: str
    status: str
    fsr_hz: float = math.nan
    noise_std_w: float = math.nan
    calibration_rms_hz: float = math.nan
    crlb_rms_hz: float = math.nan
    crlb_ratio: float = math.nan
    samples: int = 0
    warnings: tuple[str, ...] = ()
    error: str = ""
    resumed: bool = False
    calibration: object = field(default=None, repr=False, compare=False)
    metadata: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        """Whether the device is calibrated."""
        return self.status == OK


def build_calibrator(
    method: str = "learned",
    *,
    fsr_hz=50e9,
    fsr_tolerance: float | None = None,
    retrieval: str | None = None,
    **params,
):
    """The unfitted calibrator of a registered method with the given settings.

    Parameters
    ----------
    method : str
        A calibration tag (:func:`wavemeter.calibration.registered`): ``"learned"``,
        ``"conventional"``, ``"wideband"``, ``"thermal"``, ``"cascade"``, ...
    fsr_hz : float or tuple of float
        Design FSR (Hz); a cascade's, coarsest first.
    fsr_tolerance, retrieval : optional
        Set only when given (None: the method's default).
    **params
        Further settings of the method's calibrator, by name.

    Raises
    ------
    InputError
        For an unknown method (``parameter="method"``), or a setting the method does not
        have (``parameter`` names it).
    """
    from ..calibration import registered

    classes = registered()
    if method not in classes:
        raise InputError(
            f"method {method!r} is not a calibration method; methods: {', '.join(classes)}",
            parameter="method",
        )
    calibrator = classes[method]()
    given = {"fsr_tolerance": fsr_tolerance, "retrieval": retrieval}
    settings = {"fsr_hz": fsr_hz, **{k: v for k, v in given.items() if v is not None}, **params}
    for name, value in settings.items():
        try:
            calibrator.set_params(**{name: value})
        except InputError as exc:
            raise InputError(f"method {method!r}: {exc}", parameter=name) from exc
    return calibrator


def _json_ready(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON-ready")


def calibrate_options(
    method: str = "learned",
    *,
    fsr_hz=50e9,
    fsr_tolerance: float | None = None,
    retrieval: str | None = None,
    request: ColumnRequest | None = None,
    drop_invalid: bool = False,
    **params,
) -> dict:
    """The options of :func:`calibrate_file`, checked, as JSON reads them back (tuples and
    arrays as lists): what a calibration's metadata keep and a fleet compares.

    Raises
    ------
    InputError
        For an unknown method or setting (as :func:`build_calibrator`), or a setting that
        is not a number, text, list or array.
    """
    build_calibrator(
        method, fsr_hz=fsr_hz, fsr_tolerance=fsr_tolerance, retrieval=retrieval, **params
    )
    record = {
        "method": method,
        "fsr_hz": fsr_hz,
        "fsr_tolerance": fsr_tolerance,
        "retrieval": retrieval,
        "request": dataclasses.asdict(request or ColumnRequest()),
        "drop_invalid": drop_invalid,
        **params,
    }
    try:
        return json.loads(json.dumps(record, default=_json_ready, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise InputError(f"the calibration settings must be JSON-ready values: {exc}") from exc


def _noise_std_w(calibration) -> float:
    """The detector noise estimate (W) the calibration states; NaN where it states none."""
    noise = calibration.summary().values.get("noise_std_w")
    return math.nan if noise is None else float(noise.value)


def _crlb_rms_hz(calibration, table, inputs: dict) -> float:
    """RMS (Hz) of the Cramer-Rao bound of the sweep's readings; NaN where the calibration
    gives no bound (no ``"crlb"`` capability)."""
    if "crlb" not in calibration.capabilities:
        return math.nan
    if "coarse_hz" in calibration.requires:
        inputs = {**inputs, "coarse_hz": table.x_hz}
    bound = calibration.crlb_hz(table.powers_w, **inputs)
    return float(np.sqrt(np.mean(np.square(bound))))


def _result(device: str, source, calibration, crlb_rms_hz, metadata: dict, resumed: bool):
    """The result of a fitted (or loaded) calibration."""
    records = (calibration.diagnostics_ or {}).get("warnings") or []
    rms = float(calibration.calibration_rms_hz_)
    return DeviceResult(
        device=device,
        source=str(source),
        status=OK,
        fsr_hz=float(calibration.fsr_hz_),
        noise_std_w=_noise_std_w(calibration),
        calibration_rms_hz=rms,
        crlb_rms_hz=crlb_rms_hz,
        crlb_ratio=rms / crlb_rms_hz if crlb_rms_hz > 0 else math.nan,
        samples=int(calibration.n_samples_),
        warnings=tuple(dict.fromkeys(str(record.get("cause")) for record in records)),
        resumed=resumed,
        calibration=calibration,
        metadata=metadata,
    )


def calibrate_file(
    path,
    out_path=None,
    *,
    method: str = "learned",
    fsr_hz=50e9,
    fsr_tolerance: float | None = None,
    retrieval: str | None = None,
    request: ColumnRequest | None = None,
    drop_invalid: bool = False,
    device: str | None = None,
    **params,
) -> DeviceResult:
    """Calibrate one device from its sweep file.

    Parameters
    ----------
    path : str or Path
        The sweep: a data file with a frequency or wavelength column and 3+ port columns.
    out_path : str or Path, optional
        Where to save the calibration (JSON, atomically); None: not saved.
    method : str
        Registered calibration tag (:func:`build_calibrator`).
    fsr_hz : float or tuple of float
        Design FSR (Hz).
    fsr_tolerance : float, optional
        Relative half width of the FSR search (default: the method's).
    retrieval : {"pinv", "ml"}, optional
        Phase retrieval (default: the method's).
    request : ColumnRequest, optional
        Columns and units chosen by the user; the rest are found by name.
    drop_invalid : bool
        Skip invalid rows instead of failing.
    device : str, optional
        The device's name (default: the file's stem).
    **params
        Further settings of the method's calibrator.

    Returns
    -------
    DeviceResult
        With ``status="ok"``, the fitted calibration and its metadata.

    Raises
    ------
    InputError, FileFormatError, EdgeMinimumError
        What reading the file or fitting refuses; messages name the file.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.jobs import calibrate_file
    >>> result = calibrate_file(folder / "sweep.csv", folder / "chip.wmcal.json", fsr_hz=50e9)
    >>> result.status, result.device, result.samples
    ('ok', 'sweep', 200)
    >>> print(f"FSR {result.fsr_hz / 1e9:.2f} GHz, {result.crlb_ratio:.2f} x the Cramer-Rao bound")
    FSR 51.51 GHz, 1.00 x the Cramer-Rao bound
    >>> (folder / "chip.wmcal.json").exists()
    True
    """
    path = Path(path)
    options = calibrate_options(
        method,
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        retrieval=retrieval,
        request=request,
        drop_invalid=drop_invalid,
        **params,
    )
    calibrator = build_calibrator(
        method, fsr_hz=fsr_hz, fsr_tolerance=fsr_tolerance, retrieval=retrieval, **params
    )
    thermal = "temperature_k" in calibrator.requires
    table = read_table(
        path, request, need_x=True, allow_invalid=drop_invalid, find_temperature=thermal
    ).valid_only()
    if thermal and table.temperature_k is None:
        raise InputError(
            f"{path}: a {calibrator.method_label} calibration needs the chip temperature of "
            "each reading, and the file has no temperature column: name it (temperature)",
            parameter="temperature",
        )
    inputs = {"temperature_k": table.temperature_k} if thermal else {}
    with about_file(path):
        with _WARNINGS_LOCK, recorded_calibration_warnings():
            calibrator.fit(
                table.powers_w, table.x_hz, table.monitor_w, list(table.port_names), **inputs
            )
        crlb_rms_hz = _crlb_rms_hz(calibrator, table, inputs)
    metadata = {
        "sweep_file": str(path),
        "x_column": table.x_column,
        "x_unit": table.x_unit,
        "port_columns": list(table.port_names),
        "port_units": list(table.port_units),
        "monitor_column": table.monitor_column,
        "temperature_column": table.temperature_column if thermal else None,
        "rows": table.n_rows,
        "dropped_rows": table.dropped_rows,
        "crlb_rms_hz": crlb_rms_hz if math.isfinite(crlb_rms_hz) else None,
        "calibrate_options": options,
    }
    name = path.stem if device is None else device
    result = _result(name, path, calibrator, crlb_rms_hz, metadata, resumed=False)
    if out_path is not None:
        from ..calibration.files.document import save_calibration

        save_calibration(calibrator, out_path, metadata)
    return result


def calibrate_device(path, *, device: str | None = None, **options) -> DeviceResult:
    r""":func:`calibrate_file` without saving, for a fleet: bad input is a result.

    Parameters
    ----------
    path : str or Path
        The sweep file.
    device : str, optional
        The device's name (default: the file's stem).
    **options
        As :func:`calibrate_file` takes them (``method``, ``fsr_hz``, ...).

    Returns
    -------
    DeviceResult
        ``status="ok"`` with the fitted calibration, or ``status="error"`` with the message
        of the :class:`~wavemeter.exceptions.WavemeterError` or ``OSError`` that stopped
        it. Any other exception is a bug and is raised.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.jobs import calibrate_device
    >>> _ = (folder / "broken.csv").write_text("frequency_hz,p1_w\n1,2\n")  # one port only
    >>> results = [calibrate_device(folder / name) for name in ("sweep.csv", "broken.csv")]
    >>> [(result.device, result.status) for result in results]  # one bad file stops nothing
    [('sweep', 'ok'), ('broken', 'error')]
    >>> print(results[1].error.split(": ", 1)[1].split("; ")[0])
    found 1 port column(s) (p1_w)
    """
    name = Path(path).stem if device is None else device
    try:
        return calibrate_file(path, device=name, **options)
    except (WavemeterError, OSError) as exc:
        return DeviceResult(device=name, source=str(path), status=ERROR, error=_message(exc))


def _message(exc: Exception) -> str:
    """An error's message on one line; an OSError's without Python's ``[Errno N]``."""
    text = str(exc) or type(exc).__name__
    if isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    return " ".join(text.split())


def saved_result(cal_path, source, device: str) -> DeviceResult:
    """The result of a device from the calibration an earlier run saved (``resumed``).

    The numbers are those of the run that saved it: FSR, noise, RMS and warnings from the
    calibration, the Cramer-Rao RMS from its metadata (NaN when the file has none, e.g.
    one written by ``wavemeter calibrate``).

    Raises
    ------
    FileFormatError
        When the file does not load (missing, corrupt, foreign).
    """
    from ..calibration.files.document import read_calibration_file

    saved = read_calibration_file(cal_path)
    crlb = saved.metadata.get("crlb_rms_hz")
    crlb_rms_hz = float(crlb) if isinstance(crlb, (int, float)) else math.nan
    return _result(device, source, saved.calibrator, crlb_rms_hz, saved.metadata, resumed=True)


@dataclass(frozen=True)
class SweepRead:
    """What reading a sweep file found, for the calibration's metadata and messages.

    Attributes
    ----------
    source : Path
        The file (as named to the user).
    x_column, x_unit : str or None
        The frequency or wavelength column and its unit.
    port_names, port_units : tuple of str
        The port columns and their units.
    monitor_column, temperature_column : str or None
        The power monitor's and the chip temperature's columns.
    n_rows : int
        Valid rows, the readings calibrated on.
    dropped_rows : int
        Rows skipped as invalid.
    invalid_examples : tuple of str
        The first skipped rows with their reasons, ``line 5 (P2_mW is NaN)``.
    temperature_range_k : list of float or None
        Lowest and highest chip temperature of the valid rows (K), with a temperature column.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.io import iter_readings
    >>> from wavemeter.jobs import fit_sweep_chunks
    >>> stream = iter_readings(folder / "sweep.csv", need_x=True, allow_invalid=True)
    >>> read = fit_sweep_chunks(wm.Calibrator(fsr_hz=50e9), stream)
    >>> read.x_column, read.x_unit, read.port_units, read.n_rows, read.dropped_rows
    ('frequency_hz', 'Hz', ('W', 'W', 'W'), 200, 0)
    """

    source: Path
    x_column: str | None
    x_unit: str | None
    port_names: tuple[str, ...]
    port_units: tuple[str, ...]
    monitor_column: str | None
    temperature_column: str | None
    n_rows: int
    dropped_rows: int
    invalid_examples: tuple[str, ...] = ()
    temperature_range_k: list[float] | None = None


def fit_sweep_chunks(
    calibrator, stream: ReadingStream, *, dark_w=None, progress: Callable | None = None
) -> SweepRead:
    """Fit a learned calibrator on a sweep read in chunks, in memory bounded by the chunk.

    Each chunk's valid rows go to :meth:`~wavemeter.calibration.Calibrator.fit_chunks`
    (its moments and its diagnostic sample) and are dropped: the calibration is the one
    ``fit`` gives on the valid rows read whole (bit for bit up to ``diagnostic_samples``
    readings, to rounding beyond).

    Parameters
    ----------
    calibrator : Calibrator
        Unfitted; a learned calibrator (one with ``fit_chunks``).
    stream : ReadingStream
        The sweep, opened with :func:`~wavemeter.io.iter_readings` (``need_x=True``) and
        not yet iterated; its ``allow_invalid`` decides whether invalid rows are skipped.
    dark_w : None or array_like, shape (n,)
        Per-port dark readings (W), subtracted from every reading.
    progress : callable, optional
        ``progress(description, total, unit=...)`` returning a context manager that yields
        ``advance(steps)`` (as :func:`wavemeter.progress.progress_bar`), advanced in the
        units of the read. None: silent.

    Returns
    -------
    SweepRead

    Raises
    ------
    InputError
        For a calibrator that cannot fit chunks, what the read refuses (invalid rows when
        not allowed, bad cells) and what ``fit_chunks`` refuses.
    EdgeMinimumError
        As ``fit``.

    Warns
    -----
    CalibrationWarning
        As ``fit``.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.io import iter_readings
    >>> from wavemeter.jobs import fit_sweep_chunks
    >>> stream = iter_readings(folder / "sweep.csv", chunk_rows=50, need_x=True, allow_invalid=True)
    >>> cal = wm.Calibrator(fsr_hz=50e9)
    >>> read = fit_sweep_chunks(cal, stream)  # memory bounded by the chunk, whatever the file
    >>> read.n_rows, read.port_names
    (200, ('p1_w', 'p2_w', 'p3_w'))
    >>> whole = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> print(f"{cal.fsr_hz_ / 1e9:.4f} GHz, read whole: {whole.fsr_hz_ / 1e9:.4f} GHz")
    51.5076 GHz, read whole: 51.5076 GHz
    """
    if "fit_chunks" not in calibrator.capabilities:
        raise InputError(
            f"a {calibrator.method_label} calibration is fitted on the whole sweep at once "
            "(no 'fit_chunks' among its capabilities)"
        )
    found: dict = {"temperature": [np.inf, -np.inf]}

    def chunks(advance):
        done = 0
        for table in stream:
            found.setdefault("x", (table.x_column, table.x_unit))
            valid = table.valid_only()
            if valid.temperature_k is not None and valid.n_rows:
                low, high = found["temperature"]
                found["temperature"] = [
                    min(low, float(valid.temperature_k.min())),
                    max(high, float(valid.temperature_k.max())),
                ]
            yield valid.x_hz, valid.powers_w, valid.monitor_w
            if advance is not None:
                advance(stream.progress - done)
            done = stream.progress

    total, unit = stream.progress_total
    bar = progress(f"calibrating on {stream.source}", total, unit=unit) if progress else None
    with bar if bar is not None else contextlib.nullcontext() as advance:
        calibrator.fit_chunks(chunks(advance), list(stream.port_names), dark_w=dark_w)
    x_column, x_unit = found["x"]
    temperature = found["temperature"]
    return SweepRead(
        source=stream.source,
        x_column=x_column,
        x_unit=x_unit,
        port_names=tuple(stream.port_names),
        port_units=tuple(stream.port_units),
        monitor_column=stream.monitor_column,
        temperature_column=stream.temperature_column,
        n_rows=stream.rows - stream.invalid_rows,
        dropped_rows=stream.invalid_rows,
        invalid_examples=tuple(stream.invalid_examples),
        temperature_range_k=temperature if np.isfinite(temperature[0]) else None,
    )
