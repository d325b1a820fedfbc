"""Calibrating a device from its sweep: the one job ``calibrate`` and ``fleet calibrate`` run.

:func:`calibrate_file` builds the calibrator the :class:`CalibrateOptions` ask for
(:func:`~wavemeter.jobs.calibrator.build_calibrator`), reads the sweep (in chunks, with
progress and in memory bounded by the chunk, for a calibrator with the ``"fit_chunks"``
capability; whole, one or several files, for the others), subtracts the dark readings,
fits, makes the metadata and saves the calibration atomically. It returns a
:class:`DeviceResult` with the numbers a fleet's summary shows: the fitted FSR, the
detector noise estimate, the RMS error of the calibration on its own sweep, the RMS
Cramer-Rao bound of the sweep (on every k-th reading beyond ``SAMPLE_ROWS``) and their
ratio. :func:`calibrate_device` does the same for a fleet: bad input becomes a result with
``status="error"``; :func:`saved_result` rebuilds a result from a saved file.

The metadata (the same function for both commands): the sweep files and their columns,
rows, temperatures, the dark readings' file (:func:`~wavemeter.jobs.sweeps.sweep_metadata`),
``crlb_rms_hz`` and ``calibrate_options`` (:func:`~wavemeter.jobs.calibrator.options_record`).
``calibrate`` and ``fleet calibrate`` of the same sweep with the same options write files
that differ only in these fields:

- ``created_utc``: when the file was written;
- ``metadata.sweep_file``: the sweep as each command was given it (the fleet names the
  files it found in a folder or by a pattern by their path there).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import InputError, WavemeterError, recorded_calibration_warnings
from ..io import ColumnRequest, iter_readings
from ..io.streaming import CHUNK_ROWS
from .calibrator import CalibrateOptions, build_calibrator, options_record
from .chunks import SAMPLE_ROWS, RowSample, fit_sweep_chunks
from .measure import about_file
from .readings import check_reading_options, needs_temperature
from .sweeps import SweepsRead, input_label, read_dark_w, read_sweeps, sweep_metadata

__all__ = [
    "CalibrationRefused",
    "DeviceResult",
    "calibrate_file",
    "calibrate_device",
    "saved_result",
    "OK",
    "ERROR",
    "DIFFERING_FIELDS",
]

#: status of a device calibrated (or found calibrated), and of one that failed
OK = "ok"
ERROR = "error"
#: what may differ between the files ``calibrate`` and ``fleet calibrate`` write of the
#: same sweep with the same options (module docstring)
DIFFERING_FIELDS = ("created_utc", "metadata.sweep_file")
#: Python records warnings process-wide (not per thread): fits in threads of one process
#: record their warnings one at a time, so that each records its own
_WARNINGS_LOCK = threading.Lock()


class CalibrationRefused(WavemeterError):
    """A fit that warned, refused (``strict``): nothing was saved.

    Attributes
    ----------
    warnings : tuple of CalibrationWarning
        The fit's warnings, in order.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> from wavemeter.jobs import CalibrateOptions, CalibrationRefused, calibrate_file
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(800, span_fsr=3.0)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> powers[:, 1] *= np.linspace(1.0, 1.05, len(f_hz))  # port 2: 5 % over the band
    >>> folder = Path(tempfile.mkdtemp())
    >>> write_table(folder / "sweep.csv",
    ...             {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}})
    >>> try:
    ...     calibrate_file(folder / "sweep.csv", folder / "chip.wmcal.json",
    ...                    options=CalibrateOptions(fsr_hz=50e9, strict=True))
    ... except CalibrationRefused as error:
    ...     print([warning.cause for warning in error.warnings])
    ['dispersion']
    >>> (folder / "chip.wmcal.json").exists()  # nothing saved
    False
    """

    def __init__(self, source: str, refused):
        self.warnings = tuple(refused)
        listed = "; ".join(f"[{warning.cause}] {warning}" for warning in self.warnings)
        super().__init__(f"{source}: strict refuses a calibration that warns: {listed}")


@dataclass(frozen=True)
class DeviceResult:
    """What calibrating one device gave: its numbers, or why it failed.

    Attributes
    ----------
    device : str
        The device's name: its (first) sweep file's stem.
    source : str
        The sweep file(s), as messages name them.
    status : {"ok", "error"}
        Calibrated, or failed (``error`` says why).
    fsr_hz : float
        Fitted free spectral range (Hz); NaN when failed.
    noise_std_w : float
        Detector noise standard deviation the fit states (W); NaN where it states none.
    calibration_rms_hz : float
        RMS frequency error of the calibration on its own sweep (Hz).
    crlb_rms_hz : float
        RMS over the sweep's readings of the Cramer-Rao bound (Hz) under the calibrated map
        and noise; NaN for a method without one (no ``"crlb"`` capability).
    crlb_ratio : float
        ``calibration_rms_hz / crlb_rms_hz``: 1 at the physical limit; NaN without a bound.
    samples : int
        Sweep readings the calibration was fitted on.
    warnings : tuple of str
        Causes of the fit's calibration warnings, each once, in order.
    error : str
        The error message of a failed device; empty otherwise.
    resumed : bool
        The result was read from a calibration saved by an earlier run.
    calibration : BaseCalibrator or None
        The fitted calibration (not compared, not shown).
    metadata : dict
        What the calibration file keeps besides the calibration (not compared).
    read : SweepsRead or None
        What was read (files, columns, rows skipped); None when resumed or failed.
    fit_warnings : tuple of CalibrationWarning
        The fit's warnings themselves, in order (recorded, not issued).

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
    read: SweepsRead | None = field(default=None, repr=False, compare=False)
    fit_warnings: tuple = field(default=(), repr=False, compare=False)

    @property
    def ok(self) -> bool:
        """Whether the device is calibrated."""
        return self.status == OK


def _noise_std_w(calibration) -> float:
    """The detector noise estimate (W) the calibration states; NaN where it states none."""
    noise = calibration.summary().values.get("noise_std_w")
    return math.nan if noise is None else float(noise.value)


def _crlb_rms_hz(calibration, powers_w, frequency_hz, inputs: dict) -> float:
    """RMS (Hz) of the Cramer-Rao bound of sweep readings; NaN where the calibration gives
    no bound (no ``"crlb"`` capability) or needs an input the readings lack."""
    if "crlb" not in calibration.capabilities or not len(frequency_hz):
        return math.nan
    if "coarse_hz" in calibration.requires:
        inputs = {**inputs, "coarse_hz": frequency_hz}
    if set(calibration.requires) - set(inputs):
        return math.nan
    bound = calibration.crlb_hz(powers_w, **inputs)
    return float(np.sqrt(np.mean(np.square(bound))))


def _result(device: str, source, calibration, crlb_rms_hz, metadata: dict, **extra):
    """The result of a fitted (or loaded) calibration."""
    records = (calibration.summary().diagnostics or {}).get("warnings") or []
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
        calibration=calibration,
        metadata=metadata,
        **extra,
    )


def _paths(paths) -> tuple:
    """One path or a sequence of them, as a tuple (at least one)."""
    paths = (paths,) if isinstance(paths, (str, Path)) else tuple(paths)
    if not paths:
        raise InputError("no sweep file to calibrate: paths is empty", parameter="paths")
    return paths


def _check_inputs(calibrator, paths: tuple, options: CalibrateOptions) -> None:
    """Before any reading: several files only for a calibrator that needs the chip
    temperature, standard input once, the temperatures and dark readings given once."""
    if len(paths) > 1 and not needs_temperature(calibrator):
        raise InputError(
            f"method {options.method!r} takes one sweep file, got {len(paths)}: only a "
            "calibrator that needs the chip temperature of each reading (thermal) is fitted "
            "on several sweeps, one per temperature; merge the files into one if they are "
            "one sweep",
            parameter="paths",
        )
    inputs = [*paths, *([] if options.dark_file is None else [options.dark_file])]
    if sum(str(path) == "-" for path in inputs) > 1:
        raise InputError(
            "only one input can be read from standard input ('-'): the sweep or the dark readings",
            parameter="paths",
        )
    if options.dark_w is not None and options.dark_file is not None:
        raise InputError(
            "dark_file and dark_w both give the dark readings; give a file or values, not both",
            parameter="dark_w",
        )
    given = options.temperature_k
    column = (options.request or ColumnRequest()).temperature
    if column is not None and given:
        raise InputError(
            "a temperature column (temperature) and temperature_k both give the chip "
            "temperature; give the column or the values, not both",
            parameter="temperature_k",
        )
    check_reading_options(calibrator, temperature_k=given)
    if given and len(given) != len(paths):
        raise InputError(
            f"temperature_k is given {len(given)} time(s) for {len(paths)} sweep file(s); "
            "give it once per file, in file order, or leave it out to read each file's "
            "temperature column",
            parameter="temperature_k",
        )


@contextlib.contextmanager
def _recorded(label: str):
    """The fit's calibration warnings recorded (one fit at a time in this process), its
    errors prefixed with the files."""
    with about_file(label), _WARNINGS_LOCK, recorded_calibration_warnings() as caught:
        yield caught


def _fit_in_chunks(calibrator, paths: tuple, options: CalibrateOptions, progress, check):
    """Read the (one) sweep in chunks and fit it: what was read, a sample of its rows, the
    inputs of its readings (none), the fit's warnings."""
    label = input_label(paths[0])
    stream = iter_readings(
        paths[0],
        options.request,
        chunk_rows=CHUNK_ROWS,
        need_x=True,
        allow_invalid=options.drop_invalid,
        name=label,
    )
    if check is not None:
        check(stream)
    dark_w, dark = read_dark_w(options, stream, progress=progress)
    sample = RowSample(SAMPLE_ROWS)
    with _recorded(label) as caught:
        record = fit_sweep_chunks(
            calibrator, stream, dark_w=dark_w, progress=progress, sample=sample
        )
    read = SweepsRead((record,), record.temperature_range_k, dark=dark)
    return read, sample, {}, caught


def _fit_whole(calibrator, paths: tuple, options: CalibrateOptions, progress, check):
    """Read the sweeps whole and fit them: what was read, a sample of its rows, the
    inputs of its readings, the fit's warnings."""
    sweeps = read_sweeps(
        paths,
        options,
        temperature=needs_temperature(calibrator),
        method_label=calibrator.method_label,
        progress=progress,
    )
    first = sweeps.read.first
    if check is not None:
        check(first)
    dark_w, dark = read_dark_w(options, first, progress=progress)
    inputs = {} if sweeps.temperature_k is None else {"temperature_k": sweeps.temperature_k}
    label = sweeps.read.label
    busy = progress(f"calibrating on {label}", None, "") if progress else contextlib.nullcontext()
    with busy, _recorded(label) as caught:
        calibrator.fit(
            sweeps.powers_w,
            sweeps.x_hz,
            sweeps.monitor_w,
            list(first.port_names),
            dark_w=dark_w,
            **inputs,
        )
    stride = max(1, math.ceil(len(sweeps.x_hz) / SAMPLE_ROWS))
    sample = RowSample(SAMPLE_ROWS)
    sample.add(sweeps.powers_w[::stride], sweeps.x_hz[::stride])
    inputs = {name: values[::stride] for name, values in inputs.items()}
    return dataclasses.replace(sweeps.read, dark=dark), sample, inputs, caught


def calibrate_file(
    paths,
    out_path=None,
    *,
    options: CalibrateOptions | None = None,
    device: str | None = None,
    progress: Callable | None = None,
    check: Callable | None = None,
    **keywords,
) -> DeviceResult:
    """Calibrate one device from its sweep file(s), and save the calibration.

    Parameters
    ----------
    paths : str, Path or sequence of them
        The sweep: a data file with a frequency or wavelength column and 3+ port columns
        (``"-"``: standard input); several only for a calibrator that needs the chip
        temperature (concatenated in order).
    out_path : str or Path, optional
        Where to save the calibration (JSON, atomically); None: not saved.
    options : CalibrateOptions, optional
        What to calibrate with; or give its fields and the method's settings as keywords
        (``method="wideband", fsr_hz=50e9, phase_order=2``), not both.
    device : str, optional
        The device's name (default: the first file's stem).
    progress : callable, optional
        ``progress(description, total, unit)`` returning a context manager that yields
        ``advance(steps)`` (:func:`wavemeter.progress.progress_bar`); ``total`` None for a
        task of unknown length. None: silent.
    check : callable, optional
        ``check(layout)`` with what the (first) sweep file offers (``source``,
        ``port_names``), before the fit; what it raises stops the job.
    **keywords
        Fields of :class:`CalibrateOptions` and settings of the method, by name.

    Returns
    -------
    DeviceResult
        With ``status="ok"``, the fitted calibration, its metadata, what was read and the
        fit's warnings (recorded; the caller decides how to show them).

    Raises
    ------
    InputError, FileFormatError, EdgeMinimumError
        What the options, reading the files or fitting refuse; messages name the file.
    CalibrationRefused
        With ``strict``, for a fit that warned; nothing is saved.

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
    if options is None:
        options = CalibrateOptions.from_keywords(**keywords)
    elif keywords:
        raise InputError(
            f"give the options or keywords, not both (got {', '.join(keywords)})",
            parameter="options",
        )
    paths = _paths(paths)
    calibrator = build_calibrator(options)
    _check_inputs(calibrator, paths, options)
    record = options_record(options, calibrator)
    # in chunks: a calibrator that can (a set cannot), of one sweep, needing no inputs
    chunked = "fit_chunks" in calibrator.capabilities and not calibrator.requires
    fit = _fit_in_chunks if chunked and len(paths) == 1 else _fit_whole
    read, sample, inputs, caught = fit(calibrator, paths, options, progress, check)
    if options.strict and caught:
        raise CalibrationRefused(read.label, caught)
    crlb_rms_hz = _crlb_rms_hz(calibrator, sample.powers_w, sample.frequency_hz, inputs)
    metadata = {
        **sweep_metadata(read, options.dark_file),
        "crlb_rms_hz": crlb_rms_hz if math.isfinite(crlb_rms_hz) else None,
        "calibrate_options": record,
    }
    name = Path(input_label(paths[0])).stem if device is None else device
    result = _result(
        name, read.label, calibrator, crlb_rms_hz, metadata, read=read, fit_warnings=tuple(caught)
    )
    if out_path is not None:
        from ..calibration import save_calibration

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
        As :func:`calibrate_file` takes them (``options=`` or keywords).

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
    calibration, the Cramer-Rao RMS from its metadata (NaN when the file has none).

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
