"""Lines of port readings to blocks of rows, by the column rules of ``wavemeter stream``.

A :class:`LineParser` belongs to one line source (standard input, a followed file, one TCP
connection). Its first line that is not blank or a comment is the header, read by
:func:`wavemeter.jobs.read_header` as ``stream`` reads it; every data line after it is one
reading, its numbers read by :meth:`wavemeter.jobs.LineReader.block` (a block of lines at
once, as ``stream`` reads each) and converted to SI by
:func:`wavemeter.io.convert.convert_rows` (or, for a few rows,
:class:`~wavemeter.io.convert.PlainRowConverter`, row by row; a lone line in linear units
in plain floats first, ~5 us against ~30 us). A line that holds no valid reading becomes an
invalid row with its reason; its channel is the next one of the switch schedule,
or, with a channel column, the one its cell names (a line without a readable channel is
counted as unroutable and dropped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..io import ColumnRequest
from ..io.checks import ColumnChecks
from ..io.convert import PlainRowConverter, convert_rows
from ..io.power_codes import SENTINEL_W
from ..jobs import LineReader, check_readings, read_header
from ..units import POWER_UNITS, canonical_unit, decimal_scale
from .blocks import RowBlock

__all__ = ["LineParser", "MAX_CHANNELS", "LineCounts"]

#: channel numbers a channel column may name: 0 .. MAX_CHANNELS - 1
MAX_CHANNELS = 256
#: blocks of at most this many valid rows are converted a row at a time (about 30 us a
#: row; a block through ``convert_rows`` costs 0.15-0.3 ms whatever its rows)
PLAIN_ROWS = 4


@dataclass
class LineCounts:
    """What a line source has seen.

    Attributes
    ----------
    lines : int
        Data lines (blank and comment lines aside).
    invalid : int
        Data lines that held no valid reading (published as INVALID readings).
    unroutable : int
        Data lines whose channel could not be read (not published).
    reasons : dict of str to int
        Invalid lines by reason (the first 20 reasons).
    """

    lines: int = 0
    invalid: int = 0
    unroutable: int = 0
    reasons: dict[str, int] = field(default_factory=dict)

    def note(self, reason: str) -> None:
        if reason in self.reasons or len(self.reasons) < 20:
            self.reasons[reason] = self.reasons.get(reason, 0) + 1


class LineParser:
    """One line source's text lines to :class:`RowBlock` s.

    Parameters
    ----------
    name : str
        What the source is called in messages.
    request : ColumnRequest, optional
        Columns chosen by the user.
    channels : int
        Switch inputs the source cycles through (line ``k`` is channel ``k % channels``);
        ignored with a ``channel_column``.
    channel_column : str, optional
        A column naming each reading's channel (an integer 0 .. MAX_CHANNELS - 1).
    coarse_hz, temperature_k : float, optional
        One coarse frequency (Hz) or chip temperature (K) for every reading, for a
        calibration that needs them, when the lines have no such column.
    """

    def __init__(
        self,
        name: str,
        request: ColumnRequest | None = None,
        *,
        channels: int = 1,
        channel_column: str | None = None,
        coarse_hz: float | None = None,
        temperature_k: float | None = None,
    ):
        request = request or ColumnRequest()
        if channel_column is not None:
            request = ColumnRequest(**{**vars(request), "keep": (*request.keep, channel_column)})
        self.name = name
        self.request = request
        self.channels = channels
        self.channel_column = channel_column
        self.coarse_hz = coarse_hz
        self.temperature_k = temperature_k
        self.header = None
        self.counts = LineCounts()
        self._number = 0
        self._switch = 0

    def start(self, lines: list[str], calibration) -> list[str]:
        """Read the header from the first of ``lines`` that is not blank or a comment, check
        it against the calibration, and return the lines after it (all of them when none is
        a header yet: nothing is consumed).

        Raises
        ------
        InputError
            For a header whose columns cannot be found, or that the calibration cannot read.
        """
        for index, text in enumerate(lines):
            line = text.lstrip("\ufeff").strip()
            if not line or line.startswith("#"):
                continue
            number = self._number + index + 1
            try:
                header = read_header(
                    iter([(number, line)]),
                    Path(self.name),
                    self.request,
                    "temperature_k" in calibration.requires and self.temperature_k is None,
                )
            except InputError as exc:
                raise InputError(f"{self.name}: {exc}", parameter=exc.parameter) from None
            self.check(calibration, header)
            self.header = header
            self._reader = LineReader(header)
            self._plain = PlainRowConverter.of(header.plan)
            self._floats = _LinearRow.of(header.plan) if self._plain is not None else None
            self._checks = ColumnChecks()
            self._number = number
            return lines[index + 1 :]
        self._number += len(lines)
        return []

    def check(self, calibration, header=None) -> None:
        """Raise InputError when ``calibration`` cannot read this source's lines."""
        header = header or self.header
        try:
            check_readings(
                calibration,
                header,
                coarse_hz=self.coarse_hz,
                temperature_k=self.temperature_k,
                ports_given=self.request is not None and self.request.ports is not None,
            )
        except InputError as exc:
            raise InputError(f"{self.name}: {exc}", parameter=exc.parameter) from None

    def rows(self, lines: list[str], arrival_ns: int) -> RowBlock | None:
        """The readings of data lines (after :meth:`start`), None when they hold none.

        Parameters
        ----------
        lines : list of str
            Data lines, with or without their newlines.
        arrival_ns : int
            When they arrived (ns since the epoch): their source time.
        """
        kept = []
        for text in lines:
            line = text.rstrip("\r\n")
            first = line[:1]
            if (
                not first
                or (first.isspace() or first == "#")
                and (not line.strip() or line.lstrip().startswith("#"))
            ):
                continue  # blank lines and comments, as stream skips them
            kept.append(line)
        if not kept:
            return None
        if len(kept) == 1 and self.channel_column is None and self._plain is not None:
            block = self._plain_row(kept[0], arrival_ns)
            if block is not None:
                return block
        start = self._number
        self._number += len(kept)
        self.counts.lines += len(kept)
        data, reasons = self._reader.block(kept)
        channels, routed = self._channels(data, reasons)
        if routed is not None:
            data = {name: values[routed] for name, values in data.items()}
            reasons = [reasons[k] for k in np.flatnonzero(routed)]
            if not len(channels):
                return None
        powers, temperature, coarse, reasons = self._convert(data, reasons, start)
        invalid = np.array([reason is not None for reason in reasons])
        for reason in reasons:
            if reason is not None:
                self.counts.invalid += 1
                self.counts.note(reason)
        return RowBlock(
            channel=channels,
            powers_w=powers,
            invalid=invalid,
            source_time_ns=np.full(len(channels), arrival_ns, dtype=np.int64),
            temperature_k=temperature,
            coarse_hz=coarse,
        )

    def _plain_row(self, line: str, arrival_ns: int) -> RowBlock | None:
        """A lone valid line without a channel column, read as :meth:`rows` reads it
        (:meth:`LineReader.values` and the plain converter) without the arrays of a block;
        None for a line they refuse (:meth:`rows` then names why)."""
        values, reason = self._reader.values(line)
        if reason is not None:
            return None
        if self._floats is not None:
            found = self._floats.convert(values)
            if found is None:  # the converter names what is wrong, or reads it after all
                found = self._plain.convert(values)
        else:
            found = self._plain.convert(values)
        if found is None:
            return None
        powers, kelvin = found
        self._number += 1
        self.counts.lines += 1
        channel = self._switch % self.channels
        self._switch += 1
        temperature = _given(1, self.header.temperature_column, self.temperature_k)
        if temperature is not None and self.header.temperature_column:
            temperature[0] = kelvin
        return RowBlock(
            channel=np.array([channel], dtype=np.int64),
            powers_w=powers[np.newaxis],
            invalid=np.zeros(1, dtype=bool),
            source_time_ns=np.array([arrival_ns], dtype=np.int64),
            temperature_k=temperature,
            coarse_hz=_given(1, self.header.coarse_column, self.coarse_hz),
        )

    def _channels(self, data, reasons):
        """Each line's channel, and which lines have one (None: all)."""
        n = len(reasons)
        if self.channel_column is None:
            channels = (self._switch + np.arange(n, dtype=np.int64)) % self.channels
            self._switch += n
            return channels, None
        cells = data[self.channel_column]
        with np.errstate(invalid="ignore"):
            routed = (cells >= 0) & (cells < MAX_CHANNELS) & (cells == np.floor(cells))
        for k in np.flatnonzero(~routed):
            self.counts.unroutable += 1
            self.counts.note(reasons[k] or f"column {self.channel_column!r}: no channel")
        return cells[routed].astype(np.int64), None if routed.all() else routed

    def _convert(self, data: dict, reasons: list, start: int):
        """Powers (n, ports) W, temperature (n,) K or None, coarse (n,) Hz or None, reasons."""
        plan = self.header.plan
        n = len(reasons)
        temperature = _given(n, self.header.temperature_column, self.temperature_k)
        coarse = _given(n, self.header.coarse_column, self.coarse_hz)
        powers = np.full((n, len(plan.port_names)), np.nan)
        rows = np.array([k for k, reason in enumerate(reasons) if reason is None], dtype=int)
        if not len(rows):
            return powers, temperature, coarse, reasons
        if len(rows) <= PLAIN_ROWS and self._plain is not None:
            plain = [
                self._plain.convert({name: float(data[name][row]) for name in data}) for row in rows
            ]
            if all(found is not None for found in plain):
                for row, (row_powers, kelvin) in zip(rows, plain, strict=True):
                    powers[row] = row_powers
                    if temperature is not None and self.header.temperature_column:
                        temperature[row] = kelvin
                return powers, temperature, coarse, reasons
        columns = {name: data[name][rows] for name in plan.fields}
        table = convert_rows(plan, columns, start, self._label, self._checks)
        powers[rows] = table.powers_w
        if temperature is not None and self.header.temperature_column:
            temperature[rows] = table.temperature_k
        if coarse is not None and self.header.coarse_column:
            coarse[rows] = table.coarse_hz
        reasons = list(reasons)
        invalid = table.invalid
        if invalid.any():
            codes = table.invalid_code
            for position in np.flatnonzero(invalid):
                reasons[rows[position]] = table.invalid_reasons[codes[position]]
        return powers, temperature, coarse, reasons

    def _label(self, row: int) -> str:
        return f"{self.name} line {row + 1}"


def _given(n: int, column: str | None, value: float | None) -> np.ndarray | None:
    """A per-reading input: NaN to fill from a column, the one value given, or None."""
    if column is not None:
        return np.full(n, np.nan)
    return None if value is None else np.full(n, float(value))


class _LinearRow:
    """A row of port powers in linear units (W, mW, uW, nW, V or relative), without a
    temperature, converted in plain floats: the numbers
    :class:`~wavemeter.io.convert.PlainRowConverter` gives (the same scaling,
    :func:`~wavemeter.units.decimal_scale`), None for any row it would refuse (not finite,
    a power-meter code above ``SENTINEL_W``, no light) and for any it might read
    differently; :class:`PlainRowConverter` then decides."""

    def __init__(self, scales: list[tuple[str, float, bool]]):
        self.scales = scales  # (field, 10**|k|, multiply) per port, in port order

    @classmethod
    def of(cls, plan) -> _LinearRow | None:
        """For up to 7 ports (a sum in the order numpy sums them) in linear units, no
        temperature column; else None."""
        if plan.singles or not 0 < len(plan.ports) < 8:
            return None
        scales = []
        for role, unit in zip(plan.ports, plan.role_units, strict=True):
            exponent = POWER_UNITS.get(canonical_unit(unit or "W", "power"))
            if exponent is None:  # dBm
                return None
            scales.append((role.name, *decimal_scale(exponent)))
        return cls(scales)

    def convert(self, values: dict[str, float]) -> tuple[np.ndarray, None] | None:
        powers = []
        for name, scale, multiply in self.scales:
            raw = values[name]
            if not (math.isfinite(raw) and raw <= SENTINEL_W):
                return None
            power = raw * scale if multiply else raw / scale
            if not math.isfinite(power):
                return None
            powers.append(power)
        if not sum(powers) > 0:
            return None
        return np.array(powers), None
