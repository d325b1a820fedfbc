"""Measuring a file of readings with a calibration, chunk by chunk, in bounded memory.

:func:`measure_file` reads the readings with :func:`~wavemeter.io.iter_readings`, turns each
chunk into frequency with the calibration and appends it to the output with
:func:`~wavemeter.io.table_writer`: the memory it takes is that of one chunk (and of the
calibration), whatever the size of the file; the output appears, complete, only when
every row is written (any error, also an interrupt, leaves no output and an existing one
untouched). Rows stay in file order, one output row per input row.

The output columns: ``frequency_hz``, ``wavelength_nm`` (vacuum), ``phase_rad``,
``frequency_std_hz`` (when asked for or given by the calibration), for a cascade
``order_error_probability``, ``flags`` (:class:`~wavemeter.calibration.contract.flags.ReadingFlag`
bits; a row skipped as invalid has ``INVALID`` and NaN values), for a calibration that
needs the chip temperature ``temperature_k``, then the kept columns.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..calibration.contract.flags import ReadingFlag
from ..exceptions import WavemeterError
from ..io import ColumnRequest, ReadingStream, iter_readings, table_writer
from ..io.streaming import CHUNK_ROWS
from ..units import SPEED_OF_LIGHT_M_S
from ..validation import check_choice
from .readings import check_reading_options, check_readings

__all__ = [
    "measure_file",
    "MeasureSummary",
    "ReadingsRefused",
    "ChunkMeasurement",
    "MEASURE_CHUNK_ROWS",
]

#: rows measured per chunk by default (a few MB of readings and results): those read at a time
MEASURE_CHUNK_ROWS = CHUNK_ROWS


@dataclass
class MeasureSummary:
    """What :func:`measure_file` did.

    Attributes
    ----------
    source : Path
        The readings file.
    out_path : Path
        The output written (``-``: standard output).
    rows : int
        Rows written, one per data row of the file.
    invalid_rows : int
        Rows skipped as invalid (flag ``INVALID``).
    invalid_examples : list of str
        The first (up to 5) of them with their reasons, ``line 5 (P2_mW is NaN)``.
    flag_counts : dict of str to int
        Rows with each flag bit set, by bit name, in the order of the bits (bits no row
        has are left out).
    flagged : int
        Rows with any flag.
    warnings : list of Warning
        The warnings the measurement gave (each once), also issued with
        :func:`warnings.warn`.

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
    >>> from wavemeter.jobs import measure_file
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> readings = device.powers(f_hz[:5], power_w=1e-3, noise_w=5e-7, rng=2)
    >>> readings[2] = np.nan  # a row the instrument could not read
    >>> write_table(folder / "readings.csv", {f"p{k + 1}_w": readings[:, k] for k in range(3)})
    >>> stream = iter_readings(folder / "readings.csv", allow_invalid=True)  # flag, do not refuse
    >>> summary = measure_file(cal, stream, folder / "frequencies.csv")
    >>> summary.rows, summary.invalid_rows, summary.flag_counts
    (5, 1, {'INVALID': 1})
    >>> summary.out_path.name
    'frequencies.csv'
    """

    source: Path
    out_path: Path
    rows: int = 0
    invalid_rows: int = 0
    invalid_examples: list[str] = field(default_factory=list)
    flag_counts: dict[str, int] = field(default_factory=dict)
    flagged: int = 0
    warnings: list[Warning] = field(default_factory=list)


def measure_file(
    calibration,
    readings,
    out_path,
    *,
    request: ColumnRequest | None = None,
    file_format: str | None = None,
    chunk_rows: int = MEASURE_CHUNK_ROWS,
    coarse_hz: float | None = None,
    temperature_k: float | None = None,
    uncertainty: bool | None = None,
    drop_invalid: bool = False,
    errors: str = "coerce",
    progress: Callable | None = None,
) -> MeasureSummary:
    """Turn a file of port readings into frequencies, a chunk of rows at a time.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    readings : str, Path or ReadingStream
        The readings file (``"-"``: standard input), or one opened with
        :func:`~wavemeter.io.iter_readings` (not yet iterated; ``request``, ``chunk_rows``
        and ``drop_invalid`` are then those it was opened with, ``request`` given only to
        say whether the ports were chosen).
    out_path : str or Path
        The output file (``"-"``: standard output), written atomically.
    request : ColumnRequest, optional
        Columns chosen by the user (ports, power unit, coarse and temperature columns,
        kept columns).
    file_format : {"csv", "tsv", "parquet", "hdf5", "npz"}, optional
        Output format; default from the extension of ``out_path``.
    chunk_rows : int
        Rows read, measured and written at a time.
    coarse_hz : float, optional
        Coarse frequency (Hz) of every reading, for a calibration that needs one (a
        calibration set, a wide-band calibration) when the file has no coarse column.
    temperature_k : float, optional
        Chip temperature (K) of every reading, for a calibration that needs it, instead
        of the file's temperature column.
    uncertainty : bool, optional
        Write ``frequency_std_hz``; default: when the calibration gives it.
    drop_invalid : bool
        Write invalid rows as NaN with the ``INVALID`` flag instead of failing.
    errors : {"coerce", "raise"}
        ``"coerce"``: a reading the calibration cannot read is written as NaN with the
        flags that say why, the others as usual; ``"raise"``: the file is refused
        (:class:`ReadingsRefused`, nothing written) when any reading cannot be read.
    progress : callable, optional
        ``progress(description, total, unit=...)`` returning a context manager that
        yields ``advance(steps)`` (as :func:`wavemeter.progress.progress_bar`); it is
        advanced in the units of the read (rows, or bytes of a text file). None: silent.

    Returns
    -------
    MeasureSummary

    Raises
    ------
    InputError
        For what :func:`~wavemeter.io.iter_readings` refuses, and what the checks of
        :mod:`wavemeter.jobs.readings` refuse (ports other than the calibration's, a
        missing temperature or coarse frequency, an input it does not use,
        ``uncertainty`` asked of a calibration that gives none); no output is written then.
    ReadingsRefused
        With ``errors="raise"``, when some reading cannot be read; no output is written.

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
    >>> from wavemeter.jobs import measure_file
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> readings = device.powers(f_hz[:5], power_w=1e-3, noise_w=5e-7, rng=2)
    >>> readings[2] = np.nan  # a row the instrument could not read
    >>> write_table(folder / "readings.csv", {f"p{k + 1}_w": readings[:, k] for k in range(3)})
    >>> stream = iter_readings(folder / "readings.csv", allow_invalid=True)  # flag, do not refuse
    >>> summary = measure_file(cal, stream, folder / "frequencies.csv")
    >>> summary.rows, summary.flagged, summary.flag_counts
    (5, 1, {'INVALID': 1})
    >>> lines = (folder / "frequencies.csv").read_text().splitlines()
    >>> lines[0]
    'frequency_hz,wavelength_nm,phase_rad,frequency_std_hz,flags'
    >>> len(lines) - 1  # one row out per row in, the unreadable one NaN with its flag
    5
    """
    check_choice("errors", errors, ("coerce", "raise"))
    check_reading_options(
        calibration, coarse_hz=coarse_hz, temperature_k=temperature_k, uncertainty=uncertainty
    )
    offered = "frequency_std" in calibration.capabilities
    uncertainty = offered if uncertainty is None else uncertainty
    thermal = "temperature_k" in calibration.requires
    if isinstance(readings, ReadingStream):
        stream = readings
    else:
        stream = iter_readings(
            readings,
            request,
            chunk_rows=chunk_rows,
            allow_invalid=drop_invalid,
            find_temperature=thermal and temperature_k is None,
        )
    check_readings(
        calibration,
        stream,
        coarse_hz=coarse_hz,
        temperature_k=temperature_k,
        ports_given=request is not None and request.ports is not None,
    )
    summary = MeasureSummary(source=stream.source, out_path=Path(out_path))
    measured = ChunkMeasurement(calibration, uncertainty, coarse_hz, temperature_k)
    counts = np.zeros(len(ReadingFlag), dtype=np.int64)
    total, unit = stream.progress_total
    bar = progress(f"measuring {stream.source}", total, unit=unit) if progress else None
    with contextlib.ExitStack() as stack:
        advance = stack.enter_context(bar) if bar is not None else None
        write = stack.enter_context(table_writer(out_path, file_format))
        done = 0
        unread: list[str] = []
        unread_count = 0
        for table in stream:
            columns = measured.chunk(table)
            flags = columns["flags"]
            if errors == "raise":
                missing = np.flatnonzero(np.isnan(columns["frequency_hz"]))
                unread_count += missing.size
                unread += [_unread_label(table, k, flags[k]) for k in missing[: 5 - len(unread)]]
            counts += [np.count_nonzero(flags & bit) for bit in ReadingFlag]
            summary.flagged += int(np.count_nonzero(flags))
            write(columns)
            if advance is not None:
                advance(stream.progress - done)
            done = stream.progress
        if unread_count:
            raise ReadingsRefused(stream.source, unread_count, stream.rows, unread)
        summary.warnings = measured.finish()
        for warning in summary.warnings:
            warnings.warn(warning, stacklevel=2)
    summary.rows = stream.rows
    summary.invalid_rows = stream.invalid_rows
    summary.invalid_examples = list(stream.invalid_examples)
    summary.flag_counts = {
        bit.name: int(count) for bit, count in zip(ReadingFlag, counts, strict=True) if count
    }
    return summary


class ReadingsRefused(WavemeterError):
    """Readings a calibration cannot read, refused (``errors="raise"``): nothing was written.

    Attributes
    ----------
    unread : int
        Readings that could not be read.
    examples : list of str
        The first of them by file line, with their flags (``line 12 (OUTSIDE_SPAN)``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import iter_readings, write_table
    >>> from wavemeter.jobs import ReadingsRefused, measure_file
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(device.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)
    >>> readings = device.powers(f_hz[:5], power_w=1e-3, noise_w=5e-7, rng=2)
    >>> readings[3] = np.nan  # a row the instrument could not read
    >>> folder = Path(tempfile.mkdtemp())
    >>> write_table(folder / "readings.csv", {f"p{k + 1}_w": readings[:, k] for k in range(3)})
    >>> stream = iter_readings(folder / "readings.csv", allow_invalid=True)
    >>> try:
    ...     measure_file(cal, stream, folder / "out.csv", errors="raise")
    ... except ReadingsRefused as error:
    ...     print(error.unread, error.examples, (folder / "out.csv").exists())
    1 ['line 5 (INVALID)'] False
    """

    def __init__(self, source, unread: int, rows: int, examples: list[str]):
        self.unread = unread
        self.examples = list(examples)
        super().__init__(
            f"{source}: {unread} of {rows} readings cannot be read ({', '.join(examples)}"
            f"{', ...' if unread > len(examples) else ''}); strict refuses the file, so "
            "nothing was written"
        )


def _unread_label(table, row: int, flags: int) -> str:
    """``line 12 (OUTSIDE_SPAN)``: a reading by its file line, with its flags."""
    names = [bit.name for bit in ReadingFlag if flags & bit] or ["no flag"]
    return f"{table.row_label(int(table.row_index[row]))} ({', '.join(names)})"


class ChunkMeasurement:
    """Measures chunks of readings; keeps what the whole file decides (the cascade's
    noise scale, the warnings, each given once).

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    uncertainty : bool
        Give ``frequency_std_hz``.
    coarse_hz, temperature_k : float or None
        One coarse frequency (Hz) / chip temperature (K) for every reading, instead of the
        file's column.
    phase : bool
        Give ``phase_rad`` and ``wavelength_nm`` (a job that needs only the frequency
        skips the second retrieval).
    """

    def __init__(self, calibration, uncertainty: bool, coarse_hz, temperature_k, phase=True):
        self.calibration = calibration
        self.uncertainty = uncertainty
        self.phase = phase
        self.coarse_hz = coarse_hz
        self.temperature_k = temperature_k
        self.thermal = "temperature_k" in calibration.requires
        self.extras = tuple(calibration.reading_outputs)
        self.states: list = []
        self.warnings: dict[tuple[type, str], Warning] = {}

    def chunk(self, table) -> dict[str, np.ndarray]:
        """The output columns of one chunk of readings (m rows)."""
        rows = table.n_rows
        frequency = np.full(rows, np.nan)
        phase = np.full(rows, np.nan)
        std = np.full(rows, np.nan)
        flags = np.where(table.invalid, int(ReadingFlag.INVALID), 0)
        extras = {name: np.full(rows, np.nan) for name in self.extras}
        temperature = None
        if self.thermal:
            temperature = (
                table.temperature_k
                if self.temperature_k is None
                else np.full(rows, float(self.temperature_k))
            )
        valid = np.flatnonzero(~table.invalid)
        powers = table.powers_w[valid]
        extra = {}
        if "coarse_hz" in self.calibration.requires:
            coarse = table.coarse_hz
            extra["coarse_hz"] = (
                np.full(valid.size, self.coarse_hz) if coarse is None else coarse[valid]
            )
        if temperature is not None:
            extra["temperature_k"] = temperature[valid]
        if valid.size:
            with about_file(table.source), warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                found = self.calibration.readout(powers, **extra)
                frequency[valid] = found.frequency_hz
                phase[valid] = found.phase_rad
                std[valid] = found.frequency_std_hz
                flags[valid] = found.flags
                for name, values in extras.items():
                    values[valid] = found.extras[name]
                self.states.append(found.state)
            for warning in caught:
                key = (warning.category, str(warning.message))
                self.warnings.setdefault(key, warning.message)
        columns = {"frequency_hz": frequency}
        if self.phase:
            with np.errstate(divide="ignore", invalid="ignore"):
                columns["wavelength_nm"] = SPEED_OF_LIGHT_M_S / frequency * 1e9
            columns["phase_rad"] = phase
        columns |= {
            **({"frequency_std_hz": std} if self.uncertainty else {}),
            **extras,
            "flags": flags,
            **({} if temperature is None else {"temperature_k": temperature}),
        }
        for name, values in table.kept.items():
            columns.setdefault(name, values)
        return columns

    def finish(self) -> list[Warning]:
        """The warnings of the whole file: those the chunks gave, each once, then those the
        calibration draws from every chunk's readout (``readout_notes``)."""
        return list(self.warnings.values()) + self.calibration.readout_notes(self.states)


@contextlib.contextmanager
def about_file(path):
    """Prefix an error the calibration raises with the file it concerns."""
    try:
        yield
    except WavemeterError as exc:
        if str(exc).startswith(str(path)):
            raise
        renamed = type(exc)(f"{path}: {exc}")
        renamed.parameter = getattr(exc, "parameter", None)
        raise renamed from exc
