"""Published readings as Python objects: a batch of one channel's readings, and one reading.

A :class:`ReadingBatch` holds the readings one processing step made for one channel,
column by column (what is encoded and logged); :class:`Reading` is one of them with its
fields as attributes (what :meth:`Client.readings <wavemeter.service.Client.readings>`
yields). Neither knows sockets or files.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError

__all__ = ["CORE_FIELDS", "INTEGER_FIELDS", "Reading", "ReadingBatch"]

#: the fields every reading has, in order (``channel`` is the batch's)
CORE_FIELDS = (
    "sequence",
    "source_time_ns",
    "time_ns",
    "frequency_hz",
    "frequency_std_hz",
    "flags",
)
#: fields held as int64; every other field is float64
INTEGER_FIELDS = frozenset({"sequence", "source_time_ns", "time_ns", "flags"})


class Reading:
    """One published reading.

    Attributes
    ----------
    channel : int
        The channel (switch input) it was read on.
    sequence : int
        Its number on the channel: 0, 1, 2, ... with no gap while the service runs.
    source_time_ns : int
        When the source took it (ns since the epoch): the simulated meter's or
        ``Server.feed``'s time, else when its line arrived.
    time_ns : int
        When the service read it out (``time.time_ns()``).
    frequency_hz, frequency_std_hz : float
        The frequency and its standard deviation (Hz); NaN for a reading that cannot be read.
    flags : int
        Quality bits (:class:`wavemeter.ReadingFlag`).
    extras : dict of str to float
        Every further field: the calibration's extra outputs (``order_error_probability``),
        ``temperature_k`` where the calibration uses it, ``true_frequency_hz`` when
        simulated; also readable as attributes (``reading.true_frequency_hz``).
    """

    __slots__ = ("channel", *CORE_FIELDS, "extras")

    def __init__(self, channel: int, values: Mapping[str, float]):
        self.channel = channel
        for name in CORE_FIELDS:
            setattr(self, name, values[name])
        self.extras = {name: value for name, value in values.items() if name not in CORE_FIELDS}

    def __getattr__(self, name: str):
        extras = object.__getattribute__(self, "extras")
        if name in extras:
            return extras[name]
        raise AttributeError(f"a reading has no field {name!r}; it has {sorted(self.as_dict())}")

    def as_dict(self) -> dict[str, float]:
        """Every field by name, ``channel`` first."""
        core = {name: getattr(self, name) for name in CORE_FIELDS}
        return {"channel": self.channel, **core, **self.extras}

    def __repr__(self) -> str:
        return (
            f"Reading(channel={self.channel}, sequence={self.sequence}, "
            f"frequency_hz={self.frequency_hz!r}, flags={self.flags})"
        )


@dataclass
class ReadingBatch:
    """Consecutive readings of one channel, field by field.

    Attributes
    ----------
    channel : int
        The channel.
    columns : dict of str to ndarray, shape (N,)
        Every field (:data:`CORE_FIELDS` first, then the extras), int64 or float64.
    run : str
        The service run that made them (a new run restarts the sequences).
    name : str
        The channel's name.
    """

    channel: int
    columns: dict[str, np.ndarray]
    run: str = ""
    name: str = ""
    _size: int = field(init=False, repr=False)

    def __post_init__(self):
        sizes = {len(values) for values in self.columns.values()}
        if len(sizes) > 1:
            raise InputError(f"the columns of a batch differ in length: {sorted(sizes)}")
        self._size = sizes.pop() if sizes else 0

    def __len__(self) -> int:
        return self._size

    @property
    def fields(self) -> tuple[str, ...]:
        """The field names, in order."""
        return tuple(self.columns)

    def readings(self) -> Iterator[Reading]:
        """The readings one at a time, with Python numbers."""
        names = list(self.columns)
        for row in zip(*(self.columns[name].tolist() for name in names), strict=True):
            yield Reading(self.channel, dict(zip(names, row, strict=True)))

    def last(self) -> Reading:
        """The latest reading of the batch."""
        values = {name: column[-1].item() for name, column in self.columns.items()}
        return Reading(self.channel, values)
