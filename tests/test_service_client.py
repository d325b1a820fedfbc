"""The service's client: it counts the readings it missed (gaps in the sequences) and the
service's restarts (a new run numbering from 0 again)."""

from __future__ import annotations

import pytest

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

from wavemeter.service.client import _Tracker  # noqa: E402
from wavemeter.service.encoding import channel_topic, encode_batch  # noqa: E402

from .helpers import reading_batch  # noqa: E402


def test_the_client_counts_gaps_and_restarts():
    tracker = _Tracker(token=None, channel=None)

    def take(batch):
        return tracker.take([channel_topic(batch.channel), encode_batch(batch)])

    take(reading_batch(0, 5))
    take(reading_batch(5, 5))
    assert tracker.missed == 0
    take(reading_batch(12, 5))  # 10 and 11 lost
    assert tracker.missed == 2
    take(reading_batch(0, 5, run="r2"))  # a restarted service numbers from 0 again
    take(reading_batch(5, 5, run="r2"))
    assert (tracker.missed, tracker.restarts) == (2, 1)
