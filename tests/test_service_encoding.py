"""The wire format of the service: batches round-trip exactly, foreign or damaged messages
are refused with a reason (a client counting gaps and restarts: ``test_service_client.py``)."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

import wavemeter as wm  # noqa: E402
from wavemeter.service.encoding import (  # noqa: E402
    READINGS_FORMAT,
    VERSION,
    channel_topic,
    decode_message,
    encode_batch,
    encode_message,
)
from wavemeter.service.records import CORE_FIELDS  # noqa: E402

from .helpers import reading_batch  # noqa: E402


def test_a_batch_round_trips_exactly():
    batch = reading_batch()
    kind, back = decode_message(encode_batch(batch))
    assert kind == READINGS_FORMAT
    assert (back.channel, back.run, back.name, len(back)) == (3, "r1", "Ti:Sa", 5)
    assert back.fields == (*CORE_FIELDS, "true_frequency_hz")
    for name, values in batch.columns.items():
        np.testing.assert_array_equal(back.columns[name], values)  # NaN included, bit for bit
    readings = list(back.readings())
    assert [r.sequence for r in readings] == [0, 1, 2, 3, 4]
    assert readings[1].flags == int(wm.ReadingFlag.INVALID) and np.isnan(readings[1].frequency_hz)
    assert readings[0].true_frequency_hz == batch.columns["true_frequency_hz"][0]
    assert isinstance(readings[0].sequence, int) and readings[0].channel == 3
    with pytest.raises(AttributeError, match="no field 'order_error_probability'"):
        _ = readings[0].order_error_probability


def test_foreign_or_damaged_messages_are_refused_with_a_reason():
    body = encode_batch(reading_batch())
    message = msgpack.unpackb(body)
    cases = [
        (b"\xc1 not msgpack", "not msgpack"),
        (msgpack.packb([1, 2]), "unknown format"),
        (msgpack.packb({"format": "other.thing", "version": 1}), "unknown format"),
        (msgpack.packb({**message, "version": VERSION + 1}), "version 2"),
        (msgpack.packb({**message, "count": 6}), "does not hold 6"),
        (msgpack.packb({**message, "columns": [["sequence", "|O", b"x"]]}), "is not"),
    ]
    for data, reason in cases:
        with pytest.raises(wm.InputError, match=reason):
            decode_message(data)


def test_other_messages_decode_as_maps_and_topics_end_in_a_slash():
    kind, message = decode_message(encode_message("wavemeter.heartbeat", run="r", time_ns=5))
    assert kind == "wavemeter.heartbeat" and message["time_ns"] == 5
    assert channel_topic(3) == b"ch/3/" and not channel_topic(30).startswith(channel_topic(3))
