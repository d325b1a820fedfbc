"""Live readout: lines of port readings in, one line of frequency out per reading, at once.

:func:`stream_lines` reads a header line, finds the columns in it as the file readers do
(:func:`wavemeter.io.plan.plan_columns`: ports, their units, a temperature or coarse
column), then turns every data line into an output line the moment it arrives, written and
flushed before the next line is read: ``frequency_hz,wavelength_nm,frequency_std_hz``, for
a cascade ``order_error_probability``, then ``flags``, floats at full precision (the
shortest text that reads back to the same float64, as the table writer writes them). Each
reading goes through the calibration's :meth:`~wavemeter.calibration.BaseCalibrator.stream`,
so it gets the numbers ``predict``, ``frequency_std_hz`` and ``flags`` give it.

A line that is no reading (another number of cells than the header, text where a number
should be) or an invalid one (NaN, a power-meter sentinel, no light, as in files) is written
as NaN with the ``INVALID`` flag, with a warning naming its line; blank lines and ``#``
comment lines are skipped. :func:`follow_lines` gives the lines of a file that is being
appended to, like ``tail -n +1 -f``.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from ..calibration.contract.flags import ReadingFlag
from ..calibration.contract.streaming import INVALID_READING_CAUSE
from ..exceptions import CalibrationWarning, InputError
from ..io import ColumnRequest
from ..io.checks import ColumnChecks
from ..io.convert import PlainRowConverter, convert_rows
from ..units import SPEED_OF_LIGHT_M_S
from .line_reader import LineReader
from .measure import about_file
from .readings import check_reading_options, check_readings
from .stream_header import StreamHeader, read_header

__all__ = [
    "stream_lines",
    "follow_lines",
    "StreamSummary",
    "STREAM_COLUMNS",
    "MAX_LINE_WARNINGS",
]

#: the output columns, in order; a calibration's ``reading_outputs`` (a cascade's
#: ``order_error_probability``) come before ``flags``
STREAM_COLUMNS = ("frequency_hz", "wavelength_nm", "frequency_std_hz", "flags")
#: invalid lines warned about one by one; later ones are written and counted silently
MAX_LINE_WARNINGS = 10


@dataclass
class StreamSummary:
    r"""What :func:`stream_lines` did.

    Attributes
    ----------
    source : Path
        The input, as named in messages.
    rows : int
        Readings written, one per data line.
    invalid_rows : int
        Lines written as NaN with the ``INVALID`` flag because they held no valid reading.
    flag_counts : dict of str to int
        Readings with each flag bit set, by bit name (bits no reading has are left out).
    flagged : int
        Readings with any flag.
    interrupted : bool
        The stream was ended by Ctrl-C (KeyboardInterrupt), not by the end of the lines.

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
    >>> import io
    >>> import warnings
    >>> from wavemeter.jobs import stream_lines
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> good = ",".join(f"{p:.6e}" for p in powers[100]) + "\n"
    >>> lines = ["p1_w,p2_w,p3_w\n", "1e-4,nan,2e-4\n", good]  # the first reading is broken
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     summary = stream_lines(cal, lines, io.StringIO())
    >>> print(str(caught[0].message))  # the line is written as NaN, flagged, and said
    <input> line 2: p2_w is NaN, empty or inf: written as NaN with the INVALID flag
    >>> summary.rows, summary.flagged, summary.flag_counts, summary.interrupted
    (2, 1, {'INVALID': 1}, False)
    """

    source: Path
    rows: int = 0
    invalid_rows: int = 0
    flag_counts: dict[str, int] = field(default_factory=dict)
    flagged: int = 0
    interrupted: bool = False


def stream_lines(
    calibration,
    lines: Iterable[str],
    out: TextIO,
    *,
    request: ColumnRequest | None = None,
    coarse_hz: float | None = None,
    temperature_k: float | None = None,
    name: str = "<input>",
    check: Callable[[StreamHeader], None] | None = None,
) -> StreamSummary:
    r"""Turn lines of port readings into lines of frequency, each as soon as it arrives.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    lines : iterable of str
        Text lines, the header first (blank lines and ``#`` comment lines are skipped
        anywhere; an Excel ``sep=`` first line names the delimiter); separated as
        ``request`` says, else by tab, ``;`` or comma (see
        :class:`~wavemeter.io.text_layout.LineCells`). May be endless
        (:func:`follow_lines`, a pipe): each line is read only after the output of the
        one before it is written.
    out : text file
        Where the output goes: the header line, then one line per data line, each flushed.
    request : ColumnRequest, optional
        Columns chosen by the user (ports, power unit, coarse and temperature columns,
        delimiter and decimal mark).
    coarse_hz : float, optional
        Coarse frequency (Hz) of every reading, for a calibration that needs one, when the
        lines have no coarse column.
    temperature_k : float, optional
        Chip temperature (K) of every reading, for a calibration that needs it, instead of
        a temperature column.
    name : str
        What the input is called in messages (``<stdin>``, a file name).
    check : callable, optional
        ``check(header)`` is called with the :class:`StreamHeader` before anything is
        written (the command line checks it against the calibration with its own
        messages); what it raises ends the stream.

    Returns
    -------
    StreamSummary
        Also when Ctrl-C (KeyboardInterrupt) ended the stream, which it does as the end of
        the lines does (``interrupted`` says so): every line written so far is complete.

    Raises
    ------
    InputError
        Before any output, for lines without a header, a header whose columns cannot be
        found (as in files), ports other than the calibration's, a missing temperature or
        coarse frequency.

    Warns
    -----
    CalibrationWarning
        Cause :data:`~wavemeter.calibration.contract.base.INVALID_READING_CAUSE` for each of the
        first :data:`MAX_LINE_WARNINGS` invalid lines, naming the line and what is wrong.

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
    >>> import io
    >>> from wavemeter.jobs import stream_lines
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> rows = [",".join(f"{p:.6e}" for p in row) + "\n" for row in powers[:3]]
    >>> lines = ["p1_w,p2_w,p3_w\n", *rows]  # a header, then one reading a line, in W
    >>> out = io.StringIO()
    >>> summary = stream_lines(cal, lines, out)  # each line is read and written as it comes
    >>> out.getvalue().splitlines()[0]
    'frequency_hz,wavelength_nm,frequency_std_hz,flags'
    >>> summary.rows, summary.flagged
    (3, 0)
    """
    source = Path(name)
    summary = StreamSummary(source=source)
    numbered = iter(enumerate(lines, start=1))
    thermal = "temperature_k" in calibration.requires
    check_reading_options(calibration, coarse_hz=coarse_hz, temperature_k=temperature_k)
    ports_given = request is not None and request.ports is not None
    try:
        with about_file(source):
            header = read_header(numbered, source, request, thermal and temperature_k is None)
            if check is not None:
                check(header)
            check_readings(
                calibration,
                header,
                coarse_hz=coarse_hz,
                temperature_k=temperature_k,
                ports_given=ports_given,
            )
        _Stream(calibration, header, out, coarse_hz, temperature_k).run(numbered, summary)
    except KeyboardInterrupt:
        summary.interrupted = True
    return summary


class _Latest:
    """An endless iterator of the value set last. It hands ``calibration.stream`` (one
    record for each row it takes) the rows one at a time; lines that hold no valid reading
    never reach it."""

    __slots__ = ("value",)

    def __init__(self):
        self.value = None

    def __iter__(self):
        return self

    def __next__(self):
        return self.value


class _Stream:
    """Reads data lines and writes their output lines (one stream)."""

    def __init__(self, calibration, header: StreamHeader, out: TextIO, coarse_hz, temperature_k):
        self.header = header
        self.out = out
        plan = header.plan
        self.cells = LineReader(header)
        self.checks = ColumnChecks()
        self.plain = PlainRowConverter.of(plan)
        self.powers = _Latest()
        self.temperature = self.coarse = None
        temperature = coarse = None
        if "temperature_k" in calibration.requires:
            temperature = temperature_k
            if temperature_k is None:
                temperature = self.temperature = _Latest()
        if "coarse_hz" in calibration.requires:
            coarse = coarse_hz
            if coarse_hz is None:
                coarse = self.coarse = _Latest()
        self.records = calibration.stream(self.powers, coarse_hz=coarse, temperature_k=temperature)
        self.extras = tuple(calibration.reading_outputs)
        self.counts = np.zeros(len(ReadingFlag), dtype=np.int64)
        self.bits = [int(bit) for bit in ReadingFlag]
        nan = float("nan")
        self.unread = (nan, nan, nan, *(nan for _ in self.extras), int(ReadingFlag.INVALID))

    def run(self, numbered, summary: StreamSummary) -> None:
        """Write the header line, then one line per data line until the lines end."""
        columns = [*STREAM_COLUMNS[:-1], *self.extras, STREAM_COLUMNS[-1]]
        self._write(",".join(columns))
        try:
            for number, text in numbered:
                line = text.rstrip("\r\n")  # an empty last cell is a cell
                if not line.strip() or line.lstrip().startswith("#"):
                    continue
                values, reason = self._read(line, number)
                summary.rows += 1
                if reason is not None:
                    values = self.unread
                    summary.invalid_rows += 1
                    if summary.invalid_rows <= MAX_LINE_WARNINGS:
                        self._warn(number, reason, last=summary.invalid_rows == MAX_LINE_WARNINGS)
                *numbers, flags = values
                self._write(",".join(map(repr, numbers)) + f",{flags}")
                if flags:
                    summary.flagged += 1
                    self.counts += [bool(flags & bit) for bit in self.bits]
        finally:
            summary.flag_counts = {
                bit.name: int(count)
                for bit, count in zip(ReadingFlag, self.counts, strict=True)
                if count
            }

    def _write(self, line: str) -> None:
        self.out.write(line + "\n")
        self.out.flush()

    def _warn(self, number: int, reason: str, last: bool) -> None:
        more = "; further invalid lines are written so without a warning" if last else ""
        warnings.warn(
            CalibrationWarning(
                f"{self.header.source} line {number}: {reason}: written as NaN with the "
                f"INVALID flag{more}",
                cause=INVALID_READING_CAUSE,
                remedy="check the readings' source: one number per column, the light on",
            ),
            stacklevel=4,
        )

    def _read(self, line: str, number: int) -> tuple[tuple, str | None]:
        """The output values of a data line (the flags last), or why it is no valid reading."""
        data, reason = self.cells.values(line)
        if reason is not None:
            return (), reason
        plain = None if self.plain is None else self.plain.convert(data)
        if plain is not None:
            self.powers.value, temperature_k = plain
            if self.temperature is not None:
                self.temperature.value = temperature_k
        else:
            rows = {name: np.array([value]) for name, value in data.items()}
            table = convert_rows(self.header.plan, rows, number - 1, _line_label, self.checks)
            if table.invalid[0]:
                return (), table.invalid_reasons[table.invalid_code[0]]
            self.powers.value = table.powers_w[0]
            if self.temperature is not None:
                self.temperature.value = table.temperature_k[0]
            if self.coarse is not None:
                self.coarse.value = table.coarse_hz[0]
        record = next(self.records)
        frequency = record.frequency_hz
        values = (frequency, SPEED_OF_LIGHT_M_S / frequency * 1e9, record.frequency_std_hz)
        values += tuple(record.extras[name] for name in self.extras)
        return (*values, record.flags), None


def _line_label(row: int) -> str:
    """Line ``row + 1`` of the input: data rows are indexed by their line numbers."""
    return f"line {row + 1}"


def follow_lines(path, *, poll_s: float = 0.05, stop=None) -> Iterator[str]:
    r"""The lines of a file, then those appended to it later, like ``tail -n +1 -f``.

    Parameters
    ----------
    path : str or Path
        A text file (UTF-8), opened now.
    poll_s : float
        Seconds to wait before looking again when the file has no new line.
    stop : callable or threading.Event, optional
        Checked whenever every line written so far has been given: the lines end when it
        returns True (is set). None: they never end (stop with Ctrl-C).

    Returns
    -------
    iterator of str
        Whole lines, each with its newline; a last line still being written is held
        until its newline arrives (and dropped when the lines end before it does).

    Raises
    ------
    InputError
        When the file does not exist or is a folder.

    Examples
    --------
    >>> import tempfile, threading
    >>> from pathlib import Path
    >>> from wavemeter.jobs import follow_lines
    >>> path = Path(tempfile.mkdtemp()) / "live.csv"
    >>> _ = path.write_text("p1_w,p2_w,p3_w\n5e-4,2.5e-4,2.5e-4\n")
    >>> done = threading.Event()
    >>> done.set()  # stop once every line written so far was given (else: follow forever)
    >>> list(follow_lines(path, stop=done))
    ['p1_w,p2_w,p3_w\n', '5e-4,2.5e-4,2.5e-4\n']
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: file not found")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a data file")
    stopped = getattr(stop, "is_set", stop) or (lambda: False)
    handle = open(path, encoding="utf-8", errors="replace")  # noqa: SIM115

    def lines() -> Iterator[str]:
        with handle:
            held = ""
            while True:
                text = handle.readline()
                if text:
                    held += text
                    if held.endswith("\n"):
                        yield held
                        held = ""
                elif stopped():
                    return
                else:
                    time.sleep(poll_s)

    return lines()
