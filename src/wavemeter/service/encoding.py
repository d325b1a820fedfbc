"""The wire format: what the publish and control sockets carry, versioned.

Data messages are two ZeroMQ frames, a topic and a msgpack map whose ``format`` and
``version`` say what it is (``docs/user-guide/service.rst`` describes every field):

- ``wavemeter.readings`` v1 on topic ``ch/<channel>/``: a batch of one channel's readings,
  each field a little-endian array (``<i8`` or ``<f8``) in a msgpack ``bin``;
- ``wavemeter.status`` v1 on ``status/``: every channel's status, when one changes;
- ``wavemeter.heartbeat`` v1 on ``heartbeat/``: sent to every subscriber every
  :data:`HEARTBEAT_S`, also when there is nothing to publish.

A subscriber asks for topics with a ``wavemeter.subscribe`` map. Control requests and
replies are JSON objects (UTF-8). Nothing here unpickles or evaluates anything.
"""

from __future__ import annotations

import json
import math

import msgpack
import numpy as np

from ..exceptions import InputError
from .records import INTEGER_FIELDS, ReadingBatch

__all__ = [
    "VERSION",
    "READINGS_FORMAT",
    "STATUS_FORMAT",
    "HEARTBEAT_FORMAT",
    "SUBSCRIBE_FORMAT",
    "STATUS_TOPIC",
    "HEARTBEAT_TOPIC",
    "HEARTBEAT_S",
    "MAX_BATCH",
    "channel_topic",
    "encode_batch",
    "encode_message",
    "decode_message",
    "encode_request",
    "decode_json",
    "json_safe",
]

#: the version of every message format this module writes and reads
VERSION = 1
READINGS_FORMAT = "wavemeter.readings"
STATUS_FORMAT = "wavemeter.status"
HEARTBEAT_FORMAT = "wavemeter.heartbeat"
SUBSCRIBE_FORMAT = "wavemeter.subscribe"
STATUS_TOPIC = b"status/"
HEARTBEAT_TOPIC = b"heartbeat/"
#: seconds between heartbeats to each subscriber
HEARTBEAT_S = 0.25
#: the most readings in one message (a larger batch is split)
MAX_BATCH = 8192
#: the array types a readings message may hold
_DTYPES = {"<i8": np.dtype("<i8"), "<f8": np.dtype("<f8")}
_FORMATS = (READINGS_FORMAT, STATUS_FORMAT, HEARTBEAT_FORMAT, SUBSCRIBE_FORMAT)


def channel_topic(channel: int) -> bytes:
    """The topic of a channel's readings: ``b"ch/3/"`` (the slash ends ``3`` before ``30``)."""
    return b"ch/%d/" % channel


def encode_batch(batch: ReadingBatch) -> bytes:
    """A batch of readings as one ``wavemeter.readings`` message body."""
    columns = []
    for name, values in batch.columns.items():
        dtype = "<i8" if name in INTEGER_FIELDS else "<f8"
        columns.append([name, dtype, np.ascontiguousarray(values, dtype=dtype).tobytes()])
    return encode_message(
        READINGS_FORMAT,
        run=batch.run,
        channel=batch.channel,
        name=batch.name,
        count=len(batch),
        columns=columns,
    )


def encode_message(format: str, **fields) -> bytes:
    """A message body: ``format``, ``version`` and ``fields`` as a msgpack map."""
    return msgpack.packb({"format": format, "version": VERSION, **fields}, use_bin_type=True)


def decode_message(body: bytes) -> tuple[str, dict | ReadingBatch]:
    """The format of a message body and what it holds.

    Returns
    -------
    (str, ReadingBatch or dict)
        A :class:`ReadingBatch` for ``wavemeter.readings``, else the map.

    Raises
    ------
    InputError
        For a body that is not one of these formats at this version, or whose arrays do
        not fit their declared types and count.
    """
    try:
        message = msgpack.unpackb(body, raw=False, strict_map_key=False)
    except (ValueError, msgpack.UnpackException) as exc:
        raise InputError(f"a message that is not msgpack ({exc})") from None
    if not isinstance(message, dict) or message.get("format") not in _FORMATS:
        kind = message.get("format") if isinstance(message, dict) else type(message).__name__
        raise InputError(f"a message of unknown format {kind!r}; expected one of {_FORMATS}")
    if message.get("version") != VERSION:
        raise InputError(
            f"a {message['format']} message of version {message.get('version')!r}; this "
            f"package reads version {VERSION}: update it"
        )
    if message["format"] != READINGS_FORMAT:
        return message["format"], message
    return READINGS_FORMAT, _batch(message)


def _batch(message: dict) -> ReadingBatch:
    count = message.get("count")
    columns = {}
    for entry in message.get("columns", ()):
        if not (isinstance(entry, list) and len(entry) == 3 and entry[1] in _DTYPES):
            raise InputError(f"a readings column {str(entry)[:60]!r} is not [name, type, data]")
        name, dtype, data = entry
        if not isinstance(data, bytes) or len(data) != count * _DTYPES[dtype].itemsize:
            raise InputError(f"readings column {name!r} does not hold {count} values")
        columns[name] = np.frombuffer(data, dtype=_DTYPES[dtype])
    return ReadingBatch(
        channel=int(message["channel"]),
        columns=columns,
        run=str(message.get("run", "")),
        name=str(message.get("name", "")),
    )


def encode_request(name: str, token: str | None = None, **arguments) -> bytes:
    """A control request: ``{"request": name, "token": ..., **arguments}`` as JSON."""
    request = {"request": name, **arguments}
    if token is not None:
        request["token"] = token
    return json.dumps(request).encode()


def decode_json(body: bytes) -> dict:
    """A JSON object from a control message.

    Raises
    ------
    InputError
        For bytes that are not UTF-8 JSON of an object.
    """
    try:
        value = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"not a JSON object ({exc})") from None
    if not isinstance(value, dict):
        raise InputError(f"not a JSON object but {type(value).__name__}")
    return value


def json_safe(value):
    """``value`` with NaN and inf as None, numpy numbers as Python ones, tuples as lists
    (what strict JSON can hold)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
